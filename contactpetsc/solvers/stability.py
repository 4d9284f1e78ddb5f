"""Stability of a converged adhesive state: the top eigenvalue of a pencil.

Equilibria of adhesive contact are stationary points of the elastic plus
interaction energy.  In displacement space, with the contact nodes C held at
zero gap (their pressure is the multiplier), the Hessian on the other nodes N is

    H = (K^-1)_NN - A_N,      A = da/dg (the law's derivative),

on W, the displacements that vanish on C (and, on a periodic cell, have zero
mean: K there has no mean mode).  H is positive definite iff every eigenvalue
lambda of the pencil A x = lambda (K^-1)_NN x is below one.  The reported
margin is 1 - lambda_max: positive = stable, negative = unstable.  An
instability is a smooth mode over the attractive zone beyond the force peak,
where A > 0, the well separated top of the pencil.

Two ways to lambda_max:

* Periodic grids: LOBPCG on the pencil itself (K^-1 is diagonal in Fourier space
  there).  It stops when the K-norm of the top Ritz pair's residual is below
  ``RESIDUAL_TOL``.  Preconditioned (``-<prefix>stability_preconditioner``) by

  - ``compliance``: K restricted to W; an iteration costs two FFT pairs (one
    K^-1, one K).  In effect a power iteration: it stalls where the top of the
    pencil is a cluster of asperity modes (rough surfaces at 1024^2 and up).
  - ``mlmi`` or ``multigrid``: an approximate H^-1 (``stability_pc.py``), with
    which the iteration converges like inverse iteration near the top of the
    pencil: the adhesive multilevel cycle on H's pressure form (where A >= 0 on
    N: the exponential law), or a displacement-form V-cycle on H (any sign of A:
    the LJ laws).
  - ``auto`` (the default): ``mlmi`` where A >= 0 on N, else ``multigrid``.
* Isolated windows with contact nodes: LOBPCG on the window's padded grid
  (``descent_space.PaddedWindow``), where the displacement of the whole padded grid is the
  unknown: its energy 1/2 u . C^-1 u plus the law on the window has the Hessian C^-1 - A on
  u = 0 at C, whose minimum over the nodes outside the window is the window's (K^-1)_NN - A.
  So the padded pencil A x = lambda C^-1 x has the window's lambda_max, and C^-1 (the padded
  circulant's inverse) is diagonal in Fourier space: no inner solve.  Preconditioned by the
  compliance C (two FFT pairs an iteration) for its first
  ``stability_window.COMPLIANCE_FIRST`` iterations, where a coarse or weakly adhesive window
  settles, then by the displacement cycle on the padded H (``stability_pc.padded_levels``,
  about four and a half pairs an iteration), whose iterations do not grow as dx / z0 falls
  where the compliance's do: ``auto``; ``compliance`` or ``multigrid`` throughout on request.
  Needs whole rows per rank.
* Other windows (no contact nodes, or a grid split along x): Lanczos on A S, S =
  ((K^-1)_NN)^-1 = K_NN - K_NC K_CC^-1 K_CN the compliance of N with C clamped,
  self-adjoint in the S inner product.  S is one FFT pair, plus (with contact nodes) a CG
  solve on K_CC preconditioned by the Fourier inverse, to a tenth of ``tol``.  It stops
  when the Ritz value changes by less than ``tol``.  The top of the pencil is a cluster (a
  contact ring's modes around its circumference): the settled Ritz value can sit short of
  lambda_max by more than ``tol`` (docs/performance.md, "The stability check on a window").

In both the top Ritz value grows monotonically towards lambda_max (a Ritz value
above one proves instability, to the inner CG's tolerance where S is one), and an
unsettled positive margin is an upper bound.  The nodal law derivative is used
also with element integration (its linearisation is not symmetric).  The windows' two
methods live in ``stability_window.py``; LOBPCG itself (``_lobpcg``) here, which both the
cell's and the padded check run.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..log_events import log_event
from ..physics.traction import node_blocks
from .options import code_default


#: LOBPCG stops when the K-norm of the top Ritz pair's residual, A x - theta (K^-1)_NN x with
#: x of unit (K^-1)_NN-norm, is below this (times max(1, theta)).  The Ritz value's error is
#: then of the order of its square over the spectral gap (docs/performance.md, "The stability
#: check: LOBPCG on the pencil"), where a settled Ritz value (the Lanczos test) can sit on a
#: plateau short of lambda_max
RESIDUAL_TOL = 1e-3

#: LOBPCG's preconditioners (``-<prefix>stability_preconditioner``; module doc)
PRECONDITIONER_CHOICES = ("auto", "compliance", "mlmi", "multigrid")


def preconditioner_choice(value: str, name: str) -> str:
    """``value`` if it is one of PRECONDITIONER_CHOICES, else a ValueError naming ``name``."""
    if value not in PRECONDITIONER_CHOICES:
        raise ValueError(f"{name} = {value!r}: accepted values are {', '.join(PRECONDITIONER_CHOICES)}")
    return value


def stability_margin(problem, gap: np.ndarray, q_rows: np.ndarray | None, steps: int = 60,
                     tol: float = 1e-4, method: str = "auto", residual_tol: float = RESIDUAL_TOL,
                     preconditioner: str = "auto") -> float:
    """1 - lambda_max of the pencil (module doc) at the rank's gap rows ``gap`` [m] (ny_loc, nx)
    of the problem's state, contact pressures ``q_rows`` [Pa] (hard wall) or None; at most
    ``steps`` iterations; collective.  ``method``: "auto" (as in the module doc), or "lobpcg"
    (periodic grids only; stops at ``residual_tol``) or "lanczos" (stops at ``tol``) to
    compare them (``run_scripts/bench/bench_stability.py``), or "padded" (windows; LOBPCG on the
    padded grid, ``residual_tol``).  ``preconditioner``: LOBPCG's,
    "auto", "compliance", "mlmi" (periodic grids) or "multigrid" (module doc;
    ``bench_stability.py --methods``, ``bench_window_stability.py``).

    Returns (margin, settled): settled False when the iteration ran its ``steps`` without
    settling.  The Ritz value only grows towards lambda_max, so an unsettled positive margin
    is an upper bound: the state may still be unstable (seen on rough surfaces, whose top of
    the pencil is a cluster of asperity modes)."""
    grid = problem.grid
    comm = grid.mpi_comm
    d = problem.traction.nodal_derivative(gap)
    contact = (q_rows > 0) if q_rows is not None else np.zeros(gap.shape, bool)
    d[contact] = 0.0       # in place: d is the law's fresh array
    if comm.allreduce(float(d.max()), op=MPI.MAX) <= 0.0:
        return 1.0, True   # A <= 0: no positive eigenvalue
    if method == "auto":
        # a window's LOBPCG on its padded grid needs whole rows; without contact nodes Lanczos'
        # S is K itself, one FFT pair a step (the padded iteration's two)
        padded = grid.px == 1 and comm.allreduce(bool(contact.any()), op=MPI.LOR)
        method = "lobpcg" if grid.periodic else ("padded" if padded else "lanczos")
    if method == "padded":
        from .stability_window import padded_lobpcg
        lam, settled = padded_lobpcg(problem, d, contact, steps, residual_tol, preconditioner)
        return 1.0 - lam, settled
    if method == "lobpcg":
        if not grid.periodic:
            raise ValueError("stability method 'lobpcg' needs a periodic grid (K^-1 diagonal in Fourier space)")
        preconditioner = preconditioner_choice(preconditioner, "stability preconditioner")
        if preconditioner == "auto":
            attractive = comm.allreduce(float(d[~contact].min(initial=0.0)), op=MPI.MIN) >= 0.0
            preconditioner = "mlmi" if attractive else "multigrid"
        hessian = None
        if preconditioner != "compliance":
            from .stability_pc import AdhesiveCyclePreconditioner, DisplacementCycle, cell_levels
            hessian = (AdhesiveCyclePreconditioner(problem, d, contact) if preconditioner == "mlmi"
                       else DisplacementCycle(cell_levels(problem), d, contact))
        try:
            lam, settled = _lobpcg(problem.op, comm, d, contact, steps, residual_tol, precondition=hessian)
        finally:
            if hessian is not None:
                hessian.release()
    else:
        from .stability_window import lanczos
        lam, settled = lanczos(problem, comm, d, contact, _start(grid, d, np.empty(d.shape)), steps, tol)
    return 1.0 - lam, settled


def stability_mode(value: str, name: str) -> tuple[bool, bool]:
    """(check by default, auto) of ``-<prefix>stability_check`` = true, false or auto: with
    auto every solve checks unless its caller leaves the check out (``paths.sweep`` away from
    folds, ``fold_watch.py``)."""
    text = str(value).strip().lower()
    if text in ("", "1", "true", "yes", "on"):
        return True, False
    if text in ("0", "false", "no", "off"):
        return False, False
    if text == "auto":
        return True, True
    raise ValueError(f"{name} = {value!r}: accepted values are true, false, auto")


class StabilityCheck:
    """The stability check of an ``AdhesiveProblem``, a strategy on it: ``-<prefix>stability_check``
    (true, false or auto: ``by_default``, ``auto``), ``-<prefix>stability_steps`` (``steps``) and
    ``-<prefix>stability_preconditioner`` (``preconditioner``, LOBPCG's), read when made (inside
    the problem's ``inserted_options``); ``margin()`` at the problem's state, with ``settled``
    whether its estimate settled."""

    def __init__(self, problem, default):
        self.problem = problem
        opts = PETSc.Options(problem.prefix)
        self.by_default, self.auto = stability_mode(opts.getString("stability_check", str(default)),
                                                    f"-{problem.prefix}stability_check")
        self.steps = opts.getInt("stability_steps", code_default("adhesion", "stability_steps"))
        name = opts.getString("stability_preconditioner", code_default("adhesion", "stability_preconditioner"))
        self.preconditioner = preconditioner_choice(name.strip().lower(), f"-{problem.prefix}stability_preconditioner")
        if self.preconditioner == "mlmi" and not problem.grid.periodic:
            raise ValueError(f"-{problem.prefix}stability_preconditioner mlmi needs a periodic grid; on an isolated "
                             f"window the accepted values are auto, compliance, multigrid")
        self.settled = None   #: whether the last margin's estimate settled

    def margin(self) -> float:
        """1 - lambda_max(A S) at the problem's state (module doc); its time goes to the
        problem's ``check_time``.  Collective."""
        pb = self.problem
        t0 = pb.history.elapsed()
        xb = pb.blocks(pb._x, readonly=True)
        gap = pb._current_gap(xb)
        ev = log_event("CPStabilityCheck")
        ev.begin()
        try:
            margin, self.settled = stability_margin(pb, gap, q_rows=xb[0] if pb.hard_wall else None,
                                                    steps=self.steps, preconditioner=self.preconditioner)
        finally:
            ev.end()
        pb.check_time += pb.history.elapsed() - t0
        return margin


def leaves_checks_out(problem) -> bool:
    """Whether ``problem``'s stability check is ``auto`` (a path may leave it out away from
    folds); False for a problem without one (non-adhesive, a relaxation search) or before
    its options are read."""
    return bool(getattr(getattr(problem, "stability_check", None), "auto", False))


def _start(grid, d: np.ndarray, out: np.ndarray) -> np.ndarray:
    """The iterations' start, into ``out`` (the shape of the law's derivative rows ``d``): the
    positive part of A (the attractive zone beyond the force peak), varied from node to node by
    a fixed hash of the global index (rank-count independent), so that it has every Fourier
    mode: a uniform start is in the null space of the periodic compliance (the mean mode).  A
    block of nodes at a time (the hash's temporaries are a block's)."""
    first = grid.ys * grid.nx       # the global index of this rank's first node
    flat_d, flat_out = d.reshape(-1), out.reshape(-1)
    for block in node_blocks(flat_d.size):
        part = flat_d[block]
        index = np.arange(first + block.start, first + block.start + part.size)
        flat_out[block] = np.maximum(part, 0.0) * (1.0 + 0.5 * np.modf(np.abs(np.sin(index * 12.9898)) * 43758.5453)[0])
    return out


def _lobpcg(op, comm, d, contact, steps, residual_tol, precondition=None, project_mean=True, on_a=slice(None)):
    """(lambda_max estimate, settled) of the pencil A x = lambda (K^-1)_NN x on W by LOBPCG
    (Knyazev's locally optimal block preconditioned CG, block size one) from ``_start``,
    preconditioned by K on W, or by ``precondition(r, out)`` (full (ny_loc, nx) arrays; the
    result is projected on W).  Each Rayleigh-Ritz step is on span{x, w, p} (iterate,
    preconditioned residual, previous direction), so the top Ritz value never decreases
    whatever the preconditioner; the stopping test is the K-norm of the residual in both.
    ``on_a``: the slice of the flat rows outside which A vanishes (a padded window's rows);
    ``project_mean``: whether W excludes the mean (a periodic cell's K^-1 does not see it)."""
    shape = d.shape
    n_free = comm.allreduce(float(d.size - np.count_nonzero(contact)))
    # without contact nodes (the full LJ curve) no mask: two passes a projection less
    masked = n_free < comm.allreduce(d.size)
    # the contact nodes by index: zeroed in place, faster than a full mask's product and a few
    # per cent of a grid array instead of one
    held = np.flatnonzero(contact) if masked else None
    a = d.reshape(-1)[on_a]

    def on_w(x):
        """x projected on W (orthogonally): zero on C and (``project_mean``) of zero mean; in
        place, no temporaries"""
        if masked:
            x[held] = 0.0
        if project_mean:
            x -= comm.allreduce(float(x.sum())) / n_free
            if masked:
                x[held] = 0.0
        return x

    def mult(f, x, out):
        f(x.reshape(shape), out.reshape(shape))
        return on_w(out)

    # rows: the iterate x, the preconditioned residual w, the direction p, and M times each;
    # x and p kept M-normalised and w's M-norm taken into the Gram matrices, so that they need
    # only their off-diagonal M products and the A products (A diagonal: made a row at a time
    # in t, not kept)
    basis, mbasis = np.zeros((3, d.size)), np.zeros((3, d.size))
    x, w, p = basis
    mx, mw, mp = mbasis
    _start(op.grid, d, x)     # in the basis's row: no start array beside it
    on_w(x)
    mult(op.apply_inverse, x, mx)
    nrm = np.sqrt(comm.allreduce(float(x @ mx)))
    if not nrm > 0.0:
        return 0.0, True
    x /= nrm
    mx /= nrm
    r, t = np.empty_like(x), np.empty_like(x)
    theta = comm.allreduce(float(x[on_a] @ np.multiply(a, x[on_a], out=t[on_a])))
    m = 2   # rows of the basis in use (p joins after the first step)
    for _ in range(steps):
        np.multiply(mx, -theta, out=r)
        r[on_a] += np.multiply(a, x[on_a], out=t[on_a])
        on_w(r)
        mult(op.apply, r, w)
        res = np.sqrt(max(comm.allreduce(float(r @ w)), 0.0))
        if theta > 1.0 or res <= residual_tol * max(1.0, abs(theta)):
            return theta, True
        if precondition is not None:
            precondition(r.reshape(shape), w.reshape(shape))
            on_w(w)
        mult(op.apply_inverse, w, mw)
        nw = np.sqrt(comm.allreduce(float(w @ mw)))
        if precondition is not None and not (np.isfinite(nw) and nw > 0.0):
            # the cycle failed on this residual (an indefinite H off the stable states): K r
            mult(op.apply, r, w)
            mult(op.apply_inverse, w, mw)
            nw = np.sqrt(comm.allreduce(float(w @ mw)))
        # Gram matrices of the M-normalised basis: A products in full, M products off the
        # diagonal (ones on it); w stays as it is, its norm taken into the matrices (scale)
        ij = [(0, 1), (0, 2), (1, 2)][:1 if m == 2 else 3]
        a_pairs = [(i, i) for i in range(m)] + ij
        a_dots = {}
        for j in range(m):
            if j:    # t holds A x already (the residual's)
                np.multiply(a, basis[j][on_a], out=t[on_a])
            a_dots.update({(i, j): basis[i][on_a] @ t[on_a] for i, jj in a_pairs if jj == j})
        # one reduction, of an array (a list would be concatenated)
        g = comm.allreduce(np.array([a_dots[pair] for pair in a_pairs] + [basis[i] @ mbasis[j] for i, j in ij]))
        scale = np.ones(m)
        scale[1] = 1.0 / nw
        ga, gm = np.diag(g[:m] * scale ** 2), np.eye(m)
        for k, (i, j) in enumerate(ij):
            ga[i, j] = ga[j, i] = g[m + k] * scale[i] * scale[j]
            gm[i, j] = gm[j, i] = g[m + len(ij) + k] * scale[i] * scale[j]
        # Rayleigh-Ritz in an M-orthonormal basis of the span, dropping directions it has
        # (nearly) lost: p and w become parallel as the iteration converges
        ev, vec = np.linalg.eigh(gm)
        keep = ev > 1e-12 * ev.max()
        z = vec[:, keep] / np.sqrt(ev[keep])
        th, y = np.linalg.eigh(z.T @ ga @ z)
        c = z @ y[:, -1]
        theta = float(th[-1])
        # the new direction and M times it in r and t (both free until the next step); its
        # M-norm from the Gram matrix (the basis' M products)
        nrm = np.sqrt(max(float(c[1:m] @ gm[1:m, 1:m] @ c[1:m]), 0.0))
        coef = c[1:m] * scale[1:m]
        new_p, new_mp = np.matmul(coef, basis[1:m], out=r), np.matmul(coef, mbasis[1:m], out=t)
        for row, new in ((x, new_p), (mx, new_mp)):
            row *= c[0]
            row += new
        nrm_x = np.sqrt(comm.allreduce(float(x @ mx)))
        x /= nrm_x
        mx /= nrm_x
        if nrm > 0.0:
            np.divide(new_p, nrm, out=p)
            np.divide(new_mp, nrm, out=mp)
            m = 3
        else:
            m = 2
    return theta, False
