"""The pull-off force of a loading path refined: the most tensile stable state, searched by
continuation to the end of each stable segment and by golden section between higher forces
(docs/formulation.md, "Loading paths").

The problem is duck-typed as in ``paths``: ``solve(approach=...)``, ``snapshot()`` and
``restore(snapshot)``, plus ``snes()`` for its Newton iteration limit where it has one;
``RelaxedSearch`` makes the paper's relaxation solver such a problem (a relaxation sweep's
pull-off, refined by relaxation solves).
"""
from __future__ import annotations

import numpy as np

from .fold_watch import MARGIN_FLOOR
from .paths import Path, good_state
from .solvers.stability import leaves_checks_out

#: Newton iterations of a solve of the pull-off search (``refine_pull_off``)
SEARCH_NEWTON_STEPS = 30
#: a relaxation solve of the pull-off search has stalled when its adhesive relaxation
#: coefficient falls below this share of its first value (``RelaxedSearch``): a converging
#: solve keeps it within a few halvings of it, a stalled one halves it at nearly every cycle
SEARCH_STALL = 1e-6


def refine_pull_off(problem, path: Path, xtol: float, max_solves: int = 40,
                    jump_tol: float = 0.05) -> float:
    """The most tensile stable state of the path [N], to ``xtol`` [m] in approach.

    Searches by continuation (``_continue``) from the sampled minimum towards its
    neighbours along the path (across a reversal of the approach too) and from every stable
    state next to a loss of stability or a failed step towards it (``path._edges``), at most
    ``max_solves`` solves each;
    golden-section search where the smallest force lies between two higher ones.  The
    states on either side of a jump (located by bisection in ``sweep``) are candidates.
    NaN when the most tensile state found is not bracketed by the path (``Path._bracketed``:
    no pull-off reached).  Sets ``path.refined_pull_off``; the problem's state is restored.
    A state without a stiffness (NaN: the relaxation's, a restarted path's earlier steps,
    ``-<prefix>stiffness false``)
    predicts with the secant of the branch instead (``_continue``)."""
    if path._best is None:
        path.refined_pull_off = float("nan")
        return path.refined_pull_off
    pts = path.points
    end = problem.snapshot()
    found = []   # (force, reached): reached = bounded by higher forces or at a segment's end
    k, snap = path._best
    sides = [path._side(k, s) for s in (-1, 1)]
    snes = problem.snes() if hasattr(problem, "snes") else None
    if snes is not None:
        rtol, atol, stol, max_it = snes.getTolerances()
        # Newton from a state at most a quarter step away needs a few iterations; one that has
        # not converged in SEARCH_NEWTON_STEPS has left the branch (near its end, such solves ran
        # to the iteration limit and cost most of the search)
        snes.setTolerances(max_it=min(max_it, SEARCH_NEWTON_STEPS))
    auto = leaves_checks_out(problem)

    def check(*ends):
        """The solves between path points ``ends`` leave the check out (False) under auto when
        each was checked stable with a margin above MARGIN_FLOOR and the path joined them
        without a jump: the branch between them has no fold (a fold ends the branch in
        approach); otherwise the problem's own setting (None)."""
        margins = [pts[i].stability_margin for i in ends]
        return False if auto and all(np.isfinite(m) and m > MARGIN_FLOOR for m in margins) else None

    try:
        searched, bracket, smooth = set(), [pts[k].approach, pts[k].approach], [k]
        for n, (side, step) in enumerate(zip(sides, (-1, 1))):
            if side in ("stable", "edge", "turn"):
                towards = pts[k + step].approach
                searched.add((k, towards))
                # towards an unstable or failed state the check finds where the segment ends
                joined = check(k, k + step) if side != "edge" else None
                force, reached, nearest = _continue(problem, snap, pts[k], towards, xtol, max_solves, jump_tol,
                                                    joined, path._slope(k, -step))
                found.append((force, reached))
                bracket[n] = nearest
                smooth += [k + step] if side != "edge" else [None]
        d_k = pts[k].approach
        if (bracket[0] - d_k) * (bracket[1] - d_k) < 0 and all(f[0] == np.inf for f in found):
            # nothing below the sampled minimum on either side: it lies between the nearest
            # stable states on either side
            ends = None if None in smooth or len(smooth) < 3 else check(*smooth)
            found.append((_golden(problem, snap, bracket[0], bracket[1], xtol, max_solves, ends), True))
        for i, towards, edge_snap in path._edges:
            if (i, towards) not in searched:
                behind = -1 if i + 1 < len(pts) and pts[i + 1].approach == towards else 1
                found.append(_continue(problem, edge_snap, pts[i], towards, xtol, max_solves, jump_tol,
                                       slope=path._slope(i, behind))[:2])
    finally:
        if snes is not None:
            snes.setTolerances(max_it=max_it)
    # the sampled minimum itself: reached when the path brackets it (``Path._bracketed``);
    # the states on either side of each jump (the end of the old branch, bisected)
    found.append((pts[k].force, path._bracketed(k)))
    found += [(f, True) for j in path.jumps for f in (j.force_before, j.force_after)]
    problem.restore(end)
    end.destroy()
    force, reached = min(found, key=lambda f: (f[0], not f[1]))
    path.refined_pull_off = force if reached else float("nan")
    return path.refined_pull_off


