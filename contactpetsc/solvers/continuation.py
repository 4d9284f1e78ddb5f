"""Continuation of ``AdhesiveProblem`` (docs/formulation.md, "Adhesive contact: unknowns and Newton"):
first states (nested iteration, the Signorini state, loading from rest), the fallback chain
(the paper's relaxation, pseudo-transient continuation), the stall watch and the time budget."""
from __future__ import annotations

import time
import warnings

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..physics.resolution import UnderResolvedWarning
from .base import AdhesiveSolveError, ContactSolveError, reason_name
from .descent import EnergyDescent, descent_applies, require_descent
from .options import code_default
from .problem import ContactProblem
from .relaxation import RelaxationSolver
from .states import AdhesiveState
from .transfer import can_halve, halved, prolong_bilinear, prolong_constant, restrict


#: the methods of -<prefix>fallback
FALLBACKS = ("descent", "relaxation", "ptc")


class Continuation:
    """Mixin of ``AdhesiveProblem``: how each solve starts and where it goes when Newton fails."""

    def _read_fallback_options(self, opts: PETSc.Options) -> None:
        """``-<prefix>fallback``, ``fallback_tol`` and ``strategy`` (at build time)."""
        # the relaxation paths tried in turn where Newton fails or ends on an unstable state.
        # Hard-wall laws: the paper's relaxation first, then PTC -- each reaches states where
        # the other stops at its cap (a strongly adhesive sphere loaded from rest, a jump-off);
        # the energy descent first where it applies: it reaches the minimum next to the last
        # state without pseudo-time (docs/formulation.md, "Energy descent")
        chain = ("descent," if descent_applies(self) else "") + ("relaxation,ptc" if self.hard_wall else "ptc")
        chain = opts.getString("fallback", chain).lower()
        self.fallback_chain = [m.strip() for m in chain.split(",") if m.strip()]
        if not self.fallback_chain or any(m not in FALLBACKS for m in self.fallback_chain):
            raise ValueError(f"-{self.prefix}fallback must be {', '.join(FALLBACKS)} or a comma-separated "
                             f"chain of them, got {chain!r}")
        if "descent" in self.fallback_chain:
            require_descent(self, f"-{self.prefix}fallback {chain}")
        if "relaxation" in self.fallback_chain and not self.hard_wall:
            raise ValueError(f"-{self.prefix}fallback relaxation needs a hard-wall law (the paper's relaxation "
                             f"stores contact pressures apart), got {self.law.name!r}")
        self.fallback_tol = opts.getReal("fallback_tol", code_default("adhesion", "fallback_tol"))
        self.strategy = opts.getString("strategy", code_default("adhesion", "strategy")).lower()
        if self.strategy not in ("newton", "descent"):
            raise ValueError(f"-{self.prefix}strategy must be newton or descent, got {self.strategy!r}")
        if self.strategy == "descent":
            require_descent(self, f"-{self.prefix}strategy descent")

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

    def _coarse_problem(self):
        """The same problem on the 2x coarser grid (h averaged over 2 x 2 blocks), or None."""
        if self._coarse is not None:
            return self._coarse or None
        self._coarse = False
        if not self.has_coarse_level():
            return None
        grid = self.grid
        gc = halved(grid)
        hc = gc.create_vec()
        gc.rows(hc)[...] = restrict(grid.rows(self.heights, readonly=True))
        # FFTW_MEASURE planning would cost more than the coarse solves themselves
        op = self.op.on_grid(gc, prefix=self.prefix, planner="estimate")
        with warnings.catch_warnings():
            # a coarse grid of the nested iteration resolves less than the fine one by design
            warnings.simplefilter("ignore", UnderResolvedWarning)
            # auto: a hard-wall grid chooses from its own snap number (the cycle fails near one);
            # the full LJ curve's coarse grids take the finest grid's pick (docs/formulation.md)
            coarse = type(self)(gc, hc, self.e_star, self.law, element_integration=self.element_integration,
                                prefix=self.prefix, operator=op,
                                preconditioner=self.preconditioner_choice if self.hard_wall else self.preconditioner,
                                stability_check=False, petsc_options=self.petsc_options)
        coarse._build()
        coarse._budget_start = self._budget_start   # one budget for the nested solves
        coarse.tol = max(self.fmg_tol, self.tol)
        coarse.use_predictor = False
        if "descent" in coarse.fallback_chain:
            # a level only predicts: where its descent does not reach a state, the level is
            # dropped rather than followed by thousands of relaxation cycles or PTC steps
            coarse.fallback_chain = ["descent"]
        coarse.compute_tangent = False   # a level of the nested iteration needs no predictor or stiffness
        # a level only predicts: an under-resolved level's Krylov solves that stagnate to the fine
        # grid's limit cost more than the fine solve (docs/performance.md, "Energy descent as the
        # fallback"); an inexact step is still judged by the line search, and the fallback follows
        limit = PETSc.Options(self.prefix).getInt("fmg_ksp_max_it", code_default("adhesion", "fmg_ksp_max_it"))
        ksp = coarse._snes.getKSP()
        ksp.setTolerances(max_it=min(ksp.getTolerances()[3], limit))
        self._coarse = coarse
        return coarse

    def has_coarse_level(self) -> bool:
        """Whether the nested iteration has a level below this grid (``-<prefix>fmg``)."""
        grid = self.grid
        # levels coarser than the adhesive range are kept: without them the first level
        # that resolves it needs continuation too (docs/formulation.md, "Adhesive contact: unknowns and Newton")
        return bool(self.fmg and can_halve(grid) and min(grid.nx, grid.ny) // 2 >= self.fmg_min_size)

    def coarse_state(self) -> list:
        """The coarse levels that the next steps are predicted from (``_coarse_step``), as they
        are now, finest first: (grid, the rank's rows of its unknowns (n_blocks, ny_local, nx):
        [q,] a, approach [m]) each; [] where no level is stepped (``-<prefix>fmg_steps`` off,
        levels dropped).  What a restarted path takes up (``warm_start_coarse``) to predict its
        next step as the uninterrupted one does."""
        out, level = [], self._coarse if self.fmg_steps else None
        while level and level._started:
            out.append((level.grid, level.blocks(level._x, readonly=True), level._approach))
            level = level._coarse
        return out

    def warm_start_coarse(self, levels: list) -> None:
        """Take up the coarse levels of ``coarse_state`` after ``warm_start`` (a restart):
        ``levels`` finest first, each (approach [m], read), ``read(grid)`` giving the rank's rows
        of the level's unknowns on ``grid``.  The level below the last is off, as it was
        (dropped, or none); levels this run's options do not make are left out."""
        level = self
        for approach, read in levels:
            coarse = level._coarse_problem()
            if coarse is None:
                return
            coarse.blocks(coarse._x)[...] = read(coarse.grid)
            coarse._approach, coarse._started = float(approach), True
            level = coarse
        if level._coarse is None:
            level._coarse = False

    def _nested_guess(self, approach: float) -> bool:
        """Unknowns from the coarse problem's solution at ``approach``, prolonged piecewise
        constant (pressures are densities); False when there is none."""
        coarse = self._coarse_problem()
        if coarse is None:
            return False
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if not st.converged:
            self._drop_coarse()
            return False
        xb, xc = self.blocks(self._x), coarse.blocks(coarse._x, readonly=True)
        for k in range(self.n_blocks):
            xb[k] = prolong_constant(xc[k])
        return True

    def _coarse_step(self, approach: float) -> bool:
        """Predictor from the coarse grid: x + P (x_c(delta) - x_c(delta_prev)) (P bilinear), the coarse
        problem stepped along with this one (full approximation); False when the coarse
        problem is not at this problem's previous approach or its step failed."""
        coarse = self._coarse
        if not (coarse and self.fmg_steps and coarse._approach == self._prev_approach):
            return False
        old = coarse._x.copy()
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if st.converged:
            old.aypx(-1.0, coarse._x)
            xb, dc = self.blocks(self._x), coarse.blocks(old, readonly=True)
            # the increment is smoother than the state: bilinear (fewer FFT pairs than
            # piecewise constant; docs/formulation.md, "Adhesive contact: unknowns and Newton")
            for k in range(self.n_blocks):
                xb[k] += prolong_bilinear(dc[k], coarse.grid)
            if self.hard_wall:
                np.maximum(xb[0], 0.0, out=xb[0])
        old.destroy()
        if not st.converged:
            self._drop_coarse()
        return st.converged

    def _drop_coarse(self) -> None:
        """Stop using the coarse level after a failed solve there (even with its fallback):
        a grid that cannot follow the path gives no useful start, and costs a fallback run
        at every later step.  Its FFT pairs stay counted."""
        self._coarse_pairs += self._coarse.fft_pairs() / 4.0
        self._coarse = False

    def _initial_guess(self, approach: float) -> None:
        """First state at ``approach``: the coarse grid's solution (nested iteration), or
        the non-adhesive (Signorini) solution where the bodies overlap, the undeformed
        bodies otherwise, with a = a(g) of that state."""
        grid = self.grid
        xb = self.blocks(self._x)
        if self._nested_guess(approach):
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
        self._approach = float(approach)
        self._started = True
        self._drop_tangent()
        if self.compute_tangent:
            # the next step's predictor from this state's tangent, as after the solve that
            # reached it: a restarted path takes the uninterrupted one's steps
            self._tangent_due = self._approach
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
            self._drop_tangent()
            st = self.solve(approach=approach, raise_on_failure=False, check_stability=check_stability)
            newton, linear = newton + st.newton_iterations, linear + st.linear_iterations
            st.solver += " (from the Signorini state: loading from rest failed)"
        st.newton_iterations, st.linear_iterations = newton, linear
        st.fft_pairs, st.wall_time = self.fft_pairs() - pairs0, self.history.elapsed() - t0
        if not st.converged and raise_on_failure:
            raise AdhesiveSolveError(f"adhesive solve did not converge while loading from rest to "
                                     f"{approach:.4e} m: {st.reason} at approach {st.approach:.4e} m")
        return st
    def _run_snes(self, snes: PETSc.SNES | None = None):
        snes = snes or self._snes
        self._lin0 = self.history[-1].linear_iterations if len(self.history) else 0
        self._stalled = False
        snes.solve(None, self._x)
        self._n_solves += 1
        code = snes.getConvergedReason()
        name = self.budget_reason if code < 0 and self.out_of_time() else reason_name(code)
        if self._stalled:
            name = (f"STALLED (no smaller error in {self.stall_steps} Newton steps; smallest "
                    f"{self._best[0]:.3e} z0 at step {self._best[1]})")
        return code > 0, name, snes.getIterationNumber(), snes.getLinearSolveIterations()

    def _follow_fallback(self, approach, x_start, check, newton, linear, solver, skip=()):
        """The methods of ``-<prefix>fallback`` in turn from the last converged state ``x_start``
        (or a stalled Newton's best iterate), but those in ``skip``; returns (converged, reason,
        newton, linear, margin, solver)."""
        # Newton found no state on this branch, or an unstable one (the branch has
        # ended: a jump).  From the last converged state, follow a relaxation path
        # to a stable state, then polish by Newton: the methods of -<prefix>fallback
        # in turn (hard-wall laws: the paper's relaxation, then PTC; lj: PTC).
        stalled = self._stalled
        for method in (m for m in self.fallback_chain if m not in skip):
            # a stalled Newton was near a state but for a few nodes: PTC from its best iterate
            (self._x_best if stalled and method == "ptc" else x_start).copy(self._x)
            if method == "descent":
                ok, reason, n2, l2 = EnergyDescent(self).descend(approach, self._x)
                if ok:
                    # the polish: VI Newton at the approach itself (a hard wall's descent ends
                    # within offset_tol z0 of it)
                    ok, reason, n3, l3 = self._run_snes()
                    n2, l2 = n2 + n3, l2 + l3
            elif method == "relaxation":
                relax = RelaxationSolver(self, tol=self.fallback_tol, max_cycles=self.fallback_max_cycles)
                ok, reason, n2, l2 = relax.relax(approach, polished=True)
                if ok:
                    ok, reason, n3, l3 = self._run_snes()
                    n2, l2 = n2 + n3, l2 + l3
            else:
                self.shift, self._ptc_prev = self.ptc_shift0, 0.0
                ok, reason, n2, l2 = self._run_snes(self._ptc)
                self.shift = 0.0
            solver += "+" + method
            newton, linear = newton + n2, linear + l2
            margin = self.stability() if (ok and check) else float("nan")
            if (ok and not margin <= 0) or self.out_of_time():
                break
        return ok, reason, newton, linear, margin, solver

    def prepare(self, approach: float) -> None:
        """Make the SNES and a state to start from, and set displacement control at approach
        delta [m] (what an outside solver of this problem's unknowns, ``RelaxationSolver``,
        needs before it works on ``x``)."""
        self.snes()
        self.centre_owner = None
        if not self._started:
            self._initial_guess(approach)
            self._started = True
        self._approach = float(approach)

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
        if self._coarse:
            self._coarse._destroy_solvers()
        self._drop_tangent()
        for name in ("_snes", "_ptc"):
            obj = getattr(self, name, None)
            if obj is not None:
                obj.destroy()
            setattr(self, name, None)
