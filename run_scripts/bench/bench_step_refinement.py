#!/usr/bin/env python3
"""Benchmark: is a load-unload path the limit of small steps?  (issue 33, goal 3)

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1) and a law with
w = --w E* dx and range dx, on the load-unload path of ``bench_adhesion_path.py`` (--states
approaches from 1 % to 10 % contact and back).  The path is run with its own steps and with
every step divided into --refine equal sub-steps (warm starts throughout, every default a
scene gets).  At each approach the coarse path visits, the paths' states are compared
with the finest run's (the quasi-static limit): the contact nodes (p > 0) that differ, the
force's relative difference, the largest gap difference [z0] and the energy difference [J].
Where the states differ, the lower energy says which path found the lower minimum.

With --sweep the path is also run as a scene's sweep runs it (``paths.sweep``, jumps located):
its steps in sub-steps of at most --max-step z0, with --agreement TOL (z0) each checked against
its quarters and divided until their gaps agree to TOL, at most --levels times
(``protocol.agreement``; under the descent its increments, the probe's of at most --increment
z0, ``protocol.agreement_increment``), and compared with the finest run likewise (``refine`` =
"sweep ...").

Per state one JSON line; pairs exact, CPU s one run (``process_time``).

    .venv/bin/python run_scripts/bench/bench_step_refinement.py --size 256 --law lj --refine 1 4 16
    .venv/bin/python run_scripts/bench/bench_step_refinement.py --size 256 --law lj --refine 16 --sweep --agreement 1e-3
    .venv/bin/python run_scripts/bench/bench_step_refinement.py --size 1024 --step-at 0.10 --refine 16 4 1 --sweep --agreement 1e-3

One rank.
"""
import os
import sys
import time

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__, law="lj")
ap.add_argument("--states", type=int, default=10)
ap.add_argument("--step-at", type=float, help="instead of the path: one step to the approach of this contact "
                "fraction, from a cold state --step z0 before it (the peers' step case)")
ap.add_argument("--step", type=float, default=0.1, help="the --step-at step [z0]")
ap.add_argument("--refine", type=int, nargs="+", default=[1, 4, 16])
ap.add_argument("--sweep", action="store_true", help="also the path as a scene's sweep runs it")
ap.add_argument("--agreement", type=float, default=0.0, help="the sweep's check against its quarters [z0] (0: none)")
ap.add_argument("--max-step", type=float, default=0.1, help="the sweep's longest sub-step [z0]")
ap.add_argument("--levels", type=int, default=2, help="the sweep's divisions at most (--agreement)")
ap.add_argument("--increment", type=float, default=0.25,
                help="the check's probe under the descent: increments of at most this [z0] (0: the descent's own)")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.paths import sweep  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, load_unload_path, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    z0 = law.length_scale()
    if args.step_at:
        d = calibrate(grid, h, law, [args.step_at])[0]
        coarse = [d - args.step * z0, d]
    else:
        coarse = load_unload_path(grid, h, law, args.states)
    reference = {}

    def compare(j, r, st, pairs, cpu, failed):
        """Emit state j of the path refined r times (or "agreement"), against the finest path's."""
        gap = grid.rows(st.gap, readonly=True).copy()
        contact = grid.rows(st.pressure, readonly=True) > 0
        row = dict(n=n, law=args.law, w=args.w, refine=r, state=j, approach=st.approach, force=st.force,
                   energy=st.energy, contact_fraction=st.contact_fraction, converged=st.converged,
                   stable=st.stable, solver=st.solver, fft_pairs_so_far=pairs, cpu_so_far=cpu,
                   failed_so_far=failed)
        if j in reference:
            g0, c0, f0, e0 = reference[j]
            row.update(contact_nodes_differing=int(np.count_nonzero(contact != c0)),
                       force_rel_diff=abs(st.force - f0) / abs(f0), gap_diff_z0=float(np.abs(gap - g0).max()) / z0,
                       energy_diff=st.energy - e0)
        else:
            reference[j] = (gap, contact, st.force, st.energy)
        emit(**row)

    for r in sorted(args.refine, reverse=True):     # the finest first: the reference
        # every coarse step in r equal sub-steps; the coarse approaches are among them
        path = [coarse[0]]
        for a, b in zip(coarse, coarse[1:]):
            path += list(np.linspace(a, b, r + 1)[1:])
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"ref{r}_")
        pairs = cpu = 0.0
        failed = 0
        for k, d in enumerate(path):
            t0 = time.process_time()
            st = pb.solve(approach=float(d), raise_on_failure=False)
            cpu += time.process_time() - t0
            pairs += st.fft_pairs
            failed += not st.converged
            if k % r:
                continue
            compare(k // r, r, st, pairs, cpu, failed)

    if args.sweep:
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix="agree_")
        totals = dict(pairs=0.0, cpu=0.0, failed=0, t=time.process_time())

        def on_state(k, st, pt):
            totals["pairs"] += st.fft_pairs
            totals["failed"] += not st.converged
            compare(k, f"sweep (agreement {args.agreement:g})", st, totals["pairs"], time.process_time() - totals["t"], totals["failed"])

        sweep(pb, coarse, refine=6, max_step=args.max_step * z0, agreement=args.agreement * z0,
              levels=args.levels, foot=args.increment * z0, on_state=on_state, on_failure=on_state)


main()