def _continue(problem, snap, start, towards, xtol, max_solves, jump_tol, check=None, slope=float("nan")):
    """(smallest force [N], reached, nearest) of the stable states connected to ``snap``
    (the state of point ``start``) by continuation towards the approach ``towards`` [m]:
    steps of a quarter of the way, halved where a solve fails, is unstable or jumps (its
    force misses the tangent prediction by more than ``jump_tol`` of the force and by more
    than the predicted change), down to ``xtol`` -- there the stable segment ends (reached).
    Each solve starts from the last state kept, the nearest on the branch.  A state without
    a stiffness (NaN) predicts with the secant from the state kept before it [N/m], the
    first with ``slope`` (``Path._slope``; NaN: no change predicted).  A smallest force
    between two higher ones is refined by golden-section search (reached); one at ``start``
    is not reached here (inf).  ``nearest``: the approach [m] of the first state beyond
    ``start`` (``start``'s own without one).  ``check``: the solves' ``check_stability``."""
    problem.restore(snap)
    cur = (start.approach, start.force, start.stiffness if np.isfinite(start.stiffness) else slope)
    states = [(cur[0], cur[1])]                # (approach, force) of the states kept
    # only the most tensile state beyond the start is wanted again (the golden section's start):
    # a snapshot of every state kept had held up to max_solves copies of the unknowns
    lowest = None
    h, solves, ended = (towards - start.approach) / 4.0, 0, False
    while solves < max_solves and abs(towards - cur[0]) > 1e-12 * max(abs(towards), xtol):
        d = towards if abs(towards - cur[0]) <= abs(h) * (1 + 1e-12) else cur[0] + h
        here = problem.snapshot()
        st = problem.solve(approach=d, raise_on_failure=False, fallback=False, check_stability=check)
        solves += 1
        st.release_fields()     # only its numbers are wanted (``path_steps._locate_jump``)
        predicted = cur[1] + (cur[2] if np.isfinite(cur[2]) else 0.0) * (d - cur[0])
        scale = max(abs(cur[1]), abs(st.force), np.finfo(float).tiny)
        if good_state(st) and abs(st.force - predicted) <= max(jump_tol * scale, abs(predicted - cur[1])):
            cur = (d, st.force, st.stiffness if np.isfinite(st.stiffness) else (st.force - cur[1]) / (d - cur[0]))
            if st.force < min(f for _, f in states):
                if lowest is not None:
                    lowest.destroy()
                lowest = problem.snapshot()
            states.append((d, st.force))
            here.destroy()
        else:
            problem.restore(here)
            here.destroy()
            if abs(h) <= xtol:
                ended = True
                break
            h *= 0.5
    m = min(range(len(states)), key=lambda i: states[i][1])
    nearest = states[min(1, len(states) - 1)][0]
    force, reached = (states[m][1], m < len(states) - 1 or ended) if m else (np.inf, False)
    if 0 < m < len(states) - 1:
        force = min(force, _golden(problem, lowest, states[m - 1][0], states[m + 1][0], xtol, max_solves,
                                   check))
    if lowest is not None:
        lowest.destroy()
    return force, reached, nearest


