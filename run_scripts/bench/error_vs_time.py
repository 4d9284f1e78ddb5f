#!/usr/bin/env python3
"""Error against run time per scene: every solver of ours and the peers, one run.

Scenes
------
* ``rough``: non-adhesive rough contact, the benchmark surface of
  ``examples/scenes/bench_rough.toml`` (``rough_surface.py``, E* = 1), load
  control at a mean pressure of 0.005 E*; n = --n.
* ``adhesive``: the same surface with the full Lennard-Jones law ``lj``,
  z0 = dx, w = 0.05 E* dx (the rough case of ``bench_adhesion.py``), at one
  approach delta, displacement control from rest.  delta is the height
  quantile --quantile of h (the rigid overlap covers that fraction of the
  cell; the contact area reached, p > 0, is reported).
* ``sphere``: the sphere of ``bench_adhesion.py`` (R = 1000 z0, isolated,
  n = 128, dx = z0 = E* = 1), hard-wall LJ at Tabor parameter --tabor,
  delta = z0 from rest.

Error (one measure per scene, evaluated on each solver's fields): the
largest gap difference max |g - g_ref| to a reference solution of ours
(SNES VI + spectral preconditioner at tolerance --ref-tol), in units of the
rms height (``rough``) or of z0 (``adhesive``, ``sphere``).

Solvers
-------
* SNES VI Newton with each preconditioner of --pcs (``mlmi``, ``spectral``,
  ``none``; tolerance --tol in the solver's own measure): one curve point
  per fine-grid Newton iteration, from a SNES monitor that evaluates the
  error on the iterate (the gap of the residual for ``rough``, K p + h -
  delta with a separate operator for the adhesive scenes).  The monitor's
  own time is subtracted from the clock; the coarse grids of the nested
  iteration have no points (the curve starts when the fine grid does).
  Stability checks are off (the peers make none); the tangent computed after
  convergence is in the solve's total time, not in the curve.
* The reference paper's relaxation (``RelaxationSolver``; here on the
  sphere): run from rest at each tolerance of --relax-tols (E_Total and the
  contact residual, z0), one point per run (its time, its returned gap).
  Per cycle, with both LJ forms on the sphere and the rough surface:
  ``relaxation_vs_newton.py``.
* Peers, whose iterations we cannot observe: run from rest at each
  iteration cap of --caps, one point per run (the peer's own solve time,
  the error of its returned gap).  ``rough``: Tamaas 2.9 PolonskyKeerRey
  (``peers/tamaas_signorini.py --max-iter``, peer venv).  ``adhesive``:
  ContactMechanics 1.8.3 + Adhesion 0.93, L-BFGS-B with the same law
  (``peers/cm_adhesion.py --maxiter``, peer-venv-cm).  A sequence stops when
  a run no longer uses its whole cap (converged, or stopped by the
  optimiser), takes longer than --peer-max-time or reaches an error below
  --stop-error.
* Not run: TAO (contactpetsc has no TAO solver); relaxation for ``rough``
  (load control and no adhesive law: the paper's solver is the adhesive
  cycle around the projected relaxation) and for ``adhesive``
  (``relaxation_vs_newton.py`` compares it there); Tamaas for the adhesive
  scenes (no LJ-type law); ContactMechanics for ``rough`` (no driver) and
  for ``sphere`` (the driver is periodic and has no hard wall).

Usage::

    .venv/bin/python run_scripts/bench/error_vs_time.py [--scenes rough adhesive sphere] [--n 256]
        [--pcs mlmi spectral none] [--no-peer] [--plot docs/figures] [--json out.jsonl]
        [PETSc options, e.g. -sphere_ref_fallback relaxation]
    .venv/bin/python run_scripts/bench/error_vs_time.py --replot out.jsonl --plot docs/figures

Options prefixes: ``<scene>_ref_`` (the reference), ``<scene>_<pc>_`` (Newton),
``rough_<pc>_``, ``rel<tol>_`` (relaxation).

Output: one JSON line per curve (scene, solver, points (time [s], error),
total time [s], FFT pairs, own error), a time-to-error table (markdown) on
stdout, and with --plot the figures <dir>/error_vs_time_<scene>.png.
Times are wall-clock seconds of the solve only (set-up, FFTW planning and
the peers' imports excluded).  One rank is the measured configuration; on
more ranks ours run in parallel and the peers on rank 0.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import petsc4py

VENV = os.path.expanduser("~/.cache/contactpetsc")
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--scenes", nargs="+", default=["rough", "adhesive", "sphere"],
                choices=["rough", "adhesive", "sphere"])
ap.add_argument("--n", type=int, default=256, help="grid of the rough scenes")
ap.add_argument("--sphere-n", type=int, default=128)
ap.add_argument("--tabor", type=float, default=2.0)
ap.add_argument("--quantile", type=float, default=0.3,
                help="adhesive scene: the approach is this quantile of the heights")
ap.add_argument("--pcs", nargs="+", default=["mlmi", "spectral", "none"])
ap.add_argument("--tol", type=float, default=1e-10, help="our solvers' tolerance (own measure)")
ap.add_argument("--ref-tol", type=float, default=1e-11)
ap.add_argument("--relax-tols", type=float, nargs="+", default=[1e-2, 1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8])
ap.add_argument("--caps", type=int, nargs="+", default=[8, 16, 32, 64, 128, 256, 512, 1024, 2048],
                help="peer iteration caps")
ap.add_argument("--peer-max-time", type=float, default=120.0,
                help="stop a peer (or relaxation) sequence after a run longer than this [s]")
ap.add_argument("--stop-error", type=float, default=1e-10,
                help="stop a peer (or relaxation) sequence once a run's error is below this")
ap.add_argument("--no-peer", action="store_true")
ap.add_argument("--plot", default=None, help="directory for error_vs_time_<scene>.png")
ap.add_argument("--json", default=None, help="also write the JSON lines to this file")
ap.add_argument("--replot", default=None, metavar="JSONL",
                help="no solves: the table and figures of the curves in this --json file")
ap.add_argument("--tamaas-python", default=os.path.join(VENV, "peer-venv", "bin", "python"))
ap.add_argument("--cm-python", default=os.path.join(VENV, "peer-venv-cm", "bin", "python"))
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry import surfaces  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.operators.elastic import half_space  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.solvers import ContactProblem  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.relaxation import RelaxationSolver  # noqa: E402

from rough_surface import rough_surface as bench_surface  # noqa: E402

comm = PETSc.COMM_WORLD.tompi4py()
rank = comm.Get_rank()
HERE = os.path.dirname(os.path.abspath(__file__))
THRESHOLDS = (1e-4, 1e-8)
curves = []   # dicts: scene, solver, kind ("iterations" or "runs"), points [(t, err)], ...


def emit(row):
    curves.append(row)
    if rank == 0:
        line = json.dumps(row)
        print(line, flush=True)
        if args.json:
            with open(args.json, "a") as f:
                f.write(line + "\n")


class GapError:
    """max |g - g_ref| / scale on the rank's rows; g from the Vec's rows or from the pressure."""

    def __init__(self, grid, heights, gap_ref, scale):
        self.grid, self.scale = grid, scale
        self.h = grid.rows(heights, readonly=True).copy()
        self.ref = grid.rows(gap_ref, readonly=True).copy()
        self.op = None   # built on first use: a separate operator keeps the solvers' FFT counts clean
        self._g = np.empty_like(self.ref)
        self.ref_global = None   # (nx, ny) reference gap on rank 0, for the peers' fields

    def of_gap(self, gap_rows):
        return comm.allreduce(float(np.abs(gap_rows - self.ref).max()), op=MPI.MAX) / self.scale

    def of_pressure(self, p_rows, delta):
        if self.op is None:
            self.op = half_space(self.grid, 1.0, prefix="evaluation_")
        self.op.apply(p_rows, self._g)
        self._g += self.h
        self._g -= delta
        return self.of_gap(self._g)

    def of_global(self, gap):
        """Error of a peer's (nx, ny) gap (rank 0 only)."""
        return float(np.abs(gap - self.ref_global).max()) / self.scale


