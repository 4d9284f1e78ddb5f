"""What leaving the stability check out saves: scenes run with -adhesion_stability_check auto,
true and false (docs/performance.md, "The stability check left out where it cannot change an
answer").

Each scene is run by the command line in a process of its own, one rank; the table gives,
per mode, the states checked, the FFT pairs of the path's steps (curve.csv) and of the whole
run (history.csv: the pull-off refinement too), the solve time, and whether the jumps
(approaches of jumps.csv) and the pull-off force are those of the always-on check.  Each run
is repeated (``--repeat``): the path's FFT pairs repeat exactly, while the pull-off search's
iteration counts change by a few per cent from run to run with the FFT's round-off (FFTW's
plans and the arrays' alignment), so the run's FFT pairs and the times are medians (with
their range).

    .venv/bin/python run_scripts/bench/bench_stability_check.py [--only adhesive-sphere] [--repeat 3] [--markdown out.md]
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

#: the scenes, each from its example file (the rough cell: the stability matrix's rough cases, resolved)
SCENES = {"adhesive-sphere": os.path.join(ROOT, "examples", "scenes", "adhesive_sphere.toml"),
           "atomic-tip": os.path.join(ROOT, "examples", "scenes", "atomic_tip.toml"),
           "rough-adhesive": os.path.join(ROOT, "examples", "scenes", "rough_adhesive_cell.toml")}


def run(scene: str, mode: str, out: str) -> dict:
    subprocess.run([sys.executable, "-m", "contactpetsc", "run", scene, "--output", out, "--overwrite",
                    "-adhesion_stability_check", mode], check=True, capture_output=True, text=True)
    with open(os.path.join(out, "curve.csv")) as f:
        rows = list(csv.DictReader(f))
    with open(os.path.join(out, "history.csv")) as f:
        last = list(csv.DictReader(f))[-1]
    with open(os.path.join(out, "summary.json")) as f:
        summary = json.load(f)
    jumps = []
    if os.path.exists(os.path.join(out, "jumps.csv")):
        with open(os.path.join(out, "jumps.csv")) as f:
            jumps = [(j["kind"], j["approach_before_m"], j["approach_after_m"]) for j in csv.DictReader(f)]
    return dict(steps=len(rows), checked=sum(r["stability_checked"] == "True" for r in rows),
                path_pairs=sum(float(r["fft_pairs"]) for r in rows), pairs=float(last["fft_pairs"]),
                path_time=sum(float(r["wall_time_s"]) for r in rows), time=float(last["wall_time"]),
                jumps=jumps, pull_off=summary.get("pull_off_force_N"),
                converged=all(r["converged"] == "True" for r in rows))


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", help="one scene: adhesive-sphere, atomic-tip or rough-adhesive")
    ap.add_argument("--repeat", type=int, default=3, help="runs per scene and mode (medians)")
    ap.add_argument("--markdown", help="write the table here too")
    args = ap.parse_args(argv)
    lines = ["| scene | mode | states checked | FFT pairs, path | vs true | FFT pairs, run: median (range) | "
             "vs true | solve time, run [s]: median (range) | jumps, pull-off as with true |",
             "|---|---|---:|---:|---:|---:|---:|---:|---|"]

    def median(rs, key):
        values = sorted(r[key] for r in rs)
        return values[len(values) // 2], values[0], values[-1]

    with tempfile.TemporaryDirectory() as tmp:
        for name, scene in SCENES.items():
            if args.only and name != args.only:
                continue
            got = {mode: [run(scene, mode, os.path.join(tmp, f"{name}-{mode}")) for _ in range(args.repeat)]
                   for mode in ("true", "auto", "false")}
            ref = got["true"][0]
            ref_pairs = median(got["true"], "pairs")[0]
            for mode, rs in got.items():
                r = rs[0]
                same = all(x["jumps"] == ref["jumps"] and (
                    x["pull_off"] == ref["pull_off"] or (x["pull_off"] is not None and ref["pull_off"] is not None
                                                         and abs(x["pull_off"] / ref["pull_off"] - 1) < 1e-8))
                    for x in rs)
                path = {x["path_pairs"] for x in rs}
                pairs, time = median(rs, "pairs"), median(rs, "time")
                lines.append(f"| {name} | {mode} | {r['checked']} / {r['steps']} | "
                             f"{'/'.join(f'{p:.0f}' for p in sorted(path))} | "
                             f"{r['path_pairs'] / ref['path_pairs'] - 1:+.1%} | "
                             f"{pairs[0]:.0f} ({pairs[1]:.0f}-{pairs[2]:.0f}) | {pairs[0] / ref_pairs - 1:+.1%} | "
                             f"{time[0]:.1f} ({time[1]:.1f}-{time[2]:.1f}) | {'yes' if same else 'NO'} "
                             f"({len(r['jumps'])} jumps)" + ("" if r["converged"] else ", a step failed") + " |")
                print(lines[-1], flush=True)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
