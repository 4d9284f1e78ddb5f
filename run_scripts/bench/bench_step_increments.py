#!/usr/bin/env python3
"""Benchmark: one path step in sub-steps solved in full, in one step, or in the descent's increments.

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1), the full LJ curve with
w = --w E* dx and z0 = dx; the approach giving --area contact (``rough_surface.calibrate``) and
the state --step z0 below it (a cold solve, untimed).  From that state each --variants entry
solves the step on a fresh problem: ``tK`` in K equal sub-steps each solved in full (``t1``:
one step), ``iK`` in one solve with the descent strategy's K increments
(``-<prefix>descent_max_step`` = --step / K).  The tangent is off; the stability check runs on
the last state.  The first variant is the reference the others are compared with: the
largest gap difference [z0] and the energy difference [J].  Where they differ, the lower
energy says which found the lower minimum; the quasi-static state is the one many small
sub-steps reach.

    .venv/bin/python run_scripts/bench/bench_step_increments.py --size 1024 --area 0.10 --variants t16 i4 t1 i8

One JSON line per variant; pairs exact, CPU s one run (``process_time``).  One rank.
"""
import os
import sys
import time

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__, law="lj")
ap.add_argument("--area", type=float, default=0.10, help="contact fraction at the step's end")
ap.add_argument("--step", type=float, default=0.1, help="the step [z0]")
ap.add_argument("--variants", nargs="+", default=["t16", "i4", "t1"])
args, petsc_args = ap.parse_known_args()
for v in args.variants:
    if v[:1] not in ("t", "i") or not v[1:].isdigit() or int(v[1:]) < 1:
        ap.error(f"--variants: tK (K sub-steps in full) or iK (K increments), K >= 1; got {v!r}")
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    z0 = law.length_scale()
    end = calibrate(grid, h, law, [args.area])[0]
    start = end - args.step * z0
    cold = AdhesiveProblem(grid, h, 1.0, law, prefix="cold_", stability_check=False)
    st0 = cold.solve(approach=start)
    q, a = st0.contact_pressure.copy(), st0.adhesive_pressure.copy()
    emit(n=n, law=args.law, w=args.w, start=start, end=end, start_contact=st0.contact_fraction)
    cold.destroy()
    reference = None
    for v in args.variants:
        kind, k = v[0], int(v[1:])
        opts = {"stiffness": False}
        if kind == "i":
            opts["descent_max_step"] = args.step / k
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"{v}_", petsc_options=opts)
        pb.warm_start(q, a, start)
        pairs, cpu = 0.0, time.process_time()
        for d in (np.linspace(start, end, k + 1)[1:] if kind == "t" else [end]):
            st = pb.solve(approach=float(d), raise_on_failure=False, check_stability=d == end)
            pairs += st.fft_pairs
        row = dict(n=n, variant=v, contact_fraction=st.contact_fraction, fft_pairs=pairs,
                   cpu=time.process_time() - cpu, energy=st.energy, converged=st.converged,
                   stable=st.stable, solver=st.solver)
        gap = grid.rows(st.gap, readonly=True).copy()
        if reference is None:
            reference = (gap, st.energy)
        else:
            row.update(gap_diff_z0=float(np.abs(gap - reference[0]).max()) / z0,
                       energy_diff=st.energy - reference[1])
        emit(**row)
        pb.destroy()


main()
