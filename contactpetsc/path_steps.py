"""One step of a displacement-controlled path (``paths.sweep``): its solve, the test for a jump
(located by bisection), and the check of the step against the quasi-static limit
(``protocol.agreement``: docs/formulation.md, "Loading paths")."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from petsc4py import PETSc

from .fold_watch import FoldWatch
from .solvers.base import pieces

#: the pieces a sub-step is checked against (``protocol.agreement``): a path refined 4x and 16x
#: lands in the same states where it is the quasi-static one (issue 33's criterion)
AGREEMENT_SPLIT = 4
#: what the solver column says of a step whose check did not settle (``unsettled``)
NOT_AGREEING, NOT_CHECKED = "not agreeing with", "not checked"


def unsettled(solver: str) -> bool:
    """Whether a step's solver column (``paths._advance``) says its check did not settle."""
    return NOT_AGREEING in solver or NOT_CHECKED in solver


@dataclass
class Jump:
    """A jump between branches, located within [approach_before, approach_after]."""
    kind: str                 #: jump-on | jump-off
    approach_before: float    #: last approach on the old branch [m]
    approach_after: float     #: first approach on the new branch [m]
    force_before: float       #: [N]
    force_after: float        #: [N]


def cost_of(st) -> np.ndarray:
    """A state's cost: (FFT pairs, wall time [s], Newton iterations, Krylov iterations)."""
    return np.array([st.fft_pairs, st.wall_time, st.newton_iterations, st.linear_iterations], float)


def solve_step(problem, snap, prev, d, path, jump_tol, refine, increments=None):
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


def agreed_pieces(problem, snap, prev, d, path, jump_tol, refine, agreement):
    """The sub-step from ``prev`` (the state in ``snap``) to ``d`` [m] in ``AGREEMENT_SPLIT``
    equal pieces, each a ``solve_step``, checked against a probe of the whole sub-step from the
    same start.  Returns (the last piece's state or None, the cost of the probe and the pieces
    before the last): None where the pieces part from the probe (their gaps differ by more than
    ``agreement`` [m] somewhere) or a solve fails; the problem, the path's jumps and its fold
    watch are then as they were before."""
    n_jumps = len(path.jumps)
    watched = None if path._watch is None else path._watch.state()
    gap, cost, _ = _probe(problem, snap, d)
    if gap is None:
        return None, cost
    here, start = prev, snap
    for k in range(1, AGREEMENT_SPLIT + 1):
        st = solve_step(problem, start, here, d if k == AGREEMENT_SPLIT else prev[0] + (d - prev[0]) * k / AGREEMENT_SPLIT,
                    path, jump_tol, refine)
        if start is not snap:
            start.destroy()
        if not st.converged or k == AGREEMENT_SPLIT:
            break
        cost += cost_of(st)
        here, start = (st.approach, st.force, st.stiffness), problem.snapshot()
    agree = st.converged and gap_difference(st.gap, gap) <= agreement
    gap.destroy()
    if not agree:
        cost += cost_of(st)
        _undo(problem, snap, path, n_jumps, watched)
        return None, cost
    return st, cost


def _probe(problem, snap, d, increments=None):
    """A probe of the step from the state in ``snap`` to ``d`` [m] (in ``increments`` under the
    descent, if given): solved without the stability check or the tangent (but where the Newton
    strategy's branch check needs it), only its gaps are wanted; the problem is back at ``snap`` after it.  Returns (its gap Vec, None where it
    failed; its cost; the increments its descent took, at least 1: the ladder's foot)."""
    more = {} if increments is None else {"increments": increments}
    probe = problem.solve(approach=d, raise_on_failure=False, check_stability=False, tangent=False, **more)
    problem.restore(snap)
    gap = probe.gap if probe.converged else None
    probe.release_fields()
    return gap, cost_of(probe), max(int(getattr(probe, "descent_increments", 1)), 1)


def _undo(problem, snap, path, n_jumps, watched) -> None:
    """Undo solves from ``snap``: the problem back to it, the path's jumps back to the first
    ``n_jumps``, its fold watch back to the state ``watched`` (``FoldWatch.state``) or None."""
    del path.jumps[n_jumps:]
    if watched is not None:
        path._watch = FoldWatch.restored(watched)
    problem.restore(snap)


def agreed_increments(problem, snap, prev, d, path, jump_tol, refine, agreement, levels, foot=0.0):
    """The sub-step from ``prev`` (the state in ``snap``) to ``d`` [m] under the descent strategy:
    descended in n increments of at most ``foot`` [m] (a probe, without the stability check or the
    tangent; ``foot`` 0: as the descent's options say, by default whole), then in 4n, 16n, ... equal increments
    (``AdhesiveProblem.solve(increments=)``: a continuation in the approach without the states
    between, the sub-steps' asperity order at a fraction of their cost), each a ``solve_step``
    compared with the one before, until two agree to ``agreement`` [m] or ``levels`` were
    tried.  A candidate that parts from the one before is undone (its jumps, what the fold
    watch saw) and is the next one's reference.  Returns (the last candidate's state, the
    cost of the probe and the candidates undone, (its increments, whether it agreed))."""
    gap, cost, n = _probe(problem, snap, d, pieces(d - prev[0], foot) if foot > 0 else None)
    for level in range(1, levels + 1):
        n *= AGREEMENT_SPLIT
        n_jumps = len(path.jumps)
        watched = None if path._watch is None else path._watch.state()
        st = solve_step(problem, snap, prev, d, path, jump_tol, refine, increments=n)
        # a descent that gave up on its increments took the step whole (``descend_step``): no
        # finer way than the probe's, so nothing to agree
        finer = getattr(st, "descent_increments", n) == n
        agree = st.converged and finer and gap is not None and gap_difference(st.gap, gap) <= agreement
        if agree or level == levels:
            break
        cost += cost_of(st)
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
        # only its numbers are wanted: its fields, held until the next solve had returned,
        # were a second state's at that solve's peak
        st.release_fields()
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
        descending = getattr(problem, "descending_loading", False)
        st = problem.solve(approach=d_hi, raise_on_failure=False)
        st.release_fields()
        w_after, k_hi = st.force, st.stiffness
        problem.solve(approach=after.approach, raise_on_failure=False).release_fields()
        # the path goes on from the state after the jump as if these two solves had not been
        # (the step back to d_hi would count as an unloading step)
        if descending:
            problem.descending_loading = True
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
