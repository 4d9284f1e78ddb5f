"""Which states of a displacement-controlled path need the stability check
(``-adhesion_stability_check auto``; docs/robustness.md, "Leaving the stability check out").

The check (``solvers/stability.py``, an estimate of 1 - lambda_max of the stability pencil) can change
an answer of a sweep only where a fold is near: there Newton may converge to the unstable
branch next to the stable one, and the check sends the solve to its fallback (a jump)
and keeps the state out of the pull-off.  Away from folds the margin is bounded away
from zero and varies smoothly with the approach, so a path step leaves the check out
unless one of these says a fold may be near (``FoldWatch.reason``):

- the adhesion is under-resolved (snap number K_ii max da/dg >= 1: every node can snap on
  its own, a fold at every step);
- fewer than two states of the present branch were checked (no margin trend yet: the
  path's start, a restart, the state after a jump);
- the approach reverses (the start of the unloading branch, a pull-off bracket);
- the state is the most tensile one of the path so far (a pull-off candidate: the sampled
  pull-off is always a checked state);
- the force misses the tangent prediction from the last state by more than
  ``PREDICTION_TOL`` of the predicted change (the branch bends: near a fold
  dF/d delta grows without bound);
- Newton needed more than ``NEWTON_SLACK`` iterations beyond the last checked state's;
- the margin's trend reaches zero: near a fold the margin falls as c sqrt(delta_fold -
  delta), so its square is linear in the approach; the square extrapolated from the last
  two checked states with ``TREND_SAFETY`` times its slope reaches ``MARGIN_FLOOR``^2 within
  the distance to the new state.

Jump bisection, load control and central-gap control always check: they work next to
folds, or report the stability of every state.  The pull-off search
(``pull_off.refine_pull_off``) checks too, except between two path points the path joined
without a jump, each checked stable with a margin above ``MARGIN_FLOOR``: the branch between
them has no fold (a fold ends a branch in approach).
"""
from __future__ import annotations

import numpy as np

#: relative miss of the tangent prediction that marks a bending branch
PREDICTION_TOL = 0.25
#: Newton iterations beyond the last checked state's that mark a harder step
NEWTON_SLACK = 2
#: factor on the slope of the squared margin (linear extrapolation puts a sqrt fold up to
#: several times further away than it is while the margin is still well above zero)
TREND_SAFETY = 4.0
#: a margin below this is near a fold whatever its trend
MARGIN_FLOOR = 0.05


class FoldWatch:
    """The record of a sweep that ``reason`` judges from: the checked states of the present
    branch (approach [m], margin, Newton iterations), the last converged state's approach and
    step direction, and the most tensile force [N] of the path's stable states."""

    def __init__(self, lowest: float = np.inf, snap_number: float = 0.0):
        self.checked: list[tuple[float, float, int]] = []
        self.direction = 0.0
        self.lowest = lowest
        self.snap_number = snap_number

    def reason(self, prev: tuple, delta: float, newton: int, force: float) -> str | None:
        """Why the state just converged at approach ``delta`` [m] (``newton`` iterations, net
        force ``force`` [N]) from the last state ``prev`` = (approach, force, dF/d delta) needs the
        check, or None: no fold can be near."""
        if self.snap_number >= 1.0:
            return f"snap number {self.snap_number:.2f} >= 1: every node can snap on its own"
        if len(self.checked) < 2:
            return "fewer than two checked states on this branch (no margin trend)"
        step = delta - prev[0]
        if self.direction and np.sign(step) != self.direction:
            return "the approach reverses"
        if force < self.lowest:
            return "the most tensile state so far (a pull-off candidate)"
        d0, w0, k0 = prev
        if not np.isfinite(k0):
            return "no tangent at the last state"
        change = k0 * step
        miss = abs(force - (w0 + change))
        if miss > PREDICTION_TOL * max(abs(change), np.finfo(float).tiny):
            return f"the force misses the tangent prediction by {miss / max(abs(change), 1e-300):.0%} of its change"
        (a1, m1, _), (a2, m2, n2) = self.checked[-2:]
        if newton > n2 + NEWTON_SLACK:
            return f"Newton needed {newton} iterations (the last checked state {n2})"
        slope = abs(m2 * m2 - m1 * m1) / max(abs(a2 - a1), np.finfo(float).tiny)
        if m2 * m2 - TREND_SAFETY * slope * abs(delta - a2) <= MARGIN_FLOOR ** 2:
            return f"the margin's trend ({m2:.3f} at the last checked state) may reach zero"
        return None

    def seen(self, st, before: float | None, jumped: bool) -> None:
        """Record a converged state ``st`` of the path, reached from the approach ``before`` [m]
        (None: the path's first state); ``jumped``: it is on a new branch."""
        if jumped:
            self.checked = []
        if before is not None and st.approach != before:
            self.direction = float(np.sign(st.approach - before))
        if st.stable is not None and np.isfinite(st.stability_margin):
            self.checked.append((st.approach, st.stability_margin, st.newton_iterations))
        if st.stable is not False:
            self.lowest = min(self.lowest, st.force)

    def state(self) -> dict:
        """What ``reason`` judges from (JSON-able): a restart that restores it (``restored``) makes
        the uninterrupted run's decisions, which the path's points alone cannot rebuild (the
        watch also sees the states of sub-steps, and each state's margin and Newton count)."""
        return {"checked": [list(c) for c in self.checked[-2:]], "direction": self.direction,
                "lowest": self.lowest if np.isfinite(self.lowest) else None, "snap_number": self.snap_number}

    @classmethod
    def restored(cls, state: dict) -> "FoldWatch":
        """The watch whose ``state()`` was ``state``."""
        lowest = state["lowest"]
        watch = cls(np.inf if lowest is None else float(lowest), float(state["snap_number"]))
        watch.checked = [(float(a), float(m), int(n)) for a, m, n in state["checked"]]
        watch.direction = float(state["direction"])
        return watch
