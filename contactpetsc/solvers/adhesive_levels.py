"""Nested iteration of ``AdhesiveProblem``: a strategy that drives the same problem on 2x
coarser grids (docs/formulation.md, "Adhesive contact: unknowns and Newton").

* The first state of a solve is the coarse problem's solution at the same approach,
  prolonged piecewise constant (pressures are densities), recursively down to
  ``min_size`` nodes.
* Later steps are predicted by the ``step_levels`` levels below, each put at the restricted
  fine state with FAS's tau correction and stepped: x + P (x_c(delta) - x_c), P bilinear.
* A level that fails (even with its fallback) is dropped for good: a grid that cannot
  follow the path gives no useful start and would cost a fallback run at every later step.

Options, under ``<problem prefix>fmg_``: ``-<prefix>fmg`` (on/off), ``_min_size``, ``_tol`` (the
levels' error measures, z0), ``_step_levels`` (the predictor) and ``_ksp_max_it``.
"""
from __future__ import annotations

import warnings

import numpy as np
from petsc4py import PETSc

from ..physics.resolution import UnderResolvedWarning
from .adhesive_residual import total_pressure
from .options import code_default
from .transfer import can_halve, halved, prolong_bilinear, prolong_constant, restrict


#: the levels that predict a path's step by default: on an isolated window with a smooth law,
#: and elsewhere (a periodic cell, or a step law).  A cell two: on the rough benchmark's Newton
#: paths they took 25-33 % fewer pairs than the tangent predictor (which reached other states at
#: 256^2), and a third level (32^2) cost more than it saved.  A window none: on the adhesive
#: sphere's paths (Tabor 0.1-5, both smooth laws) the tangent predictor reaches the same states
#: in up to 29 % fewer pairs; the levels' prediction started Newton at a larger error, and at
#: Tabor 5 the under-resolved levels' Newton failed each step (docs/performance.md, "The adhesive
#: sphere's states").  A step law's tangent is blind to its zone (its derivative is zero): with
#: it Maugis-Dugdale's sphere was 0.106 pi w R off, with the levels 0.061
STEP_LEVELS, WINDOW_STEP_LEVELS = 2, 0


