"""The energy descent strategy's step of an ``AdhesiveProblem``: the approach followed in
increments, each descended by ``descent.EnergyDescent`` (docs/formulation.md, "Energy descent")."""
from __future__ import annotations

from petsc4py import PETSc

from .base import pieces
from .descent import EnergyDescent
from .descent_options import descent_options


def descend_step(problem, approach: float, start: PETSc.Vec, increments: int | None = None,
                 target: tuple | None = None) -> tuple[bool, str, int, int, int, bool]:
    """The descent strategy's step of ``problem`` from ``start`` (its last state) to ``approach``
    [m]: in increments of at most ``-<prefix>descent_max_step`` z0 (or in ``increments`` equal
    ones, a path's check of its step: ``path_steps.agreed_increments``), each but the last descended
    only to ``-<prefix>descent_step_tol`` (a continuation in the approach: the asperities snap
    one increment at a time, in the order a quasi-static path meets them), the last to the
    descent's tolerance, or until its gaps are near ``target`` (``EnergyDescent.descend``).
    (converged, reason, iterations, Krylov iterations, increments taken) of them all, and
    whether the target was reached; the state reached is in the problem's unknowns.
    Collective."""
    prev = problem._start_approach    # the start's own (after a failed solve: the last converged)
    options = descent_options(problem.prefix)
    if prev is None:
        increments = 1
    elif increments is None:
        increments = pieces(approach - prev, options.max_step * problem.z0)
    iterations = linear = 0
    taken = 1
    for k in range(1, increments):
        if problem.out_of_time():
            break
        increment = EnergyDescent(problem, tol=options.step_tol)
        ok, _, it, lin = increment.descend(prev + (approach - prev) * k / increments, start)
        stalled = increment.stalled
        del increment
        PETSc.garbage_cleanup(problem.grid.comm)   # its TAO's contexts hold its arrays
        iterations, linear = iterations + it, linear + lin
        # a stalled increment is at its state to the energy's round-off: the next goes on from it
        if not (ok or stalled):
            # (a NaN, a failed line search): the whole step from the start instead (the
            # problem's copy of its unknowns, made as the first increment wrote its state)
            start, taken = problem.saved_start(), 1
            break
        start = problem._x      # the increment's state: the next one's start
        taken += 1
    last = EnergyDescent(problem)
    ok, reason, it, lin = last.descend(approach, start, target)
    return ok, reason, iterations + it, linear + lin, taken, last.reached
