"""A measured map pressed by a flat with a given force: contactpetsc against ContactMechanics on
the same file (each code reading it itself) and the same load, on an isolated window.

    .venv/bin/python run_scripts/checks/measured_peer.py [FILE] [--estar 10e9] [--force 1e-3]
                                                        [--record]

The peer (``run_scripts/peers/cm_window.py``) runs in ContactMechanics' venv
(``run_scripts/peers/setup_peers.sh``; ``$CONTACTPETSC_PEER_VENV``-cm): SurfaceTopography reads
and detrends the file (least-squares plane), its heights peaks up, on ContactMechanics' free
elastic half-space.  Ours: ``surfaces.from_topography(detrend="mean-plane")``, the same map
turned into the gap h = max(z) - z, solved by ``ContactProblem.solve(force=)``.  Printed: both
contact fractions, the relative L2 difference of the pressure fields, the nodes whose contact
differs, and ours with the map upside down (what the code did before heights were taken as the
surface).  ``--record`` writes the peer's figures to
``tests/data/topography-samples/contact_reference.json`` for the test that checks ours
against them (``tests/test_measured_side.py``).  Default file: the AFM scan ``matrix-3.txt``.
"""
from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.join(HERE, "..", "..")
SAMPLES = os.path.join(ROOT, "tests", "data", "topography-samples")
PEER_VENV = os.environ.get("CONTACTPETSC_PEER_VENV",
                           os.path.expanduser("~/.cache/contactpetsc/peer-venv")) + "-cm"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", nargs="?", default=os.path.join(SAMPLES, "matrix-3.txt"))
    ap.add_argument("--estar", type=float, default=10e9, help="E* [Pa]")
    ap.add_argument("--force", type=float, default=1e-3, help="the total force [N]")
    ap.add_argument("--record", action="store_true", help="write the peer's figures for the tests")
    args, petsc_args = ap.parse_known_args()
    import petsc4py
    petsc4py.init([sys.argv[0]] + petsc_args)
    import numpy as np

    from contactpetsc.geometry import surfaces
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.solvers import ContactProblem
    from contactpetsc.topography import read_topography

    with tempfile.TemporaryDirectory() as tmp:
        npz = os.path.join(tmp, "peer.npz")
        run = subprocess.run([os.path.join(PEER_VENV, "bin", "python"), os.path.join(ROOT, "run_scripts", "peers",
                              "cm_window.py"), args.path, "--estar", repr(args.estar), "--force", repr(args.force),
                              "--out", npz], capture_output=True, text=True)
        if run.returncode:
            sys.exit(f"the peer failed: {run.stderr.strip()[-2000:]}")
        peer = json.loads(run.stdout.strip().splitlines()[-1])
        peer_p = np.load(npz)["pressure"]
    topo = read_topography(args.path, metadata_only=True)
    grid = SurfaceGrid(*topo.shape, topo.dx, topo.dy, periodic=False)
    ours = {}
    for side in ("surface", "gap"):
        state = ContactProblem(grid, surfaces.from_topography(grid, args.path, detrend="mean-plane",
                                                              heights_are=side), args.estar).solve(force=args.force)
        ours[side] = (state.contact_fraction, grid.gather(state.pressure))
    fraction, p = ours["surface"]
    print(f"{os.path.basename(args.path)}: {grid.nx} x {grid.ny}, E* = {args.estar:g} Pa, F = {args.force:g} N "
          f"(mean pressure {args.force / (grid.nx * grid.dx * grid.ny * grid.dy):.4g} Pa over the window)")
    print(f"  contact fraction: ours {fraction:.6g}, ContactMechanics {peer['contact_fraction']:.6g} "
          f"({peer['iterations']} iterations); ours upside down {ours['gap'][0]:.6g}")
    print(f"  pressure fields: relative L2 difference {np.linalg.norm(p - peer_p) / np.linalg.norm(peer_p):.3g}, "
          f"{int(np.count_nonzero((p > 0) != (peer_p > 0)))} nodes differ in contact")
    if args.record:
        path = os.path.join(SAMPLES, "contact_reference.json")
        table = json.load(open(path)) if os.path.exists(path) else {}
        top = np.argsort(peer_p, axis=None)[::-1][:5]
        table[os.path.basename(args.path)] = {
            "estar_Pa": args.estar, "force_N": args.force, "detrend": "mean-plane", "peer": peer["peer"],
            "contact_nodes": int(np.count_nonzero(peer_p > 0)), "contact_fraction": peer["contact_fraction"],
            "largest_pressures_Pa": {f"{i},{j}": float(peer_p[i, j])
                                     for i, j in zip(*np.unravel_index(top, peer_p.shape))}}
        with open(path, "w") as f:
            json.dump(table, f, indent=1, sort_keys=True)
        print(f"  recorded in {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
