#!/usr/bin/env python3
"""Benchmark: the stability check on an isolated window, its methods on the adhesive sphere's states.

The sphere of ``bench_sphere_path.py`` (radius --radius z0, a --window z0 window, E* = 1, the
law --law with the work of adhesion of Tabor parameter --tabor) on the grid dx = z0 / --refine,
solved with warm starts at the approaches --approaches [z0] (the check off while solving).  At
each state the margin 1 - lambda_max of the stability pencil (``solvers/stability.py``) by

* ``lanczos``: Lanczos on A S, S the clamped compliance (a CG on K_CC per step), to the Ritz
  value's change ``tol``;
* ``padded``: LOBPCG on the window's padded grid to its residual tolerance (what ``auto`` takes
  with contact nodes and whole rows per rank), preconditioned as ``auto`` does (the compliance
  for its first iterations, then the displacement cycle on the padded grids);
* ``padded-compliance`` and ``padded-multigrid``: the same with the compliance throughout, or
  the cycle from the first iteration (``-<prefix>stability_preconditioner``);
* ``reference``: ``padded-compliance`` to a residual of 1e-7 (at most 3000 iterations);

each at the code's default steps, with its FFT pairs (exact), CPU s (``process_time``), whether
it settled and its margin's difference to the reference.  One JSON line per state.  One rank.

    .venv/bin/python run_scripts/bench/bench_window_stability.py --tabor 2 --refine 2 \
        --approaches -1 0 1 2 1 0 -1 -2
"""
import argparse
import sys

import petsc4py

from bench_args import emit, timed_margin

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--tabor", type=float, default=2.0)
ap.add_argument("--law", default="hardwall-lj", choices=("lj", "hardwall-lj"))
ap.add_argument("--radius", type=float, default=100.0, help="sphere radius [z0]")
ap.add_argument("--window", type=int, default=128, help="window width [z0]")
ap.add_argument("--refine", type=int, default=2, help="grid nodes per z0")
ap.add_argument("--approaches", type=float, nargs="+", default=[-1.0, 0.0, 1.0, 2.0, 1.0, 0.0, -1.0, -2.0])
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.options import code_default  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def main():
    w = float(np.sqrt(args.tabor ** 3 / args.radius))      # z0 = 1, E* = 1
    n = args.window * args.refine
    grid = SurfaceGrid(n, n, 1.0 / args.refine, periodic=False)
    heights = sphere(grid, args.radius)
    pb = AdhesiveProblem(grid, heights, 1.0, make_law(args.law, work_of_adhesion=w, z0=1.0), prefix="win_",
                         petsc_options={"stability_check": "false"})
    steps = code_default("adhesion", "stability_steps")
    for d in args.approaches:
        st = pb.solve(approach=float(d), raise_on_failure=False)
        ref = timed_margin(pb, "padded", steps=3000, residual_tol=1e-7, preconditioner="compliance")
        row = dict(tabor=args.tabor, law=args.law, n=n, approach=d, converged=st.converged,
                   contact_fraction=st.contact_fraction, reference=ref[0], reference_settled=ref[1])
        for name in ("lanczos", "padded", "padded-compliance", "padded-multigrid"):
            method, _, preconditioner = name.partition("-")
            m, settled, pairs, cpu = timed_margin(pb, method, steps=steps, preconditioner=preconditioner or "auto")
            row[name] = dict(margin=m, settled=settled, fft_pairs=pairs, cpu_s=cpu, error=m - ref[0])
        emit(**row)
        st.release_fields()


main()
