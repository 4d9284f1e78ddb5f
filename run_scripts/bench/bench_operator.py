#!/usr/bin/env python3
"""Benchmark of one elastic operator apply against a raw pyfftw FFT pair.

For each n in --sizes and each kind in --kinds this times one apply v = K p of

* ``periodic``: ``PeriodicHalfSpace`` on a periodic n x n grid (transform n x n),
* ``isolated``: ``IsolatedHalfSpace`` on an isolated n x n grid (padded 2n x 2n),

through the pure-numpy rows path ``op.apply(grid.rows(x, readonly=True),
grid.rows(y))`` and through the PETSc shell Mat ``K.mult(x, y)``, against the
reference ``t_fft_pair``: a raw single-rank, single-thread pyfftw 2-D r2c plus
c2r pair of the same transform size (FFTW_MEASURE, out-of-place,
``execute()`` only, no normalisation), measured in the same run.

Usage
-----
Everything (1 and 2 ranks, the combined table, the speed-up lines, then the
JSON lines)::

    python run_scripts/bench/bench_operator.py [--ranks 1 2] [--sizes 256 512 ...]
        [--kinds periodic isolated] [--repeats K] [--markdown] [PETSc options]

Run without an MPI launcher, the script is a *launcher*: it runs itself as a
worker under ``mpirun -n R`` for each R in --ranks (setting the OpenMPI
run-as-root variables when run as root, and OMP_NUM_THREADS=1) and combines
the workers' results.  One worker alone::

    mpirun -n R python run_scripts/bench/bench_operator.py [--sizes ...] [--kinds ...]
        [--repeats K] [-log_view] [-elastic_fft_planner measure]

(``--worker`` forces worker mode in a single process without mpirun.)  Options
this script does not know are handed to PETSc (``petsc4py.init``), so
``-log_view`` shows the CPFFTForward/CPFFTBackward/CPElasticMult events and
``-elastic_fft_planner`` sets the library's FFTW planner (default measure).

Output: a human-readable table (the launcher adds the speed-ups; --markdown
also prints it as Markdown), then, last, one JSON line per case with the
keys ``n, kind, ranks, t_apply, t_fft_pair, ratio`` (seconds; ratio =
t_apply / t_fft_pair).

Method
------
* All plans and buffers are made before timing (planning is not counted);
  one untimed warm-up of each measurement follows.
* The machine is noisy, so the measurements are interleaved (apply, Mat mult,
  FFT pair[, 1-rank apply]; the order rotates every repeat) for at least K repeats and at
  least --min-time seconds (default 3), and medians are quoted.  Default K:
  15 for n <= 1024, 9 for n = 2048, 5 for n = 4096.
* Other processes: the CPU time the whole machine used during a case
  (/proc/stat) minus the benchmark's own, per second, is the "foreign load"
  in cores.  A case with more than --max-foreign (0.25) cores is measured
  again after --retry-wait seconds, at most --retries (3) times, and the
  quietest attempt is kept.  The table shows the foreign load, so a
  disturbed figure is visible.
* A multi-rank apply starts after a barrier and its time is the maximum over
  the ranks.
* The reference pair is always single-rank: rank 0 times it while every other
  rank waits in a *sleeping* non-blocking barrier (Ibarrier + Test + sleep),
  so that no rank busy-polls a core during the measurement.  Rank-0-only code
  contains no collective.  On R ranks the reference is thus the single-rank
  pair measured inside the R-rank run, interleaved with the applies it is
  compared with; the launcher also shows the pair measured in the 1-rank run
  for comparison.
* Speed-up: t_apply(1 rank) / t_apply(R ranks) compares two
  separate mpirun runs, minutes apart, so it also contains any drift of the
  machine's speed in between.  On R > 1 ranks the worker therefore also times
  the same operator built on rank 0 alone (COMM_SELF), interleaved with the
  R-rank apply while the other ranks sleep, and reports the "in-run"
  speed-up from it (--no-serial-in-run skips this and its memory).
* ``petsc4py.init`` is called (by the worker only, before any PETSc import)
  with the options this script does not parse; the launcher itself never
  initialises MPI.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import time

DETAIL = "BENCH-DETAIL "
KINDS = ("periodic", "isolated")


def default_repeats(n: int) -> int:
    return 15 if n <= 1024 else 9 if n <= 2048 else 5


def parse_args(argv):
    p = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0],
        epilog="Unknown options (e.g. -log_view) are passed to PETSc.")
    p.add_argument("--sizes", type=int, nargs="+", default=[256, 512, 1024, 2048, 4096])
    p.add_argument("--kinds", nargs="+", choices=KINDS, default=list(KINDS))
    p.add_argument("--repeats", type=int, default=None,
                   help="repeats per case (default 15 for n <= 1024, 9 for 2048, 5 above)")
    p.add_argument("--min-time", type=float, default=3.0,
                   help="repeat until at least this many seconds were measured per case (default 3)")
    p.add_argument("--max-foreign", type=float, default=0.25,
                   help="measure a case again if other processes used more than this many "
                        "cores meanwhile (default 0.25)")
    p.add_argument("--retries", type=int, default=3,
                   help="at most this many re-measurements per case (default 3)")
    p.add_argument("--retry-wait", type=float, default=20.0,
                   help="seconds to wait before a re-measurement (default 20)")
    p.add_argument("--ranks", type=int, nargs="+", default=[1, 2],
                   help="launcher: rank counts to run (default 1 2)")
    p.add_argument("--markdown", action="store_true",
                   help="launcher: also print the table as Markdown")
    p.add_argument("--mpirun", default="mpirun", help="launcher: MPI launcher command")
    p.add_argument("--worker", action="store_true",
                   help="run the measurement in this process (implied under mpirun)")
    p.add_argument("--no-serial-in-run", action="store_true",
                   help="on several ranks, do not also time the 1-rank apply on rank 0 "
                        "(saves the memory of a second, serial operator)")
    p.add_argument("--emit-detail", action="store_true", help=argparse.SUPPRESS)
    return p.parse_known_args(argv)


def under_mpi_launcher() -> bool:
    return any(k in os.environ for k in ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK",
                                         "MPI_LOCALNRANKS", "HYDI_CONTROL_FD"))


def machine_busy_seconds() -> float:
    """CPU time used by all processes on the machine so far (Linux /proc/stat), s."""
    try:
        with open("/proc/stat") as fh:
            v = [int(t) for t in fh.readline().split()[1:9]]
    except (OSError, ValueError):
        return float("nan")
    return (sum(v) - v[3] - v[4]) / os.sysconf("SC_CLK_TCK")   # minus idle and iowait


def own_cpu_seconds() -> float:
    t = os.times()
    return t.user + t.system


def median(xs):
    s = sorted(xs)
    m = len(s) // 2
    return s[m] if len(s) % 2 else 0.5 * (s[m - 1] + s[m])


# =============================================================================
# worker
# =============================================================================
def worker(args, petsc_argv):
    import petsc4py
    petsc4py.init(petsc_argv)
    import gc

    import numpy as np
    import pyfftw
    from mpi4py import MPI
    from petsc4py import PETSc

    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.operators.elastic import IsolatedHalfSpace, PeriodicHalfSpace

    comm = PETSc.COMM_WORLD.tompi4py()
    rank, size = comm.Get_rank(), comm.Get_size()
    clock = time.perf_counter

    def idle_barrier():
        """Barrier in which ranks other than 0 sleep instead of busy-polling a core."""
        req = comm.Ibarrier()
        if rank == 0:
            req.Wait()
        else:
            while not req.Test():
                time.sleep(2e-4)

    def log(msg):
        if rank == 0:
            print(msg, file=sys.stderr, flush=True)

    results = []
    for n in args.sizes:
        for kind in args.kinds:
            repeats = args.repeats or default_repeats(n)
            periodic = kind == "periodic"
            N = n if periodic else 2 * n
            # --- set-up (not timed beyond the planning report) ----------------
            t0 = clock()
            grid = SurfaceGrid(n, n, 1.0 / n, periodic=periodic)
            op = (PeriodicHalfSpace if periodic else IsolatedHalfSpace)(grid, 1.0)
            K = op.as_mat()
            x, y, y2 = grid.create_vec(), grid.create_vec(), grid.create_vec()
            rng = np.random.default_rng(1234 + grid.ys)
            grid.rows(x)[...] = rng.random((grid.ny_local, n))
            comm.Barrier()
            t_setup = comm.allreduce(clock() - t0, op=MPI.MAX)

            t_plan_pair = 0.0
            serial = size > 1 and not args.no_serial_in_run
            if rank == 0:  # rank-0-only: no collectives on COMM_WORLD in here
                if serial:
                    # the same operator on rank 0 alone (COMM_SELF), timed while the
                    # other ranks sleep: a 1-rank apply interleaved with the R-rank one
                    sgrid = SurfaceGrid(n, n, 1.0 / n, periodic=periodic, comm=PETSc.COMM_SELF)
                    sop = (PeriodicHalfSpace if periodic else IsolatedHalfSpace)(sgrid, 1.0)
                    sx = np.random.default_rng(7).random((n, n))
                    sy = np.empty_like(sx)
                t0 = clock()
                a = pyfftw.empty_aligned((N, N), "float64")
                spec = pyfftw.empty_aligned((N, N // 2 + 1), "complex128")
                b = pyfftw.empty_aligned((N, N), "float64")
                fwd = pyfftw.FFTW(a, spec, axes=(0, 1), flags=("FFTW_MEASURE",), threads=1)
                bwd = pyfftw.FFTW(spec, b, axes=(0, 1), direction="FFTW_BACKWARD",
                                  flags=("FFTW_MEASURE",), threads=1)
                a[...] = np.random.default_rng(99).random((N, N))
                t_plan_pair = clock() - t0
            idle_barrier()
            log(f"# n={n} {kind} ranks={size}: operator set-up {t_setup:.2f} s, "
                f"raw pair planning {t_plan_pair:.2f} s")

            xr = grid.rows(x, readonly=True)   # views stay valid: arrays are not restored
            yr = grid.rows(y)

            def collective_time(fn, *args):
                """Wall time of fn(*args) on the slowest rank, all ranks starting together."""
                comm.Barrier()
                t = clock()
                fn(*args)
                t = clock() - t
                return comm.allreduce(t, op=MPI.MAX)

            def m_apply():
                return collective_time(op.apply, xr, yr)

            def m_mult():
                return collective_time(K.mult, x, y2)

            def m_pair():
                comm.Barrier()
                t = 0.0
                if rank == 0:  # others sleep in idle_barrier
                    t = clock()
                    fwd.execute()
                    bwd.execute()
                    t = clock() - t
                idle_barrier()
                return comm.bcast(t, root=0)

            def m_serial():
                comm.Barrier()
                t = 0.0
                if rank == 0:  # others sleep in idle_barrier
                    t = clock()
                    sop.apply(sx, sy)
                    t = clock() - t
                idle_barrier()
                return comm.bcast(t, root=0)

            meas = {"apply": m_apply, "mult": m_mult, "pair": m_pair}
            if serial:
                meas["serial"] = m_serial
            names = list(meas)
            nm = len(names)
            for name in names:          # warm-up
                meas[name]()

            def measure():
                """Interleaved repeats; returns (times, foreign CPU load in cores)."""
                times = {name: [] for name in names}
                comm.Barrier()
                own0, busy0, w0 = own_cpu_seconds(), machine_busy_seconds(), clock()
                r = 0
                while True:
                    order = names[r % nm:] + names[:r % nm]
                    for name in order:
                        times[name].append(meas[name]())
                    r += 1
                    more = r < repeats or clock() - w0 < args.min_time
                    if not comm.bcast(more, root=0):   # rank 0's clock decides
                        break
                comm.Barrier()
                wall = clock() - w0
                own = comm.allreduce(own_cpu_seconds() - own0, op=MPI.SUM)
                foreign = (machine_busy_seconds() - busy0 - own) / wall
                return times, comm.bcast(foreign, root=0)

            attempts = []
            for attempt in range(1 + args.retries):
                attempts.append(measure())
                foreign = attempts[-1][1]
                if not foreign > args.max_foreign:   # also stops on nan (no /proc/stat)
                    break
                if attempt < args.retries:
                    log(f"#   foreign CPU load {foreign:.2f} cores > {args.max_foreign}: "
                        f"measuring again in {args.retry_wait:g} s")
                    time.sleep(args.retry_wait)
            times, foreign = min(attempts, key=lambda a: a[1] if a[1] == a[1] else 0.0)

            # sanity: the Mat path gives the same result as the rows path
            err = comm.allreduce(float(np.max(np.abs(grid.rows(y2, readonly=True) - yr))),
                                 op=MPI.MAX)
            scale = comm.allreduce(float(np.max(np.abs(yr))), op=MPI.MAX)
            if not err <= 1e-12 * scale:
                raise RuntimeError(f"K.mult and op.apply disagree: {err:g} vs scale {scale:g}")

            t_apply, t_mult, t_pair = (median(times[k]) for k in ("apply", "mult", "pair"))
            t_serial = median(times["serial"]) if serial else None
            rec = dict(n=n, kind=kind, ranks=size, t_apply=t_apply, t_fft_pair=t_pair,
                       ratio=t_apply / t_pair, t_mult=t_mult, repeats=len(times["apply"]),
                       foreign_load=foreign, attempts=len(attempts),
                       t_apply_min=min(times["apply"]), t_pair_min=min(times["pair"]),
                       t_mult_min=min(times["mult"]),
                       ratio_paired=median([p / q for p, q in zip(times["apply"], times["pair"])]),
                       t_setup=t_setup, t_plan_pair=t_plan_pair, transform=N,
                       t_apply_1rank_in_run=t_serial,
                       speedup_in_run=None if t_serial is None else t_serial / t_apply)
            results.append(rec)
            if serial:
                log(f"#   1-rank apply in this run {t_serial * 1e3:.2f} ms, "
                    f"speed-up {t_serial / t_apply:.2f}")
            log(f"#   t_apply {t_apply * 1e3:.2f} ms, t_mult {t_mult * 1e3:.2f} ms, "
                f"t_fft_pair {t_pair * 1e3:.2f} ms, ratio {t_apply / t_pair:.3f}, "
                f"{len(times['apply'])} repeats, foreign load {foreign:.2f} cores")

            # --- free this case before the next (collective destroys) ---------
            K.destroy()
            for v in (x, y, y2):
                v.destroy()
            grid.da.destroy()
            del xr, yr, op, K, grid, x, y, y2
            if rank == 0:
                del fwd, bwd, a, b, spec
                if serial:
                    sgrid.da.destroy()
                    del sop, sgrid, sx, sy
            gc.collect()

    if rank == 0:
        print_table(results)
        if args.emit_detail:  # for the launcher
            for rec in results:
                print(DETAIL + json.dumps(rec))
        for rec in results:
            print(json.dumps(core(rec)))
        sys.stdout.flush()


def core(rec):
    return {k: rec[k] for k in ("n", "kind", "ranks", "t_apply", "t_fft_pair", "ratio")}


# =============================================================================
# output
# =============================================================================
def speedups(results):
    """{(n, kind, R): t_apply(1 rank) / t_apply(R ranks)} from separate runs, R > 1."""
    by = {(r["n"], r["kind"], r["ranks"]): r for r in results}
    return {(n, k, R): by[(n, k, 1)]["t_apply"] / by[(n, k, R)]["t_apply"]
            for (n, k, R) in by if R > 1 and (n, k, 1) in by}


def table_rows(results):
    sp = speedups(results)
    pair1 = {(r["n"], r["kind"]): r["t_fft_pair"] for r in results if r["ranks"] == 1}
    ms = lambda t: "-" if t is None else f"{t * 1e3:.2f}"   # noqa: E731
    rows = []
    for r in sorted(results, key=lambda r: (KINDS.index(r["kind"]), r["n"], r["ranks"])):
        key = (r["n"], r["kind"])
        s = sp.get((*key, r["ranks"]))
        s_run = r.get("speedup_in_run")
        rows.append([
            str(r["n"]), r["kind"], f"{r['transform']}^2", str(r["ranks"]),
            ms(r["t_apply"]), ms(r["t_fft_pair"]), f"{r['ratio']:.3f}",
            ms(r["t_mult"]), f"{r['t_mult'] / r['t_apply']:.3f}",
            "-" if s is None else f"{s:.2f}",
            ms(r.get("t_apply_1rank_in_run")),
            "-" if s_run is None else f"{s_run:.2f}",
            ms(pair1.get(key) if r["ranks"] > 1 else None),
            str(r["repeats"]), f"{max(r['foreign_load'], 0.0):.2f}",
        ])
    return rows


HEADER = ["n", "kind", "FFT", "ranks", "t_apply", "t_fft_pair", "ratio", "t_mult",
          "mult/apply", "speed-up", "1-rank apply in run", "speed-up in run",
          "pair in 1-rank run", "repeats", "foreign load"]
NOTES = """\
times in ms, medians over the repeats; FFT = transform size.
ratio = t_apply / t_fft_pair, t_fft_pair = raw single-rank pyfftw r2c + c2r of the FFT size
  (on R ranks: timed on rank 0 inside the R-rank run while the other ranks sleep).
