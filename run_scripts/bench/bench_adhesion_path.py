#!/usr/bin/env python3
"""Benchmark: an adhesive load-unload path on the rough benchmark surface at one grid size.

The case is the rough case of ``bench_adhesion.py``, the surface and the law of
``rough_surface.py`` (the full LJ curve ``lj``, z0 = dx, w = 0.05 E* dx; ``--law exponential``:
a hard wall with exponential attraction, rho = dx), one solver with warm
starts along the path and ``-path_stiffness false`` unless given.  The approach rises in equal steps from the one
giving ``--areas[0]`` contact area (p > 0) to the one giving ``--areas[1]`` and falls back
(``--states`` in all, half up and half down), approaches interpolated on a loading sweep of
the heights averaged to ``--calibrate-max-n`` (untimed).  One JSON line per state (approach,
time, FFT pairs, Newton and Krylov counts, contact fraction, converged, stable (with the
stability check's margin and whether it settled), resident size
over the one before the problem in doubles per grid point; each state's fields are released
after its line, as a scene's run releases them before the next step), then a
summary: total time, FFT pairs per state (median, largest), the time of one FFT pair of the
half-space operator at this size (``--pair-reps`` bare applies), and the memory per grid
point: the high-water mark (VmHWM, reset through /proc/self/clear_refs after the surface is
made) minus the resident size before the problem, in doubles (8 B) per grid point.

    .venv/bin/python run_scripts/bench/bench_adhesion_path.py --size 1024 [--states 10]
        [--areas 0.01 0.10] [--law lj|exponential] [-path_<option> ...]

On more than one rank (``mpirun -n 2 ...``) rank 0 prints, the memory figures are the ranks'
summed and the summary names the ranks.
"""
import argparse
import os
import sys
import time

import petsc4py

from bench_args import add_path_arguments, check_path_arguments, emit, reset_peak, status_kb

HERE = os.path.dirname(os.path.abspath(__file__))
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--size", type=int, default=1024)
add_path_arguments(ap)
ap.add_argument("--law", default="lj", choices=("lj", "exponential"),
                help="the full LJ curve, or a hard wall with exponential attraction (range rho = dx)")
ap.add_argument("--pair-reps", type=int, default=5, help="bare operator applies timed for the pair time")
args, petsc_args = ap.parse_known_args()
check_path_arguments(ap, args)
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, path_approaches, rough_surface  # noqa: E402


def main():
    comm = PETSc.COMM_WORLD.tompi4py()
    say = emit if comm.rank == 0 else (lambda **row: None)

    def summed_kb(field):
        # every rank's resident size over its own before the problem, in doubles per grid point
        return comm.allreduce(status_kb(field) - base) * 1024.0 / (8.0 * n * n)

    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, name=args.law)
    t = time.perf_counter()
    ends = calibrate(grid, h, law, args.areas, max_n=args.calibrate_max_n)
    if ends is None:
        say(n=n, solver="calibration", converged=False,
             message="the calibration sweep converged at fewer than two approaches")
        return
    say(n=n, calibration_time=time.perf_counter() - t, approaches_at_areas=ends, areas=args.areas)
    opts = PETSc.Options("path_")
    if not opts.hasName("stiffness"):
        opts.setValue("stiffness", False)
    base = status_kb("VmRSS")
    reset_peak()   # the peak from here on
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="path_")
    rows = []
    t_path = time.perf_counter()
    for k, d in enumerate(path_approaches(ends[0], ends[1], args.states)):
        t = time.perf_counter()
        st = pb.solve(approach=float(d), raise_on_failure=False)
        row = dict(n=n, state=k, approach=float(d), time=time.perf_counter() - t, fft_pairs=st.fft_pairs,
                   newton=st.newton_iterations, krylov=st.linear_iterations, check_time=st.check_time,
                   contact_fraction=st.contact_fraction, converged=st.converged, stable=st.stable,
                   stability_settled=st.stability_converged, stability_margin=st.stability_margin,
                   solver=st.solver, rss_doubles_per_point=summed_kb("VmRSS"))
        rows.append(row)
        say(**row)
        st.release_fields()   # as ``runner.run`` does before the next step: a path holds no state's fields
    total = time.perf_counter() - t_path
    peak_kb = comm.allreduce(status_kb("VmHWM"))
    # one bare FFT pair of the fine operator (forward + inverse), on a state-like field
    p = np.asarray(grid.rows(h, readonly=True)).copy()
    out = np.empty_like(p)
    pb.op.apply(p, out)
    t = time.perf_counter()
    for _ in range(args.pair_reps):
        pb.op.apply(p, out)
    pair = (time.perf_counter() - t) / args.pair_reps
    pairs = [r["fft_pairs"] for r in rows]
    say(n=n, law=args.law, ranks=comm.size, summary=True, states=len(rows), converged=sum(r["converged"] for r in rows), total_time=total,
         fft_pairs_total=float(sum(pairs)), fft_pairs_median=float(np.median(pairs)),
         fft_pairs_max=float(max(pairs)), max_over_median=float(max(pairs) / np.median(pairs)),
         pair_time=pair, time_per_pair=total / sum(pairs), peak_mb=peak_kb / 1024.0,
         doubles_per_point=summed_kb("VmHWM"), load_average=os.getloadavg()[0])


main()
