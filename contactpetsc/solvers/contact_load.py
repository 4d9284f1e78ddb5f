"""Load control of ``ContactProblem`` (docs/formulation.md, "Controls"): one Newton iteration in
(p, delta), delta the multiplier of the load (``JointLoadNewton``); with a hardness, where
W(delta) is a staircase, a safeguarded, inexact Newton iteration on the approach around
displacement-controlled solves, its slope dW/d delta from one reduced solve K_II z = 1 on the
converged contact set (``ContactLoadControl``)."""
from __future__ import annotations

import warnings

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .base import MAX_TOL

#: the smallest mean pressure of load control, in units of E*
MIN_LOAD = 1e-12


class SolverOptionWarning(UserWarning):
    """A solver option that changes the method, and what it costs (docs/robustness.md)."""


class ContactLoadControl:
    """Mixin of ``ContactProblem``: ``_solve_load`` (with a hardness) and the slope it steps with."""

    def _approach_slope(self):
        """(dW/d delta [Pa/m] as d(mean p)/d delta, z = dp/d delta) on the last solve's inactive set.

        Solves K_II z = 1 with its own KSP (options prefix ``<prefix>slope_``),
        preconditioned like the Newton steps.
        """
        grid = self.grid
        p, gap = grid.rows(self._x, readonly=True), grid.rows(self._f, readonly=True)
        inactive = (p > 0) | (gap <= 0)
        if np.isfinite(self.hardness):
            inactive &= (p < self.hardness) | (gap >= 0)   # nodes at the cap stay there: dp = 0
        cached = self._slope_cache
        if cached is not None:
            same = cached[0].shape == inactive.shape and np.array_equal(cached[0], inactive)
            if grid.mpi_comm.allreduce(bool(same), op=MPI.LAND):
                return cached[1], cached[2]   # same set, same K_II: same z
        if self._dp is None:
            self._dp = grid.create_vec()
        if grid.mpi_comm.allreduce(int(np.count_nonzero(inactive))) == 0:
            # every node open or at the cap (a hardness): the load does not move with delta here
            self._dp.set(0.0)
            self._slope_cache = (inactive, 0.0, self._dp)
            return 0.0, self._dp
        local = (np.flatnonzero(inactive) + grid.offset).astype(PETSc.IntType)
        index_set = PETSc.IS().createGeneral(local, comm=grid.comm)
        J = self._snes.getJacobian()[0]
        A = J.createSubMatrix(index_set, index_set)
        ctx = A.getPythonContext()
        ksp = self._slope_ksp
        ksp.reset()  # the inactive set, hence the size, changes between calls
        ksp.setOperators(A, A)
        b, z = A.createVecs()
        b.set(1.0)
        guess = self._z_guess if self.slope_warm else None
        if guess is not None:
            # the last z (or the coarse grid's): the set changes little between outer steps
            ctx.from_full(grid.rows(guess, readonly=True), z)
        else:
            z.set(0.0)
        ksp.setInitialGuessNonzero(guess is not None)
        ksp.solve(b, z)
        self._linear += ksp.getIterationNumber()
        dp = self._dp   # overwritten in place: the warm start z was read above
        dp.set(0.0)
        ctx.to_full(z, grid.rows(dp))
        # petsc4py defers freeing parallel objects to PETSc's garbage until exit:
        # destroy the per-solve temporaries explicitly (collective, all ranks here)
        for obj in (b, z, A, index_set):
            obj.destroy()
        slope = dp.sum() / (self.grid.nx * self.grid.ny)
        self._slope_cache = (inactive, slope, dp)
        self._z_guess = dp
        return slope, dp

    def _solve_load(self, target: float):
        """Safeguarded, inexact Newton on delta; returns (converged, reason).

        W(delta) = mean p is increasing and (for contact of rough surfaces,
        typically) convex, so after the first step the Newton iterates approach
        the root from above; a step is only replaced by bisection when it leaves
        the bracket [lo, hi] of evaluated approaches.  The inner solves are
        inexact: their complementarity tolerance is ``inner_eta`` times the
        last approach update (in units of the length scale), never above
        ``load_inner_tol``; the last solve is to the full tolerance.

        Periodic cells: mean(g) = mean(h) - delta >= 0, so delta <= mean(h) =
        ``bound``, and delta = mean(h) means full contact, where mean p is set
        by the initial guess (the reduced Jacobian keeps the mean of the step at
        zero): a step beyond ``bound`` tries full contact once, with the
        initial pressure's mean set to the target.  With a hardness H, gaps
        at p = H may be negative and delta may pass mean(h), up to max(h)
        (there p = H everywhere, above any admissible target): ``ceiling``.
        With a hardness W(delta) is a staircase where most contact nodes sit at
        H (each node reaching H adds H/n; between, only the few elastic nodes
        move, with a slope far above the staircase's mean one), and it need not
        be convex: every solve is then exact (a loose solve's load may be
        out of order on a steep stair and spoil the bracket), and the step uses
        the secant through the last evaluated state where the Newton step is
        shorter or undefined (no elastic node: zero slope).
        """
        grid = self.grid
        n = grid.nx * grid.ny
        lo = lo0 = float(self.heights.min()[1])  # delta <= min h: no contact, no load
        lo_exact = hi_exact = True
        hi = np.inf                         # smallest evaluated approach with a load above the target
        bound = self.heights.sum() / n if grid.periodic else np.inf
        capped = np.isfinite(self.hardness)
        ceiling = float(self.heights.max()[1]) if capped and grid.periodic else (np.inf if capped else bound)
        tried_full = False
        delta = self._approach if self._approach is not None else lo
        p = self._pressure.copy()
        inner = self.tol if capped else max(self.tol, self.inner_tol0)
        last = None                         # (delta, load) of the last evaluated state
        slope = 0.0
        reason = "no iteration"
        for _ in range(self.max_outer):
            ok, reason = self._solve_at(delta, p, inner)
            if not ok:
                if not (tried_full and delta == bound):
                    return False, reason   # a real failure of the inner solve: report it
                # full contact tried below the full-contact load: no equilibrium there
                hi = min(hi, delta)
                p = self._pressure.copy()
                delta = 0.5 * (lo + min(hi, bound))
                continue
            self._x.copy(p)
            p.copy(self._pressure)
            w = p.sum() / n
            load_err = abs(w - target) / target
            # the load error that a complementarity error tol (a gap error of tol * L,
            # i.e. an approach error of that size) allows: a tighter load_tol cannot be met
            load_tol = max(self.load_tol, 2.0 * slope * self.tol * self._gap_scale() / target)
            if load_err <= load_tol and load_err > MAX_TOL and self._root is self:
                # a coarse level's state is only a start; the reported one must carry its load
                return False, (f"LOAD_ERROR_UNCONTROLLED (relative load error {load_err:.3e}: at this load the "
                               f"complementarity tol {self.tol:.1e} allows load errors up to {load_tol:.3e}; "
                               f"lower -{self.prefix}tol)")
            if load_err <= load_tol:
                if inner <= self.tol:
                    return True, reason
                inner = self.tol   # right load, loose solve: tighten at the same approach
                continue
            # brackets from inexact (loose) solves are soft: a Newton step may cross them
            exact = inner <= self.tol
            if w < target:
                lo, lo_exact = max(lo, delta), exact
            else:
                hi, hi_exact = min(hi, delta), exact
            slope, dp = self._approach_slope()
            if capped and last is not None and last[0] != delta:
                secant = (w - last[1]) / (delta - last[0])
                if secant > 0 and not 0 < slope <= secant:
                    slope = secant
            last = (delta, w)
            new = delta + (target - w) / slope if slope > 0 else np.inf
            if np.isfinite(new):
                if new >= hi and not hi_exact:
                    hi = np.inf
                if new <= lo and not lo_exact:
                    lo = lo0
            upper = min(hi, ceiling)
            if new >= bound and hi > bound and not tried_full:
                tried_full = True  # full contact: delta = mean h, mean p from the guess
                new = bound
                p.axpy(new - delta, dp)
                p.shift(target - p.sum() / n)
                rows = grid.rows(p)
                np.clip(rows, 0.0, self.hardness, out=rows)
            elif lo < new < upper:
                p.axpy(new - delta, dp)  # Newton predictor on the current contact set
                rows = grid.rows(p)
                np.clip(rows, 0.0, self.hardness, out=rows)
            elif np.isfinite(upper):
                new = 0.5 * (lo + upper)
            else:
                new = lo + 2.0 * max(delta - lo, self.length_scale)
            if not capped:
                inner = max(self.tol, min(self.inner_tol0, self.inner_eta * abs(new - delta) / self.length_scale))
            delta = new
        return False, f"DIVERGED_LOAD_ITERATION ({self.max_outer} approach updates; last SNES {reason})"


