"""Per-step bookkeeping of a long path: is the cost of writing a step flat in the path's length?

Runs a scene of many cheap steps (a 16 x 16 periodic rough cell under load control, no field
files, no plots) through the product's front door, ``runner.run``, and times each step's
overhead: the time from one solve's end to the next one's start (writing curve.csv,
history.csv, summary.json, the progress line).  Prints the median overhead over the first and
the last ``--window`` steps and their ratio (1 when the overhead is flat), in wall time and in
the process's CPU time: the wall time includes the disk's fsync latency (three fsyncs a step,
bursty on a shared disk) and other processes' load, the CPU time is our own bookkeeping.

    python run_scripts/bench/bench_long_path.py [--steps 10000] [--window 500] [--output DIR]
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import time

import petsc4py

petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--steps", type=int, default=10000)
    p.add_argument("--window", type=int, default=500)
    p.add_argument("--output", default=None, help="output directory (default: a temporary one, removed)")
    args = p.parse_args()
    from contactpetsc.app import runner, scenes
    from contactpetsc.solvers import ContactProblem
    out = args.output or tempfile.mkdtemp(prefix="bench-long-path-")
    loads = 5e6 * (1.0 + 0.5 * np.sin(0.01 * np.arange(args.steps)))
    scene = scenes.validate({"name": "long-path",
                             "geometry": {"kind": "self-affine", "nx": 16, "dx": 1e-8, "rms_slope": 0.1},
                             "material": {"e_star": 1e9},
                             "protocol": {"control": "mean_pressure", "values": [float(v) for v in loads]},
                             "output": {"directory": os.path.join(out, "run"), "fields": False}})
    starts, ends, cpu_starts, cpu_ends = [], [], [], []
    solve = ContactProblem.solve

    def timed(self, **kw):
        starts.append(time.perf_counter())
        cpu_starts.append(time.process_time())
        st = solve(self, **kw)
        ends.append(time.perf_counter())
        cpu_ends.append(time.process_time())
        return st

    ContactProblem.solve = timed
    devnull = os.open(os.devnull, os.O_WRONLY)
    saved = os.dup(1)
    os.dup2(devnull, 1)          # the progress lines of 10^4 steps, not timed on a terminal
    try:
        t0 = time.perf_counter()
        runner.run(scene, comm=PETSc.COMM_SELF)
        total = time.perf_counter() - t0
    finally:
        os.dup2(saved, 1)
        if args.output is None:
            shutil.rmtree(out, ignore_errors=True)
    print(f"{args.steps} steps in {total:.1f} s; solves {np.sum(np.array(ends) - np.array(starts)):.1f} s")
    for name, a, b in (("wall", starts, ends), ("cpu", cpu_starts, cpu_ends)):
        overhead = np.array(a[1:]) - np.array(b[:-1])   # after solve k, before solve k + 1
        w = min(args.window, len(overhead) // 2)
        first, last = np.median(overhead[:w]), np.median(overhead[-w:])   # fsync latency is bursty
        print(f"bookkeeping per step ({name}): first {w} steps {first * 1e3:.2f} ms, last {w} steps "
              f"{last * 1e3:.2f} ms, ratio {last / first:.2f}")


if __name__ == "__main__":
    main()
