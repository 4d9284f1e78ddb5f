#!/usr/bin/env python3
"""Benchmark: the adhesive sphere's load-unload path against the non-adhesive solve (issue 33, goal 1).

A sphere of radius --radius z0 on an isolated window --window z0 wide (E* = 1), the law --law
(the full LJ curve, or hard-wall LJ) with the work of adhesion of each Tabor parameter of
--tabor, mu = (R w^2 / (E*^2 z0^3))^(1/3), on the grid that resolves it: dx = z0, z0 / 2,
z0 / 4, ... the first whose adhesive zone spans 4 nodes and whose snap number K_ii max da/dg is
below 1 (the problem's own criteria: coarser, the code warns that the adhesion is
under-resolved).  One problem per Tabor parameter, solved with warm starts along a load-unload
path in steps of --step z0 with every default a scene gets (the stability check and the
tangent stiffness included): from the path's end up to --depth z0, then down to its end,
1.2 times the JKR pull-off approach of that w (at least -2 z0; Maugis-Dugdale's is at most 8 %
beyond JKR's), so that the path starts out of contact and jumps on and off (--start: another
first approach).  The unit of the ratios is the non-adhesive solve (``ContactProblem``, the
Hertz state) of the same heights at the path's largest approach, cold, to the same tolerance,
its solve's CPU alone.

One JSON line per state (approach, FFT pairs, CPU s, Newton and Krylov counts, contact
fraction, force, tangent stiffness, converged, stable, solver, the pairs and CPU over the unit;
the reason where it failed or the branch check ran), then per Tabor
parameter a summary: the states converged, and over those the largest and median ratios, the
largest over the median; the failed states apart (their cost is the fallbacks' before they gave
up).  One rank.

    .venv/bin/python run_scripts/bench/bench_sphere_path.py [--window 128] [--tabor 0.1 0.5 1 2 5]
        [--law lj|hardwall-lj] [--radius 100] [--step 0.25] [--start Z] [--first K] [-sphere_<option> ...]
"""
import argparse
import sys
import time

import petsc4py

from bench_args import emit

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--window", type=int, default=128, help="window width [z0]")
ap.add_argument("--tabor", type=float, nargs="+", default=[0.1, 0.5, 1.0, 2.0, 5.0])
ap.add_argument("--law", default="lj", choices=("lj", "hardwall-lj"))
ap.add_argument("--radius", type=float, default=100.0, help="sphere radius [z0]")
ap.add_argument("--step", type=float, default=0.25, help="approach step [z0]")
ap.add_argument("--depth", type=float, default=2.0, help="largest approach [z0]")
ap.add_argument("--start", type=float, default=None, help="the path's first approach [z0] (default: its end)")
ap.add_argument("--first", type=int, default=None, help="only the path's first states (a probe)")
args, petsc_args = ap.parse_known_args()
if args.first is not None and args.first < 1:
    ap.error(f"--first must be >= 1, got {args.first}")
if args.start is not None and args.start >= args.depth:
    ap.error(f"--start must be below --depth ({args.depth:g}), got {args.start:g}")
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.closed_forms import maugis_units  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.physics.resolution import RESOLUTION_NODES, check_resolution  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.problem import ContactProblem  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"
#: the JKR pull-off approach under displacement control, in Maugis' units (the minimum of
#: Delta(A) = A^2 - 2 sqrt(6 A) / 3, at A = 6^-1/3)
JKR_PULL_OFF_DELTA = (6.0 ** (-2.0 / 3.0)) - 2.0 * np.sqrt(6.0 * 6.0 ** (-1.0 / 3.0)) / 3.0


def path(w: float, z0: float, radius: float) -> np.ndarray:
    """The approaches [m]: up from the end (or --start z0) to --depth z0, down to the end, 1.2 x
    JKR's pull-off approach (at least -2 z0)."""
    h = args.step * z0
    end = min(-2.0 * z0, 1.2 * JKR_PULL_OFF_DELTA * maugis_units(1.0, radius, w)[0])
    up = np.arange(end if args.start is None else args.start * z0, args.depth * z0 + 0.5 * h, h)
    down = np.arange(up[-1] - h, end - 0.5 * h, -h)
    return np.concatenate([up, down])


