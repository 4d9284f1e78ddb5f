"""MLMI: a multilevel preconditioner for the reduced contact Jacobian K_II.

After Venner & Lubrecht (2000), the reference paper's solver family, recast
as a linear preconditioner for Krylov iterations inside the VI Newton method.

Why distributive relaxation.  K is a pseudo-differential operator of order
-1 (symbol 2/(E*|q|)): its smallest eigenvalues belong to the highest
frequencies, so plain Jacobi or Gauss-Seidel damps smooth errors and leaves
rough ones, the opposite of what a multigrid smoother must do.  Distributing
each correction over the node and its four neighbours with the stencil
D = [1 on the node, -1/4 on each neighbour] (symbol
D(q) = 1 - (cos qx dx + cos qy dy)/2 ~ |q|^2) makes the relaxed operator
K D of order +1, which Jacobi smooths well.  Smoother on level l:

    x <- x + Lambda^-1/2 chi_I D chi_I Lambda^-1/2 (b - K_II x),

with Lambda_ii = lambda_i / omega, lambda_i = (chi D chi K chi)_ii =
K_0 - (K_x n_x,i + K_y n_y,i)/4 the local diagonal (n the in-set neighbours
of node i along x and y, K_0, K_x, K_y the self and nearest influence
coefficients), and omega = 2 / (min + max) of the symbol K D / lambda over the
high-frequency half of the modes (optimal Richardson damping there for an
interior node).  The symmetric, local scaling matters: a global 1/lambda
over-corrects nodes with few in-set neighbours (small asperity contacts) and
makes the cycle indefinite.

Coarse grids halve the number of nodes in x and y (spacing doubles) and use
the same half-space operator rediscretised (Love coefficients or 2/(E*|q|)
of the coarse elements).  Transfers: a coarse node belongs to the coarse set
if all of its 2 x 2 children are in I; prolongation copies a coarse correction
to the children in I (pressure is a density), restriction averages the
children's gap residuals (R = P^T / 4, so the cycle is symmetric and R K P
approximates the rediscretised K).  A V(nu1, nu2)- or W-cycle with
``coarse_sweeps`` smoothing sweeps on the coarsest grid is a fixed symmetric
linear operator, so it preconditions CG.  Transfers are rank-local because
the fine grid's row ownership is aligned to 2^(levels-1) rows.

Options (prefix of the solver, e.g. ``-contact_``): ``mlmi_levels`` (max,
default 8), ``mlmi_cycle`` (v|w), ``mlmi_pre``/``mlmi_post`` (sweeps, 1),
``mlmi_coarse_sweeps`` (4), ``mlmi_min_size`` (coarsest grid >= this, 8),
``mlmi_power_its`` (6) and ``mlmi_rho_bound`` (1.6) for the damping bound.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..log_events import log_event
from .preconditioners import ReducedPreconditioner
from .transfer import block_all, can_halve, halved, prolong_constant, restrict


class Level:
    """One grid of the hierarchy: operator, smoothing constants, halo exchange."""

    def __init__(self, op):
        self.op = op
        self.grid = g = op.grid
        f = op.fft
        qx, qy = f.wavevectors(f.Nx * g.dx, f.Ny * g.dy)
        k_hat = op.kernel * (f.Nx * f.Ny)
        d_hat = 1.0 - 0.5 * (np.cos(qx * g.dx) + np.cos(qy * g.dy))
        lam = op.spectral_sum(k_hat * d_hat)
        kd = k_hat * d_hat / lam
        # influence coefficients K_0 (self), K_x, K_y (nearest neighbours), for the local diagonal
        self.k0 = op.self_influence
        self.kx = op.spectral_sum(k_hat * np.cos(qx * g.dx))
        self.ky = op.spectral_sum(k_hat * np.cos(qy * g.dy))
        high = (np.abs(qx * g.dx) >= np.pi / 2) | (np.abs(qy * g.dy) >= np.pi / 2)
        comm = g.mpi_comm
        lo = comm.allreduce(float(kd[high].min()) if high.any() else np.inf, op=MPI.MIN)
        hi = comm.allreduce(float(kd[high].max()) if high.any() else 0.0, op=MPI.MAX)
        self.omega = 2.0 / (lo + hi)
        self.halo_lo = np.zeros(g.nx_local)
        self.halo_hi = np.zeros(g.nx_local)
        self.halo_left = np.zeros(g.ny_local)
        self.halo_right = np.zeros(g.ny_local)
        self.work = np.zeros(g.local_shape)
        self.work2 = np.zeros(g.local_shape)
        self.ku = np.zeros(g.local_shape)
        self.mask = None

    def set_mask(self, mask: np.ndarray, power_its: int, bound: float) -> None:
        """The level's part of the inactive set; sets the symmetric scaling of the smoother.

        Start from (omega / lambda_i)^(1/2), then estimate rho(S K_II) by
        ``power_its`` power iterations from every other node of I (a start with
        both the smooth and the rough modes of each contact patch; rank-independent) and scale S down
        so that the estimate, times a 10 % margin, stays below ``bound`` < 2:
        then every sweep is a contraction in the energy norm and the cycle is
        positive definite on any set.
        """
        grid = self.grid
        key = (power_its, bound)
        same = (self.mask is not None and getattr(self, "_key", None) == key
                and np.array_equal(self.mask > 0, mask))
        if grid.mpi_comm.allreduce(bool(same), op=MPI.LAND):
            return  # same set: same scaling and the same (guaranteed) damping bound
        self._key = key
        self.mask = mask.astype(float)
        sx, sy = self.neighbour_sums(self.mask, self.work, self.ku)
        lam = self.k0 - 0.25 * (self.kx * sx + self.ky * sy)   # (chi D chi K chi)_ii
        with np.errstate(divide="ignore", invalid="ignore"):
            self.scale = np.where(self.mask > 0, np.sqrt(self.omega / np.where(lam > 0, lam, 1.0)), 0.0)
        comm = grid.mpi_comm
        i = np.arange(grid.xs, grid.xe)[None, :]
        j = np.arange(grid.ys, grid.ye)[:, None]
        v = np.where((i + j) % 2 == 0, 1.0, 0.0) * self.mask
        norm = np.sqrt(comm.allreduce(float(np.vdot(v, v))))
        rho = 0.0
        if norm > 0:
            v /= norm
            for _ in range(power_its):
                self.op.apply(v, self.ku)
                self.ku *= self.mask
                w = self.distribute(self.ku, self.work2.copy())
                rho = np.sqrt(comm.allreduce(float(np.vdot(w, w))))
                if rho == 0:
                    break
                v = w / rho
        self.rho = 1.1 * rho
        if self.rho > bound:
            self.scale *= np.sqrt(bound / self.rho)

    def neighbour_sums(self, r: np.ndarray, sx: np.ndarray, sy: np.ndarray):
        """(sum over the 2 x-neighbours, sum over the 2 y-neighbours) of r; halo rows and
        columns from adjacent ranks (or, periodic, the wrap-around)."""
        grid = self.grid
        grid.halo_rows(r, self.halo_lo, self.halo_hi, edge="zero", left=self.halo_left, right=self.halo_right)
        # each sum is (left + right) exactly as zero-fill-and-add gave it, two passes fewer
        sx[:, 1:] = r[:, :-1]
        sx[:, 0] = self.halo_left
        sx[:, :-1] += r[:, 1:]
        sx[:, -1] += self.halo_right
        sy[1:] = r[:-1]
        sy[0] = self.halo_lo
        sy[:-1] += r[1:]
        sy[-1] += self.halo_hi
        return sx, sy

    def distribute(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        """out = S r = Lambda^-1/2 chi D chi Lambda^-1/2 r (omega folded into Lambda): symmetric."""
        t = r * self.scale
        sx, sy = self.neighbour_sums(t, out, self.work2)
        sx += sy
        np.multiply(sx, -0.25, out=sx)
        sx += t
        sx *= self.scale
        return sx

    def residual(self, b: np.ndarray, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        """out = b - chi_I K x."""
        self.op.apply(x, self.ku)
        np.subtract(b, self.ku * self.mask, out=out)
        return out

    def smooth(self, b, x, sweeps: int, zero_start: bool) -> np.ndarray:
        for k in range(sweeps):
            r = b if (zero_start and k == 0) else self.residual(b, x, self.work)
            x += self.distribute(r, self.ku)
        return x


def build_levels(fine_op, max_levels: int = 8, min_size: int = 8) -> list[Level]:
    """Halve the grid while both sizes stay even, >= min_size, and every rank keeps an even row count."""
    g = fine_op.grid
    levels = [Level(fine_op)]
    while len(levels) < max_levels:
        if not can_halve(g) or g.nx // 2 < min_size or g.ny // 2 < min_size:
            break
        gc = halved(g)
        op = fine_op.on_grid(gc, planner="estimate", prefix=fine_op.prefix)
        levels.append(Level(op))
        g = gc
    return levels


def shared_levels(data, op, prefix: str) -> list[Level]:
    """The hierarchy of one problem's preconditioners and cycles: built on the first request
    into its ``PreconditionerData`` ``data`` for the fine operator ``op``
    (``-<prefix>mlmi_levels``, ``-<prefix>mlmi_min_size``), then shared."""
    if data.mlmi_levels is None:
        opts = PETSc.Options(prefix)
        data.mlmi_levels = build_levels(op, opts.getInt("mlmi_levels", 8), opts.getInt("mlmi_min_size", 8))
    return data.mlmi_levels


class MLMIPC(ReducedPreconditioner):
    """Multilevel V/W-cycle with distributive Jacobi smoothing on the inactive set (see module doc)."""

    def initialize(self, ctx):
        data = ctx.parent.pc_data
        prefix = ctx.parent.prefix
        opts = PETSc.Options(prefix)
        self.levels = shared_levels(data, ctx.op, prefix)
        self.cycle = opts.getString("mlmi_cycle", "v").lower()
        if self.cycle not in ("v", "w"):
            raise ValueError(f"{prefix}mlmi_cycle must be v or w, got {self.cycle!r}")
        self.pre = opts.getInt("mlmi_pre", 1)
        self.post = opts.getInt("mlmi_post", 1)
        self.coarse_sweeps = opts.getInt("mlmi_coarse_sweeps", 4)
        self.power_its = opts.getInt("mlmi_power_its", 6)
        self.bound = opts.getReal("mlmi_rho_bound", 1.6)
        # the distributive stencil and (on periodic cells) K vanish at q = 0, so the
        # cycle leaves the mean of p on I alone; a rank-one term gives it the
        # stiffness of the lowest mode, keeping M positive definite
        if data.mlmi_mean_stiffness is None:
            data.mlmi_mean_stiffness = ctx.op.lowest_mode_stiffness()
        self.mean_stiffness = data.mlmi_mean_stiffness

    def update(self, ctx):
        mask = ctx.mask
        for l, lev in enumerate(self.levels):
            lev.set_mask(mask, self.power_its, self.bound)
            if l + 1 < len(self.levels):
                mask = block_all(mask)
        self.n_set = max(ctx.grid.mpi_comm.allreduce(int(ctx.mask.sum())), 1)
        self.x = [np.zeros_like(lev.mask) for lev in self.levels]
        self.r = [np.zeros_like(lev.mask) for lev in self.levels]

    def describe(self):
        sizes = ", ".join(f"{lev.grid.nx}x{lev.grid.ny}" for lev in self.levels)
        return [f"contactpetsc MLMIPC: {self.cycle.upper()}-cycle on {len(self.levels)} levels ({sizes})",
                f"  smoothing {self.pre} pre, {self.post} post, {self.coarse_sweeps} on the coarsest; "
                f"damping bound {self.bound:g} from {self.power_its} power iterations"]

    def _cycle(self, l: int, b: np.ndarray) -> np.ndarray:
        lev = self.levels[l]
        x = self.x[l]
        x[...] = 0.0
        if l == len(self.levels) - 1:
            return lev.smooth(b, x, self.coarse_sweeps, zero_start=True)
        lev.smooth(b, x, self.pre, zero_start=True)
        for _ in range(2 if self.cycle == "w" else 1):
            r = lev.residual(b, x, self.r[l])
            bc = restrict(r) * self.levels[l + 1].mask
            ec = self._cycle(l + 1, bc)
            x += prolong_constant(ec) * lev.mask
        return lev.smooth(b, x, self.post, zero_start=False)

    def inner(self, f, out):
        ev = log_event("CPMLMICycle")
        ev.begin()
        out[...] = self._cycle(0, f)
        mean_f = self.levels[0].grid.mpi_comm.allreduce(float(f.sum())) / self.n_set
        out += (self.mean_stiffness * mean_f) * self.levels[0].mask
        ev.end()
        return out
