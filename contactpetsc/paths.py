"""Quasi-static loading paths of adhesive contacts: sweeps, jumps, pull-off, S-curves
(docs/formulation.md, "Loading paths").

Displacement control follows a branch of stable equilibria, each step warm-started with
the tangent predictor; where a branch ends at a fold the contact jumps, and the jump is
located by bisection of the approach and reported only when it is a discontinuity (the
force gap across the final bracket exceeds what the branches' slopes give over its
width).  The pull-off force is the most tensile stable state of the path (NaN where the
path does not bracket that state in approach: a sphere that never left the far field is
most tensile where the path turned); ``pull_off.refine_pull_off`` refines it by
continuation to the end of each stable segment.  Central-gap control (Greenwood's device) keeps every state,
stable or not, and traces the whole S-shaped curve of a sphere.

The problem is duck-typed: ``solve(approach=...)``, ``snapshot()`` (an object with
``destroy()``) and ``restore(snapshot)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .fold_watch import FoldWatch
from .path_steps import Jump  # noqa: F401 (API: a Path's jumps)
from .path_steps import (AGREEMENT_SPLIT, NOT_AGREEING, NOT_CHECKED, agreed_increments, agreed_pieces, cost_of,
                         solve_step)
from .solvers.base import pieces
from .solvers.stability import leaves_checks_out

@dataclass
class PathPoint:
    """A point of a loading path (scalars only; fields live in the solver's state)."""
    step: int
    branch: str               #: loading | unloading | central-gap
    approach: float           #: [m]
    central_gap: float        #: [m]
    force: float              #: net force [N], negative = tensile
    adhesive_force: float     #: [N]
    contact_fraction: float
    stable: bool | None
    converged: bool
    solver: str
    fft_pairs: float
    wall_time: float
    complementarity_error: float
    adhesive_error: float
    total_error: float
    reason: str = ""          #: the solver's converged or diverged reason
    stiffness: float = float("nan")  #: tangent dF/d delta [N/m] (NaN when not computed)
    stability_margin: float = float("nan")  #: 1 - lambda_max(A S) (NaN where not checked)


@dataclass
class Path:
    points: list = field(default_factory=list)
    jumps: list = field(default_factory=list)

    refined_pull_off: float | None = None   #: set by ``pull_off.refine_pull_off``
    _watch: FoldWatch | None = None          #: what ``sweep`` leaves the stability check out by (auto)
    _best: tuple | None = None               #: (point index, snapshot) of the most tensile stable state
    #: (point index, approach to search towards [m], snapshot) of stable states next to a
    #: loss of stability or a failed step: where a stable segment ends
    _edges: list = field(default_factory=list)

    @property
    def pull_off_force(self) -> float:
        """The most tensile force [N] of the path's stable states, or its refinement
        (``pull_off.refine_pull_off``); NaN when the path does not bracket that state (``_bracketed``:
        no pull-off reached)."""
        if self.refined_pull_off is not None:
            return self.refined_pull_off
        good = [k for k, p in enumerate(self.points) if good_state(p)]
        if not good:
            return float("nan")
        k = min(good, key=lambda i: self.points[i].force)
        return self.points[k].force if self._bracketed(k) else float("nan")

    def _side(self, k: int, step: int) -> str:
        """What lies next to point k along the path: "end", "jump" (a jump in between),
        "edge" (an unstable or failed point), "stable", or "turn" (a stable point across a
        reversal of the approach: the same branch, retraced)."""
        j = k + step
        pts = self.points
        if not (0 <= j < len(pts)):
            return "end"
        lo, hi = sorted((pts[k].approach, pts[j].approach))
        turned = pts[j].branch != pts[k].branch
        kind = None if turned else {"loading": "jump-on", "unloading": "jump-off"}.get(pts[k].branch)
        jumped = any((kind is None or jp.kind == kind) and
                     (lo <= jp.approach_before <= hi or lo <= jp.approach_after <= hi) for jp in self.jumps)
        if jumped:
            return "jump"
        if not good_state(pts[j]):
            return "edge"
        return "turn" if turned else "stable"

    def _slope(self, k: int, step: int) -> float:
        """dF/d delta [N/m] of point k by the secant to its neighbour at k + ``step`` where the
        path joins them on one branch (``_side`` "stable" or "turn"), NaN otherwise: for states
        without a stiffness (the relaxation's; the points of a restarted path)."""
        if self._side(k, step) not in ("stable", "turn"):
            return float("nan")
        a, b = self.points[k], self.points[k + step]
        return (b.force - a.force) / (b.approach - a.approach) if b.approach != a.approach else float("nan")

    def _bracketed(self, k: int) -> bool:
        """Whether point k's force is a pull-off: the path reaches beyond it in approach on
        both sides (a smaller force would lie between), or a loss of stability or a jump
        borders it.  A most tensile state at a reversal or an end of the path, with both
        neighbours on one side of it, is not one: more approach might pull harder (a sphere
        that never left the far field)."""
        signs = set()
        for step in (-1, 1):
            side = self._side(k, step)
            if side == "end":
                continue
            if side in ("edge", "jump"):
                return True
            signs.add(np.sign(self.points[k + step].approach - self.points[k].approach))
        return {-1.0, 1.0} <= signs

    def column(self, name: str) -> np.ndarray:
        return np.array([getattr(p, name) for p in self.points])


def good_state(p) -> bool:
    """Whether a point or state converged and is not known to be unstable."""
    return p.converged and p.stable is not False


def path_point(step, branch, st) -> PathPoint:
    return PathPoint(step=step, branch=branch, approach=st.approach, central_gap=st.central_gap,
                     force=st.force, adhesive_force=st.adhesive_force,
                     contact_fraction=st.contact_fraction, stable=st.stable, converged=st.converged,
                     solver=st.solver, fft_pairs=st.fft_pairs, wall_time=st.wall_time,
                     complementarity_error=st.complementarity_error,
                     adhesive_error=st.adhesive_error, total_error=st.total_error, reason=st.reason,
                     stiffness=st.stiffness, stability_margin=st.stability_margin)


def sweep(problem, approaches, *, branch: str | None = None, jump_tol: float = 0.05,
          refine: int = 6, on_state=None, path: Path | None = None, stop_on_failure: bool = False,
          on_failure=None, previous: tuple | None = None, substeps: int = 3, max_step: float = 0.0,
          agreement: float = 0.0, levels: int = 2, foot: float = 0.0) -> Path:
    """Displacement-controlled path through ``approaches`` [m] (loading where they rise,
    unloading where they fall).  ``on_state(step, state, point)`` is called for each
    converged step (e.g. to write fields), ``on_failure(step, state, point)`` for each
    failed one.  ``previous`` = (approach [m], force [N], dF/d delta [N/m] or NaN) of the
    problem's current state when the path continues one (a restart), so that a jump between
    it and the first step is found too.  A step longer than ``max_step`` [m] (0: any) is taken
    in equal sub-steps of at most that: the quasi-static path, whose states do not depend on
    the step (docs/formulation.md, "Loading paths").  With ``agreement`` [m] > 0 each sub-step
    is checked against finer ways to its approach (more increments of the descent, the first
    of at most ``foot`` [m] (0: the descent's own), or its ``AGREEMENT_SPLIT`` pieces), at most
    ``levels`` times, until their states' gaps agree to that (``_advance``).  A step or sub-step that fails is tried
    again from the last converged state in halved steps, down to 2**-``substeps`` of it
    (``_advance``); the sub-steps' states are not points of the path, their cost is counted in
    the step's.
    A step that still fails is kept as a point (not converged, with its reason)
    and the path goes on from the last converged state, or,
    with ``stop_on_failure``, ends there (a run that must stay contiguous, to restart
    from).  Returns the Path with its jumps."""
    if agreement > 0 and levels < 1:
        raise ValueError(f"levels must be >= 1 where agreement > 0, got {levels!r}")
    path = Path() if path is None else path
    approaches = [float(a) for a in approaches]
    prev = previous      # (approach, force, stiffness) of the last state
    last = None          # (point index, snapshot) of the last point if it was stable
    for k, delta in enumerate(approaches):
        here = branch or ("loading" if prev is None or delta >= prev[0] else "unloading")
        st, prev = _advance(problem, delta, prev, path, jump_tol, refine, substeps, max_step, agreement, levels,
                            foot)
        pt = path_point(k, here, st)
        path.points.append(pt)
        last = keep_for_search(path, problem, last)
        if not st.converged and on_failure is not None:
            on_failure(k, st, pt)
        if not st.converged and stop_on_failure:
            break
        if st.converged and on_state is not None:
            on_state(k, st, pt)
    if last is not None:
        last[1].destroy()
    return path


def keep_for_search(path: Path, problem, last: tuple | None) -> tuple | None:
    """What the pull-off search (``pull_off.refine_pull_off``) starts from, kept as the path's
    last point is appended (the problem at its state): the most tensile stable state
    (``path._best``) and the stable states where a stable segment ends (``path._edges``).
    ``last``: (index, snapshot) of the point before, if it was stable, or None; returns this
    point's (the caller destroys its snapshot when no point follows)."""
    i = len(path.points) - 1
    pt = path.points[i]
    good = good_state(pt)
    if last is not None:
        if path._side(last[0], 1) == "edge":
            # the stable segment of the last point ends before this one (at a jump the
            # bisection has found its end already: the jump's force_before)
            path._edges.append((last[0], pt.approach, last[1]))
        else:
            last[1].destroy()
        last = None
    if good:
        last = (i, problem.snapshot())
        if path._side(i, -1) == "edge":
            # a stable segment begins here after an unstable or failed point (after a
            # jump the new branch's extension backwards was never traversed)
            path._edges.append((i, path.points[i - 1].approach, problem.snapshot()))
        best = path._best
        if best is None or pt.force < path.points[best[0]].force:
            if best is not None:
                best[1].destroy()
            path._best = (i, problem.snapshot())
    return last


def _advance(problem, target, prev, path, jump_tol, refine, substeps, max_step=0.0, agreement=0.0,
             levels=2, foot=0.0):
    """Solve at ``target`` from the present state in equal sub-steps of at most ``max_step``
    [m] (0: one step), testing each for a jump; where one fails, go back to the last converged
    state and get there in halved steps, at least 2**-``substeps`` of the sub-step each.  A step longer than Newton's basin is not the
    end of the branch: a strongly adhesive hard-wall sphere's compressed states need
    shorter steps than its path gives (docs/studies.md).

    With ``agreement`` [m] > 0 each sub-step is checked against the quasi-static limit: the
    state it reaches whole from the last one (a probe, without the stability check or the
    tangent) is compared with the state of a finer way there.  Under the energy descent that is the sub-step
    descended in 4, 16, ... increments (``path_steps.agreed_increments``); otherwise its
    ``AGREEMENT_SPLIT`` equal pieces (``path_steps.agreed_pieces``).  Where their gaps differ by more than
    ``agreement`` anywhere, the sub-step was too coarse (the asperities that snap within it
    snapped in another order): the increments are multiplied, or the pieces undone and the
    sub-step divided into them, at most ``levels`` times; the pieces of the last level are
    taken unchecked (docs/formulation.md, "Loading paths").

    Returns the state at ``target`` (or the failed one) with the cost of every try, probe and
    sub-step in it, and the (approach, force, stiffness) of the last converged state."""
    if path._watch is None and leaves_checks_out(problem):
        # the check left out away from folds (-<prefix>stability_check auto; the problem
        # reads its options at its first solve)
        path._watch = FoldWatch(min([p.force for p in path.points if good_state(p)], default=np.inf),
                                getattr(problem, "snap_number", 0.0))
    if prev is None:   # the path's first state: nothing to jump from or go back to
        st = problem.solve(approach=target, raise_on_failure=False)
        if st.converged and path._watch is not None:
            path._watch.seen(st, None, jumped=False)
        return st, ((st.approach, st.force, st.stiffness) if st.converged else None)
    whole = target - prev[0]
    h0 = whole / pieces(whole, max_step)
    h, spent, done = h0, np.zeros(4), 0
    base = h0               # the sub-step the failure halvings count from (the check's divisions move it)
    finest = abs(h0) * float(AGREEMENT_SPLIT) ** -levels    # the shortest sub-step checked against its pieces
    agreed = None           # the shortest sub-step [m] whose pieces agreed with it
    unsettled = False       # a sub-step of ``finest`` (the last level's pieces) was taken unchecked
    verdicts = []           # the descent's increments per sub-step: (increments, agreed)
    # the sum of the sub-steps rounds: far from the origin (|approach| >> max_step) a remainder
    # of a few ulps past the last piece would be one more solve
    slack = 64.0 * np.spacing(abs(target))
    while True:
        d = target if abs(target - prev[0]) <= abs(h) * (1 + 1e-9) + slack else prev[0] + h
        snap = problem.snapshot()
        descends = agreement > 0 and getattr(problem, "descends", False)
        check_it = agreement > 0 and abs(d - prev[0]) > finest * (1 + 1e-9) and not descends
        if descends:
            st, cost, verdict = agreed_increments(problem, snap, prev, d, path, jump_tol, refine,
                                                   agreement, levels, foot)
            spent += cost
            if st.converged:
                verdicts.append(verdict)
        elif check_it:
            st, cost = agreed_pieces(problem, snap, prev, d, path, jump_tol, refine, agreement)
            spent += cost
            if st is None:          # the pieces and the whole sub-step part: divide it
                h /= AGREEMENT_SPLIT
                base = h
                snap.destroy()
                continue
            agreed = min(agreed or np.inf, abs(d - prev[0]))
            done += AGREEMENT_SPLIT - 1     # the pieces before the last
        else:
            st = solve_step(problem, snap, prev, d, path, jump_tol, refine)
            unsettled |= agreement > 0 and st.converged
        # (a converged sub-step goes on even past a time budget: the next solve says so)
        final = (st.converged and d == target) or (not st.converged and (
            substeps <= 0 or problem.out_of_time() or abs(h) <= abs(base) * 2.0 ** -substeps * (1 + 1e-12)))
        if not final:
            spent += cost_of(st)
            if st.converged:
                prev, done = (st.approach, st.force, st.stiffness), done + 1
            else:
                problem.restore(snap)   # the last converged state, with its tangent
                h *= 0.5
        snap.destroy()
        if final:
            break
    if not st.converged and st.approach != target:
        st.reason += f" (at the sub-step to approach {st.approach:.6e} m of the step to {target:.6e} m)"
    if spent.any():
        st.fft_pairs += spent[0]
        st.wall_time += spent[1]
        st.newton_iterations += int(spent[2])
        st.linear_iterations += int(spent[3])
        # the pieces the step was taken in: the converged sub-steps and the last solve
        notes = [f"{done + 1} sub-steps" if done else ("no halved step converged" if not st.converged else "")]
        if agreement > 0 and st.converged:
            if unsettled:
                notes.append(f"sub-steps of {finest:.3e} m {NOT_CHECKED}")
            elif agreed is not None:
                notes.append(f"pieces agree at sub-steps of {agreed:.3e} m")
            elif verdicts:
                most = max(k for k, _ in verdicts)
                settled = all(ok for _, ok in verdicts)
                notes.append(f"{most} increments agree with {most // AGREEMENT_SPLIT}" if settled
                             else f"{most} increments, {NOT_AGREEING} {most // AGREEMENT_SPLIT}")
        if any(notes):
            st.solver += " (" + "; ".join(n for n in notes if n) + ")"
    if st.converged:
        prev = (st.approach, st.force, st.stiffness)
    return st, prev


def central_gap_path(problem, central_gaps, *, on_state=None, path: Path | None = None,
                     stop_on_failure: bool = False, on_failure=None) -> Path:
    """Prescribed central gaps [m] (Greenwood's device): every state kept, unstable ones marked;
    a failed step as in ``sweep``."""
    path = Path() if path is None else path
    for k, gc in enumerate(central_gaps):
        st = problem.solve(central_gap=float(gc), raise_on_failure=False)
        pt = path_point(k, "central-gap", st)
        path.points.append(pt)
        if not st.converged and on_failure is not None:
            on_failure(k, st, pt)
        if not st.converged and stop_on_failure:
            break
        if st.converged and on_state is not None:
            on_state(k, st, pt)
    return path


def edge_gap_path(problem, step: float, min_gap: float, *, direction: tuple[int, int] = (1, 0),
                  stop=None, max_nodes: int | None = None, on_state=None, path: Path | None = None) -> Path:
    """The rest of the S-curve once the apex touches: prescribed gaps at nodes moving outward.

    Past the point where the central node touches, its gap no longer picks one state
    (at g <= 0 the solves leave the branch for full contact); the contact radius,
    though, grows along the whole curve -- the unstable branch and the adhered one
    beyond the jump-off fold.  So the control node steps outward along ``direction``
    from the present one (``problem.set_control_node``), one node at a time, and each
    node's gap is prescribed from its present value down to ``min_gap`` [m] in steps
    of ``step`` [m]: the contact edge is led across the grid node by node.  Every state
    is kept, unstable ones marked (branch "edge-gap"; the point's ``central_gap`` is the
    control node's gap).  Ends when ``stop(point)`` is true for a converged point, at
    the first failed solve, after ``max_nodes`` nodes, or at the grid's edge; the
    problem keeps the last control node (``set_control_node()`` returns to the apex)."""
    path = Path() if path is None else path
    g = problem.grid
    j0, i0 = divmod(problem.centre_index, g.nx)
    k = 0
    for m in range(1, max_nodes + 1 if max_nodes else 1 << 30):
        i, j = i0 + m * direction[0], j0 + m * direction[1]
        if not (0 <= i < g.nx and 0 <= j < g.ny):
            break
        problem.set_control_node((i, j))
        for gap in np.arange(problem.control_gap() - step, min_gap - 1e-12 * step, -step):
            st = problem.solve(central_gap=float(gap), raise_on_failure=False)
            pt = path_point(k, "edge-gap", st)
            path.points.append(pt)
            if not st.converged:
                return path
            if on_state is not None:
                on_state(k, st, pt)
            k += 1
            if stop is not None and stop(pt):
                return path
    return path
