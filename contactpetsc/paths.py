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
from petsc4py import PETSc

from .fold_watch import FoldWatch
from .solvers.base import pieces
from .solvers.stability import leaves_checks_out

#: the pieces a sub-step is checked against (``protocol.agreement``): a path refined 4x and 16x
#: lands in the same states where it is the quasi-static one (issue 33's criterion)
AGREEMENT_SPLIT = 4


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
class Jump:
    """A jump between branches, located within [approach_before, approach_after]."""
    kind: str                 #: jump-on | jump-off
    approach_before: float    #: last approach on the old branch [m]
    approach_after: float     #: first approach on the new branch [m]
    force_before: float       #: [N]
    force_after: float        #: [N]


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
    descended in 4, 16, ... increments (``_agreed_increments``); otherwise its
    ``AGREEMENT_SPLIT`` equal pieces (``_agreed_piece``).  Where their gaps differ by more than
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
            st, cost, verdict = _agreed_increments(problem, snap, prev, d, path, jump_tol, refine,
                                                   agreement, levels, foot)
            spent += cost
            if st.converged:
                verdicts.append(verdict)
        elif check_it:
            st, cost = _agreed_piece(problem, snap, prev, d, path, jump_tol, refine, agreement)
            spent += cost
            if st is None:          # the pieces and the whole sub-step part: divide it
                h /= AGREEMENT_SPLIT
                base = h
                snap.destroy()
                continue
            agreed = min(agreed or np.inf, abs(d - prev[0]))
            done += AGREEMENT_SPLIT - 1     # the pieces before the last
        else:
            st = _piece(problem, snap, prev, d, path, jump_tol, refine)
            unsettled |= agreement > 0 and st.converged
        # (a converged sub-step goes on even past a time budget: the next solve says so)
        final = (st.converged and d == target) or (not st.converged and (
            substeps <= 0 or problem.out_of_time() or abs(h) <= abs(base) * 2.0 ** -substeps * (1 + 1e-12)))
        if not final:
            spent += _cost(st)
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
                notes.append(f"sub-steps of {finest:.3e} m not checked")
            elif agreed is not None:
                notes.append(f"pieces agree at sub-steps of {agreed:.3e} m")
            elif verdicts:
                most = max(k for k, _ in verdicts)
                settled = all(ok for _, ok in verdicts)
                notes.append(f"{most} increments agree with {most // AGREEMENT_SPLIT}" if settled
                             else f"{most} increments, not agreeing with {most // AGREEMENT_SPLIT}")
        if any(notes):
            st.solver += " (" + "; ".join(n for n in notes if n) + ")"
    if st.converged:
        prev = (st.approach, st.force, st.stiffness)
    return st, prev


def _cost(st) -> np.ndarray:
    return np.array([st.fft_pairs, st.wall_time, st.newton_iterations, st.linear_iterations], float)


def _piece(problem, snap, prev, d, path, jump_tol, refine, increments=None):
    """Solve one sub-step from ``prev`` (the state in ``snap``) to approach ``d`` [m] (under the
    descent strategy in ``increments`` if given) and test it for a jump (recorded in
    ``path.jumps``) and for the fold watch; returns its state."""
    watch = path._watch
    n_jumps = len(path.jumps)
    check = None if watch is None else (
        lambda newton, force: watch.reason(prev, d, newton, force) is not None)
    more = {} if increments is None else {"increments": increments}
    st = problem.solve(approach=d, raise_on_failure=False, check_stability=check, **more)
    if st.converged:
        d0, w0, k0 = prev
        predicted = w0 + (k0 if np.isfinite(k0) else 0.0) * (d - d0)
        scale = max(abs(w0), abs(st.force), np.finfo(float).tiny)
        # the fallback was needed, or the force missed the tangent prediction by
        # more than the predicted change itself: another branch
        if st.fallback or abs(st.force - predicted) > max(jump_tol * scale, abs(predicted - w0)):
            jump = _locate_jump(problem, snap, prev, st, refine)
            if problem.out_of_time():
                # the bisection's solves were cut short: neither the jump nor its absence
                # is known, so the step is not done (a restart solves it again)
                problem.restore(snap)
                st.converged, jump = False, None
                st.reason = problem.budget_reason + " (while locating a jump; the step is not kept)"
            if jump is not None and abs(jump.force_after - jump.force_before) > jump_tol * scale:
                jump.kind = "jump-on" if d > d0 else "jump-off"
                path.jumps.append(jump)
        if st.converged and watch is not None:
            watch.seen(st, prev[0], jumped=st.fallback or len(path.jumps) > n_jumps)
    return st


