"""The real instrument files of tests/data/topography-samples/, read by contactpetsc's readers and
compared with SurfaceTopography's reading (reference.json): one line per file, read right,
refused (with the reason the user sees), or wrong (what differs).

    .venv/bin/python run_scripts/checks/topography_samples.py [--markdown]

"Read right" means: the same grid (nx, ny), spacing (n dx = SurfaceTopography's physical size,
1e-9 relative), heights at the recorded nodes (1e-9 relative to the map's rms, in metres;
points not measured NaN alike) and the same mean.  A file SurfaceTopography cannot read
(``error`` in reference.json) is shown with what contactpetsc read.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import warnings

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", ".."))
SAMPLES = os.path.join(HERE, "..", "..", "tests", "data", "topography-samples")

from contactpetsc.topography import read_topography  # noqa: E402
from contactpetsc.topography.units import metres_per  # noqa: E402


def compare(topo, ref: dict) -> list[str]:
    """What differs between contactpetsc's map ``topo`` [m] and SurfaceTopography's ``ref``."""
    scale = metres_per(ref["unit"]) if ref.get("unit") else 1.0
    out = []
    if list(topo.shape) != ref["nb_grid_pts"]:
        return [f"grid {list(topo.shape)}, SurfaceTopography {ref['nb_grid_pts']}"]
    for n, size, d in zip(topo.shape, ref["physical_sizes"], (topo.dx, topo.dy)):
        if d is None or not np.isclose(n * d, size * scale, rtol=1e-9, atol=0):
            out.append(f"size {None if d is None else n * d!r} m, SurfaceTopography {size * scale!r} m")
    tol = 1e-9 * ref["rms"] * scale
    for key, want in ref["nodes"].items():
        i, j = map(int, key.split(","))
        got = topo.heights[i, j]
        if want is None:
            if np.isfinite(got) and "filled_points" not in topo.metadata:
                out.append(f"node ({i}, {j}) {got!r} m, not measured in SurfaceTopography")
        elif not abs(got - want * scale) <= tol:
            out.append(f"node ({i}, {j}) {got!r} m, SurfaceTopography {want * scale!r} m")
    return out


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--markdown", action="store_true", help="a markdown table")
    args = p.parse_args()
    with open(os.path.join(SAMPLES, "reference.json")) as f:
        reference = json.load(f)
    rows = []
    for name, ref in sorted(reference.items()):
        path = os.path.join(SAMPLES, name)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                topo = read_topography(path)
                filled = ""
            except (OSError, ValueError, KeyError) as exc:
                if "not measured" not in str(exc):
                    rows.append((name, "refused", str(exc)))
                    continue
                # refused without a fill, the way on named: read as the message says
                topo = read_topography(path, fill="harmonic")
                filled = (f" with geometry.fill = \"harmonic\" ({topo.metadata['filled_points']} points "
                          f"filled; refused without: {exc})")
        note = "; ".join(str(w.message) for w in caught)
        spacing = "no spacing" if topo.dx is None else f"dx = {topo.dx:.4g} m, dy = {topo.dy:.4g} m"
        what = f"{topo.format}, {topo.shape[0]} x {topo.shape[1]}, {spacing}"
        if "error" in ref:
            rows.append((name, "read (no SurfaceTopography reference)", f"{what}; SurfaceTopography: {ref['error']}"))
            continue
        wrong = compare(topo, ref)
        rows.append((name, "WRONG" if wrong else "read right" + filled,
                     "; ".join(wrong) or what + (f"; warns: {note}" if note else "")))
    if args.markdown:
        print("| file | result | detail |\n|---|---|---|")
        for name, verdict, detail in rows:
            print(f"| `{name}` | {verdict} | {detail.replace('|', '/')} |")
    else:
        for row in rows:
            print(" | ".join(row))
    return 1 if any(v == "WRONG" for _, v, _ in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
