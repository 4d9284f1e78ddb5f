"""A hard wall's mean of u in the energy descent (``descent.py``'s module doc): K^-1 does not
see it and the approach fixes it, so the descent holds it by the penalty
c/2 N mean(u)^2 + W N mean(u) (c the largest modal stiffness [Pa/m], W the mean-pressure
multiplier [Pa]).  A state with mean(u) = m is exactly an equilibrium at approach delta - m.
W is updated to the measured mean pressure between TAO's rounds (Uzawa; from the second round
on, by the secant of m(W)) until m is within what Newton's confirmation measures
(``closed``); Newton then closes the last offset."""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..physics.resolution import steepest_slope
from .options import code_default


class MeanMultiplier:
    """The multiplier W [Pa] of a hard wall's descent of ``problem`` (an ``AdhesiveProblem``) and
    its rounds, the penalty's stiffness ``c`` [Pa/m]; ``tol``: the tolerance the descent's caller
    gave (None: the problem's own, for Newton to confirm).  Options (prefix ``prefix``, the
    descent's): ``offset_tol`` (z0) and ``max_rounds``."""

    def __init__(self, problem, prefix: str, c: float, tol: float | None):
        opts = PETSc.Options(prefix)
        self.c = c
        self.z0 = problem.z0
        self.max_rounds = opts.getInt("max_rounds", code_default("adhesion", "descent_max_rounds"))
        self.offset_tol = opts.getReal("offset_tol", 0.1 * problem.tol)
        if tol is not None:
            # a descent to a looser error (an increment of a step, ``descent_step.py``) holds
            # the mean no tighter: its rounds had stopped at their first iterate, error within
            # tol, and moved W blindly to max_rounds for an offset of 1e-6 z0
            self.offset_tol = max(self.offset_tol, tol)
        # the rounds end where the offset m is within offset_tol as Newton's confirmation will
        # measure it: its gaps do not carry m (K p has zero mean), so next to the wall its
        # self-consistency residual is m da/dg, an error of m max|da/dg| max(K_ii / z0, 1 / P)
        # in its measures (the hard-wall LJ law's slope there is 15.6 P / z0, the exponential
        # law's 1 P / rho: there m / z0 itself, unless K_ii P / z0 > 1).  In z0 alone, Newton
        # took a Krylov step at those states, a scene's peak of memory.  Only where the law is
        # steeper than that (a law without a slope, Dugdale's, keeps m / z0)
        self.limit = self.offset_tol * problem.z0
        # a pressure error's weight in the error measures [1/Pa]: K_ii / z0 in the gaps' and
        # 1 / P in the pressures', the larger counts
        self.per_pascal = max(problem.kappa / problem.z0, 1.0 / problem.pressure_scale)
        if tol is None:
            effect = steepest_slope(problem.law) * self.per_pascal
            if np.isfinite(effect) and effect * problem.z0 > 1.0 + 1e-9:
                self.limit = self.offset_tol / effect
        self.start(0.0)

    def start(self, W: float) -> None:
        """A new descent from the multiplier ``W`` [Pa] (the start's mean pressure)."""
        self.W = W
        self.round = 1               # the round under way (``target``)
        self.visible = np.inf        # what the last update of W moved the error by
        self._last = None            # (W, mean u) of the round before

    def pressure(self, mean_u: float) -> float:
        """The mean pressure W + c m [Pa] at the mean of u ``mean_u`` [m]."""
        return self.c * mean_u + self.W

    def energy(self, mean_u: float, n: int) -> float:
        """The penalty's energy per node area, N m (c m / 2 + W) [J/m^2] over ``n`` nodes."""
        return n * mean_u * (0.5 * self.c * mean_u + self.W)

    def closed(self, mean_u: float) -> bool:
        """Whether the offset ``mean_u`` [m] is within ``offset_tol`` z0, and its effect on
        Newton's error measures within ``offset_tol`` (``limit``; the rounds end)."""
        return abs(mean_u) <= self.limit

    def target(self, mean_u: float, tol: float) -> float:
        """The error [z0] this round stops at, the mean of u being ``mean_u`` [m] and the
        descent's tolerance ``tol``: a round that leaves an offset above ``offset_tol`` is
        followed by another, whose new W moves the state by about that offset: it stops once
        its error [z0] is below the offset [z0] (the last polishing steps of every round but
        the last were lost).  ``tol`` where the round may be the last."""
        if not self.closed(mean_u) and self.round < self.max_rounds:
            # and below what the last update of W moved the error by, else the round stops at
            # its first iterate without moving the state, and W moves on blind (a hundredth of
            # the tolerance at least: within the measures' round-off at any grid, where a
            # blind round costs one evaluation and an unreachable target TAO's max_it)
            return min(max(tol, abs(mean_u) / self.z0), max(self.visible, 0.01 * tol))
        return tol

    def update(self, mean_u: float) -> None:
        """The next round's W after a round that ended at the mean ``mean_u`` [m]: the measured
        mean pressure W + c m; from the second round on, the secant of m(W) where it falls as
        it should (slope below -1/c's sign): the offset then falls superlinearly instead of by
        k / (c + k)."""
        step = self.c * mean_u
        if self._last is not None and mean_u != self._last[1]:
            slope = (mean_u - self._last[1]) / (self.W - self._last[0])
            if slope < 0:
                step = -mean_u / slope
        self._last = (self.W, mean_u)
        self.W += step
        self.round += 1
        # where m is held to its effect on Newton's measures only (``limit``): an update of W
        # below the tolerance's effect on the error measures
        self.visible = (0.5 * abs(step) * self.per_pascal
                        if abs(mean_u) <= self.offset_tol * self.z0 else np.inf)