def _agreed_piece(problem, snap, prev, d, path, jump_tol, refine, agreement):
    """The sub-step from ``prev`` (the state in ``snap``) to ``d`` [m] in ``AGREEMENT_SPLIT``
    equal pieces, each a ``_piece``, checked against a probe of the whole sub-step from the
    same start.  Returns (the last piece's state or None, the cost of the probe and the pieces
    before the last): None where the pieces part from the probe (their gaps differ by more than
    ``agreement`` [m] somewhere) or a solve fails; the problem, the path's jumps and its fold
    watch are then as they were before."""
    cost = np.zeros(4)
    n_jumps = len(path.jumps)
    watched = None if path._watch is None else path._watch.state()
    # a probe: neither the stability check nor the tangent, only its gaps are wanted
    probe = problem.solve(approach=d, raise_on_failure=False, check_stability=False, tangent=False)
    cost += _cost(probe)
    problem.restore(snap)
    if not probe.converged:
        return None, cost
    gap = probe.gap
    probe.release_fields()
    here, start = prev, snap
    for k in range(1, AGREEMENT_SPLIT + 1):
        st = _piece(problem, start, here, d if k == AGREEMENT_SPLIT else prev[0] + (d - prev[0]) * k / AGREEMENT_SPLIT,
                    path, jump_tol, refine)
        if start is not snap:
            start.destroy()
        if not st.converged or k == AGREEMENT_SPLIT:
            break
        cost += _cost(st)
        here, start = (st.approach, st.force, st.stiffness), problem.snapshot()
    agree = st.converged and gap_difference(st.gap, gap) <= agreement
    gap.destroy()
    if not agree:
        cost += _cost(st)
        _undo(problem, snap, path, n_jumps, watched)
        return None, cost
    return st, cost


def _undo(problem, snap, path, n_jumps, watched) -> None:
    """Undo solves from ``snap``: the problem back to it, the path's jumps back to the first
    ``n_jumps``, its fold watch back to the state ``watched`` (``FoldWatch.state``) or None."""
    del path.jumps[n_jumps:]
    if watched is not None:
        path._watch = FoldWatch.restored(watched)
    problem.restore(snap)