class Clock:
    """Wall time since ``start`` minus the time spent in the monitor."""

    def __init__(self):
        self.t0, self.overhead, self.points = time.perf_counter(), 0.0, []

    def monitor(self, error_of_snes):
        def fn(snes, it, fnorm):
            t = time.perf_counter()
            err = error_of_snes(snes)
            self.points.append((t - self.t0 - self.overhead, err))
            self.overhead += time.perf_counter() - t
        return fn

    def elapsed(self):
        return time.perf_counter() - self.t0 - self.overhead


def summary(scene, solver, points, **extra):
    """The curve's row, with the time to reach each threshold (None if never reached)."""
    row = dict(scene=scene, solver=solver, points=[[float(t), float(e)] for t, e in points])
    for thr in THRESHOLDS:
        row[f"t_{thr:.0e}"] = next((t for t, e in points if e <= thr), None)
    row["final_error"] = float(points[-1][1]) if points else None
    row.update(extra)
    emit(row)


def newton_curve(problem, solve, error_of_snes):
    """Run ``solve()`` with a monitor on the problem's SNES; returns the state."""
    clock = Clock()
    problem.snes().setMonitor(clock.monitor(error_of_snes))
    comm.Barrier()
    clock.t0 = time.perf_counter()
    st = solve()
    total = comm.allreduce(clock.elapsed(), op=MPI.MAX)
    return st, clock.points, total


