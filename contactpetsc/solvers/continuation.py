"""Continuation of ``AdhesiveProblem`` (docs/formulation.md, "Adhesive contact: unknowns and Newton"):
first states (the Signorini state, loading from rest), warm starts, the SNES runs with their
stall watch, and the time budget.  The strategies it calls: the nested iteration
(``adhesive_levels.py``) and the fallback chain (``fallback.py``)."""
from __future__ import annotations

import time

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .base import AdhesiveSolveError, ContactSolveError
from .problem import ContactProblem
from .states import AdhesiveState


class Continuation:
    """Mixin of ``AdhesiveProblem``: how each solve starts and where it goes when Newton fails."""

    def out_of_time(self) -> bool:
        """Whether the wall-time budget (``-<prefix>time_budget``) is spent; collective (the
        ranks' clocks differ: one rank's verdict would split the ranks between two branches)."""
        if not self.time_budget:
            return False
        if self._budget_start is None:
            self._budget_start = time.monotonic()
        late = time.monotonic() - self._budget_start > self.time_budget
        return bool(self.grid.mpi_comm.allreduce(late, op=MPI.LOR))

    @property
    def budget_reason(self) -> str:
        return (f"WALL_TIME_BUDGET (the {self.time_budget:g} s of -{self.prefix}time_budget are spent; "
                f"finished solves are kept)")

    def _initial_guess(self, approach: float) -> None:
        """First state at ``approach``: the coarse grid's solution (nested iteration), or
        the non-adhesive (Signorini) solution where the bodies overlap, the undeformed
        bodies otherwise, with a = a(g) of that state."""
        grid = self.grid
        xb = self.blocks(self._x)
        if self.coarse_levels.first_state(approach):
            if self.strategy == "descent":
                # the levels gave the first state; the descent takes every later one from the
                # last: freed before the fine descent, whose peak they would add to
                self.coarse_levels.release()
            return
        xb[...] = 0.0
        gap = grid.rows(self.heights, readonly=True) - approach
        if grid.mpi_comm.allreduce(float(gap.min()), op=MPI.MIN) < 0:
            cp = ContactProblem(grid, self.heights, self.e_star, operator=self.op,
                                prefix=self.prefix + "initial_", tol=1e-6, length_scale=self.z0)
            try:
                st = cp.solve(approach=approach)
            except ContactSolveError:
                # no Signorini state here (a periodic cell pressed beyond its mean plane):
                # start from the undeformed bodies; Newton says whether a state exists
                st = None
            if st is not None:
                gap = grid.rows(st.gap, readonly=True).copy()
                xb[0 if self.hard_wall else -1] = grid.rows(st.pressure, readonly=True)
        xb[-1] += self.traction.pressure(np.maximum(gap, 0.0) if self.hard_wall else gap)

    def warm_start(self, contact_pressure: PETSc.Vec | None, adhesive_pressure: PETSc.Vec,
                   approach: float) -> None:
        """Start the next solve from these pressures [Pa] at this approach [m] (a previous
        step, or one read back on restart); ``contact_pressure`` is ignored without a wall."""
        self.snes()
        xb = self.blocks(self._x)
        grid = self.grid
        if self.hard_wall:
            xb[0] = grid.rows(contact_pressure, readonly=True)
        xb[-1] = grid.rows(adhesive_pressure, readonly=True)
        self._approach = self._start_approach = float(approach)
        self._started = True
        # the next step's predictor from this state's tangent, as after the solve that
        # reached it: a restarted path takes the uninterrupted one's steps
        self.predictor.due()
    def _load_from_rest(self, approach, raise_on_failure, check_stability) -> AdhesiveState:
        """The first solve: the state reached by loading from separation (min h - z0) to
        ``approach`` in steps of at most ``-<prefix>initial_step`` z0, each warm-started.
        Adhesive contact has many equilibria at one approach; this picks the physical one
        of a first loading and gives Newton a near start at every step."""
        start = float(self.heights.min()[1]) - self.z0
        self._initial_guess(start)
        self._started = True
        n = max(1, int(np.ceil((approach - start) / (self.initial_step * self.z0))))
        pairs0, t0 = self.fft_pairs(), self.history.elapsed()
        newton = linear = 0
        st = None
        for d in np.linspace(start, approach, n + 1)[1:] if approach > start else [approach]:
            last = d == approach
            st = self.solve(approach=float(d), raise_on_failure=False,
                            check_stability=check_stability if last else False)
            newton, linear = newton + st.newton_iterations, linear + st.linear_iterations
            if not st.converged:
                break
        if not st.converged:
            # a jump on the way that no relaxation path reached (strong adhesion with a hard
            # wall): start again from the Signorini solution at the target itself
            self._initial_guess(approach)
            self.predictor.drop()
            self.descending_loading = False
            st = self.solve(approach=approach, raise_on_failure=False, check_stability=check_stability)
            newton, linear = newton + st.newton_iterations, linear + st.linear_iterations
            st.solver += " (from the Signorini state: loading from rest failed)"
        st.newton_iterations, st.linear_iterations = newton, linear
        st.fft_pairs, st.wall_time = self.fft_pairs() - pairs0, self.history.elapsed() - t0
        if not st.converged and raise_on_failure:
            raise AdhesiveSolveError(f"adhesive solve did not converge while loading from rest to "
                                     f"{approach:.4e} m: {st.reason} at approach {st.approach:.4e} m")
        return st
    def prepare(self, approach: float) -> None:
        """Make the SNES and a state to start from, and set displacement control at approach
        delta [m] (what an outside solver of this problem's unknowns, ``RelaxationSolver``,
        needs before it works on ``x``)."""
        self.snes()
        self.centre_owner = None
        if not self._started:
            self._initial_guess(approach)
            self._started = True
        self._approach = self._start_approach = float(approach)

    def record_solve(self) -> None:
        """Count one solve (the ``solve`` column of the history)."""
        self._n_solves += 1

    @property
    def solve_count(self) -> int:
        """Solves so far (SNES runs and relaxations)."""
        return self._n_solves

    def _destroy_solvers(self) -> None:
        """Destroy the SNES, the PTC SNES, the tangent and the coarse level's solvers: their
        callbacks hold the problem, a cycle that Python's collector cannot see."""
        if self.coarse_levels is not None:
            self.coarse_levels.destroy()
        if self.predictor is not None:
            self.predictor.drop()
        if self.fallback is not None:
            self.fallback.destroy()
        if self.newton is not None:
            self.newton.destroy()
        self._snes = self.newton = None
