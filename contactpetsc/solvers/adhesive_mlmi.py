"""A multilevel preconditioner for the whole reduced adhesive Jacobian (``-<prefix>preconditioner mlmi``).

The Newton system (``adhesive_jacobian.py``) has, per node, the rows

    contact node (q free):  (K dp)_i = r_q,i
    other nodes:            alpha_i dp_i + beta_i (K dp)_i = r_a,i

for the total pressure correction dp = dq + da, with alpha = kappa (1 + shift),
beta = -kappa A_ii for the pressure-form rows of the law (A = da/dg) and
alpha = shift kappa - G'(a), beta = 1 for gap-form rows; at a contact node the
a row then gives da_i = (r_a,i + kappa A_ii r_q,i) / alpha_i.  Divided by beta,
every row is one of

    L dp = (K + C) dp = f,   C = diag(c), c = alpha / beta (0 at contact nodes):

a half-space operator plus the local stiffness of the law, which a spectral
K^-1 cannot see.  MLMI solves it by a multilevel cycle in the manner of Venner
& Lubrecht's multilevel multi-integration with distributive relaxation:

* smoother: distributive Jacobi (``mlmi.py``: the correction spread over the
  node and its distributive neighbours with D = [1, -1/4 x 4], local diagonal
  lambda_i + c_i) on the contact rows and the wall side of the law
  (-K_ii < c_i < 1e4 K_ii: a smooth error there still sees K's large smooth
  eigenvalues); plain Jacobi with the diagonal K_ii + c_i on the attractive
  tail (c_i <= -K_ii) and on rows local whatever the mode (c_i larger).
  Both from one residual, damped so that a power-iteration estimate of the
  smoothing operator's spectral radius times 1.1 stays below 1.6 (the
  estimate of each Newton step starts from the last one's vector);
* coarse grids: the hierarchy of ``mlmi.py`` (the half-space operator
  rediscretised on the 2x coarser grid, as the nested iteration's coarse
  problems), c restricted by 2 x 2 means (the Galerkin product R C P of the
  constant prolongation), residuals by 2 x 2 means, corrections copied to the
  children;
* coarsest grid: an exact dense solve of K_c + C_c (K_c built once from the
  operator; on a periodic cell its mean mode gets the lowest mode's stiffness
  so that it stays regular where c vanishes), gathered on every rank;
* a V(0, 1)-cycle (the coarse correction straight from the right-hand side,
  then one sweep: one residual per level, 1.33 fine-grid FFT pairs a cycle; V(1, 1) cost
  twice that for at most 10 % fewer Krylov iterations): a fixed linear operator, for
  GMRES or BiCGStab (L is not symmetric in general: c < 0 on the attractive tail).

Options (the adhesive prefix, the names of ``mlmi.py``): ``mlmi_levels``,
``mlmi_min_size`` (the hierarchy), ``mlmi_pre``/``mlmi_post`` (sweeps, 0 and 1),
``mlmi_coarse_sweeps`` (4, where the coarsest grid is too large to invert),
``mlmi_power_its`` (2 per set-up, 3x that at the first) and ``mlmi_rho_bound`` (1.6).
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..collective import collective_guard
from ..log_events import log_event
from .mlmi import shared_levels
from .reduced import view_context
from .transfer import add_prolonged, children, restrict

#: the coarsest grid is solved exactly when it has at most this many nodes, else smoothed
DENSE_MAX = 1024
#: c above this multiple of K_ii: the row is a pure local one (the law nearly flat, A ~ 0)
C_CAP = 1e8
#: c from this multiple of K_ii on: the smoother treats the row as local (Jacobi)
DIST_MAX = 1e4
#: the first set-up's power iterations, in multiples of ``mlmi_power_its`` (no vector to start from)
FIRST_POWER_ITS = 3


def distributive(c: np.ndarray, k_ii: float) -> np.ndarray:
    """The rows the smoother relaxes distributively: -K_ii < c < DIST_MAX K_ii.  Where c >= 0
    (contact, the wall side of the law) a smooth error over a zone still sees K's large smooth
    eigenvalues, which Jacobi with K_ii + c over-corrects many times (the cycle's damping then
    fell to ~0.14 on every row); D localises them.  Jacobi on the attractive tail (c <= -K_ii)
    and on rows with c so large that they are local whatever the mode (held at a bound,
    a flat law)."""
    return (c > -k_ii) & (c < DIST_MAX * k_ii)


class _Level:
    """One grid's share of the cycle: c, the smoother's scalings, work arrays."""

    def __init__(self, base, work):
        self.base = base            # mlmi.Level: operator, influence coefficients, halos
        self.op, self.grid = base.op, base.grid
        # the cycle's work arrays, shared by the problem's cycles (Newton, tangent, PTC):
        # none outlives an application or a set-up
        self.x, self.r, self.ku, self.s1, self.s2 = work
        self.dense = None           # (K_c as a dense matrix, lowest mode term) on the coarsest
        self.v = None               # the last power iteration's vector (unit norm)

    def release(self) -> None:
        """Drop the set-up's arrays (not the power iteration's vector, the next set-up's start)."""
        self.c = self.kdom = self.scale = self.jac = self.keep = self.inverse = None

    def set_c(self, c: np.ndarray, power_its: int, bound: float) -> None:
        """c on this level; the smoother's split, scalings and damping."""
        b = self.base
        self.c = c
        k_ii = b.k0
        self.kdom = distributive(c, k_ii)
        # in place, in the work arrays and the two that are kept (scale, jac): a set-up's
        # temporaries had made the tangent's set-up a path's peak of memory
        kd = self.scale = self.kdom.astype(float)
        sx, sy = b.neighbour_sums(kd, self.s1, self.s2)
        lam = np.multiply(sx, b.kx, out=sx)
        lam += np.multiply(sy, b.ky, out=sy)
        lam *= 0.25
        np.subtract(b.k0, lam, out=lam)
        lam += c
        positive = lam > 0
        np.copyto(lam, 1.0, where=~positive)
        np.divide(b.omega, lam, out=lam)
        np.sqrt(lam, out=self.scale)                      # (omega / lambda)^1/2 ...
        np.copyto(self.scale, 0.0, where=~(self.kdom & positive))   # ... on the distributive rows
        diag = np.add(c, k_ii, out=self.s1)               # the diagonal k_ii + c ...
        np.copyto(diag, 1.0, where=diag == 0)
        self.jac = np.divide(1.0, diag)                    # ... inverted off the distributive rows
        np.copyto(self.jac, 0.0, where=self.kdom)
        self.theta = 1.0
        comm = self.grid.mpi_comm
        v = self.v
        if v is None:
            # first set-up: every other node, both the smooth and the rough modes of each zone
            i = np.arange(self.grid.nx)[None, :]
            j = np.arange(self.grid.ys, self.grid.ye)[:, None]
            v = np.where((i + j) % 2 == 0, 1.0, 0.0)
            v /= np.sqrt(comm.allreduce(float(np.vdot(v, v))))
        rho = 0.0
        for _ in range(power_its if self.v is not None else FIRST_POWER_ITS * power_its):
            # into v itself: the product has read it before the correction writes
            w = self.correction(self.apply(v, self.r), v)
            rho = np.sqrt(comm.allreduce(float(np.vdot(w, w))))
            if rho == 0:
                break
            v = np.divide(w, rho, out=w)
        # the next Newton step's estimate starts from this one's vector: its rows change little
        self.v = v if rho > 0 else None
        if 1.1 * rho > bound:
            self.theta = bound / (1.1 * rho)

    def apply(self, x: np.ndarray, out: np.ndarray) -> np.ndarray:
        """out = (K + C) x."""
        self.op.apply(x, out)
        out += self.c * x
        return out

    def correction(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        """out = theta (S_dist + J_local) r: one smoothing step's correction from the residual r
        (out may be ``s1``; r not ``ku``, which holds the scaled residual)."""
        t = np.multiply(r, self.scale, out=self.ku)
        sx, sy = self.base.neighbour_sums(t, self.s1, self.s2)
        sx += sy
        np.multiply(sx, -0.25, out=sx)
        sx += t
        np.multiply(sx, self.scale, out=out)
        out += np.multiply(self.jac, r, out=sy)
        out *= self.theta
        return out

    def smooth(self, b: np.ndarray, x: np.ndarray, zero_start: bool) -> None:
        r = b if zero_start else np.subtract(b, self.apply(x, self.ku), out=self.r)
        x += self.correction(r, self.s1)

    # -- coarsest grid: exact solve ---------------------------------------------------
    def build_dense(self, lowest_stiffness: float) -> None:
        """K_c as a dense matrix in global row-major order (once; every rank holds it)."""
        g = self.grid
        n = g.nx * g.ny
        k = self.op.as_dense()
        if g.periodic:
            # K has no mean mode there: the lowest mode's compliance keeps K_c + C_c regular
            k += 1.0 / (lowest_stiffness * n)
        self.dense = k

    def factor(self) -> None:
        g = self.grid
        c = np.concatenate(g.mpi_comm.allgather(self.c.reshape(-1)))
        self.inverse = np.linalg.inv(self.dense + np.diag(c))

    def solve(self, b: np.ndarray, x: np.ndarray) -> None:
        g = self.grid
        full = np.concatenate(g.mpi_comm.allgather(b.reshape(-1)))
        sol = self.inverse @ full
        start = g.ys * g.nx
        x[...] = sol[start:start + b.size].reshape(b.shape)


def law_rows(alpha: np.ndarray, beta: np.ndarray, k_ii: float) -> tuple[np.ndarray, np.ndarray]:
    """(c, 1 / beta) of the rows alpha dp + beta (K dp) = r divided by beta: c = alpha / beta,
    with beta floored where the law is flat (beta ~ 0: the row is alpha dp = r, c large, the
    smoother exact there).  ``beta`` (the caller's own array) becomes 1 / beta, in place."""
    floor = np.abs(alpha)
    floor /= C_CAP * k_ii
    small = np.abs(beta) < floor
    np.negative(floor, out=floor, where=small & (beta < 0))
    np.copyto(beta, floor, where=small)
    del floor
    c = np.divide(alpha, beta)
    return c, np.divide(1.0, beta, out=beta)


class AdhesiveCycle:
    """The V-cycle on K + diag(c) (module doc) over a problem's MLMI hierarchy, built once per
    problem in its ``PreconditionerData`` ``data`` for the operator ``op``; options (``mlmi_*``)
    under ``prefix``.  ``set_rows(c)`` sets it up, ``solve(f)`` applies it (the returned array
    is the finest level's work array, valid until the next cycle), ``release()`` frees the
    set-up.  Used by the Newton steps' preconditioner and by the stability check's."""

    def __init__(self, op, data, prefix: str):
        opts = PETSc.Options(prefix)
        base = shared_levels(data, op, prefix)
        if data.mlmi_work is None:
            # three are the hierarchy's own (the pressure-space cycle's; no two cycles overlap)
            data.mlmi_work = [(b.work, b.work2, b.ku, np.zeros_like(b.ku), np.zeros_like(b.ku)) for b in base]
        self.levels = [_Level(b, w) for b, w in zip(base, data.mlmi_work)]
        self.grid = op.grid
        self.power_its = opts.getInt("mlmi_power_its", 2)
        self.bound = opts.getReal("mlmi_rho_bound", 1.6)
        self.coarse_sweeps = opts.getInt("mlmi_coarse_sweeps", 4)
        self.pre = opts.getInt("mlmi_pre", 0)
        self.post = opts.getInt("mlmi_post", 1)
        last = self.levels[-1]
        if last.grid.nx * last.grid.ny <= DENSE_MAX:
            last.build_dense(op.lowest_mode_stiffness())
        self.n_kdom = 0

    @property
    def k_ii(self) -> float:
        """The fine grid's self-influence K_ii [m/Pa]."""
        return self.levels[0].base.k0

    def set_rows(self, c: np.ndarray) -> None:
        """Set up the cycle for the fine grid's c [m/Pa] (ny_loc, nx): the levels' c, smoothers
        and damping, the coarsest grid's factorisation.  Collective."""
        k_ii = self.k_ii
        kind = np.where(distributive(c, k_ii), 0, np.sign(c))   # distributive 0, local rows by the sign of c
        for l, lev in enumerate(self.levels):
            if l:
                # a coarse node whose children mix K-dominated rows with local ones (or local
                # rows of both signs: the attractive tail and the wall side) has no consistent
                # mean row: the cycle leaves it out (no correction there)
                k00, k01, k10, k11 = children(kind)
                same = (k00 == k01) & (k00 == k10) & (k00 == k11)
                kind = np.where(same, k00, 2)
                c = np.where(same, restrict(c), C_CAP * lev.base.k0)
            lev.set_c(c, self.power_its, self.bound)
            lev.keep = kind != 2
        if self.levels[-1].dense is not None:
            self.levels[-1].factor()
        self.n_kdom = self.grid.mpi_comm.allreduce(int(self.levels[0].kdom.sum()))

    def release(self) -> None:
        for lev in self.levels:
            lev.release()

    def solve(self, f: np.ndarray) -> np.ndarray:
        """dp with (K + C) dp ~ f: one cycle from zero."""
        ev = log_event("CPMLMICycle")
        ev.begin()
        dp = self._cycle(0, f)
        ev.end()
        return dp

    def describe(self) -> str:
        sizes = ", ".join(f"{lev.grid.nx}x{lev.grid.ny}" for lev in self.levels)
        coarse = "dense solve" if self.levels[-1].dense is not None else f"{self.coarse_sweeps} sweeps"
        return f"{len(self.levels)} levels ({sizes}); coarsest: {coarse}"

    def _cycle(self, l: int, b: np.ndarray) -> np.ndarray:
        lev = self.levels[l]
        x = lev.x
        x[...] = 0.0
        if l == len(self.levels) - 1:
            if lev.dense is not None:
                lev.solve(b, x)
            else:
                for k in range(self.coarse_sweeps):
                    lev.smooth(b, x, zero_start=k == 0)
            return x
        for k in range(self.pre):
            lev.smooth(b, x, zero_start=k == 0)
        r = np.subtract(b, lev.apply(x, lev.ku), out=lev.r) if self.pre else b
        coarse = self.levels[l + 1]
        bc = restrict(r)
        bc *= coarse.keep
        xc = self._cycle(l + 1, bc)
        xc *= coarse.keep
        add_prolonged(x, xc)
        for _ in range(self.post):
            lev.smooth(b, x, zero_start=False)
        return x


class AdhesiveMLMIPC:
    """V-cycle on (K + C) in the total-pressure correction (see module doc)."""

    _data = None

    def view(self, pc, viewer=None):
        cyc = getattr(self, "cycle", None)
        if cyc is None:
            view_context(viewer, [
                "contactpetsc AdhesiveMLMIPC: V-cycle on K + diag(alpha / beta), the whole reduced adhesive Jacobian",
                "  not set up: its levels are made at the next solve's set-up (freed after each Newton run)"])
            return
        view_context(viewer, [
            "contactpetsc AdhesiveMLMIPC: V-cycle on K + diag(alpha / beta), the whole reduced adhesive Jacobian",
            f"  {cyc.describe()}; K-dominated rows: {cyc.n_kdom} of {self.cycle.grid.nx * self.cycle.grid.ny}"])

    @collective_guard
    def setUp(self, pc):
        _, P = pc.getOperators()
        ctx = self.ctx = P.getPythonContext()
        if self._data is not ctx.parent.pc_data:
            self._data = ctx.parent.pc_data
            self.cycle = AdhesiveCycle(ctx.parent.op, self._data, ctx.parent.prefix)
        pb = ctx.problem
        kappa = pb.kappa
        d = pb.traction.diagonal
        masks = ctx.masks
        q_set = masks[0] if pb.hard_wall else np.zeros(d.shape, bool)
        free = masks[-1] | q_set
        alpha = np.full(d.shape, kappa * (1.0 + pb.shift))
        beta = np.multiply(d, -kappa)
        if pb._gap_rows is not None:
            np.copyto(alpha, pb.shift * kappa - pb._gap_slope, where=pb._gap_rows)
            np.copyto(beta, 1.0, where=pb._gap_rows)
        # the a rows of the contact nodes, kept on those nodes only (a few per cent of the grid:
        # two full arrays had been held through the Newton run)
        self.contact = np.flatnonzero(q_set)
        self.alpha = alpha.reshape(-1)[self.contact]
        self.a_gain = np.multiply(d.reshape(-1)[self.contact], kappa)
        k_ii = self.cycle.k_ii
        # in place (a set-up's temporaries had been the tangent's peak of memory)
        c, inv_beta = law_rows(alpha, beta, k_ii)
        del alpha
        np.copyto(c, 0.0, where=q_set)
        held = ~free
        np.copyto(c, C_CAP * k_ii, where=held)   # unknowns held at a bound: dp = 0
        np.copyto(inv_beta, 0.0, where=held)
        np.copyto(inv_beta, 1.0, where=q_set)
        del held, free
        self.inv_beta = inv_beta
        self.cycle.set_rows(c)

    def reset(self, pc):
        """Free the set-up's arrays between solves (the Newton solver resets its Krylov solver
        then; SNES VI also does where the inactive set changes, a set-up follows)."""
        self.ctx = self.contact = self.alpha = self.inv_beta = self.a_gain = None
        if getattr(self, "cycle", None) is not None:
            self.cycle.release()

    @collective_guard
    def apply(self, pc, x, y):
        ctx = self.ctx
        full, out = ctx.full_arrays(x, y)
        r_a = full[-1]
        hard = ctx.problem.hard_wall
        # the right-hand side of (K + C) dp = f, row by row, in the a block of out until the
        # cycle is done; every block of out is then written whole (q and a with a hard wall)
        f = np.multiply(r_a, self.inv_beta, out=out[-1])
        contact = self.contact
        if hard:
            r_q = full[0].reshape(-1)[contact]
            f.reshape(-1)[contact] = r_q
        dp = self.cycle.solve(f)
        np.copyto(out[-1], dp)
        if hard:
            # at a contact node the a row gives da from (K dp)_i = r_q,i
            da_c = np.multiply(self.a_gain, r_q, out=r_q)
            da_c += r_a.reshape(-1)[contact]
            da_c /= self.alpha
            out[-1].reshape(-1)[contact] = da_c
            q = out[0]
            q[...] = 0.0
            q.reshape(-1)[contact] = dp.reshape(-1)[contact] - da_c
        ctx.finish(out, y)
