"""The SNES callbacks of ``AdhesiveProblem``: residual, Jacobian update, step limit and the
convergence test with its error measures (docs/formulation.md, "Adhesive contact: unknowns and Newton")."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_guard, max_error
from .base import convergence_verdict, weighted_pairs


def total_pressure(blocks: np.ndarray) -> np.ndarray:
    """p = q + a [Pa] of unknowns ``blocks`` ((n_blocks, ny_loc, nx): [q,] a); with one block
    (the full LJ curve) that block itself, not a copy."""
    return blocks.sum(axis=0) if blocks.shape[0] > 1 else blocks[0]


class AdhesiveCallbacks:
    """Mixin of ``AdhesiveProblem``: what the SNES calls back."""

    #: every how many unknowns one goes into the scratch gap's fingerprint (``_current_gap``)
    MARK_STRIDE = 61
    #: (approach, control, sum, sample) of the unknowns whose gap and K p the scratch rows hold,
    #: or None
    _gap_mark = None

    def _gap(self, blocks: np.ndarray, out: np.ndarray) -> np.ndarray:
        """The gap [m] (``VIProblem.gap``) of the unknowns ``blocks``; K p stays in ``_v`` (whose
        point is then no longer the one ``_current_gap`` recognises)."""
        self._gap_mark = None
        return self.gap(total_pressure(blocks), out, displacement=self._v)

    def _mark(self, blocks: np.ndarray) -> tuple:
        # under central-gap control the gap follows the prescribed central gap, not the approach
        control = self._central_gap if self.centre_owner is not None else None
        flat = blocks.reshape(-1)
        return self._approach, control, float(flat.sum()), flat[::self.MARK_STRIDE].copy()

    def _current_gap(self, blocks: np.ndarray) -> np.ndarray:
        """The scratch rows ``_g`` (and ``_v``) at the unknowns ``blocks``: made (one FFT pair)
        unless they hold them already.  SNES asks for the Jacobian at the point whose residual its
        line search has just evaluated, and the check, the tangent and the state's fields come
        at the converged point of Newton's last residual.  The rows are recognised by a
        fingerprint of the unknowns (the approach or prescribed central gap, their sum and every
        ``MARK_STRIDE``-th one; a solve starts without one), not
        a copy: a point taken for another would only linearise the law at a nearby gap, which
        the next residual, always exact, corrects.  Collective: every rank makes them or none."""
        here, mark = self._mark(blocks), self._gap_mark
        same = mark is not None and here[:3] == mark[:3] and np.array_equal(here[3], mark[3])
        if not self.grid.mpi_comm.allreduce(same, op=MPI.LAND):
            self._gap(blocks, self._g)
            # the approach as the gap left it (central-gap control sets it from the unknowns)
            self._gap_mark = (self._approach,) + here[1:]
        return self._g

    def no_equilibrium(self, approach: float) -> str | None:
        """Why no state exists at ``approach`` delta [m], or None: a hard wall on a periodic cell,
        where K has no mean mode and the mean gap is mean(h) - delta, cannot keep g >= 0 where
        that is negative.  Collective."""
        if not (self.hard_wall and self.grid.periodic):
            return None
        grid = self.grid
        mean_gap = grid.mpi_comm.allreduce(float(grid.rows(self.heights, readonly=True).sum())) / (
            grid.nx * grid.ny) - float(approach)
        if mean_gap >= 0:
            return None
        return (f"NO_EQUILIBRIUM (periodic cell: the mean gap mean(h) - delta = {mean_gap:.4e} m is negative, "
                f"a hard wall cannot keep g >= 0; state: the last converged state's pressures)")

    def control_approach(self, h_plus_v: np.ndarray) -> float:
        """delta [m]; under central-gap control the one that gives the control node its gap."""
        if self.centre_owner is not None:
            self._approach = self.centre_value(h_plus_v) - self._central_gap
        return self._approach

    @collective_guard
    def _residual(self, snes, x, f):
        xb, fb = self.blocks(x, readonly=True), self.blocks(f)
        g = self._current_gap(xb)
        if self.hard_wall:
            fb[0] = g
        fa, a = fb[-1], xb[-1]
        self.traction.pressure(g, out=fa)
        # |a - a(g)| relative to P + |a(g)| (P the law's peak attraction): the pressure
        # error on the law's own scale, which K_ii |a - a(g)| in z0 cannot see when
        # w / (E* z0) is small; on the repulsive side |a(g)| makes it a gap error
        scale = np.abs(fa)
        scale += self.pressure_scale
        np.subtract(a, fa, out=fa)
        self._adhesive_residual = float(np.abs(fa).max()) * self.kappa
        self._pressure_residual = float((np.abs(fa) / scale).max())
        fa *= self.kappa
        if self.gap_form:
            # on the repulsive side (g < 0) the row is g - G(a), G the law's
            # inverse: Newton on a = a(g) there moves g by at most ~g/9 per step when g is
            # too small (a ~ g^-9 is convex); on g = G(a) it goes to G(a) at once
            rows = self._repulsive_rows(a, g)
            fa[rows] = g[rows] - self.traction.repulsive_gap(a[rows])[0]

    @collective_guard
    def _limit_step(self, x, y):
        """Shorten the Newton step x - y so that no gap falls more than ``step_limit`` z0
        below min(g, 0): a linear model taken in the attractive tail can send nodes deep
        into the LJ wall (errors of thousands of z0), which costs several steps to undo."""
        g = self._g   # the gap at x: the Jacobian was just evaluated there
        dp = -self.blocks(y, readonly=True).sum(axis=0)
        dg = self.op.apply(dp, dp)    # in place: dp is this call's own temporary
        if self.centre_owner is not None:
            dg -= self.centre_value(dg)
        floor = np.minimum(g, 0.0) - self.step_limit * self.z0
        deep = (g + dg < floor)
        lam = float(np.min((g[deep] - floor[deep]) / -dg[deep])) if deep.any() else 1.0
        lam = self.grid.mpi_comm.allreduce(lam, op=MPI.MIN)
        if lam < 1.0:
            y.scale(max(lam, 0.1))
        return lam < 1.0

    @staticmethod
    def _repulsive_rows(a: np.ndarray, g: np.ndarray) -> np.ndarray:
        return g < 0

    @collective_guard
    def _jacobian(self, snes, x, J, P):
        xb = self.blocks(x, readonly=True)
        self._current_gap(xb)
        self.traction.linearise(self._g)
        if self.gap_form:
            rows = self._repulsive_rows(xb[-1], self._g)
            slope = np.zeros_like(self._g)
            slope[rows] = self.traction.repulsive_gap(xb[-1][rows])[1]
            self._gap_rows, self._gap_slope = rows, slope
            # the rows' flat positions and slopes: the Jacobian applies them once or twice
            # per Krylov iteration, and gathers of a few rows beat boolean masks of all of them
            at = np.flatnonzero(rows)
            self._gap_at = (at, slope.reshape(-1)[at])
        if self.shift:
            # switched evolution relaxation: the shift follows the residual, falling as
            # it falls (towards Newton), rising when a step made it worse
            err, prev = self._last_error, self._ptc_prev
            if prev > 0 and np.isfinite(err):
                self.shift = float(np.clip(self.shift * err / prev, 1e-8, 1e8))
            self._ptc_prev = err

    def _measures(self, x, f):
        """(complementarity error [z0], self-consistency error [z0], pressure error [relative],
        mean p, contact fraction) at the last residual evaluation.

        The pressure error is the largest of |a - a(g)| / (P + |a(g)|) and |min(q / P, g / z0)|
        (P the law's peak attraction, ``pressure_scale``): pressures right on the law's
        own scale, whatever w / (E* z0) -- the errors in z0 are K_ii times pressure errors
        and vanish with the pressures themselves."""
        comm = self.grid.mpi_comm
        xb, fb = self.blocks(x, readonly=True), self.blocks(f, readonly=True)
        p = xb.sum(axis=0)
        errs = np.array([0.0, self._adhesive_residual, self._pressure_residual])
        if self.hard_wall:
            q, g = xb[0], fb[0]
            errs[0] = float(np.abs(np.minimum(self.kappa * q, g)).max()) / self.z0
            errs[2] = max(errs[2], float(np.abs(np.minimum(q / self.pressure_scale, g / self.z0)).max()))
        errs[1] /= self.z0
        # a NaN counts as infinite: Python's max() below would drop it (a NaN state measured 0)
        errs = max_error(comm, errs)
        sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p > 0)], float))
        n = self.grid.nx * self.grid.ny
        return errs[0], errs[1], errs[2], sums[0] / n, sums[1] / n

    def fft_pairs(self) -> float:
        """FFT pairs so far in fine-grid units: the operator's, plus those of the coarse
        levels of any MLMI cycle (preconditioner or relaxation; those freed between solves
        too) and of the nested iteration, weighted by their size."""
        ops = {id(self.op): self.op}
        levels = (self._jac.pc_data.mlmi_levels or ()) if self._snes is not None else ()
        for lev in levels:
            ops[id(lev.op)] = lev.op
        pairs = weighted_pairs(ops.values(), self.grid) + self._released_pairs
        return pairs + (self.coarse_levels.fft_pairs() if self.coarse_levels is not None else 0.0)

    @collective_guard
    def _converged(self, snes, it, norms):
        x, f = snes.getSolution(), snes.getFunction()[0]
        err_c, err_a, err_p, mean_p, frac = self._measures(x, f)
        self.history.append(
            solve=self._n_solves, iteration=it, fft_pairs=self.fft_pairs(),
            linear_iterations=self._lin0 + snes.getLinearSolveIterations(),
            complementarity_error=err_c, load_error=float("nan"), approach=self._approach,
            mean_pressure=mean_p, contact_fraction=frac, solver=self.solver_name,
            adhesive_error=err_a, pressure_error=err_p)
        # the PTC shift and the stall watch (``newton.py``) follow the errors in z0 (their trend, not their size)
        err = max(err_c, err_a)
        self._last_error = err
        # converged: gaps right in z0 and pressures right on the law's scale, both to tol
        full = max(err, err_p)
        self._keep_if_best(full, f"{'ptc' if self.shift else 'Newton'} iteration {it}", x)
        verdict = convergence_verdict(snes, it, full, self.tol)
        if verdict == PETSc.SNES.ConvergedReason.ITERATING and self.out_of_time():
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT   # named WALL_TIME_BUDGET by VINewton.run
        return verdict

    def offer_iterate(self, label: str) -> None:
        """Measure the unknowns as they stand (the last state of a descent that failed, which
        no SNES convergence test saw) and keep them as the solve's best iterate where their
        error is the smallest so far: a failed solve reports its best iterate (``solve``), and a
        descent that ran out of iterations near a minimum is nearer to a state than a Newton
        iterate that diverged.  One FFT pair.  Collective."""
        f = self.create_unknown()
        try:
            self._residual(None, self._x, f)
            err_c, err_a, err_p, _, _ = self._measures(self._x, f)
        finally:
            f.destroy()
        self._keep_if_best(max(err_c, err_a, err_p), label, self._x)

    def _keep_if_best(self, error: float, label: str, x: PETSc.Vec) -> None:
        """Keep ``x`` as the running solve's best iterate where ``error`` is below the best so
        far (an infinite error, a NaN's, never is)."""
        if error < self._solve_best[0]:
            self._solve_best = (error, label)
            if self._x_solve_best is None:   # made on demand, freed by ``release``
                self._x_solve_best = x.duplicate()
            x.copy(self._x_solve_best)

    def saved_start(self) -> PETSc.Vec:
        """The unknowns as they were when first asked for in this solve: the solve's start, which
        its fallbacks and (after a failure) the next solve start from.  A strategy that
        overwrites the unknowns asks first; made once per solve, freed at its end."""
        if self._x_start is None:
            self._x_start = self._x.copy()
        return self._x_start

    def _drop_start(self) -> None:
        if self._x_start is not None:
            self._x_start.destroy()
            self._x_start = None

    def _drop_solve_best(self) -> None:
        """Free the running solve's best iterate (its failure report is written)."""
        if self._x_solve_best is not None:
            self._x_solve_best.destroy()
            self._x_solve_best = None

    @property
    def solver_name(self) -> str:
        return f"newton-vi+{self.preconditioner}"
