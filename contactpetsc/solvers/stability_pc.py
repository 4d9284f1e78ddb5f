"""Preconditioners of the LOBPCG stability check: approximate inverses of the Hessian.

The check (``stability.py``) seeks the top eigenvalue of the pencil A x = lambda (K^-1)_NN x
on W; the Hessian there is H = (K^-1)_NN - A.  Preconditioned by T ~ H^-1, LOBPCG converges
like inverse iteration near the top of the pencil, where the compliance K (``stability.py``'s
own) acts as a power iteration and stalls on a cluster of asperity modes.  Two cycles, each
a callable ``T(r, out)`` on full (ny_loc, nx) arrays (the result is projected on W by the
caller) with ``release()``:

* ``AdhesiveCyclePreconditioner`` (``mlmi``): one adhesive multilevel cycle
  (``adhesive_mlmi.AdhesiveCycle``, the Newton steps' own) on H's pressure form.  With u = K p
  the rows H u = r on N read p - A K p = r, and u = 0 on C reads (K p)_C = 0: that is
  (K + diag(c)) p = f with c = -1/A and f = -r/A on N, c = f = 0 on C; T r = K p.  Only where
  A >= 0 on N: where A changes sign the cycle's coarse levels leave the mixed zones out and
  it amplifies smooth residuals.
* ``DisplacementCycle`` (``multigrid``): a V(1, 1)-cycle on H itself, in displacements, over
  the grids of the problem's MLMI hierarchy: weighted Jacobi (damping 0.8, diagonal
  (K^-1)_ii - A_i floored at a fifth of (K^-1)_ii), K^-1 rediscretised on each grid (one FFT
  pair a residual), A and residuals restricted by 2 x 2 means, corrections copied to the
  children; a coarse node is clamped (u = 0) unless its four children are free; 20 sweeps on
  the coarsest grid.  Any sign of A.  On a periodic cell the mean of u is H's only mode that
  K^-1 does not see; W excludes it, and the cycle leaves it to the projection.  On an isolated
  window the check's pencil lives on the padded grid (``stability.py``), whose H = C^-1 - A
  has the circulant C^-1 of each MLMI level's window operator on that level's padded grid
  (``padded_levels``): the same cycle, the padded grids halved with the window's.
"""
from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np

from ..log_events import log_event
from .descent_space import PaddedWindow
from .mlmi import shared_levels
from .transfer import add_prolonged, block_all, can_halve, halved, restrict

#: Jacobi damping, sweeps before and after the coarse correction, sweeps on the coarsest grid
DAMPING, SWEEPS, COARSE_SWEEPS = 0.8, 1, 20
#: the Jacobi diagonal's floor, in multiples of (K^-1)_ii (H_ii near zero beyond a snap)
DIAGONAL_FLOOR = 0.2


