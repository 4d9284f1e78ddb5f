"""FFT pairs of every benchmark and check script at its smallest real setting, one table.

FFT pairs count the work of a solve independently of the machine, so a refactoring that keeps
the solvers' arithmetic must keep these counts.  Each case runs
its script in a process of its own, at small sizes, without the peers, and collects the pairs the
script reports (its JSON lines, its step lines, or the curve.csv of its run directory).

    python run_scripts/checks/fft_pair_counts.py [--root CHECKOUT] [--only NAME] [--repeats 3] [--json FILE]

--root: the checkout whose scripts and package are run (default: this one); the scripts are
looked up under run_scripts/bench/, run_scripts/checks/ and run_scripts/, so the same cases run
on checkouts from before and after run_scripts/ was sorted by kind.
"""
from __future__ import annotations

import argparse
import csv
import glob
import json
import os
import re
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.abspath(os.path.join(HERE, os.pardir, os.pardir))

# (case name, script, arguments, how the pairs are read); "{out}" is a fresh directory
CASES = [
    ("signorini", "bench_signorini.py",
     ["--sizes", "64", "128", "256", "--solvers", "spectral", "mlmi", "none", "--no-peer", "--repeats", "1"], "json"),
    ("scaling", "bench_scaling.py", ["--sizes", "64", "256"], "json"),
    ("adhesion", "bench_adhesion.py",
     ["--cases", "sphere", "rough", "--sizes", "64", "128", "--mu", "2", "--no-peer"], "json"),
    ("error_vs_time", "error_vs_time.py",
     ["--scenes", "rough", "adhesive", "sphere", "--n", "64", "--sphere-n", "64", "--no-peer",
      "--relax-tols", "1e-3", "--caps", "16"], "json"),
    ("pull_off", "pull_off_table.py", ["--mu", "2", "--n", "64"], "json"),
    # the first step only: past it 64^2 is under-resolved (the study needs 512^2, docs/studies.md)
    # and the failing steps' counts vary from run to run
    ("tabor5_steps", "tabor5_steps.py", ["64", "0", "0"], "steps"),
    ("long_path", "bench_long_path.py", ["--steps", "40", "--window", "10", "--output", "{out}"], "curve"),
]
# JSON keys that name a row of a case (whichever the script reports)
KEYS = ("case", "scene", "stage", "n", "mu", "solver", "pc", "approach", "tol", "w", "z0", "cap")


def find_script(root, name):
    for sub in ("bench", "checks", ""):
        path = os.path.join(root, "run_scripts", sub, name)
        if os.path.exists(path):
            return path
    raise SystemExit(f"fft_pair_counts: {name} not found under {root}/run_scripts")


def fmt(value):
    """A row key as text; floats to 6 digits (a computed approach may differ in its last bit)."""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def rows_json(stdout, out):
    for line in stdout.splitlines():
        if not line.startswith("{"):
            continue
        row = json.loads(line)
        label = " ".join(f"{k}={fmt(row[k])}" for k in KEYS if k in row and row[k] is not None)
        if row.get("fft_pairs") is not None:
            yield label, row["fft_pairs"]
        for run in row.get("runs") or ():          # a sequence of runs (tolerances, caps)
            if isinstance(run, dict) and run.get("fft_pairs") is not None:
                sub = " ".join(f"{k}={run[k]}" for k in ("tol", "cap") if k in run)
                yield f"{label} {sub}", run["fft_pairs"]


def rows_steps(stdout, out):
    for m in re.finditer(r"approach\s+(-?[\d.]+) z0:.*? fft (\d+)", stdout):
        yield f"approach={m.group(1)}", float(m.group(2))


def rows_curve(stdout, out):
    for path in sorted(glob.glob(os.path.join(out, "**", "curve.csv"), recursive=True)):
        with open(path) as f:
            pairs = [float(r["fft_pairs"]) for r in csv.DictReader(f) if r.get("fft_pairs")]
        yield f"steps={len(pairs)} (sum)", sum(pairs)


READERS = {"json": rows_json, "steps": rows_steps, "curve": rows_curve}


def run_case(root, name, script, argv, how, timeout):
    env = dict(os.environ, PYTHONPATH=root, OMP_NUM_THREADS="1")
    with tempfile.TemporaryDirectory(prefix=f"fftpairs-{name}-") as out:
        cmd = [sys.executable, find_script(root, script)] + [a.replace("{out}", out) for a in argv]
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, cwd=root, env=env, capture_output=True, text=True, timeout=timeout)
        elapsed = time.perf_counter() - t0
        rows = list(dict.fromkeys(READERS[how](proc.stdout, out)))   # a script may repeat its rows
    if proc.returncode != 0 or not rows:
        sys.stderr.write(f"--- {name}: exit {proc.returncode}\n{proc.stdout[-2000:]}\n{proc.stderr[-3000:]}\n")
    return cmd, proc.returncode, elapsed, rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=ROOT, help="checkout to run (scripts and package)")
    ap.add_argument("--only", default="", help="run the cases whose name contains this")
    ap.add_argument("--repeats", type=int, default=1,
                    help="runs per case; the table gives the range (FFTW's measured plans differ in "
                         "rounding from run to run, which can move the counts of ill-conditioned steps)")
    ap.add_argument("--timeout", type=float, default=900.0, help="wall-time bound per case [s]")
    ap.add_argument("--json", default=None, help="also write the rows as JSON to this file")
    args = ap.parse_args()
    root = os.path.abspath(args.root)
    table = []
    for name, script, argv, how in CASES:
        if args.only not in name:
            continue
        counts = {}
        for _ in range(args.repeats):
            cmd, code, elapsed, rows = run_case(root, name, script, argv, how, args.timeout)
            shown = " ".join(os.path.relpath(c, root) if c.startswith(root) else c for c in cmd[1:])
            print(f"# {name} (exit {code}, {elapsed:.0f} s): {shown}", flush=True)
            for label, pairs in rows:
                counts.setdefault(label, []).append(pairs)
        for label, pairs in counts.items():
            lo, hi = min(pairs), max(pairs)
            text = f"{lo:12.1f}" if lo == hi else f"{lo:12.1f} .. {hi:.1f}"
            print(f"{name:14s} {label:64s} {text}", flush=True)
            table.append(dict(case=name, row=label, fft_pairs=pairs))
        if not counts:
            table.append(dict(case=name, row="(no rows)", fft_pairs=None))
    if args.json:
        with open(args.json, "w") as f:
            json.dump(table, f, indent=1)


if __name__ == "__main__":
    main()
