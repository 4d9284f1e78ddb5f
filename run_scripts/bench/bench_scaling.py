#!/usr/bin/env python3
"""Benchmark: grid scaling and MPI scaling of the non-adhesive rough solve.

The benchmark surface of ``examples/scenes/bench_rough.toml`` (built by
``rough_surface.py``), E* = 1, mean pressure 0.005 E*, solved by
``ContactProblem.solve(mean_pressure=...)`` (SNES VI Newton, nested
iteration, load control) to a complementarity error of --tol of the rms
height.  One JSON line per (n, solver) case with

* ``time`` [s]: wall time of ``solve`` (maximum over ranks), ``t_setup``:
  building the problem (operator, FFTW planning);
* ``fft_pairs`` (coarse grids weighted by size), ``newton``, ``krylov``;
* memory: ``rss_base_mb`` (VmRSS before the case: interpreter, PETSc,
  earlier cases' freed pages excluded), ``peak_surface_mb`` (VmHWM while
  the surface is generated), ``peak_solve_mb`` (VmHWM from the problem's
  construction to the end of the solve, after resetting the high-water mark
  through /proc/self/clear_refs), ``doubles_per_point`` =
  (peak_solve - rss_base) / (8 B * n^2 / ranks), summed over ranks on a
  node, i.e. per grid point of the whole problem;
* MPI: ``alltoall_bytes_per_apply`` measured (the payload the FFT passed to
  Alltoallv, summed over ranks, one forward + one backward transform,
  self-blocks excluded) against ``alltoall_bytes_model``, computed from the
  decomposition alone (``transpose_bytes.py``: slabs, or px x py blocks with
  ``-grid_px``); ``px``, ``py`` the process grid.

Usage (one process per size keeps the memory figures clean)::

    .venv/bin/python run_scripts/bench/bench_scaling.py --sizes 256 512 1024 2048
    mpirun -n 2 .venv/bin/python run_scripts/bench/bench_scaling.py --sizes 1024 2048
    .venv/bin/python run_scripts/bench/bench_scaling.py --sizes 4096 -log_view
    .venv/bin/python run_scripts/bench/bench_scaling.py --sizes 8192 --solvers spectral --check-error
    mpirun -n 4 .venv/bin/python run_scripts/bench/bench_scaling.py --sizes 1024 -grid_px 2   # 2 x 2 blocks

``--separate`` runs every size in a fresh process of the same launcher
(serial only).  Timed runs belong behind ``flock /tmp/contactpetsc-bench.lock``.
"""
import argparse
import json
import subprocess
import sys
import time

import petsc4py

from bench_args import reset_peak, status_kb

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024, 2048])
ap.add_argument("--solvers", nargs="+", default=["spectral"],
                help="preconditioners (-contact_preconditioner values): spectral, mlmi, none")
ap.add_argument("--tol", type=float, default=1e-8)
ap.add_argument("--mean-pressure", type=float, default=0.005)
ap.add_argument("--separate", action="store_true",
                help="run each size in its own process (serial runs: clean memory figures)")
ap.add_argument("--save-pressure", default=None,
                help="write the pressure (npy, rank 0, gathered) of the last case to this path "
                     "(rank-count comparisons)")
args, petsc_args = ap.parse_known_args()

if args.separate and len(args.sizes) > 1:
    rest = [a for a in sys.argv[1:] if a != "--separate"]
    i = rest.index("--sizes")
    j = i + 1
    while j < len(rest) and rest[j].isdigit():
        j += 1
    for n in args.sizes:
        subprocess.run([sys.executable, sys.argv[0], *rest[:i], "--sizes", str(n), *rest[j:]], check=True)
    sys.exit(0)

petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers import ContactProblem  # noqa: E402

from rough_surface import rough_scene, rough_surface  # noqa: E402
from transpose_bytes import transpose_bytes  # noqa: E402

E_STAR, L = rough_scene(64)["material"]["e_star"], 1.0
comm = PETSc.COMM_WORLD.tompi4py()
rank, size = comm.Get_rank(), comm.Get_size()


def node_sum_mb(kb: int) -> float:
    return comm.allreduce(kb) / 1024.0


for n in args.sizes:
    for solver in args.solvers:
        PETSc.garbage_cleanup(PETSc.COMM_WORLD)
        base = status_kb("VmRSS")
        reset_peak()
        g, h, _ = rough_surface(n, row_alignment=64)
        peak_surface = status_kb("VmHWM")
        reset_peak()
        t0 = time.perf_counter()
        prob = ContactProblem(g, h, E_STAR, preconditioner=solver, tol=args.tol, prefix="contact_")
        prob.snes()
        t_setup = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        bytes0, calls0 = prob.op.fft.alltoall_bytes, prob.op.fft.fft_pairs
        comm.Barrier()
        t0 = time.perf_counter()
        st = prob.solve(mean_pressure=args.mean_pressure * E_STAR, raise_on_failure=False)
        t = comm.allreduce(time.perf_counter() - t0, op=MPI.MAX)
        peak_solve = status_kb("VmHWM")
        fft = prob.op.fft
        applies = fft.fft_pairs - calls0
        sent = comm.allreduce(fft.alltoall_bytes - bytes0)
        pts = float(n) * n
        res = dict(
            n=n, solver=solver, ranks=size, time=t, t_setup=t_setup, fft_pairs=st.fft_pairs,
            newton=st.newton_iterations, krylov=st.linear_iterations,
            error=st.complementarity_error, load_error=st.load_error, converged=st.converged,
            contact_fraction=st.contact_fraction, approach=st.approach,
            rss_base_mb=node_sum_mb(base), peak_surface_mb=node_sum_mb(peak_surface),
            peak_solve_mb=node_sum_mb(peak_solve),
            doubles_per_point=(comm.allreduce(peak_solve - base) * 1024.0) / (8 * pts),
            alltoall_bytes_per_apply=(sent / applies if applies else 0.0),
            alltoall_bytes_model=transpose_bytes(fft), px=g.px, py=g.py,
            fine_applies=applies, time_per_fine_pair=t / max(st.fft_pairs, 1))
        PETSc.Sys.Print(json.dumps(res))
        if args.save_pressure:
            full = g.gather(st.pressure, root=0)
            if rank == 0:
                np.save(args.save_pressure, full)
        del prob, st, h, g