class AdhesiveCyclePreconditioner:
    """``mlmi`` (module doc).  The cycle is made once per problem and kept between checks in its
    ``PreconditionerData`` (``stability_cycle``), so that a check's power iterations start from
    the last check's vectors; ``release()`` frees its set-up."""

    def __init__(self, problem, d: np.ndarray, contact: np.ndarray):
        from .adhesive_mlmi import AdhesiveCycle, law_rows
        data = problem.jacobian_context.pc_data
        if data.stability_cycle is None:
            data.stability_cycle = AdhesiveCycle(problem.op, data, problem.prefix)
        self.cycle = data.stability_cycle
        self.op = problem.op
        c, inv_beta = law_rows(np.ones_like(d), np.negative(d), self.cycle.k_ii)
        np.copyto(c, 0.0, where=contact)
        self.cycle.set_rows(c)
        self.inv_beta = inv_beta
        np.copyto(inv_beta, 0.0, where=contact)

    def __call__(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        # out holds f through the cycle (the cycle's own arrays are its work), then K p
        p = self.cycle.solve(np.multiply(r, self.inv_beta, out=out))
        return self.op.apply(p, out)

    def release(self) -> None:
        self.cycle.release()
        self.inv_beta = None


class CycleLevel(NamedTuple):
    """One grid of ``DisplacementCycle``: the compliance's inverse there (``apply_inverse(x,
    out)``, one FFT pair) and its diagonal [Pa/m]."""
    apply_inverse: Callable
    inverse_diagonal: float


def _inverse_diagonal(op) -> float:
    """(K^-1)_ii [Pa/m] of ``op``: on a window's operator the padded circulant's C^-1."""
    return op.spectral_sum(op.inverse_kernel * (op.fft.Nx * op.fft.Ny))


def cell_levels(problem) -> list[CycleLevel]:
    """The cycle's grids on a periodic cell: the problem's MLMI hierarchy."""
    levels = shared_levels(problem.jacobian_context.pc_data, problem.op, problem.prefix)
    return [CycleLevel(lev.op.apply_inverse, _inverse_diagonal(lev.op)) for lev in levels]


def padded_levels(problem, space) -> list[CycleLevel]:
    """The cycle's grids for a window's check on the padded grid of ``space``
    (``descent_space.PaddedWindow``): each MLMI level's window operator's circulant inverse on
    the padded grid halved as often, as long as the padded grid halves with rank-local transfers."""
    levels = shared_levels(problem.jacobian_context.pc_data, problem.op, problem.prefix)
    out = []
    for l, lev in enumerate(levels):
        if l:
            if not can_halve(space.grid):
                break
            space = PaddedWindow(lev, grid=halved(space.grid))
        out.append(CycleLevel(space.apply_inverse, _inverse_diagonal(lev.op)))
    return out


class DisplacementCycle:
    """``multigrid`` (module doc) on the grids ``levels`` (``CycleLevel``; ``cell_levels`` or
    ``padded_levels``); its arrays live as long as the object (one check)."""

    def __init__(self, levels: list[CycleLevel], d: np.ndarray, contact: np.ndarray):
        self.levels = levels
        self.a, self.free, self.dinv = [], [], []
        a, free = d, ~contact
        for l, lev in enumerate(levels):
            if l:
                a, free = restrict(a), block_all(free)
            kinv_ii = lev.inverse_diagonal
            self.a.append(a)
            self.free.append(free.astype(float))
            self.dinv.append(DAMPING * free / np.maximum(kinv_ii - a, DIAGONAL_FLOOR * kinv_ii))
        self.r = [np.zeros(a.shape) for a in self.a]
        self.x = [np.zeros(a.shape) for a in self.a]

    def _residual(self, l: int, b: np.ndarray, x: np.ndarray) -> np.ndarray:
        """b - H x on level l, in the level's residual array."""
        out = self.levels[l].apply_inverse(x, self.r[l])
        out -= self.a[l] * x
        out *= self.free[l]
        return np.subtract(b, out, out=out)

    def _smooth(self, l: int, b: np.ndarray, x: np.ndarray, sweeps: int, zero_start: bool = False) -> None:
        if zero_start and not sweeps:
            x[...] = 0.0
        for k in range(sweeps):
            if zero_start and k == 0:
                # from x = 0 the residual is b: no FFT pair
                np.multiply(self.dinv[l], b, out=x)
            else:
                x += self.dinv[l] * self._residual(l, b, x)

    def _cycle(self, l: int, b: np.ndarray) -> np.ndarray:
        x = self.x[l]
        if l == len(self.levels) - 1:
            self._smooth(l, b, x, COARSE_SWEEPS, zero_start=True)
            return x
        self._smooth(l, b, x, SWEEPS, zero_start=True)
        coarse_free = self.free[l + 1]
        bc = restrict(self._residual(l, b, x))
        bc *= coarse_free
        xc = self._cycle(l + 1, bc)
        xc *= coarse_free
        add_prolonged(x, xc)
        x *= self.free[l]
        self._smooth(l, b, x, SWEEPS)
        return x

    def __call__(self, r: np.ndarray, out: np.ndarray) -> np.ndarray:
        ev = log_event("CPDisplacementCycle")
        ev.begin()
        np.multiply(r, self.free[0], out=out)
        out[...] = self._cycle(0, out)
        ev.end()
        return out

    def release(self) -> None:
        self.levels = self.a = self.free = self.dinv = self.r = self.x = None
