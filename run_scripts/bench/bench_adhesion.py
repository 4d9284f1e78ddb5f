#!/usr/bin/env python3
"""Benchmark: adhesive contact, error against run time, ours and the peer.

Cases
-----
* ``sphere``: a sphere (R = 1000 z0, E* = z0 = 1, isolated, n = 128, dx = z0) with
  the hard-wall LJ law at Tabor parameters 0.5 and 2, solved at one approach
  (delta = z0, in contact) from the undeformed bodies by Newton (SNES VI)
  and by the reference paper's relaxation.  Their per-iteration histories give
  the error-vs-time curves (``--plot``).
* ``rough``: the benchmark surface of ``examples/scenes/bench_rough.toml``
  (``rough_surface.py``; periodic unit cell, self-affine),
  the full LJ curve with z0 = dx and w = 0.05 E* dx, three approaches giving
  about 2 %, 10 % and 25 % contact area (p > 0, i.e. z < z0; interpolated on a
  loading sweep of our solver, untimed),
  solved in turn with warm starts by Newton (``-ours<i>_stiffness false``: the
  isolated states need no tangent stiffness, and the peer computes none), and
  by ContactMechanics + Adhesion
  (``run_scripts/peers/cm_adhesion.py`` in the peer venv, same heights, same
  approaches) with the same law (``--potential vdw82`` is exactly our lj law;
  lj93 is Adhesion's 9-3 potential with the same w and equilibrium distance).
  Stronger and shorter-range variants: ``--w 0.2 0.5``, ``--z0 0.25``.

Error: ``error`` is the largest gap difference to a reference solution of
the same case (ours at tolerance 1e-11), in z0; the solvers' own measures
are kept in ``own_error``.  One JSON line per case (n, solver, approach,
time, fft_pairs, newton, krylov, error, converged, ...; the solver name ends in +ptc where the
fallback ran).

    .venv/bin/python run_scripts/bench/bench_adhesion.py [--cases sphere rough] [--sizes 256 512 1024]
        [--w 0.05] [--z0 1.0] [--potential vdw82] [--no-peer] [--plot docs/figures] [--tol 1e-8 1e-5]
"""
import argparse
import json
import os
import sys
import tempfile
import time

import petsc4py

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--cases", nargs="+", default=["sphere", "rough"])
ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024])
ap.add_argument("--areas", type=float, nargs="+", default=[0.02, 0.10, 0.25])
ap.add_argument("--w", type=float, nargs="+", default=None, help="w / (E* dx) (default: rough_surface.ADHESIVE_W)")
ap.add_argument("--z0", type=float, nargs="+", default=None, help="z0 / dx (default: rough_surface.ADHESIVE_Z0)")
ap.add_argument("--mu", type=float, nargs="+", default=[0.5, 2.0], help="sphere Tabor parameters")
ap.add_argument("--potential", default="vdw82", choices=["vdw82", "lj93"])
ap.add_argument("--no-peer", action="store_true")
ap.add_argument("--tol", type=float, nargs="+", default=[1e-8],
                help="our tolerances [z0] (rough cases; each runs the path afresh): the default 1e-8, "
                     "and e.g. 1e-5 for the peer's accuracy (time at equal error)")
ap.add_argument("--approaches", type=float, nargs="+", default=None,
                help="rough case: these approaches (in units of the cell size 1) instead of the "
                     "calibration sweep, e.g. an earlier run's, to compare code versions on equal terms")
ap.add_argument("--calibrate-max-n", type=int, default=256,
                help="calibrate the approaches on the heights averaged to at most this grid")
ap.add_argument("--peer-maxiter", type=int, default=100000)
ap.add_argument("--plot", default=None, help="directory for the error-vs-time figures")
ap.add_argument("--peer-python", default=os.path.join(os.environ.get(
    "CONTACTPETSC_PEER_VENV_CM", os.path.expanduser("~/.cache/contactpetsc/peer-venv-cm")), "bin", "python"))
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.relaxation import RelaxationSolver  # noqa: E402
from contactpetsc.geometry.surfaces import sphere  # noqa: E402