def peer_sequence(scene, name, grid, h, gap_ref, err, run_one):
    """One peer run per cap on rank 0, from rest, on the heights ``h`` saved as .npy;
    ``run_one(cap, heights_path, tmpdir)`` -> (result dict, the peer's (nx, ny) gap) or
    (None, message).  Emits the curve."""
    err.ref_global = grid.gather(gap_ref, root=0)
    hg = grid.gather(h, root=0)
    points, rows = [], []
    if rank == 0:
        with tempfile.TemporaryDirectory() as tmp:
            hpath = os.path.join(tmp, "h.npy")
            np.save(hpath, hg)
            for cap in args.caps:
                res, gap = run_one(cap, hpath, tmp)
                if res is None:
                    rows.append(dict(cap=cap, failed=gap))
                    break
                e = err.of_global(gap) if gap is not None else float("nan")
                points.append((res["time"], e))
                rows.append(dict(cap=cap, time=res["time"], error=e, iterations=res.get("iterations"),
                                 fft_pairs=res.get("fft_pairs"), own_error=res.get("own_error")))
                used = res.get("iterations")
                if (used is not None and used < cap) or res["time"] > args.peer_max_time or e <= args.stop_error:
                    break
    points, rows = comm.bcast((points, rows), root=0)
    summary(scene, name, points, kind="runs", runs=rows)


# -- scenes ----------------------------------------------------------------------------------------
def rough_surface(n):
    return bench_surface(n, row_alignment=64)[:2]


def scene_rough():
    n, P = args.n, 0.005
    grid, h = rough_surface(n)
    rms = surfaces.rms_height(grid, h)
    ref = ContactProblem(grid, h, 1.0, tol=args.ref_tol, load_tol=1e-13, prefix="ref_").solve(mean_pressure=P)
    err = GapError(grid, h, ref.gap, rms)
    for pc in args.pcs:
        pb = ContactProblem(grid, h, 1.0, preconditioner=pc, tol=args.tol, prefix=f"rough_{pc}_")
        st, pts, total = newton_curve(
            pb, lambda: pb.solve(mean_pressure=P, raise_on_failure=False),
            lambda snes: err.of_gap(grid.rows(snes.getFunction()[0], readonly=True)))
        summary("rough", f"SNES VI + {pc}", pts, kind="iterations", time=total, fft_pairs=st.fft_pairs,
                newton=st.newton_iterations, krylov=st.linear_iterations,
                own_error=st.complementarity_error, converged=st.converged,
                error=err.of_gap(grid.rows(st.gap, readonly=True)))
    if args.no_peer:
        return

    def tamaas(cap, hpath, tmp):
        out = os.path.join(tmp, f"t{cap}.npz")
        cmd = [args.tamaas_python, os.path.join(HERE, os.pardir, "peers", "tamaas_signorini.py"), hpath,
               "--length", "1.0", "--estar", "1.0", "--mean-pressure", str(P), "--tol", "1e-15",
               "--max-iter", str(cap), "--no-check", "--out", out]
        cp = subprocess.run(cmd, capture_output=True, text=True)
        if cp.returncode != 0:
            return None, cp.stderr[-1000:]
        res = json.loads(cp.stdout.strip().splitlines()[-1])
        res["own_error"] = res["tamaas_error"]
        return res, np.load(out)["gap"]

    peer_sequence("rough", "Tamaas PKR", grid, h, ref.gap, err, tamaas)


