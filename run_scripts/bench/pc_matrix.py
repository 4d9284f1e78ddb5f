#!/usr/bin/env python3
"""Benchmark: the preconditioners of the adhesive Newton system on a matrix of cases.

Every case is solved once per preconditioner (``-<prefix>preconditioner``: spectral, mlmi, and
auto, which picks one per grid of the nested iteration from its snap number; the table gives the
finest grid's pick in brackets), each in its own problem, and reports: converged, FFT pairs (fine-grid units, deterministic), Newton steps,
Krylov iterations per Newton step, wall time, and the snap number K_ii max da/dg.

Cases
-----
* ``sphere``: R = 1000 z0-units (E* = 1, dx = 1, isolated), hard-wall LJ, Tabor
  parameters 0.1 / 1 / 2 / 5, z0 = dx and dx / 2; the first solve at delta = z0 from the
  Signorini start, then one warm-started path step to delta = 1.25 z0.
* ``rough``: the benchmark surface (``rough_surface.py``), the full LJ curve with
  w = 0.05 E* dx and z0 = dx and dx / 2, at the approaches of about 2 / 10 / 25 % contact
  area (p > 0), interpolated on a loading sweep (tol 1e-6, untimed) on the heights averaged
  to 128^2; solved in order, the first from rest, the next warm-started.

The markdown table goes to stdout (``--out``: also to a file); one JSON line per solve to
stderr.

    .venv/bin/python run_scripts/bench/pc_matrix.py [--quick] [--sizes 256 512 1024]
        [--pcs spectral mlmi auto] [--out table.md]

``--quick``: 256^2 only, the rough benchmark at z0 = dx and the spheres at Tabor 1 and 5.
"""
import argparse
import json
import sys
import time
import warnings

import petsc4py

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--quick", action="store_true")
ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
ap.add_argument("--cases", nargs="+", default=["sphere", "rough"])
ap.add_argument("--pcs", nargs="+", default=["spectral", "mlmi", "auto"])
ap.add_argument("--tabor", type=float, nargs="+", default=[0.1, 1.0, 2.0, 5.0])
ap.add_argument("--z0", type=float, nargs="+", default=[1.0, 0.5], help="z0 / dx")
ap.add_argument("--areas", type=float, nargs="+", default=[0.02, 0.10, 0.25])
ap.add_argument("--w", type=float, default=0.05, help="rough: w / (E* dx)")
ap.add_argument("--budget", type=float, default=600.0, help="time budget of one problem [s]")
ap.add_argument("--out", default=None)
args, petsc_args = ap.parse_known_args()
if args.quick:
    args.sizes, args.tabor, args.z0 = [256], [1.0, 5.0], [1.0]
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.physics.resolution import UnderResolvedWarning  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

from rough_surface import calibrate, rough_surface  # noqa: E402

comm = PETSc.COMM_WORLD.tompi4py()
rows = []
counter = [0]


def solve_path(grid, h, law, pc, approaches):
    """One problem with preconditioner ``pc`` along ``approaches``: a row per solve."""
    counter[0] += 1
    prefix = f"m{counter[0]}_"
    opts = {"stiffness": "false", "time_budget": str(args.budget)}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix, preconditioner=pc, petsc_options=opts)
    out = []
    for d in approaches:
        t = time.perf_counter()
        st = pb.solve(approach=d, raise_on_failure=False)
        out.append(dict(pc=pc, approach=d, time=time.perf_counter() - t, fft_pairs=st.fft_pairs,
                        newton=st.newton_iterations, linear=st.linear_iterations,
                        converged=bool(st.converged), fallback=bool(st.fallback),
                        area=st.contact_fraction, snap=pb.snap_number, chosen=pb.preconditioner,
                        reason=st.reason[:120]))
    return out


def record(case, n, z0, stages, results):
    for pc, res in results.items():
        for stage, r in zip(stages, res):
            row = dict(case=case, n=n, z0=z0, stage=stage, **r)
            rows.append(row)
            if comm.rank == 0:
                print(json.dumps(row), file=sys.stderr, flush=True)


def sphere_cases(n):
    R, dx = 1000.0, 1.0
    for z0_rel in args.z0:
        z0 = z0_rel * dx
        for mu in args.tabor:
            w = np.sqrt(mu ** 3 * z0 ** 3 / R)
            grid = SurfaceGrid(n, n, dx, periodic=False)
            h = sphere(grid, R)
            law = make_law("hardwall-lj", work_of_adhesion=w, z0=z0)
            res = {pc: solve_path(grid, h, law, pc, [z0, 1.25 * z0]) for pc in args.pcs}
            record(f"sphere Tabor {mu:g}", n, z0_rel, ["cold", "step"], res)


def rough_cases(n):
    grid, h, _ = rough_surface(n)
    for z0_rel in args.z0:
        z0, w = z0_rel * grid.dx, args.w * grid.dx
        law = make_law("lj", work_of_adhesion=w, z0=z0)
        approaches = calibrate(grid, h, law, args.areas)
        if approaches is None:
            continue
        res = {pc: solve_path(grid, h, law, pc, approaches) for pc in args.pcs}
        record("rough", n, z0_rel, [f"{100 * a:g} %" for a in args.areas], res)


for n in args.sizes:
    if "sphere" in args.cases:
        sphere_cases(n)
    if "rough" in args.cases:
        rough_cases(n)

if comm.rank == 0:
    head = ["case", "n", "z0/dx", "stage", "snap"]
    for pc in args.pcs:
        head += [f"{pc}: FFT pairs", "Newton", "Krylov/Newton", "time [s]", "conv."]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    keyed = {}
    for r in rows:
        keyed.setdefault((r["case"], r["n"], r["z0"], r["stage"]), {})[r["pc"]] = r
    for (case, n, z0, stage), by_pc in keyed.items():
        first = next(iter(by_pc.values()))
        cells = [case, str(n), f"{z0:g}", stage, f"{first['snap']:.2f}"]
        for pc in args.pcs:
            r = by_pc.get(pc)
            if r is None:
                cells += ["-"] * 5
                continue
            kn = r["linear"] / max(r["newton"], 1)
            cells += [f"{r['fft_pairs']:.0f}", str(r["newton"]), f"{kn:.1f}", f"{r['time']:.2f}",
                      ("yes" if r["converged"] else "**no**") + (" (fallback)" if r["fallback"] else "")
                      + (f" [{r['chosen']}]" if pc == "auto" else "")]
        lines.append("| " + " | ".join(cells) + " |")
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text)
