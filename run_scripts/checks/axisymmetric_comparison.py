"""The 3-D solver's sphere against an independent axisymmetric solver (Greenwood's problem).

For each Tabor parameter mu: the axisymmetric tool (tests/axisymmetric_lj.py: ring loads,
numpy/scipy only, the whole S-curve by continuation) traces the load-approach curve on
one or more ring meshes and refines its most tensile state; the 3-D solver loads and unloads
the same sphere in displacement control on a square isolated window at each grid spacing and
refines its pull-off (``refine_pull_off``: the most tensile stable state).  Both are
W* = W / (2 pi R w) against alpha* = delta / z0 (Greenwood's scaling; units E* = z0 = 1).

The 3-D window leaves out the law's tail outside it; the axisymmetric load is therefore also
given inside the same square ("window"), and the differences are taken against that.  The
curve difference is |W*_3D - W*_axi(alpha*)| at the 3-D path's converged, stable states,
against the nearest branch of the axisymmetric curve (window loads, solved at the 3-D
approaches; Richardson's extrapolation of the two finest ring meshes): its largest value
over the states in tension (W* <= 0), and its largest value relative to W* over the states
in compression with W* >= 1.

    .venv/bin/python run_scripts/checks/axisymmetric_comparison.py --mu 0.1,0.5,1,2 --dx 1,0.5 --markdown
    .venv/bin/python run_scripts/checks/axisymmetric_comparison.py --mu 5 --no-3d --top 5 --markdown

Prints one JSON line per (mu, dx) and, with --markdown, the table of docs/validation.md.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import petsc4py

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests"))


def axisymmetric(mu, R, top, down, refine, halves):
    """The axisymmetric curve and pull-off at one mesh refinement (E* = z0 = 1)."""
    import axisymmetric_lj as axi
    w = np.sqrt(mu ** 3 / R)
    ws = 2 * np.pi * R * w
    t0 = time.perf_counter()
    sph = axi.AxisymmetricSphere(R, 1.0, w, 1.0, axi.default_mesh(R, w, 1.0, 1.0, top, refine=refine))
    states = sph.trace(down - 0.5, top + 0.5, step=0.05)
    best = sph.pull_off(states)
    alpha = np.array([s.approach for s in states])
    return dict(refine=refine, rings=len(sph.rings.r), points=len(states),
                pull_off=best.load / ws, pull_off_approach=best.approach,
                window_pull_off={h: sph.rings.load_in_square(best.pressure, h) / ws for h in halves},
                folds=int(np.count_nonzero(np.diff(np.sign(np.diff(alpha))))),
                time=time.perf_counter() - t0, sphere=sph, states=states)


def richardson(coarse, fine):
    """The mesh-converged value from two ring widths h and h/2 (second order, measured:
    the changes fall by ~4 per halving)."""
    return fine + (fine - coarse) / 3.0


def curve_at(ref, a3, W3, half, ws):
    """The axisymmetric window load W* at the 3-D states' approaches a3, on the branch nearest
    their loads W3 (NaN where the traced curve does not span an approach)."""
    sph, states = ref["sphere"], ref["states"]
    def load(st):
        return sph.rings.load_in_square(st.pressure, half) / ws
    out = []
    for a, W in zip(a3, W3):
        st = sph.on_branch(states, a, load, W)
        out.append(np.nan if st is None else load(st))
    return np.array(out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--mu", default="0.1,0.5,1,2", help="Tabor parameters")
    ap.add_argument("--radius", type=float, default=100.0, help="R / z0")
    ap.add_argument("--window", type=float, default=128.0, help="3-D window side / z0")
    ap.add_argument("--dx", default="1,0.5", help="3-D grid spacings / z0")
    ap.add_argument("--axi-refine", default="1,2",
                    help="axisymmetric mesh refinements (1: ring width the smaller of an eighth of the "
                         "cohesive length and a sixteenth of sqrt(2 R z0)); the last two give the reference")
    ap.add_argument("--step", type=float, default=0.1, help="3-D approach step / z0")
    ap.add_argument("--top", type=float, default=None, help="approach / z0 at the end of loading")
    ap.add_argument("--element-integration", action="store_true",
                    help="the 3-D traction integrated over elements (the paper's Fig. 3) instead of nodal")
    ap.add_argument("--no-3d", action="store_true", help="the axisymmetric tool only")
    ap.add_argument("--markdown", action="store_true")
    args, petsc_args = ap.parse_known_args(argv)
    petsc4py.init([sys.argv[0]] + petsc_args)
    from petsc4py import PETSc

    from contactpetsc.geometry.surfaces import sphere
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.paths import good_state, sweep
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.pull_off import refine_pull_off
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    rank = PETSc.COMM_WORLD.getRank()
    R = args.radius
    spacings = [float(d) for d in args.dx.split(",")] if not args.no_3d else []
    sizes = {dx: int(round(args.window / dx)) for dx in spacings}
    halves = sorted({sizes[dx] * dx / 2 for dx in spacings}) or [args.window / 2]
    rows = []
    for mu in (float(m) for m in args.mu.split(",")):
        w = np.sqrt(mu ** 3 / R)
        # as run_scripts/checks/pull_off_table.py: load to about the JKR pull-off force in compression
        top = args.top or max(1.0, 2.0 * (np.pi * w * R * 1.5 / (4.0 / 3.0 * np.sqrt(R))) ** (2.0 / 3.0))
        down = -3.0 - 2.0 * mu
        refs = [axisymmetric(mu, R, top, down, float(r), halves) for r in args.axi_refine.split(",")]
        ref = refs[-1]
        axi_row = dict(mu=mu, radius=R, top=top,
                       axi=[{k: v for k, v in a.items() if k not in ("sphere", "states")} for a in refs],
                       axi_mesh_change=(refs[-1]["pull_off"] - refs[-2]["pull_off"]) if len(refs) > 1 else None)
        # the reference: Richardson's extrapolation of the two finest meshes
        pull_ref = richardson(refs[-2]["pull_off"], ref["pull_off"]) if len(refs) > 1 else ref["pull_off"]
        if not spacings:
            rows.append(dict(axi_row, dx=None, pull_off=pull_ref))
            if rank == 0:
                print(json.dumps(dict(axi_row, pull_off=pull_ref), default=float), flush=True)
        for dx in spacings:
            n = sizes[dx]
            half = n * dx / 2
            grid = SurfaceGrid(n, n, dx, periodic=False)
            pb = AdhesiveProblem(grid, sphere(grid, R), 1.0, make_law("lj", work_of_adhesion=w, z0=1.0),
                                 element_integration=args.element_integration, prefix=f"cmp{len(rows)}_")
            loading = np.arange(-2.0, top + 1e-9, args.step)
            approaches = np.concatenate([loading, np.arange(loading[-1] - args.step, down - 1e-9, -args.step)])
            t0 = time.perf_counter()
            path = sweep(pb, approaches)
            pull = refine_pull_off(pb, path, xtol=0.01 * args.step)
            elapsed = time.perf_counter() - t0
            ws = 2 * np.pi * R * w
            good = [p for p in path.points if good_state(p)]
            a3, W3 = np.array([p.approach for p in good]), np.array([p.force for p in good]) / ws
            W_axi = curve_at(ref, a3, W3, half, ws)
            if len(refs) > 1:
                W_axi = richardson(curve_at(refs[-2], a3, W3, half, ws), W_axi)
            dist = np.abs(W3 - W_axi)
            tensile, compressed = W3 <= 0, W3 >= 1
            window_ref = (richardson(refs[-2]["window_pull_off"][half], ref["window_pull_off"][half])
                          if len(refs) > 1 else ref["window_pull_off"][half])
            row = dict(axi_row, dx=dx, n=n, window=2 * half, zone_nodes=pb.zone_nodes,
                       element_integration=args.element_integration,
                       axi_pull_off=pull_ref, axi_window_pull_off=window_ref,
                       pull_off_3d=pull / ws, rel_diff=pull / ws / window_ref - 1,
                       max_curve_diff=float(np.nanmax(dist[tensile])),
                       max_curve_rel_diff=float(np.nanmax(dist[compressed] / W3[compressed]))
                       if compressed.any() else float("nan"), curve_points=int(np.count_nonzero(np.isfinite(dist))),
                       unmatched_points=int(np.count_nonzero(~np.isfinite(dist))),
                       jumps=[(j.kind, j.approach_before) for j in path.jumps],
                       converged=all(p.converged for p in path.points), time=elapsed,
                       ranks=PETSc.COMM_WORLD.getSize())
            rows.append(row)
            if rank == 0:
                print(json.dumps(row, default=float), flush=True)
            pb.destroy()
    if rank == 0 and args.markdown:
        print("\n| mu | axisym W* (whole plane) | axisym W* (window) | axisym mesh change | dx / z0 | 3-D W* | "
              "difference | curve difference, W* <= 0 | curve difference / W*, W* >= 1 | 3-D time [s] |")
        print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            change = f"{r['axi_mesh_change']:+.1e}" if r["axi_mesh_change"] is not None else ""
            if r["dx"] is None:
                print(f"| {r['mu']:g} | {r['pull_off']:.5f} | | {change} | | | | | | |")
                continue
            print(f"| {r['mu']:g} | {r['axi_pull_off']:.5f} | {r['axi_window_pull_off']:.5f} | {change} | "
                  f"{r['dx']:g} | {r['pull_off_3d']:.5f} | {100 * r['rel_diff']:+.3f} % | "
                  f"{r['max_curve_diff']:.1e} | {100 * r['max_curve_rel_diff']:.2f} % | {r['time']:.0f} |")


if __name__ == "__main__":
    main()
