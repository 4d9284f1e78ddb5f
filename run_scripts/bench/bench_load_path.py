#!/usr/bin/env python3
"""Benchmark: FFT pairs per step of a load-controlled path on the rough benchmark surface.

The surface of ``bench_signorini.py`` (``rough_surface.py``), E* = 1; mean pressures from
--low to --high E* in --steps equal steps, loading then unloading, each solve to a
complementarity error --tol of the rms height.  The first solve is nested (coarse grids
first), every later one warm-starts from the previous state.  Prints, per size, the first
solve's FFT pairs and the mean per warm step up and down, and one JSON line per size.
Compare the load-control methods with ``-lp_load_joint false`` (the outer iteration on delta).

    .venv/bin/python run_scripts/bench/bench_load_path.py [--sizes 256 512 1024] [--steps 9]
        [--low 0.002] [--high 0.01] [--tol 1e-8] [PETSc options under the prefix lp_]
"""
import argparse
import json
import os
import sys

import petsc4py

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
ap.add_argument("--steps", type=int, default=9)
ap.add_argument("--low", type=float, default=0.002)
ap.add_argument("--high", type=float, default=0.01)
ap.add_argument("--tol", type=float, default=1e-8)
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers import ContactProblem  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from rough_surface import rough_surface  # noqa: E402

for n in args.sizes:
    g, h, _ = rough_surface(n, row_alignment=64)
    prob = ContactProblem(g, h, 1.0, tol=args.tol, prefix="lp_")
    up = np.linspace(args.low, args.high, args.steps)
    pairs, converged = [], True
    for w in np.concatenate([up, up[-2::-1]]):
        st = prob.solve(mean_pressure=float(w), raise_on_failure=False)
        pairs.append(st.fft_pairs)
        converged &= st.converged
    k = args.steps
    rec = dict(n=n, ranks=g.mpi_comm.Get_size(), first=pairs[0], up=float(np.mean(pairs[1:k])),
               down=float(np.mean(pairs[k:])), total=float(np.sum(pairs)), converged=bool(converged))
    PETSc.Sys.Print(f"n = {n}: first solve {rec['first']:.1f} FFT pairs; per warm step {rec['up']:.1f} "
                    f"(loading), {rec['down']:.1f} (unloading); converged {converged}")
    PETSc.Sys.Print(json.dumps(rec))
    prob.destroy()