def resolved(law, radius: float, z0: float):
    """(grid, heights, problem) on the coarsest dx = z0 / 2^k that resolves ``law``."""
    dx = z0
    while True:
        n = int(round(args.window * z0 / dx))
        if n > 8192:
            sys.exit(f"no grid up to 8192^2 resolves {law.name} with w = {law.work_of_adhesion:g} on a {args.window} z0 window")
        if check_resolution(law, 1.0, dx, warn=False) >= RESOLUTION_NODES:
            grid = SurfaceGrid(n, n, dx, periodic=False)
            heights = sphere(grid, radius)
            pb = AdhesiveProblem(grid, heights, 1.0, law, prefix="sphere_")
            if pb.snap_number < 1.0:
                return grid, heights, pb
            pb.destroy()
            heights.destroy()
        dx *= 0.5


def main():
    z0 = 1.0
    radius = args.radius * z0
    for mu in args.tabor:
        w = float(np.sqrt(mu ** 3 * z0 ** 3 / radius))
        approaches = path(w, z0, radius)
        largest = float(approaches.max())      # the unit's approach, on the whole path
        approaches = approaches[:args.first]
        law = make_law(args.law, work_of_adhesion=w, z0=z0)
        grid, heights, pb = resolved(law, radius, z0)
        # the unit: the non-adhesive solve at the path's largest approach, cold
        unit_problem = ContactProblem(grid, heights, 1.0, prefix="unit_", tol=1e-8)
        t = time.process_time()
        unit = unit_problem.solve(approach=largest)
        unit_cpu, unit_pairs = time.process_time() - t, unit.fft_pairs
        unit_problem.destroy()
        emit(tabor=mu, law=args.law, n=grid.nx, dx_z0=grid.dx / z0, radius_z0=args.radius, work_of_adhesion=w,
             states=len(approaches), unit_pairs=unit_pairs, unit_cpu=unit_cpu, snap_number=pb.snap_number,
             zone_nodes=pb.zone_nodes)
        rows = []
        for k, d in enumerate(approaches):
            t = time.process_time()
            st = pb.solve(approach=float(d), raise_on_failure=False)
            cpu = time.process_time() - t
            row = dict(tabor=mu, state=k, approach=float(d), fft_pairs=st.fft_pairs, cpu=cpu,
                       newton=st.newton_iterations, krylov=st.linear_iterations,
                       contact_fraction=st.contact_fraction, force=st.force, stiffness=st.stiffness,
                       converged=st.converged, stable=st.stable, solver=st.solver,
                       pairs_ratio=st.fft_pairs / unit_pairs, cpu_ratio=cpu / unit_cpu)
            if not st.converged or "branch check" in st.reason:
                row["reason"] = st.reason
            rows.append(row)
            emit(**row)
            st.release_fields()
        good = [r for r in rows if r["converged"]]
        pairs = np.array([r["pairs_ratio"] for r in good] or [np.nan])
        cpus = np.array([r["cpu_ratio"] for r in good] or [np.nan])
        emit(tabor=mu, summary=True, states=len(rows), converged=len(good),
             stable=sum(r["stable"] is True for r in rows), pairs_ratio_max=float(pairs.max()),
             pairs_ratio_median=float(np.median(pairs)), cpu_ratio_max=float(cpus.max()),
             cpu_ratio_median=float(np.median(cpus)), max_over_median=float(pairs.max() / np.median(pairs)),
             states_above_3x=int((pairs > 3.0).sum()), fft_pairs_converged=float(sum(r["fft_pairs"] for r in good)),
             failed=[(r["state"], r["approach"], r["fft_pairs"]) for r in rows if not r["converged"]])
        pb.destroy()
        heights.destroy()


main()
