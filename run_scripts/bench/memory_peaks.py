#!/usr/bin/env python3
"""Diagnosis: which call of an adhesive path raised its memory's high-water mark.

The path of ``bench_adhesion_path.py`` (the rough benchmark heights, ``--states`` approaches from
the 1 % to the 10 % contact state and back, ``--law``), its problem's options under the prefix
``path_`` as there (``-path_stiffness true``: a scene's default, the tangent stiffness of every
state).  The solver's phases and their expensive callbacks are wrapped: each time one returns
with the resident size's high-water mark (``VmHWM``) higher than before, one JSON line gives the
state, the mark in doubles per grid point over the resident size before the problem, and the
chain of wrapped calls it happened in (innermost last).  The last line gives the path's peak.
As in ``bench_adhesion_path.py`` each state's fields are released before the next solve, as a
scene's run releases them.

    .venv/bin/python run_scripts/bench/memory_peaks.py --size 1024 --law exponential -path_stiffness true

One rank; reading /proc/self/status after every callback slows the path a little: times are
not measured (``bench_adhesion_path.py`` measures them).
"""
import os
import sys

import petsc4py

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
from bench_args import add_path_arguments, check_path_arguments, emit, reset_peak, rough_parser, status_kb  # noqa: E402

ap = rough_parser(__doc__)
add_path_arguments(ap)
ap.add_argument("--step-kb", type=int, default=256,
                help="report a rise of the high-water mark of at least this many kB")
args, petsc_args = ap.parse_known_args()
check_path_arguments(ap, args)
petsc4py.init([sys.argv[0]] + petsc_args)

from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers import adhesive, adhesive_mlmi, descent, newton, predictor, stability  # noqa: E402
from rough_surface import adhesive_law, calibrate, path_approaches, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"

#: (class, method) wrapped: the phases of a solve and what runs inside them
WRAPPED = ((descent.EnergyDescent, "descend"), (descent.EnergyDescent, "objective_gradient"),
           (descent.EnergyDescent, "hessian"), (descent.EnergyDescent, "hessian_mult"),
           (descent.EnergyDescent, "precondition"), (newton.VINewton, "run"),
           (stability.StabilityCheck, "margin"), (predictor.TangentPredictor, "solve"),
           (adhesive_mlmi.AdhesiveMLMIPC, "setUp"), (adhesive_mlmi.AdhesiveMLMIPC, "apply"),
           (adhesive_mlmi.AdhesiveCycle, "set_rows"), (adhesive_mlmi.AdhesiveCycle, "solve"),
           (adhesive.AdhesiveProblem, "make_state"), (adhesive.AdhesiveProblem, "_jacobian"),
           (adhesive.AdhesiveProblem, "_residual"))


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, args.w, name=args.law)
    ends = calibrate(grid, h, law, args.areas, max_n=args.calibrate_max_n)
    per_point = 8.0 * n * n / 1024.0     # kB of one double per grid point
    calls, state = [], {"k": None, "top": 0}

    def wrap(cls, name):
        method = getattr(cls, name)

        def wrapped(*a, **k):
            calls.append(f"{cls.__name__}.{name}")
            try:
                return method(*a, **k)
            finally:
                hwm = status_kb("VmHWM")
                if hwm >= state["top"] + args.step_kb:
                    state["top"] = hwm
                    emit(n=n, law=args.law, state=state["k"], doubles_per_point=(hwm - base) / per_point,
                         calls="/".join(calls))
                calls.pop()
        setattr(cls, name, wrapped)

    for cls, name in WRAPPED:
        wrap(cls, name)
    base = status_kb("VmRSS")
    reset_peak()
    state["top"] = status_kb("VmHWM")
    pb = adhesive.AdhesiveProblem(grid, h, 1.0, law, prefix="path_")
    for k, d in enumerate(path_approaches(ends[0], ends[1], args.states)):
        state["k"] = k
        # its fields released before the next solve, as a scene's run (and the benchmark) does
        pb.solve(approach=float(d), raise_on_failure=False).release_fields()
    emit(n=n, law=args.law, summary=True, doubles_per_point=(status_kb("VmHWM") - base) / per_point)


main()
