"""The Newton steps' line search of ``ContactProblem``: backtracking on PETSc's VI merit without
the slope product.

PETSc's ``bt`` forms J Y for its initial slope F^T J Y: one FFT pair per Newton step, used only
in its sufficient-decrease test (alpha = 1e-4) and its backtracking fits.  Here the line
search is ``basic`` and its pre-check backtracks: it tries lambda = 1, 1/2, 1/4, ... until the
merit at the projected trial point w = clip(x - lambda y, 0, H) -- the 2-norm of F(w) over w's
inactive set, as PETSc's VI solvers measure it -- does not exceed the present one (any
decrease is enough), scales the step by lambda and keeps F(w), which the line search's own
evaluation at the same w then reuses.  An accepted full step costs one residual (``bt``: a
residual and the slope product).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_guard


class Backtracking:
    """Mixin of ``ContactProblem``: the line search's pre-check (``_backtrack``) and the reuse
    of its last trial residual (``_reuse_trial``); the problem supplies ``_evaluate_residual``."""

    #: the smallest step fraction tried; below it the Newton iteration stops (DIVERGED_LINE_SEARCH)
    MIN_LAMBDA = 2.0 ** -20

    _trial = None           # (w, F(w), approach at w) of the last accepted trial
    _trial_work = None      # the two grid-sized buffers of the trials
    _line_search_failed = False
    #: ``-<prefix>snes_vi_zero_tolerance`` in use: PETSc's VI norm counts a node within it of a
    #: bound as at the bound (read when the pre-check is installed)
    vi_zero_tolerance = 0.0

    def _vi_norm(self, x: np.ndarray, f: np.ndarray) -> float:
        """|F| over the inactive nodes of x (SNESVIComputeInactiveSetFnorm): all but those at
        p = 0 with F > 0 and at p = H with F < 0."""
        tol = self.vi_zero_tolerance
        keep = (x > tol) | (f <= 0)
        if np.isfinite(self.hardness):
            keep &= (x < self.hardness - tol) | (f >= 0)
        local = float(np.sum(f * f, where=keep))
        return float(np.sqrt(self.grid.mpi_comm.allreduce(local)))

    @collective_guard
    def _backtrack(self, x: PETSc.Vec, y: PETSc.Vec) -> bool:
        """The pre-check (x the iterate, y the Newton step, x - y the full step); returns
        whether y was scaled."""
        grid = self.grid
        xr, yr = grid.rows(x, readonly=True), grid.rows(y)
        if self._trial_work is None:
            self._trial_work = (np.empty_like(xr), np.empty_like(xr))
        w, fw = self._trial_work
        merit = self._vi_norm(xr, grid.rows(self._f, readonly=True))
        lam = 1.0
        while True:
            # the line search forms x - (lam y) and projects: the same floating-point values
            np.multiply(yr, -lam, out=w)
            w += xr
            np.clip(w, 0.0, self.hardness, out=w)
            self._evaluate_residual(w, fw)
            if not self._vi_norm(w, fw) > merit:   # NaN: no decrease
                break
            if lam <= self.MIN_LAMBDA:
                self._line_search_failed = True
                break
            lam *= 0.5
        if lam != 1.0:
            yr *= lam
        self._trial = (w, fw, self._approach)
        return lam != 1.0

    def _reuse_trial(self, x: np.ndarray, out: np.ndarray) -> bool:
        """Whether the residual at x is the last trial's (then copied into ``out``).  Collective."""
        trial, self._trial = self._trial, None
        same = trial is not None and np.array_equal(trial[0], x)
        if not self.grid.mpi_comm.allreduce(bool(same), op=MPI.LAND):
            return False
        out[...] = trial[1]
        self._approach = trial[2]
        return True