class CoarseLevels:
    """The coarse levels below ``problem`` (an ``AdhesiveProblem``); read its options when made
    (inside the problem's ``inserted_options``)."""

    def __init__(self, problem):
        self.problem = problem
        self.prefix = problem.prefix + "fmg_"
        opts = PETSc.Options(self.prefix)
        self.enabled = PETSc.Options(problem.prefix).getBool("fmg", code_default("adhesion", "fmg"))
        self.min_size = opts.getInt("min_size", code_default("adhesion", "fmg_min_size"))
        self.tol = opts.getReal("tol", code_default("adhesion", "fmg_tol"))
        levels = STEP_LEVELS if problem.grid.periodic or not problem.law.smooth else WINDOW_STEP_LEVELS
        self.step_levels = opts.getInt("step_levels", levels)
        if self.step_levels < 0:
            raise ValueError(f"-{self.prefix}step_levels must be >= 0 (0: the tangent predictor), "
                             f"got {self.step_levels}")
        # a level only predicts: an under-resolved level's Krylov solves that stagnate to the fine
        # grid's limit cost more than the fine solve (docs/performance.md, "Energy descent as the
        # fallback"); an inexact step is still judged by the line search, and the fallback follows
        self.ksp_max_it = opts.getInt("ksp_max_it", code_default("adhesion", "fmg_ksp_max_it"))
        self._coarse = None          # the problem on the 2x coarser grid; False: none or dropped
        self.dropped = False         # dropped after a failed solve there (``_drop``)
        self._pending: list[bool] = []   # a restarted path's record of dropped levels (``restore``)
        self._dropped_pairs = 0.0    # FFT pairs of a dropped level (fine-grid units)

    def available(self) -> bool:
        """Whether there is a level below the problem's grid."""
        grid = self.problem.grid
        # levels coarser than the adhesive range are kept: without them the first level
        # that resolves it needs continuation too (docs/formulation.md, "Adhesive contact: unknowns and Newton")
        return bool(self.enabled and can_halve(grid) and min(grid.nx, grid.ny) // 2 >= self.min_size)

    def coarse(self):
        """The same problem on the 2x coarser grid (h averaged over 2 x 2 blocks), or None;
        made on first use."""
        if self._coarse is not None:
            return self._coarse or None
        self._coarse = False
        if not self.available():
            return None
        if self._pending[:1] == [True]:
            # the uninterrupted path had dropped it (``restore``)
            self.dropped, self._pending = True, []
            return None
        fine = self.problem
        grid = fine.grid
        gc = halved(grid)
        hc = gc.create_vec()
        gc.rows(hc)[...] = restrict(grid.rows(fine.heights, readonly=True))
        # FFTW_MEASURE planning would cost more than the coarse solves themselves
        op = fine.op.on_grid(gc, prefix=fine.prefix, planner="estimate")
        with warnings.catch_warnings():
            # a coarse grid of the nested iteration resolves less than the fine one by design
            warnings.simplefilter("ignore", UnderResolvedWarning)
            # auto: a hard-wall grid chooses from its own snap number (the cycle fails near one);
            # the full LJ curve's coarse grids take the finest grid's pick (docs/formulation.md)
            coarse = type(fine)(gc, hc, fine.e_star, fine.law, element_integration=fine.element_integration,
                                prefix=fine.prefix, operator=op,
                                preconditioner=fine.preconditioner_choice if fine.hard_wall else fine.preconditioner,
                                stability_check=False, petsc_options=fine.petsc_options)
        coarse._build()
        coarse._budget_start = fine._budget_start   # one budget for the nested solves
        coarse.tol = max(self.tol, fine.tol)
        if "descent" in coarse.fallback.methods:
            # a level only predicts: where its descent does not reach a state, the level is
            # dropped rather than followed by thousands of relaxation cycles or PTC steps.  A
            # hard wall's level on an isolated window is dropped where its Newton fails: its
            # padded descents cost more than the predictions they kept, and the tangent predictor
            # reaches the same states.  The full LJ curve's keeps them, for the first state's
            # nested iteration (a window's steps are the tangent's by default, ``WINDOW_STEP_LEVELS``)
            coarse.fallback.methods = [] if fine.hard_wall and not gc.periodic else ["descent"]
        coarse.predictor.predicts = coarse.predictor.wanted = False   # a level needs no tangent
        coarse.coarse_levels.step_levels = self.step_levels - 1
        coarse.coarse_levels.restore(self._pending[1:])
        self._pending = []
        ksp = coarse._snes.getKSP()
        ksp.setTolerances(max_it=min(ksp.getTolerances()[3], self.ksp_max_it))
        self._coarse = coarse
        return coarse

    def first_state(self, approach: float) -> bool:
        """The problem's unknowns from the coarse solution at ``approach``, prolonged piecewise
        constant; False where there is none (no level, or it failed and is dropped)."""
        coarse = self.coarse()
        if coarse is None:
            return False
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if not st.converged:
            self._drop()
            return False
        fine = self.problem
        xb, xc = fine.blocks(fine._x), coarse.blocks(coarse._x, readonly=True)
        for k in range(fine.n_blocks):
            xb[k] = prolong_constant(xc[k])
        return True

    def anchor(self, approach: float):
        """The coarse level put at the problem's state, which is at ``approach`` [m]: FAS's tau
        correction, taken up by the coarse heights.  The restricted gap g_c = R g (0 where the
        restricted contact pressure R q is positive) and the pressures x_c = (R q, a_c(g_c)) are
        made the coarse equilibrium at ``approach`` by the heights h_c = g_c - K_c p_c + delta.
        Returns the level (None where there is none)."""
        coarse = self.coarse()
        if coarse is None:
            return None
        fine = self.problem
        xf = fine.blocks(fine._x, readonly=True)
        gf = fine.op.apply(total_pressure(xf), np.empty(xf.shape[1:]))
        gf += fine.grid.rows(fine.heights, readonly=True)
        gf -= approach
        gc = restrict(gf)
        xc = coarse.blocks(coarse._x)
        if fine.hard_wall:
            xc[0] = restrict(xf[0])
            gc[xc[0] > 0] = 0.0
        coarse.traction.pressure(gc, out=xc[-1])
        hc = coarse.grid.rows(coarse.heights)
        coarse.op.apply(total_pressure(xc), hc)
        np.subtract(gc, hc, out=hc)
        hc += approach
        coarse._approach, coarse._started = float(approach), True
        return coarse

    def predict(self, approach: float, previous: float | None) -> bool:
        """Add the prolonged coarse step P (x_c(approach) - x_c) to the problem's unknowns, the
        coarse level ``anchor``-ed at the problem's state (at ``previous`` [m]) first; False
        (unknowns untouched) where no level steps or its step failed.  The level follows the
        fine state wherever it jumped, so it cannot fold apart from it, and it needs nothing
        from earlier steps (a restarted path predicts as the uninterrupted one)."""
        coarse = self.anchor(previous) if self.step_levels > 0 and previous is not None else None
        if coarse is None:
            return False
        start = coarse._x.copy()
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if st.converged:
            fine = self.problem
            start.aypx(-1.0, coarse._x)
            xb, dc = fine.blocks(fine._x), coarse.blocks(start, readonly=True)
            # the increment is smoother than the state: bilinear (fewer FFT pairs than
            # piecewise constant; docs/formulation.md, "Adhesive contact: unknowns and Newton")
            for k in range(fine.n_blocks):
                xb[k] += prolong_bilinear(dc[k], coarse.grid)
            if fine.hard_wall:
                np.maximum(xb[0], 0.0, out=xb[0])
        else:
            self._drop()
        start.destroy()
        return st.converged

    def _drop(self) -> None:
        """Stop using the level after a failed solve there (freed); its FFT pairs stay counted."""
        self._dropped_pairs += self._coarse.fft_pairs() / 4.0
        self._coarse.coarse_levels.release()
        self._coarse.destroy()
        self._coarse, self.dropped = False, True

    def release(self) -> None:
        """Free the levels (problems, solvers, arrays) where the strategy will not use them again:
        made anew if they are wanted after all, with the levels dropped so far dropped again
        (``state``); their FFT pairs stay counted."""
        if not self._coarse:
            return
        self._pending = self.state()
        self._dropped_pairs += self._coarse.fft_pairs() / 4.0
        # a safeguard: a level's own solves release the levels below it already
        self._coarse.coarse_levels.release()
        # its Jacobian's context holds it, a cycle through PETSc that Python's collector
        # cannot see: destroyed, not only its solvers
        self._coarse.destroy()
        self._coarse = None

    def state(self) -> list[bool]:
        """Which levels were dropped, from this one down (JSON-able; a level not made yet keeps
        what ``restore`` gave it): a restarted path that drops them again predicts as the
        uninterrupted one did."""
        if self._coarse is None:
            return list(self._pending)
        if self._coarse is False:
            return [True] if self.dropped else []
        return [False] + self._coarse.coarse_levels.state()

    def restore(self, state: list[bool]) -> None:
        """Drop the levels ``state`` (``state()`` of the uninterrupted path) says were dropped,
        each when it would be made (inside the problem's options and time budget, as then)."""
        self._pending = [bool(b) for b in state]

    def fft_pairs(self) -> float:
        """FFT pairs of the levels below, kept, dropped and released, in the problem's grid units."""
        return (self._coarse.fft_pairs() / 4.0 if self._coarse else 0.0) + self._dropped_pairs

    def destroy(self) -> None:
        """Destroy the levels' solvers (their callbacks hold the coarse problems)."""
        if self._coarse:
            self._coarse._destroy_solvers()