def _golden(problem, snap, lo, hi, xtol, max_solves, check=None) -> float:
    """Golden-section search of the smallest force [N] on [lo, hi] [m], each solve by Newton
    from ``snap`` (a stable state inside the bracket; ``check``: the solves'
    ``check_stability``); an unstable or failed solve counts as +inf."""
    lo, hi = min(lo, hi), max(lo, hi)
    best = np.inf

    def force(delta):
        nonlocal best
        problem.restore(snap)
        st = problem.solve(approach=delta, raise_on_failure=False, fallback=False, check_stability=check)
        st.release_fields()
        if not good_state(st):
            return np.inf
        best = min(best, st.force)
        return st.force

    gr = (np.sqrt(5.0) - 1.0) / 2.0
    c, d = hi - gr * (hi - lo), lo + gr * (hi - lo)
    fc, fd = force(c), force(d)
    for _ in range(max_solves):
        if hi - lo <= xtol:
            break
        if fc < fd:
            hi, d, fd = d, c, fc
            c = hi - gr * (hi - lo)
            fc = force(c)
        else:
            lo, c, fc = c, d, fd
            d = lo + gr * (hi - lo)
            fd = force(d)
    return best


class RelaxedSearch:
    """The paper's relaxation solver (``solvers.relaxation.RelaxationSolver``) as the problem of
    ``refine_pull_off``: a relaxation sweep's pull-off refined by relaxation solves, not Newton.

    Each solve relaxes from the problem's present state: the attached state the search
    restored, the nearest one on the branch (``_continue``); snapshots are the problem's.  The
    relaxation has no tangent: its states' stiffness is NaN and the jump test predicts with
    the secant of the branch.  From an attached state beyond the end of its branch (a fold)
    the relaxation does not jump: it stalls, its adhesive relaxation coefficient halving at
    nearly every cycle; a solve whose coefficient falls below ``stall`` (SEARCH_STALL) of
    its first value stops and counts as off the branch, as a Newton solve of the search not
    converged in SEARCH_NEWTON_STEPS (``stalled`` counts them).  Any other failure (the cycle
    limit, the time budget, NaN) is kept in ``failure`` ((approach [m], reason)) and ends the
    search: the later solves return that state without solving, and the caller keeps the
    sampled pull-off (``app.steppers.AdhesiveSteps.finish``).
    """
    # no ``stability_check``: the relaxation checks every state it is asked to

    def __init__(self, relax, stall: float = SEARCH_STALL):
        self.relax, self.problem, self.stall = relax, relax.problem, stall
        self.failure, self.stalled = None, 0
        self._failed = None       #: the state of the solve that failed

    def solve(self, *, approach: float, raise_on_failure: bool = True, fallback=None, check_stability=None):
        """The state at ``approach`` [m] relaxed from the present one (``fallback`` has no
        meaning here: the relaxation is the solver)."""
        if self._failed is not None:
            return self._failed
        relax, before = self.relax, self.relax.stall
        relax.stall = self.stall
        try:
            st = relax.solve(approach=approach, raise_on_failure=raise_on_failure, check_stability=check_stability)
        finally:
            relax.stall = before
        if not st.converged:
            if st.reason.startswith("DIVERGED_STALLED"):
                self.stalled += 1
            else:
                self._failed, self.failure = st, (float(approach), st.reason)
        return st

    def snapshot(self):
        return self.problem.snapshot()

    def restore(self, snap) -> None:
        self.problem.restore(snap)
