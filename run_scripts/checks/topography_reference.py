"""SurfaceTopography's reading of the real instrument files in tests/data/topography-samples/,
recorded as the truth the reader tests compare with (reference.json beside the files).

Run in SurfaceTopography's own venv (docs/topography.md; run_scripts/peers/setup_peers.sh makes
one with ContactMechanics):

    ~/.cache/contactpetsc/peer-venv-cm/bin/python run_scripts/checks/topography_reference.py

For each file: SurfaceTopography's version and reader, the map's dimension, grid (nx, ny),
physical sizes and unit, periodicity, the number of points not measured, and heights at a few
nodes that fix the orientation (corners, and nodes off the diagonals), with the nan-aware mean
and rms of all heights, in the file's unit.  A file SurfaceTopography cannot read is recorded
with its error.  The tests convert units themselves.
"""
from __future__ import annotations

import json
import os
import sys

import numpy as np

SAMPLES = os.path.join(os.path.dirname(__file__), "..", "..", "tests", "data", "topography-samples")


def _nodes(shape):
    """Corners and asymmetric interior nodes: a transposed or flipped map differs at them."""
    if len(shape) == 1:
        n = shape[0]
        return [(0,), (1,), (n // 3,), (n - 1,)]
    nx, ny = shape
    return [(0, 0), (nx - 1, 0), (0, ny - 1), (nx - 1, ny - 1), (1, 0), (0, 1),
            (nx // 3, (2 * ny) // 3), ((2 * nx) // 3, ny // 4)]


def record(path: str) -> dict:
    import SurfaceTopography
    from SurfaceTopography import open_topography
    entry = {"surfacetopography": SurfaceTopography.__version__}
    try:
        reader = open_topography(path)
        topo = reader.topography()
    except Exception as exc:   # recorded: the file is beyond SurfaceTopography
        entry["error"] = f"{type(exc).__name__}: {str(exc).splitlines()[0] if str(exc) else ''}"
        return entry
    h = np.ma.filled(np.ma.asarray(topo.heights(), dtype=float), np.nan)   # not measured: NaN
    entry.update(reader=str(reader.format()), dim=int(topo.dim),
                 nb_grid_pts=[int(n) for n in topo.nb_grid_pts],
                 physical_sizes=[float(s) for s in topo.physical_sizes],
                 unit=topo.unit, periodic=bool(topo.is_periodic),
                 undefined=int(np.count_nonzero(~np.isfinite(h))),
                 mean=float(np.nanmean(h)), rms=float(np.sqrt(np.nanmean((h - np.nanmean(h)) ** 2))),
                 nodes={",".join(map(str, n)): (None if not np.isfinite(h[n]) else float(h[n]))
                        for n in _nodes(h.shape)})
    return entry


def main() -> int:
    names = sorted(n for n in os.listdir(SAMPLES)
                   if not n.endswith((".md", ".json")) and not n.startswith("LICENSE"))
    table = {name: record(os.path.join(SAMPLES, name)) for name in names}
    with open(os.path.join(SAMPLES, "reference.json"), "w") as f:
        json.dump(table, f, indent=1, sort_keys=True)
    for name, entry in table.items():
        print(name, entry.get("error") or f"{entry['nb_grid_pts']} {entry['unit']} undefined {entry['undefined']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