def adhesive_newton_curves(scene, grid, h, law, delta, scale):
    """The reference (tolerance --ref-tol, spectral) and one Newton curve per preconditioner
    at approach ``delta`` [m] from rest; returns (the GapError, the reference state)."""
    ref = AdhesiveProblem(grid, h, 1.0, law, tol=args.ref_tol, prefix=f"{scene}_ref_", stability_check=False)
    st_ref = ref.solve(approach=delta, raise_on_failure=False)
    PETSc.Sys.Print(f"{scene} reference: converged {st_ref.converged} ({st_ref.reason}), contact fraction "
                    f"{st_ref.contact_fraction:.3f}, solver {st_ref.solver}, {st_ref.wall_time:.2f} s")
    err = GapError(grid, h, st_ref.gap, scale)
    for pc in args.pcs:
        pb = AdhesiveProblem(grid, h, 1.0, law, tol=args.tol, preconditioner=pc, prefix=f"{scene}_{pc}_",
                             stability_check=False)

        def of_snes(snes):
            return err.of_pressure(pb.blocks(snes.getSolution(), readonly=True).sum(axis=0), delta)

        st, pts, total = newton_curve(pb, lambda: pb.solve(approach=delta, raise_on_failure=False), of_snes)
        summary(scene, f"SNES VI + {pc}", pts, kind="iterations", time=total, fft_pairs=st.fft_pairs,
                newton=st.newton_iterations, krylov=st.linear_iterations, solver_path=st.solver,
                own_error=max(st.complementarity_error, st.adhesive_error), converged=st.converged,
                contact_fraction=st.contact_fraction, check_time=st.check_time,
                error=err.of_gap(grid.rows(st.gap, readonly=True)))
    return err, st_ref


def scene_adhesive():
    n = args.n
    grid, h = rough_surface(n)
    dx = grid.dx
    z0, w = dx, 0.05 * dx
    law = make_law("lj", work_of_adhesion=w, z0=z0)
    delta = float(np.quantile(grid.gather(h), args.quantile))
    err, st_ref = adhesive_newton_curves("adhesive", grid, h, law, delta, z0)
    if args.no_peer:
        return

    def cm(cap, hpath, tmp):
        out = os.path.join(tmp, f"c{cap}")
        cmd = [args.cm_python, os.path.join(HERE, os.pardir, "peers", "cm_adhesion.py"), "--surface", hpath,
               "--dx", repr(dx), "--e-star", "1.0", "--w", repr(w), "--z0", repr(z0),
               "--potential", "vdw82", f"--offsets={delta!r}", "--gtol", "1e-14",
               "--maxiter", str(cap), "--save-fields", out]
        cp = subprocess.run(cmd, capture_output=True, text=True)
        rows = [json.loads(line) for line in cp.stdout.splitlines() if line.startswith("{")]
        if not rows or rows[0].get("time") is None:
            return None, (rows[0]["message"] if rows else cp.stderr[-1000:])
        res = rows[0]
        res["own_error"] = res["error"]
        return res, np.load(res["fields"]) if "fields" in res else None

    peer_sequence("adhesive", "ContactMechanics + Adhesion (L-BFGS-B)", grid, h, st_ref.gap, err, cm)


