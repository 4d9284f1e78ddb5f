#!/usr/bin/env python3
"""Benchmark: the adhesive fallback chain, energy descent first against the chain without it.

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1), a law with w = --w E* dx
and range dx (``lj``: z0; ``exponential`` and ``hardwall-lj``: a hard wall), and per chain of
``-<prefix>fallback`` (--chains; the default chain descends first):

* cold states at the approaches giving --areas contact (``rough_surface.calibrate``), each a
  fresh problem with every default a scene gets (nested start, stability check, tangent);
* the load-unload path of ``bench_adhesion_path.py`` (--states approaches from 1 % to 10 %
  contact and back, warm starts).

Per state one JSON line: FFT pairs (exact, coarse levels weighted), CPU s (``process_time``,
one run), converged, stable, the solver (its ``+descent`` / ``+relaxation`` / ``+ptc`` where the
finest grid fell back), contact fraction, energy [J]; the same state in the first chain's run:
the largest gap difference [z0].  First line: the non-adhesive solve on the same heights (the
benchmark's mean pressure 0.005 E*), the unit of the ratios.  Each problem (a cold state, or
the whole path) has a wall-time budget of --budget s (``-<prefix>time_budget``, all its solves
together): a state it stops is reported as not converged (``WALL_TIME_BUDGET``).

    .venv/bin/python run_scripts/bench/bench_fallback.py --size 256 --law exponential
    .venv/bin/python run_scripts/bench/bench_fallback.py --size 512 --law lj --w 0.05
    .venv/bin/python run_scripts/bench/bench_fallback.py --size 256 --law lj --w 0.2 --areas --chains default --perturb 1

One rank.
"""
import os
import sys
import time

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__)
ap.add_argument("--areas", type=float, nargs="*", default=[0.01, 0.02, 0.05, 0.10],
                help="contact fractions of the cold states (none: the path only)")
ap.add_argument("--states", type=int, default=10, help="states of the load-unload path (0: none)")
ap.add_argument("--chains", nargs="+", default=None,
                help="fallback chains (default: the code default, then the chain without descent)")
ap.add_argument("--budget", type=float, default=300.0, help="wall-time budget of one problem [s]")
ap.add_argument("--perturb", type=int, default=0,
                help="seed of a round-off perturbation of the heights, h (1 + 1e-14 N(0, 1)) (0: none)")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, load_unload_path, non_adhesive_unit, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def make_problem(grid, h, law, chain, tag):
    prefix = f"fb{tag}_"
    opts = PETSc.Options(prefix)
    if chain != "default":
        opts.setValue("fallback", chain)
    opts.setValue("time_budget", args.budget)
    return AdhesiveProblem(grid, h, 1.0, law, prefix=prefix)


def solve(pb, approach):
    t0 = time.process_time()
    st = pb.solve(approach=approach, raise_on_failure=False)
    return st, time.process_time() - t0


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    if args.perturb:
        # how far a path's cost and states depend on round-off (docs/performance.md)
        rows = grid.rows(h)
        rows *= 1.0 + 1e-14 * np.random.default_rng(args.perturb).standard_normal(rows.shape)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    z0 = law.length_scale()
    unit, cpu = non_adhesive_unit(grid, h)
    emit(n=n, case="non-adhesive", fft_pairs=unit, cpu=cpu)
    chains = args.chains or ["default", "relaxation,ptc" if law.hard_wall else "ptc"]
    cold = calibrate(grid, h, law, args.areas, max_n=128) if args.areas else []
    path = load_unload_path(grid, h, law, args.states) if args.states else []
    first = {}
    for c, chain in enumerate(chains):
        def report(case, k, approach, st, cpu):
            gap = grid.rows(st.gap, readonly=True).copy()
            key = (case, k)
            diff = float(np.abs(gap - first[key]).max()) / z0 if key in first else None
            first.setdefault(key, gap)
            emit(n=n, law=args.law, w=args.w, chain=chain, case=case, state=k, approach=approach,
                 fft_pairs=st.fft_pairs, ratio=st.fft_pairs / unit, cpu=cpu,
                 converged=st.converged, stable=st.stable, solver=st.solver,
                 contact_fraction=st.contact_fraction, energy=st.energy, gap_diff_z0=diff,
                 reason="" if st.converged else st.reason[:200])
        for k, d in enumerate(cold or []):
            st, cpu = solve(make_problem(grid, h, law, chain, f"{c}c{k}"), float(d))
            report("cold", k, float(d), st, cpu)
        pb = make_problem(grid, h, law, chain, f"{c}p")
        for k, d in enumerate(path):
            st, cpu = solve(pb, float(d))
            report("path", k, float(d), st, cpu)


main()
