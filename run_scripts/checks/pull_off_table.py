"""Pull-off force of a smooth sphere against the Tabor parameter, beside Maugis-Dugdale.

For each mu a loading-unloading sweep in displacement control (Newton VI, the
full Lennard-Jones curve by default) gives the most tensile force of the
unloading branch, refined by golden section; the table compares it with
Maugis-Dugdale at lambda = 1.16 mu and the JKR (-1.5) and DMT (-2) limits,
all as P / (pi w R).  Greenwood's units: E* = z0 = 1.

    mpirun -n 2 .venv/bin/python run_scripts/checks/pull_off_table.py [--law lj] [--n 192] [--markdown]

Prints one JSON line per mu (and a markdown table with --markdown).
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import petsc4py


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mu", default="0.1,0.2,0.5,1,2,5", help="Tabor parameters")
    ap.add_argument("--law", default="lj", choices=["lj", "hardwall-lj"])
    ap.add_argument("--radius", type=float, default=100.0, help="R / z0")
    ap.add_argument("--n", type=int, default=192, help="grid nodes per side")
    ap.add_argument("--dx", type=float, default=0.5, help="grid spacing / z0")
    ap.add_argument("--step", type=float, default=0.1, help="approach step / z0 (unloading)")
    ap.add_argument("--load-step", type=float, default=None,
                    help="approach step / z0 while loading (default: --step); the pull-off is on the "
                         "unloading branch, and at large mu the loading range is tens of z0")
    ap.add_argument("--top", type=float, default=None,
                    help="approach / z0 at the end of loading (default: about the JKR pull-off force in "
                         "compression); the pull-off of an adhered sphere does not depend on it")
    ap.add_argument("--element-integration", action="store_true")
    ap.add_argument("--markdown", action="store_true")
    args, petsc_args = ap.parse_known_args(argv)
    petsc4py.init([sys.argv[0]] + petsc_args)
    from petsc4py import PETSc

    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.paths import sweep
    from contactpetsc.pull_off import refine_pull_off
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.physics.closed_forms import maugis_pull_off_bar
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    from contactpetsc.geometry.surfaces import sphere

    rank = PETSc.COMM_WORLD.getRank()
    rows = []
    R = args.radius
    for mu in (float(m) for m in args.mu.split(",")):
        w = np.sqrt(mu ** 3 / R)
        grid = SurfaceGrid(args.n, args.n, args.dx, periodic=False)
        pb = AdhesiveProblem(grid, sphere(grid, R), 1.0, make_law(args.law, work_of_adhesion=w, z0=1.0),
                             element_integration=args.element_integration, prefix=f"mu{len(rows)}_")
        # load to a compressive force of about the JKR pull-off magnitude, then unload past pull-off
        top = args.top or max(1.0, 2.0 * (np.pi * w * R * 1.5 / (4.0 / 3.0 * np.sqrt(R))) ** (2.0 / 3.0))
        down = -3.0 - 2.0 * mu
        load_step = args.load_step or args.step
        loading = np.arange(-2.0, top + 1e-9, load_step)
        approaches = np.concatenate([loading, np.arange(loading[-1] - args.step, down - 1e-9, -args.step)])
        t0 = time.perf_counter()
        path = sweep(pb, approaches)
        sampled = path.pull_off_force
        pull = refine_pull_off(pb, path, xtol=0.01 * args.step)
        elapsed = time.perf_counter() - t0
        bar = pull / (np.pi * w * R)
        md = maugis_pull_off_bar(1.16 * mu)
        # the window edge: the part of the LJ tail outside it is lost (Derjaguin estimate)
        edge_gap = (args.n * args.dx / 2) ** 2 / (2 * R)
        tail = float(-2 * make_law("lj", work_of_adhesion=w, z0=1.0).energy(edge_gap) / w)
        row = dict(mu=mu, law=args.law, n=args.n, dx=args.dx, radius=R, pull_off_bar=bar, snap_number=pb.snap_number,
                   sampled_bar=sampled / (np.pi * w * R), maugis_bar=md, rel_diff=bar / md - 1,
                   jkr_bar=-1.5, dmt_bar=-2.0, jumps=[(j.kind, j.approach_before) for j in path.jumps],
                   converged=all(p.converged for p in path.points),
                   fft_pairs=sum(p.fft_pairs for p in path.points), time=elapsed,
                   tail_lost_bar=tail, ranks=PETSc.COMM_WORLD.getSize())
        rows.append(row)
        if rank == 0:
            print(json.dumps(row), flush=True)
    if rank == 0 and args.markdown:
        print("\n| mu | P/(pi w R) here | Maugis-Dugdale (lambda = 1.16 mu) | difference | JKR | DMT | time [s] |")
        print("|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['mu']:g} | {r['pull_off_bar']:.4f} | {r['maugis_bar']:.4f} | "
                  f"{100 * r['rel_diff']:+.1f} % | -1.5 | -2 | {r['time']:.1f} |")


if __name__ == "__main__":
    main()
