#!/usr/bin/env python3
"""Error against run time: the reference paper's relaxation against SNES VI Newton, both LJ forms.

Scenes, each with the hard-wall law (eq. 7) and the full Lennard-Jones curve (eq. 8), from rest
(the Signorini state) at one approach:

* ``sphere``: the sphere of the adhesion tests (R = 1000 z0, E* = z0 = 1, isolated, --n x --n
  nodes of --dx z0) at Tabor parameter --tabor, delta = --approach z0;
* ``rough``: the rough benchmark surface (``rough_surface.py``, periodic, --rough-n^2, E* = 1)
  with z0 = dx, w = 0.05 E* dx (the adhesive scene of ``error_vs_time.py``), delta the height
  quantile --quantile.

Error: max |g - g_ref| / z0
against a Newton reference at --ref-tol (with the preconditioner Newton's ``auto`` did not pick).  Newton (--tol,
the default preconditioner ``auto``, no stability
check): one point per fine-grid Newton iteration (a SNES monitor; the coarse grids of the nested
iteration have none).  Relaxation (--relax-tol on E_Total and the contact rms): one point per
adhesive cycle (``RelaxationSolver.monitor``).  The monitors' own time is subtracted.  Each
solver runs --repeat times on fresh problems; the curve of the run with the median total time is
kept.  Output: one JSON line per curve, a table (markdown), with --plot <dir> the figure
<dir>/relaxation_vs_newton.png (one panel per scene).

Usage::

    .venv/bin/python run_scripts/bench/relaxation_vs_newton.py [--n 128] [--tabor 1] [--plot docs/figures]
    .venv/bin/python run_scripts/bench/relaxation_vs_newton.py --replot out.jsonl --plot docs/figures
"""
import argparse
import json
import os
import sys
import time

import petsc4py

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--scenes", nargs="+", default=["sphere", "rough"], choices=["sphere", "rough"])
ap.add_argument("--n", type=int, default=128)
ap.add_argument("--rough-n", type=int, default=128)
ap.add_argument("--quantile", type=float, default=0.3)
ap.add_argument("--dx", type=float, default=1.0, help="grid spacing [z0]")
ap.add_argument("--tabor", type=float, default=1.0)
ap.add_argument("--approach", type=float, default=1.0, help="delta [z0]")
ap.add_argument("--laws", nargs="+", default=["hardwall-lj", "lj"])
ap.add_argument("--tol", type=float, default=1e-10, help="Newton's tolerance (its own errors, z0)")
ap.add_argument("--ref-tol", type=float, default=1e-11)
ap.add_argument("--relax-tol", type=float, default=1e-8, help="the relaxation's E_Total and contact rms [z0]")
ap.add_argument("--max-cycles", type=int, default=5000, help="the relaxation's adhesive cycles")
ap.add_argument("--repeat", type=int, default=3)
ap.add_argument("--plot", default=None)
ap.add_argument("--json", default=None)
ap.add_argument("--replot", default=None, metavar="JSONL")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.relaxation import RelaxationSolver  # noqa: E402

from rough_surface import rough_surface  # noqa: E402

comm = PETSc.COMM_WORLD.tompi4py()
R = 1000.0


class Curve:
    """(time, error) points; the clock excludes the time spent evaluating the error."""

    def __init__(self, grid, ref_rows, z0):
        self.grid, self.ref, self.z0 = grid, ref_rows, z0
        self.points, self.overhead, self.t0 = [], 0.0, time.perf_counter()

    def add(self, gap_rows):
        t = time.perf_counter()
        err = comm.allreduce(float(np.abs(gap_rows - self.ref).max()), op=MPI.MAX) / self.z0
        self.points.append((t - self.t0 - self.overhead, err))
        self.overhead += time.perf_counter() - t

    def elapsed(self):
        return time.perf_counter() - self.t0 - self.overhead


def problem(grid, h, law, prefix, **kw):
    return AdhesiveProblem(grid, h, 1.0, law, prefix=prefix, stability_check=False, **kw)


def run_newton(grid, h, law, delta, ref, k):
    pb = problem(grid, h, law, f"newton{k}_", tol=args.tol)
    curve = Curve(grid, ref, law.z0)
    gap = np.empty_like(ref)
    pb.snes().setMonitor(lambda snes, it, fnorm: curve.add(
        pb.gap(pb.blocks(snes.getSolution(), readonly=True).sum(axis=0), gap)))
    comm.Barrier()
    curve.t0 = time.perf_counter()
    st = pb.solve(approach=delta, raise_on_failure=False)
    return st, curve, comm.allreduce(curve.elapsed(), op=MPI.MAX)


def run_relaxation(grid, h, law, delta, ref, k):
    relax = RelaxationSolver(problem(grid, h, law, f"relax{k}_"), tol=args.relax_tol, contact_tol=args.relax_tol,
                             max_cycles=args.max_cycles)
    curve = Curve(grid, ref, law.z0)
    relax.monitor = lambda cycle, gap: curve.add(gap)
    comm.Barrier()
    curve.t0 = time.perf_counter()
    st = relax.solve(approach=delta, raise_on_failure=False)
    return st, curve, comm.allreduce(curve.elapsed(), op=MPI.MAX)


