#!/usr/bin/env python3
"""Benchmark: rough periodic Signorini contact, ours against Tamaas' PKR.

The benchmark surface of ``examples/scenes/bench_rough.toml`` (periodic unit
cell, self-affine, built by ``rough_surface.py``), E* = 1, mean pressure
0.005 E*.  For each n in --sizes:

* ours: ``ContactProblem.solve(mean_pressure=...)`` with each preconditioner
  in --solvers (``none`` = ``-pc_type none``, only up to --none-max-n),
  to a complementarity error max |min(K_ii p, g)| <= --tol of
  the rms height (our measure; load error <= 1e-10);
* the peers in --peers, on the same heights (saved as .npy), each in its
  venv from ``run_scripts/peers/setup_peers.sh`` and with its own error
  measure <= --peer-tol (default --tol): ``tamaas`` (Tamaas' PolonskyKeerRey,
  ``run_scripts/peers/tamaas_signorini.py``) and ``cm`` (ContactMechanics'
  bound-constrained CG, NuMPI's CCGWithoutRestart with a prescribed mean,
  ``run_scripts/peers/cm_signorini.py``); we then recompute OUR
  complementarity measure on each peer's returned p (gap recomputed with our
  operator, delta as the peer returned it).

Usage::

    .venv/bin/python run_scripts/bench/bench_signorini.py [--sizes 256 512 1024 2048]
        [--solvers spectral mlmi none] [--none-max-n 1024] [--peers tamaas cm | --no-peer]
        [--tol 1e-8]
        [--repeats 3] [--profile] [PETSc options, e.g. -log_view]
    mpirun -n 2 .venv/bin/python run_scripts/bench/bench_signorini.py ...   (ours on 2 ranks;
        the peers run serially on rank 0)

Times: ours = wall time of ``solve`` (includes the coarse-grid set-up of the
nested iteration, excludes building the fine operator, reported as t_setup),
the median of --repeats solves on fresh problems (same operator; the counts are
the same every time); a peer = its ``solve`` only.  FFT pairs: ours counts every
FFT pair, coarse grids weighted by their size; Tamaas = 2 per iteration + 1; cm =
its substrate's operator evaluations, counted (2 per iteration + 1).
``error``: our complementarity measure max |min(K_ii p, g)| / rms(h) recomputed
from the returned pressure and approach (independent of the solver's own test).
``t_pair``: a bare single-threaded FFTW r2c + c2r pair of the grid's size
(FFTW_MEASURE, out of place, ``execute()`` only; the median of runs before and
after each solve), on rank 0; ``bound`` = FFT pairs x t_pair, ``ratio`` = time /
bound (goal: <= 1.25 at n >= 1024 on one rank, docs/performance.md).
``peer_error``: a peer's own convergence measure (Tamaas: pressure-weighted mean
gap / rms(h); cm: largest projected gap residual / rms(h)).
Output: a table, then one JSON line per case with n, solver, time, fft_pairs, error, ratio.
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

import petsc4py

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024, 2048])
ap.add_argument("--solvers", nargs="+", default=["spectral", "mlmi", "none"],
                help="preconditioners (-contact_preconditioner values): spectral, mlmi, none")
ap.add_argument("--none-max-n", type=int, default=1024,
                help="skip the unpreconditioned solver (none) above this n (it is slow)")
ap.add_argument("--tol", type=float, default=1e-8)
ap.add_argument("--peer-tol", type=float, default=None,
                help="the peers' tolerance on their own measures (default --tol): their measures are "
                     "not ours, and a tighter one brings their fields to our error --tol")
ap.add_argument("--repeats", type=int, default=3, help="solves per case; the time is their median")
ap.add_argument("--profile", action="store_true",
                help="cProfile our solves (rank 0) and print the 25 entries of largest own time")
ap.add_argument("--mean-pressure", type=float, default=0.005)
ap.add_argument("--peers", nargs="*", choices=["tamaas", "cm"], default=["tamaas", "cm"],
                help="peer codes run on each size (none: --no-peer)")
ap.add_argument("--no-peer", action="store_true", help="no peer (same as --peers with no name)")
PEER_VENV = os.environ.get("CONTACTPETSC_PEER_VENV", os.path.expanduser("~/.cache/contactpetsc/peer-venv"))
ap.add_argument("--peer-python", default=os.environ.get("CONTACTPETSC_PEER_PYTHON",
                                                        os.path.join(PEER_VENV, "bin", "python")),
                help="interpreter of the Tamaas peer venv")
ap.add_argument("--cm-python", default=os.path.join(PEER_VENV + "-cm", "bin", "python"),
                help="interpreter of the ContactMechanics peer venv")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry import surfaces  # noqa: E402
from contactpetsc.solvers import ContactProblem  # noqa: E402

from rough_surface import rough_scene, rough_surface  # noqa: E402

E_STAR, L = rough_scene(64)["material"]["e_star"], 1.0
comm = PETSc.COMM_WORLD.tompi4py()
rank = comm.Get_rank()
HERE = os.path.dirname(os.path.abspath(__file__))
PEERS_DIR = os.path.join(HERE, os.pardir, "peers")
# peer -> (interpreter, runner script, row name, key of its own error measure in the runner's JSON)
PEERS = {"tamaas": (args.peer_python, "tamaas_signorini.py", "tamaas-pkr", "tamaas_error"),
         "cm": (args.cm_python, "cm_signorini.py", "cm-ccg", "cm_error")}


def pair_timer(n):
    """A function timing one bare FFTW r2c + c2r pair of an n x n grid [s] (rank 0; None elsewhere)."""
    import pyfftw
    if rank != 0:
        return lambda: None
    a = pyfftw.empty_aligned((n, n), "float64")
    spec = pyfftw.empty_aligned((n, n // 2 + 1), "complex128")
    b = pyfftw.empty_aligned((n, n), "float64")
    fwd = pyfftw.FFTW(a, spec, axes=(0, 1), flags=("FFTW_MEASURE",), threads=1)
    bwd = pyfftw.FFTW(spec, b, axes=(0, 1), direction="FFTW_BACKWARD", flags=("FFTW_MEASURE", "FFTW_DESTROY_INPUT"),
                      threads=1)
    a[...] = np.random.default_rng(99).random((n, n))

    def timed(reps=max(3, 2 ** 22 // (n * n))):
        out = []
        for _ in range(reps):
            t = time.perf_counter()
            fwd.execute()
            bwd.execute()
            out.append(time.perf_counter() - t)
        return float(np.median(out))
    return timed


def our_measure(op, p_rows, h_rows, delta, scale):
    gap = op.apply(p_rows, np.empty_like(p_rows)) + h_rows - delta
    err = float(np.abs(np.minimum(op.self_influence * p_rows, gap)).max())
    return op.grid.mpi_comm.allreduce(err, op=MPI.MAX) / scale


profiler = None
if args.profile:
    import cProfile
    import pstats
    profiler = cProfile.Profile()
results = []
tmpdir = comm.bcast(tempfile.mkdtemp(prefix="bench-signorini-") if rank == 0 else None)
for n in args.sizes:
    g, h, _ = rough_surface(n, row_alignment=64)
    rms = surfaces.rms_height(g, h)
    op = None
    for solver in args.solvers:
        if solver == "none" and n > args.none_max_n:
            PETSc.Sys.Print(f"skipping solver none at n={n} (> --none-max-n {args.none_max_n})")
            continue
        times, pair_times = [], []
        for k in range(args.repeats):
            t0 = time.perf_counter()
            prob = ContactProblem(g, h, E_STAR, preconditioner=solver, tol=args.tol,
                                  prefix=f"b{n}{solver}{k}_", operator=op)
            if op is None:
                op, timer = prob.op, pair_timer(n)   # the pair planned after the operator: its wisdom
            t_setup = time.perf_counter() - t0
            pair_times.append(timer())
            comm.Barrier()
            t0 = time.perf_counter()
            if profiler:
                profiler.enable()
            st = prob.solve(mean_pressure=args.mean_pressure * E_STAR, raise_on_failure=False)
            if profiler:
                profiler.disable()
            times.append(comm.allreduce(time.perf_counter() - t0, op=MPI.MAX))
            pair_times.append(timer())
            prob.destroy()
        t = float(np.median(times))
        t_pair = comm.bcast(float(np.median(pair_times)) if rank == 0 else None, root=0)
        err = our_measure(op, g.rows(st.pressure, readonly=True), g.rows(h, readonly=True),
                          st.approach, rms)
        results.append(dict(n=n, solver=solver, ranks=comm.Get_size(), time=t, times=times, t_setup=t_setup,
                            fft_pairs=st.fft_pairs, newton=st.newton_iterations,
                            krylov=st.linear_iterations, error=err, load_error=st.load_error,
                            converged=st.converged, contact_fraction=st.contact_fraction,
                            t_pair=t_pair, ratio=t / (st.fft_pairs * t_pair)))
        PETSc.Sys.Print(json.dumps(results[-1]))
    if args.no_peer or not args.peers:
        continue
    full = g.gather(h, root=0)
    hpath = os.path.join(tmpdir, f"h{n}.npy")
    if rank == 0:
        np.save(hpath, full)
    for peer in args.peers:
        python, script, name, own_key = PEERS[peer]
        res = None
        if rank == 0:
            out = os.path.join(tmpdir, f"{peer}{n}.npz")
            try:
                cp = subprocess.run([python, os.path.join(PEERS_DIR, script), hpath, "--length", str(L),
                                     "--estar", str(E_STAR), "--mean-pressure", str(args.mean_pressure * E_STAR),
                                     "--tol", str(args.peer_tol or args.tol), "--out", out],
                                    capture_output=True, text=True, check=True)
                res = json.loads(cp.stdout.strip().splitlines()[-1])
                z = np.load(out)
                res["_p"], res["_delta"] = z["pressure"], float(z["delta"])
            except Exception as exc:  # noqa: BLE001
                res = {"failed": f"{type(exc).__name__}: {exc}"}
        res = comm.bcast(res, root=0)
        if "failed" in res:
            PETSc.Sys.Print(f"peer {peer} failed at n={n}: {res['failed']}")
            continue
        p_rows = np.ascontiguousarray(res["_p"].T[g.ys:g.ye])   # (nx, ny) -> our rows (ny_loc, nx)
        err = our_measure(op, p_rows, g.rows(h, readonly=True), res["_delta"], rms)
        results.append(dict(n=n, solver=name, ranks=1, time=res["time"], t_setup=None,
                            fft_pairs=res["fft_pairs"], t_pair=t_pair,
                            ratio=res["time"] / (res["fft_pairs"] * t_pair),
                            newton=None, krylov=res["iterations"],
                            error=err, peer_error=res[own_key],
                            load_error=res["mean_pressure_rel_err"], converged=res["converged"],
                            contact_fraction=res["contact_fraction"]))
        PETSc.Sys.Print(json.dumps(results[-1]))

PETSc.Sys.Print("\n   n  solver        ranks   time[s]  setup[s]  Newton  Krylov  FFT pairs  compl.err  load err"
                "  t_pair[ms]  bound[s]  ratio")
for r in results:
    PETSc.Sys.Print(f"{r['n']:5d}  {r['solver']:12s} {r['ranks']:5d} {r['time']:9.3f} "
                    f"{(r['t_setup'] or 0):9.2f} {str(r['newton']):>7s} {str(r['krylov']):>7s} "
                    f"{r['fft_pairs']:10.1f} {r['error']:10.2e} {r['load_error']:9.1e} "
                    f"{r['t_pair'] * 1e3:11.3f} {r['fft_pairs'] * r['t_pair']:9.3f} {r['ratio']:6.2f}")
for r in results:
    PETSc.Sys.Print(json.dumps({k: r[k] for k in ("n", "solver", "time", "fft_pairs", "error", "ratio")}))
if profiler and rank == 0:
    pstats.Stats(profiler).sort_stats("tottime").print_stats(25)