t_mult = the same apply through the PETSc shell Mat (K.mult(x, y)).
speed-up = t_apply(1 rank, 1-rank run) / t_apply(R ranks, R-rank run).
1-rank apply in run = the same operator on rank 0 alone (COMM_SELF), timed inside the
  R-rank run while the other ranks sleep; speed-up in run = that / t_apply.
pair in 1-rank run = t_fft_pair of the 1-rank run (cross-check of the R-rank reference).
foreign load = CPU cores used by other processes during the measurement."""


def print_table(results, markdown=False):
    rows = table_rows(results)
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(HEADER)]
    print("  ".join(h.rjust(w) for h, w in zip(HEADER, widths)))
    for r in rows:
        print("  ".join(c.rjust(w) for c, w in zip(r, widths)))
    print(NOTES)
    if markdown:
        print()
        print("| " + " | ".join(HEADER) + " |")
        print("|" + "|".join("---:" for _ in HEADER) + "|")
        for r in rows:
            print("| " + " | ".join(r) + " |")


# =============================================================================
# launcher
# =============================================================================
def loadavg() -> str:
    try:
        with open("/proc/loadavg") as fh:
            return " ".join(fh.read().split()[:3])
    except OSError:
        return "n/a"


def launcher(args, passthrough):
    mpirun = shutil.which(args.mpirun) or args.mpirun
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1")
    if hasattr(os, "geteuid") and os.geteuid() == 0:
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    common = ["--sizes", *map(str, args.sizes), "--kinds", *args.kinds]
    if args.repeats:
        common += ["--repeats", str(args.repeats)]
    if args.no_serial_in_run:
        common += ["--no-serial-in-run"]
    common += ["--min-time", str(args.min_time), "--max-foreign", str(args.max_foreign),
               "--retries", str(args.retries), "--retry-wait", str(args.retry_wait)]
    load0 = loadavg()
    results = []
    for R in args.ranks:
        cmd = [mpirun, "-n", str(R), sys.executable, os.path.abspath(__file__),
               "--worker", "--emit-detail", *common, *passthrough]
        print(f"# running: {' '.join(cmd)}", file=sys.stderr, flush=True)
        proc = subprocess.run(cmd, env=env, stdout=subprocess.PIPE, text=True)
        for line in proc.stdout.splitlines():
            if line.startswith(DETAIL):
                results.append(json.loads(line[len(DETAIL):]))
        if proc.returncode != 0:
            sys.exit(f"worker on {R} ranks failed with exit code {proc.returncode}")

    print_table(results, markdown=args.markdown)
    in_run = {(r["n"], r["kind"], r["ranks"]): r.get("speedup_in_run") for r in results}
    for (n, kind, R), s in sorted(speedups(results).items(),
                                  key=lambda t: (t[0][2], KINDS.index(t[0][1]), t[0][0])):
        s_run = in_run.get((n, kind, R))
        print(f"speed-up n={n} {kind} {R} ranks: t_apply(1 rank) / t_apply({R} ranks) = {s:.2f}"
              + ("" if s_run is None else f" (in-run: {s_run:.2f})"))
    print(f"load average (1, 5, 15 min) at start: {load0}, at end: {loadavg()}")
    for rec in sorted(results, key=lambda r: (r["ranks"], KINDS.index(r["kind"]), r["n"])):
        print(json.dumps(core(rec)))


def main():
    args, rest = parse_args(sys.argv[1:])
    if args.worker or under_mpi_launcher():
        worker(args, [sys.argv[0], *rest])
    else:
        launcher(args, rest)


if __name__ == "__main__":
    main()
