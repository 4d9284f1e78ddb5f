#!/usr/bin/env python3
"""Benchmark: the memory of a scene's whole run (``contactpetsc run``), as a user runs it.

Runs the scene in a child process (one rank), its grid set to ``--nx`` nodes a side (``ny`` too
where the scene gives one) and its output in a temporary directory, and reports the child's peak
resident size (``ru_maxrss``) in MiB and in doubles (8 B) per grid point, with the run's steps
and FFT pairs from its ``curve.csv`` and the plan's estimate for one rank (``builder.memory_per_rank``:
the figure a run's plan prints).  Unlike ``bench_adhesion_path.py``, which drives the
library in a loop of its own, this counts what the run keeps besides the solver: its states,
the recorder, the plots' fields.

    .venv/bin/python run_scripts/bench/bench_run_memory.py examples/scenes/rough_large_outputs.toml --nx 1024

Extra arguments go to ``contactpetsc run`` (PETSc options).  One JSON line.
"""
import argparse
import csv
import os
import resource
import subprocess
import sys
import tempfile
import time
import tomllib
from pathlib import Path

from bench_args import emit
from contactpetsc.app import builder, scenes

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "checks", "adversarial"))
from harness import write_scene  # noqa: E402  (the sweep's scene writer)

ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("scene", help="a scene file (TOML)")
ap.add_argument("--nx", type=int, help="grid nodes a side (default: the scene's)")
args, extra = ap.parse_known_args()


def main():
    with open(args.scene, "rb") as f:
        scene = tomllib.load(f)
    geometry = scene["geometry"]
    if args.nx:
        geometry["nx"] = args.nx
        if "ny" in geometry:
            geometry["ny"] = args.nx
    if "path" in geometry and not os.path.isabs(geometry["path"]):
        # a height file named relative to the scene's own directory
        geometry["path"] = os.path.join(os.path.dirname(os.path.abspath(args.scene)), geometry["path"])
    with tempfile.TemporaryDirectory(prefix="contactpetsc-run-memory-") as tmp:
        scene.setdefault("output", {})["directory"] = os.path.join(tmp, "out")
        path = os.path.join(tmp, "scene.toml")
        write_scene(Path(path), scene)
        # the plan's estimate for the same scene (``builder.memory_per_rank``), one rank
        validated = scenes.load(path)
        estimate = builder.memory_per_rank(validated, 1)
        nx, ny = validated["geometry"]["nx"], validated["geometry"]["ny"]
        exe = os.path.join(os.path.dirname(sys.executable), "contactpetsc")
        t = time.perf_counter()
        proc = subprocess.run([exe, "run", path] + extra, capture_output=True, text=True,
                              env=dict(os.environ, OMP_NUM_THREADS=os.environ.get("OMP_NUM_THREADS", "1")))
        wall = time.perf_counter() - t
        if proc.returncode not in (0, 3):
            sys.exit(f"contactpetsc run failed ({proc.returncode}):\n{proc.stderr[-2000:]}")
        with open(os.path.join(tmp, "out", "curve.csv")) as f:
            rows = list(csv.DictReader(f))
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024.0   # kB on Linux
    emit(scene=args.scene, nx=nx, ny=ny, steps=len(rows), converged=sum(r["converged"] == "True" for r in rows),
         fft_pairs=sum(float(r["fft_pairs"]) for r in rows), wall=wall, peak_mb=peak / 2**20,
         doubles_per_point=peak / (8.0 * nx * ny), estimate_mb=estimate / 2**20)


main()