def scene(name):
    """(grid, heights, {law name: law}, approach [m])."""
    if name == "sphere":
        grid = SurfaceGrid(args.n, args.n, args.dx, periodic=False)
        laws = {law: make_law(law, work_of_adhesion=np.sqrt(args.tabor ** 3 / R), z0=1.0) for law in args.laws}
        return grid, sphere(grid, R), laws, args.approach
    grid, h, _ = rough_surface(args.rough_n)
    dx = grid.dx
    laws = {law: make_law(law, work_of_adhesion=0.05 * dx, z0=dx) for law in args.laws}
    return grid, h, laws, float(np.quantile(grid.gather(h), args.quantile))


def solve_all():
    rows = []
    for scene_name in args.scenes:
        grid, h, laws, delta = scene(scene_name)
        for name, law in laws.items():
            rows += solve_law(scene_name, grid, h, name, law, delta)
    return rows


def solve_law(scene_name, grid, h, name, law, delta):
    rows = []
    # the reference with the other preconditioner than Newton's (the default ``auto`` picks one
    # from the snap number), so that it is not the Newton curve's own last iterate
    probe = problem(grid, h, law, "probe_", tol=args.tol)
    probe.snes()
    newton_pc = probe.preconditioner
    ref_pc = "spectral" if newton_pc == "mlmi" else "mlmi"
    st_ref = problem(grid, h, law, "ref_", tol=args.ref_tol, preconditioner=ref_pc).solve(approach=delta)
    ref = grid.rows(st_ref.gap, readonly=True).copy()
    for solver, run in (("SNES VI Newton", run_newton), ("relaxation (paper)", run_relaxation)):
        runs = [run(grid, h, law, delta, ref, k) for k in range(args.repeat)]
        times = [t for _, _, t in runs]
        st, curve, t = runs[int(np.argsort(times)[len(times) // 2])]
        row = dict(scene=scene_name, law=name, solver=solver, converged=st.converged, reason=st.reason,
                   preconditioner=newton_pc if run is run_newton else None, reference_preconditioner=ref_pc,
                   times=times, median_time=float(np.median(times)), fft_pairs=st.fft_pairs,
                   iterations=st.newton_iterations, contact_fraction=st.contact_fraction,
                   final_error=curve.points[-1][1] if curve.points else None,
                   points=[[float(a), float(b)] for a, b in curve.points])
        rows.append(row)
        if comm.rank == 0:
            print(json.dumps(row), flush=True)
            if args.json:
                with open(args.json, "a") as f:
                    f.write(json.dumps(row) + "\n")
    return rows


def table(rows):
    print("\n| scene | law | solver | iterations | FFT pairs | median time [s] (3 runs) "
          "| final max abs(g - g_ref) [z0] |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r['scene']} | {r['law']} | {r['solver']} | {r['iterations']} | {r['fft_pairs']:.0f} | "
              f"{r['median_time']:.2f} ({', '.join(f'{t:.2f}' for t in r['times'])}) | {r['final_error']:.1e} |")


def plot(rows, directory):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(dict.fromkeys(r["scene"] for r in rows))
    fig, axes = plt.subplots(1, len(names), figsize=(6.0 * len(names), 4.6), squeeze=False)
    style = {"SNES VI Newton": "-o", "relaxation (paper)": "-"}
    colour = {"hardwall-lj": "C0", "lj": "C3"}
    titles = {"sphere": f"sphere R = 1000 z0, Tabor {args.tabor:g}, {args.n}^2, dx = {args.dx:g} z0, "
                        f"delta = {args.approach:g} z0",
              "rough": f"rough benchmark surface, {args.rough_n}^2, z0 = dx, w = 0.05 E* dx, "
                       f"delta: quantile {args.quantile:g} of h"}
    for ax, name in zip(axes[0], names):
        for r in rows:
            pts = np.array(r["points"])
            if r["scene"] == name and len(pts):
                ax.semilogy(pts[:, 0], np.maximum(pts[:, 1], 1e-16), style[r["solver"]],
                            color=colour.get(r["law"]), ms=3,
                            label=f"{r['solver']}, {r['law']} ({r['fft_pairs']:.0f} FFT pairs)")
        ax.set_xlabel("wall time [s] (the run of median time of 3)")
        ax.set_ylabel("max |g - g_ref| / z0")
        ax.set_title(titles[name], fontsize=8)
        ax.legend(fontsize=8)
        ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    os.makedirs(directory, exist_ok=True)
    fig.savefig(os.path.join(directory, "relaxation_vs_newton.png"), dpi=120)


if args.replot:
    rows = [json.loads(line) for line in open(args.replot)]
else:
    rows = solve_all()
if comm.rank == 0:
    table(rows)
    if args.plot:
        plot(rows, args.plot)
