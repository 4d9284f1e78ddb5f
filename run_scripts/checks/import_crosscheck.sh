#!/usr/bin/env bash
# contactpetsc's own readers against SurfaceTopography's, through `contactpetsc import`: the
# files of tests/test_topography.py (x3p, sur, gwy, text matrix; written from the formats'
# specifications, 7 x 5 nodes, dx != dy) converted by both, the HDF5 files compared (heights
# less their minimum, dx, dy).  Needs SurfaceTopography in its own venv (docs/topography.md):
#
#   python3 -m venv ~/st && ~/st/bin/pip install SurfaceTopography
#   ST_PYTHON=~/st/bin/python bash run_scripts/checks/import_crosscheck.sh
set -eu
ROOT="$(cd "$(dirname "$0")/../.." && pwd)"
ST_PYTHON="${ST_PYTHON:-$HOME/st/bin/python}"
PY="$ROOT/.venv/bin/python"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
cd "$WORK"
PYTHONPATH="$ROOT:$ROOT/tests" "$PY" -c "
import pathlib, test_topography as t
p = pathlib.Path('.')
t.write_x3p(p / 'scan.x3p', 'D'); t.write_sur(p / 'scan.sur'); t.write_matrix(p / 'scan.txt')
t.write_gwy(p / 'scan.gwy')"
for f in scan.x3p scan.sur scan.txt; do
  PYTHONPATH="$ROOT" "$ST_PYTHON" -W ignore -m contactpetsc import "$f" "st_$f.h5" --reader surfacetopography
  PYTHONPATH="$ROOT" "$PY" -m contactpetsc import "$f" "native_$f.h5"
done
PYTHONPATH="$ROOT" "$ST_PYTHON" -W ignore -m contactpetsc import scan.gwy st_scan.gwy.h5 --reader surfacetopography
PYTHONPATH="$ROOT" "$PY" -m contactpetsc import scan.gwy native_scan.gwy.h5 --dataset Height
"$PY" - <<'PYEOF'
import h5py, numpy as np
for f in ("scan.x3p", "scan.sur", "scan.txt", "scan.gwy"):
    with h5py.File(f"st_{f}.h5") as a, h5py.File(f"native_{f}.h5") as b:
        ha, hb = a["heights"][...], b["heights"][...]
        dh = np.abs((ha - ha.min()) - (hb - hb.min())).max() / np.ptp(hb)
        dd = max(abs(a["heights"].attrs[k] / b["heights"].attrs[k] - 1) for k in ("dx", "dy"))
        print(f"{f}: shape {ha.shape} == {hb.shape}: {ha.shape == hb.shape}, heights (less their "
              f"minimum) differ by {dh:.1e} of their range, dx, dy by {dd:.1e}")
PYEOF