class JointLoadNewton:
    """Mixin of ``ContactProblem``: load control as one Newton iteration in (p, delta).

    The approach is the Lagrange multiplier of the load sum(p) = n W: each SNES VI step
    solves K_II y - mu 1 = g_I with sum(y) = sum(p) - n W by projected CG
    (``projected_cg.py``), and the residual takes delta(p), the approach at which the
    iterate is in equilibrium on its loaded nodes.  No slope solves, no outer iteration.
    The Krylov tolerance follows the Newton convergence (Eisenstat and Walker's second
    choice): rtol_k = (e_k / e_(k-1))^2, at most ``-<prefix>newton_ksp_rtol`` and at least
    what the remaining factor e_k / tol asks (with a safety factor).  A solve starts from the
    previous pressure moved onto the new load along the last step's u = M 1 (a step of a
    loading path), or scaled onto it (the first solve on a grid: the prolonged coarse state).
    """

    #: the last step's Krylov tolerance aims at this fraction of the tolerance
    FORCING_SAFETY = 0.2
    #: Krylov types of the Newton steps that the joint step's projected CG is (CG on the load's
    #: plane): with any other ``-<prefix>ksp_type`` load control runs the outer iteration, where
    #: that type solves every Newton step
    JOINT_KSP = ("cg",)

    def _load_by_joint(self) -> bool:
        """Whether load control runs the joint iteration: ``-<prefix>load_joint`` (default true),
        no hardness, and Newton steps by CG, unless ``-<prefix>load_joint true`` was given
        explicitly (then the joint step keeps its projected CG whatever ``ksp_type``).  Another
        Krylov type switches to the outer iteration with one ``SolverOptionWarning``."""
        if not self.load_joint or np.isfinite(self.hardness):
            return False
        kind = self._snes.getKSP().getType()
        if kind in self.JOINT_KSP or self.load_joint_given:
            return True
        root = self._root   # one warning for the problem and the coarse grids of its nested iteration
        if not root._warned_joint and self.grid.mpi_comm.Get_rank() == 0:
            warnings.warn(
                f"-{self.prefix}ksp_type {kind}: load control's joint Newton step in (p, delta) is CG on "
                f"the load's plane (projected CG), which {kind} cannot replace; load control runs the "
                f"outer iteration on the approach instead, where {kind} solves every Newton step: expect "
                f"1.5-7x the FFT pairs (2-7x the Newton steps) of -{self.prefix}ksp_type cg, measured on rough "
                f"cells of 64^2 to 256^2 "
                f"(-{self.prefix}load_joint true keeps the joint step, its projected CG and {kind} for "
                f"displacement control)", SolverOptionWarning, stacklevel=2)
        root._warned_joint = True
        return False

    def _joint_gap(self, p: np.ndarray, out: np.ndarray) -> np.ndarray:
        """g = h + K p - delta(p) [m], delta(p) the mean of h + K p over the loaded nodes
        (p > 0): exact at a solution, where g = 0 there, and to first order the approach
        of the joint step's multiplier (the step leaves g_I = mu 1)."""
        grid = self.grid
        v = self.op.apply(p, out)
        v += grid.rows(self.heights, readonly=True)
        loaded = p > 0
        sums = grid.mpi_comm.allreduce(np.array([float(np.sum(v, where=loaded)), float(np.count_nonzero(loaded))]))
        if sums[1] > 0:
            delta = sums[0] / sums[1]
        else:   # nothing loaded: the approach of first contact
            delta = grid.mpi_comm.allreduce(float(v.min()), op=MPI.MIN)
        self._approach = delta
        out -= delta
        return out

    def _step_sum(self) -> tuple:
        """(c, negligible) [Pa]: c = sum(p) - n W, the sum of the Newton step y (p <- p - y)
        that restores the load (the projection onto p >= 0 of the last step moved it), and the
        |c| the step may leave (a hundredth of the load tolerance: saves an FFT pair)."""
        n = self.grid.nx * self.grid.ny
        return self._x.sum() - n * self._target, 0.01 * self.load_tol * n * self._target

    def _forcing(self, rtol: float) -> float:
        """The Krylov tolerance of this Newton step (Eisenstat-Walker, see the class)."""
        err, prev = self._last_gap_error, self._prev_gap_error
        self._prev_gap_error = err
        if not self.forcing or prev is None or not (np.isfinite(err) and err > 0 and prev > 0):
            return rtol
        floor = self.FORCING_SAFETY * self._inner_tol / err
        return float(min(rtol, max((err / prev) ** 2, floor)))

    def _keep_tangent(self, A, u) -> None:
        """Keep u = M 1 of the present Newton step on the full grid (zero outside its set):
        the preconditioner's image of dp/d delta, the predictor of the next load's solve."""
        if self._tangent is None:
            self._tangent = np.empty(self.grid.local_shape)
        self._tangent.fill(0.0)
        A.getPythonContext().to_full(u, self._tangent)

    def _solve_load_joint(self, target: float):
        """Load control by the joint Newton iteration; returns (converged, reason)."""
        from .projected_cg import ProjectedCG
        snes = self._build()
        ksp = snes.getKSP()
        kind = ksp.getType()
        ksp.setType("python")
        ksp.setPythonContext(ProjectedCG(self._step_sum, self._forcing, self._keep_tangent))
        # SNES VI resets its KSP from the options database whenever the inactive set changes
        # (SNESVIResetPCandKSP): a -<prefix>ksp_type there would put plain CG back in place of
        # the projected one, which ignores the load (every joint solve then runs to max_it and
        # the outer iteration takes over, silently slow), so the database names ours meanwhile
        opts, name = PETSc.Options(), self.prefix + "ksp_type"
        given = opts.getString(name) if opts.hasName(name) else None
        opts.setValue(name, "python")
        self._prev_gap_error = None
        p = self._pressure
        n = self.grid.nx * self.grid.ny
        total = p.sum()
        if total <= 0:
            p.set(target)   # no load yet: start from full contact at the target
        elif self._tangent is not None:
            # a step of a loading path: along the last solve's M 1 (its set's response to a
            # uniform gap change, singular at the contact edges like dp/d delta), then onto p >= 0
            rows = self.grid.rows(p)
            along = self.grid.mpi_comm.allreduce(float(self._tangent.sum()))
            rows += (n * target - total) / along * self._tangent
            np.maximum(rows, 0.0, out=rows)
            del rows
            p.scale(n * target / p.sum())
        else:
            # scaled onto the load: the contact set stays, and the line search's merit (the
            # gap on the inactive set, blind to the load) sees no load error at the start
            p.scale(n * target / total)
        self._joint = True
        try:
            ok, reason = self._solve_at(self._approach if self._approach is not None else 0.0, p)
        finally:
            self._joint = False
            if given is None:
                opts.delValue(name)
            else:
                opts.setValue(name, given)
            ksp.setType(kind)
        if ok:
            self._x.copy(self._pressure)
        return ok, reason
