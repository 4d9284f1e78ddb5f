"""The sawtooth of an under-resolved sphere's force along its unloading path, against the nodes per
adhesive zone (docs/validation.md, "The sawtooth of the pull-off"; contactpetsc.physics.resolution).

Where the cohesive zone spans few grid spacings, the contact edge moves node by node: along the
unloading path the force follows one state per set of adhered nodes and jumps between them, a
sawtooth about the smooth curve, and the most tensile sampled state is the deepest tooth.  Units
E* = z0 = 1, R = 100, lj law, an isolated window; load to ``--top`` in steps of 1 z0, unload in
steps of ``--step`` over [--from, --to].  Amplitude: the force's deviation from a smooth fit
(a polynomial of degree 8 in the approach over the unloading states in tension; degree 4
leaves a misfit of 0.05 %), relative to the
pull-off; with ``--truth`` (the axisymmetric pull-off in the same window, W*) the sampled pull-off's
error too.

    python run_scripts/checks/sawtooth_amplitude.py --mu 2 --dx 1.33,1.0,0.66 --window 96
    python run_scripts/checks/sawtooth_amplitude.py --mu 5 --dx 0.5 --window 96 --top 5 --from 0 --to -7 --step 0.1
"""
import argparse
import json
import sys
import time
import warnings

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.physics.resolution import adhesive_zone_length  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

R = 100.0


def run(mu, dx, window, top, start, stop, step, element=False):
    w = np.sqrt(mu ** 3 / R)
    law = make_law("lj", work_of_adhesion=w, z0=1.0)
    n = int(round(window / dx))
    grid = SurfaceGrid(n, n, dx, periodic=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pb = AdhesiveProblem(grid, sphere(grid, R), 1.0, law, stability_check=False, element_integration=element,
                             prefix=f"saw{n}_")
    t = time.time()
    for a in np.arange(-3.0 - mu, top + 1e-9, 1.0):
        pb.solve(approach=float(a), raise_on_failure=False)
    for a in np.arange(top - 1.0, start + 1e-9, -1.0):
        pb.solve(approach=float(a), raise_on_failure=False)
    pts = []
    for a in np.arange(start, stop - 1e-9, -step):
        st = pb.solve(approach=float(a), raise_on_failure=False)
        if not st.converged or st.contact_fraction == 0:
            break
        pts.append((float(a), st.force / (2 * np.pi * R * w)))
    a, f = np.array(pts).T
    tension = f < 0
    fit = np.polyval(np.polyfit(a[tension], f[tension], 8), a[tension])
    dev = (f[tension] - fit) / abs(f.min())
    zone = adhesive_zone_length(law, 1.0, radius=R)["zone"]
    return dict(mu=mu, dx=dx, n=n, zone_nodes=zone / dx, element=element, states=len(pts),
                pull_off=float(f.min()), smooth_pull_off=float(fit.min()),
                amplitude_low=float(dev.min()), amplitude_high=float(dev.max()),
                time=round(time.time() - t, 1), path=[[round(x, 4), round(y, 6)] for x, y in pts])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--mu", type=float, default=2.0)
    ap.add_argument("--dx", default="1.33,1.0,0.66")
    ap.add_argument("--window", type=float, default=96.0)
    ap.add_argument("--top", type=float, default=1.0)
    ap.add_argument("--from", dest="start", type=float, default=0.0)
    ap.add_argument("--to", dest="stop", type=float, default=-3.5)
    ap.add_argument("--step", type=float, default=0.05)
    ap.add_argument("--element", action="store_true")
    ap.add_argument("--truth", type=float, default=None, help="W* of the axisymmetric pull-off in the window")
    args = ap.parse_args()
    for dx in map(float, args.dx.split(",")):
        r = run(args.mu, dx, args.window, args.top, args.start, args.stop, args.step, args.element)
        if args.truth is not None:
            r["pull_off_error"] = r["pull_off"] / args.truth - 1
        print(json.dumps(r), flush=True)


if __name__ == "__main__":
    main()