from peer_runs import cm_adhesion_command, json_rows  # noqa: E402
from rough_surface import ADHESIVE_W, ADHESIVE_Z0, adhesive_law, calibrate, rough_surface  # noqa: E402

args.w, args.z0 = args.w or [ADHESIVE_W], args.z0 or [ADHESIVE_Z0]

rank = PETSc.COMM_WORLD.getRank()
HERE = os.path.dirname(os.path.abspath(__file__))
curves = {}


def emit(**row):
    if rank == 0:
        print(json.dumps(row), flush=True)


def gap_error(grid, a, b, z0):
    d = grid.rows(a, readonly=True) - grid.rows(b, readonly=True)
    return grid.mpi_comm.allreduce(float(np.abs(d).max()), op=__import__("mpi4py").MPI.MAX) / z0


def history_curve(pb, first_solve=0):
    """(time, FFT pairs, errors) per iteration of a problem's solves from ``first_solve`` on
    (Newton's include its relaxation fallback, recorded in the same history)."""
    recs = [r for r in pb.history.records if r.solve >= first_solve]
    t0 = recs[0].wall_time if recs else 0.0
    return [(r.wall_time - t0, r.fft_pairs, r.adhesive_error, r.complementarity_error, r.total_error)
            for r in recs]


def sphere_cases():
    R, n, dx, delta = 1000.0, 128, 1.0, 1.0
    for mu in args.mu:
        w = np.sqrt(mu ** 3 / R)
        grid = SurfaceGrid(n, n, dx, periodic=False)
        h = sphere(grid, R)
        law = make_law("hardwall-lj", work_of_adhesion=w, z0=1.0)
        ref = AdhesiveProblem(grid, h, 1.0, law, tol=1e-11, prefix="ref_", stability_check=False)
        st_ref = ref.solve(approach=delta)
        st_ref2 = ref.solve(approach=delta + 0.25)
        for solver in ("newton", "relaxation"):
            pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"s{solver}_")
            relax = RelaxationSolver(pb) if solver == "relaxation" else None
            # a cold solve (from rest), then the next point of a loading path (warm start)
            for stage, d, st_r in (("cold", delta, st_ref), ("path step", delta + 0.25, st_ref2)):
                first = pb._n_solves
                t = time.perf_counter()
                if relax is None:
                    st = pb.solve(approach=d, raise_on_failure=False)
                else:
                    st = relax.solve(approach=d, raise_on_failure=False)
                elapsed = time.perf_counter() - t
                err = gap_error(grid, st.gap, st_r.gap, 1.0)
                curves[("sphere", mu, solver, stage)] = history_curve(pb, first)
                emit(case="sphere", stage=stage, mu=mu, n=n, solver=st.solver, approach=d, time=elapsed,
                     check_time=st.check_time,
                     fft_pairs=st.fft_pairs, error=err,
                     own_error=max(st.complementarity_error, st.adhesive_error),
                     total_error=st.total_error, converged=st.converged, stable=st.stable,
                     W_star=st.force / (2 * np.pi * R * w))