def _agreed_increments(problem, snap, prev, d, path, jump_tol, refine, agreement, levels, foot=0.0):
    """The sub-step from ``prev`` (the state in ``snap``) to ``d`` [m] under the descent strategy:
    descended in n increments of at most ``foot`` [m] (a probe, without the stability check or the
    tangent; ``foot`` 0: as the descent's options say, by default whole), then in 4n, 16n, ... equal increments
    (``AdhesiveProblem.solve(increments=)``: a continuation in the approach without the states
    between, the sub-steps' asperity order at a fraction of their cost), each a ``_piece``
    compared with the one before, until two agree to ``agreement`` [m] or ``levels`` were
    tried.  A candidate that parts from the one before is undone (its jumps, what the fold
    watch saw) and is the next one's reference.  Returns (the last candidate's state, the
    cost of the probe and the candidates undone, (its increments, whether it agreed))."""
    cost = np.zeros(4)
    # a probe: neither the stability check nor the tangent, only its gaps are wanted
    foot_increments = {"increments": pieces(d - prev[0], foot)} if foot > 0 else {}
    probe = problem.solve(approach=d, raise_on_failure=False, check_stability=False, tangent=False,
                          **foot_increments)
    cost += _cost(probe)
    problem.restore(snap)
    gap = probe.gap if probe.converged else None
    probe.release_fields()
    # the probe's own increments: the ladder's foot
    n = max(int(getattr(probe, "descent_increments", 1)), 1)
    for level in range(1, levels + 1):
        n *= AGREEMENT_SPLIT
        n_jumps = len(path.jumps)
        watched = None if path._watch is None else path._watch.state()
        st = _piece(problem, snap, prev, d, path, jump_tol, refine, increments=n)
        # a descent that gave up on its increments took the step whole (``descend_step``): no
        # finer way than the probe's, so nothing to agree
        finer = getattr(st, "descent_increments", n) == n
        agree = st.converged and finer and gap is not None and gap_difference(st.gap, gap) <= agreement
        if agree or level == levels:
            break
        cost += _cost(st)
        if st.converged and finer:
            # the next candidate's reference (a failed one keeps the one before)
            if gap is not None:
                gap.destroy()
            gap = st.gap
        st.release_fields()
        _undo(problem, snap, path, n_jumps, watched)
    if gap is not None:
        gap.destroy()
    return st, cost, (n, agree)


def gap_difference(a, b) -> float:
    """max |a - b| of two gap Vecs [m] over the grid (collective)."""
    diff = a.copy()
    diff.axpy(-1.0, b)
    out = diff.norm(PETSc.NormType.NORM_INFINITY)
    diff.destroy()
    return out


def _locate_jump(problem, snap, prev, after, refine) -> Jump | None:
    """Bisect [prev approach, after.approach] with solves from the old branch, without the
    fallback (the problem's strategy: Newton, or the descent then Newton); None when
    the branch is continuous there: the force gap across the final bracket is no larger than
    twice the larger branch slope times its width (a jump keeps its gap as the bracket
    shrinks; a steep smooth branch does not)."""
    d_lo, w_lo, k_lo = prev
    d_hi, w_hi = after.approach, after.force
    width0, gap0 = abs(d_hi - d_lo), abs(w_hi - w_lo)
    new_branch = problem.snapshot()
    problem.restore(snap)
    snap = problem.snapshot()   # our own copy: the caller frees its own
    for _ in range(refine):
        mid = 0.5 * (d_lo + d_hi)
        problem.restore(snap)
        st = problem.solve(approach=mid, raise_on_failure=False, fallback=False)
        # still on the old branch: converged from it, stable, and nearer the old force
        on_old = (st.converged and st.stable is not False
                  and abs(st.force - w_lo) < 0.5 * abs(w_hi - w_lo))
        if on_old:
            snap.destroy()
            snap = problem.snapshot()
            d_lo, w_lo, k_lo = mid, st.force, st.stiffness
        else:
            d_hi = mid
    problem.restore(new_branch)
    new_branch.destroy()
    k_hi = after.stiffness
    if refine and abs(d_hi - after.approach) > 0:
        # the force just after the jump, on the new branch, at the bisected approach
        st = problem.solve(approach=d_hi, raise_on_failure=False)
        w_after, k_hi = st.force, st.stiffness
        problem.solve(approach=after.approach, raise_on_failure=False)
    else:
        w_after = w_hi
    snap.destroy()
    width, gap = abs(d_hi - d_lo), abs(w_after - w_lo)
    slope = max(abs(k_lo), abs(k_hi))
    smooth = 2.0 * slope * width if np.isfinite(slope) else 4.0 * gap0 * width / max(width0, np.finfo(float).tiny)
    if gap <= smooth:
        return None
    return Jump(kind="", approach_before=d_lo, approach_after=d_hi, force_before=w_lo,
                force_after=w_after)


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