def scene_sphere():
    n, R, delta = args.sphere_n, 1000.0, 1.0
    grid = SurfaceGrid(n, n, 1.0, periodic=False)
    h = surfaces.sphere(grid, R)
    law = make_law("hardwall-lj", work_of_adhesion=np.sqrt(args.tabor ** 3 / R), z0=1.0)
    err, _ = adhesive_newton_curves("sphere", grid, h, law, delta, 1.0)
    points, runs = [], []
    for tol in args.relax_tols:
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"rel{tol:.0e}_", stability_check=False)
        comm.Barrier()
        st = RelaxationSolver(pb, tol=tol, contact_tol=tol).solve(approach=delta, raise_on_failure=False,
                                                                  check_stability=False)
        t = comm.allreduce(st.wall_time, op=MPI.MAX)
        e = err.of_gap(grid.rows(st.gap, readonly=True))
        points.append((t, e) if st.converged else (t, float("nan")))
        runs.append(dict(tol=tol, time=t, error=e, fft_pairs=st.fft_pairs, cycles=st.newton_iterations,
                         converged=st.converged, own_error=st.total_error))
        if not st.converged or t > args.peer_max_time or e <= args.stop_error:
            break
    summary("sphere", "relaxation (paper)", [p for p in points if np.isfinite(p[1])], kind="runs", runs=runs)


# -- output ------------------------------------------------------------------------------------------
TITLES = {
    "rough": "non-adhesive rough, {n}x{n}, mean pressure 0.005 E*",
    "adhesive": "adhesive rough (lj, z0 = dx, w = 0.05 E* dx), {n}x{n}, from rest",
    "sphere": "sphere R = 1000 z0, hard-wall LJ, Tabor {mu:g}, {m}x{m}, delta = z0 from rest",
}
YLABEL = {"rough": "max |g - g_ref| / rms height", "adhesive": "max |g - g_ref| / z0",
          "sphere": "max |g - g_ref| / z0"}


def plot(directory):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(directory, exist_ok=True)
    for scene in dict.fromkeys(c["scene"] for c in curves):
        fig, ax = plt.subplots(figsize=(6.4, 4.2))
        for k, c in enumerate(c for c in curves if c["scene"] == scene):
            if not c["points"]:
                continue
            t, e = zip(*c["points"])
            ax.loglog(t, np.maximum(e, 1e-16), marker="o" if c["kind"] == "iterations" else "s",
                      ms=3, ls="-" if c["kind"] == "iterations" else "--", color=f"C{k}", label=c["solver"])
        for thr in THRESHOLDS:
            ax.axhline(thr, color="0.6", lw=0.6, ls=":")
        ax.set_xlabel("wall time [s] (solid: per Newton iteration; dashed: one run per tolerance / cap)")
        ax.xaxis.label.set_size(8)
        ax.set_ylabel(YLABEL[scene])
        ax.set_title(TITLES[scene].format(n=args.n, m=args.sphere_n, mu=args.tabor), fontsize=9)
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(os.path.join(directory, f"error_vs_time_{scene}.png"), dpi=120)
        plt.close(fig)


def table():
    def fmt(x):
        return "-" if x is None else f"{x:.3g}"
    lines = ["| scene | solver | time to 1e-4 [s] | time to 1e-8 [s] | final error | time [s] | FFT pairs |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for c in curves:
        # the whole solve (per-iteration curves) or the last run (one run per tolerance / cap)
        last = next((r for r in reversed(c.get("runs", [])) if "time" in r), {})
        pairs, total = c.get("fft_pairs", last.get("fft_pairs")), c.get("time", last.get("time"))
        lines.append(f"| {c['scene']} | {c['solver']} | {fmt(c['t_1e-04'])} | {fmt(c['t_1e-08'])} | "
                     f"{fmt(c['final_error'])} | {fmt(total)} | {fmt(pairs)} |")
    return "\n".join(lines)


load0 = os.getloadavg()
if args.replot:
    with open(args.replot) as f:
        curves.extend(json.loads(line) for line in f)
for name in [] if args.replot else args.scenes:
    {"rough": scene_rough, "adhesive": scene_adhesive, "sphere": scene_sphere}[name]()
if rank == 0:
    if not args.replot:
        print(f"\nload average at start {load0}, at end {os.getloadavg()}; {comm.Get_size()} rank(s)")
    print(table())
    if args.plot:
        plot(args.plot)