def rough_cases():
    comm = PETSc.COMM_WORLD.tompi4py()
    for n in args.sizes:
        grid, h, _ = rough_surface(n)
        dx = grid.dx
        for w_rel in args.w:
            for z0_rel in args.z0:
                z0, w = z0_rel * dx, w_rel * dx
                law = adhesive_law(grid, w_rel, z0_rel)
                approaches = args.approaches or calibrate(grid, h, law, args.areas, max_n=args.calibrate_max_n)
                if approaches is None:
                    emit(case="rough", n=n, w=w_rel, z0=z0_rel, solver="calibration", converged=False,
                         message="the calibration sweep converged at fewer than two approaches")
                    continue
                ref = AdhesiveProblem(grid, h, 1.0, law, prefix="ref_", tol=1e-11, stability_check=False)
                refs = [ref.solve(approach=d, raise_on_failure=False) for d in approaches]
                for i, tol in enumerate(args.tol):
                    # each tolerance runs the whole path afresh (same warm starts)
                    # isolated states: no per-state stiffness (the peer computes none; the
                    # tangent is still solved where a predictor needs it); the command line wins
                    opts = PETSc.Options(f"ours{i}_")
                    if not opts.hasName("stiffness"):
                        opts.setValue("stiffness", False)
                    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"ours{i}_", tol=tol)
                    for d, st_ref in zip(approaches, refs):
                        t = time.perf_counter()
                        st = pb.solve(approach=d, raise_on_failure=False)
                        elapsed = time.perf_counter() - t
                        emit(case="rough", n=n, w=w_rel, z0=z0_rel, solver=st.solver, tol=tol, approach=d,
                             time=elapsed, check_time=st.check_time,
                             fft_pairs=st.fft_pairs, newton=st.newton_iterations,
                             krylov=st.linear_iterations, error=gap_error(grid, st.gap, st_ref.gap, z0),
                             own_error=max(st.complementarity_error, st.adhesive_error),
                             contact_fraction=st.contact_fraction, converged=st.converged, stable=st.stable,
                             ranks=comm.Get_size())
                if args.no_peer:
                    continue
                hg = grid.gather(h, root=0)
                ref_gaps = [grid.gather(s.gap, root=0) for s in refs]
                if rank == 0:
                    with tempfile.TemporaryDirectory() as tmp:
                        path = os.path.join(tmp, "heights.npy")
                        np.save(path, hg)
                        rows, err = json_rows(cm_adhesion_command(args.peer_python, path, dx, w, z0, args.potential,
                                                              approaches, tmp, args.peer_maxiter))
                        if err:
                            emit(case="rough", n=n, w=w_rel, z0=z0_rel, solver="contactmechanics+adhesion",
                                 converged=False, message=err)
                        for row, gref in zip(rows, ref_gaps):
                            fld = os.path.join(tmp, f"cm_{row['approach']!r}_gap.npy")
                            gap_err = float("nan")
                            if os.path.exists(fld):
                                gap_err = float(np.abs(np.load(fld) - gref).max()) / z0
                            emit(case="rough", n=n, w=w_rel, z0=z0_rel, solver=f"cm+adhesion-{args.potential}",
                                 approach=row["approach"], time=row["time"],
                                 fft_pairs=row.get("fft_pairs", float("nan")), error=gap_err,
                                 own_error=row.get("error"), contact_fraction=row.get("contact_fraction"),
                                 converged=row.get("converged"), message=row.get("message", ""))
                comm.Barrier()


def plot(directory):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    os.makedirs(directory, exist_ok=True)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4), sharey=True)
    for ax, stage in zip(axes, ("cold", "path step")):
        for (case, mu, solver, st), c in curves.items():
            if st != stage or not c:
                continue
            ax.semilogy([r[0] for r in c], [r[2] for r in c], marker="o" if solver == "newton" else ".",
                        ms=3, label=f"{solver}, Tabor {mu:g}")
        ax.set_xlabel("wall time [s]")
        ax.set_title({"cold": "from rest to delta = z0", "path step": "next path step, delta = 1.25 z0"}[stage])
        ax.legend()
    axes[0].set_ylabel("self-consistency error max K_ii |a - a(g)| / z0")
    fig.suptitle("Sphere R = 1000 z0, hard-wall LJ, n = 128 (run_scripts/bench/bench_adhesion.py)")
    fig.tight_layout()
    fig.savefig(os.path.join(directory, "adhesion_error_vs_time_sphere.png"), dpi=120)


if "sphere" in args.cases:
    sphere_cases()
if "rough" in args.cases:
    rough_cases()
if args.plot and rank == 0 and curves:
    plot(args.plot)
