#!/usr/bin/env python3
"""Peer runner: a measured map, read by SurfaceTopography, pressed by a flat with a given force on
ContactMechanics' free (non-periodic) elastic half-space.

Run with the ContactMechanics peer venv (run_scripts/peers/setup_peers.sh)::

    ~/.cache/contactpetsc/peer-venv-cm/bin/python run_scripts/peers/cm_window.py scan.txt \
        --estar 10e9 --force 1e-4 --detrend height --out peer.npz

The file is read by SurfaceTopography (``open_topography``, its default channel) and detrended by
it (``--detrend``: ``center`` (the mean), ``height`` (the least-squares plane) or ``curvature``);
its heights are the surface, peaks up, as ContactMechanics takes them.  The substrate is
``FreeFFTElasticHalfSpace`` (the window zero-padded to twice its size: no periodic images) with
``young`` the contact modulus E*, and the solver ContactMechanics' Polonsky-Keer constrained
conjugate gradients (``minimize_proxy(external_force=F)``), stopped at ``--pentol`` [m]
(default 1e-8 of the rms height).  Prints one JSON line: the contact fraction, force, offset,
iterations and the grid; ``--out`` writes the pixel pressures [Pa] and the displacements [m]
indexed [i, j] = (x_i, y_j).
"""
import argparse
import json
import sys

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("path", help="a topography file SurfaceTopography reads")
    ap.add_argument("--estar", type=float, required=True, help="contact modulus E* [Pa]")
    ap.add_argument("--force", type=float, required=True, help="the total force [N]")
    ap.add_argument("--detrend", default="height", choices=("center", "height", "curvature"))
    ap.add_argument("--pentol", type=float, default=None, help="penetration tolerance [m]")
    ap.add_argument("--out", default=None, help=".npz for pressure and displacement")
    args = ap.parse_args(argv)
    for name in ("estar", "force"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name} must be > 0, got {getattr(args, name)}")
    from ContactMechanics import FreeFFTElasticHalfSpace
    from ContactMechanics.Systems import NonSmoothContactSystem
    from SurfaceTopography import open_topography

    topo = open_topography(args.path).topography().detrend(detrend_mode=args.detrend).to_unit("m").squeeze()
    if topo.dim != 2:
        ap.error(f"{args.path} is a {topo.dim}-D topography: a 2-D map is needed")
    nx, ny = topo.nb_grid_pts
    substrate = FreeFFTElasticHalfSpace((nx, ny), args.estar, topo.physical_sizes)
    system = NonSmoothContactSystem(substrate=substrate, surface=topo)
    pentol = args.pentol if args.pentol is not None else 1e-8 * topo.rms_height_from_area()
    result = system.minimize_proxy(external_force=args.force, pentol=pentol, maxiter=100000)
    forces = np.asarray(result.jac)[:nx, :ny]
    area = topo.physical_sizes[0] * topo.physical_sizes[1] / (nx * ny)
    import ContactMechanics
    import SurfaceTopography
    print(json.dumps({"peer": f"ContactMechanics {ContactMechanics.__version__}, SurfaceTopography "
                              f"{SurfaceTopography.__version__}",
                      "success": bool(result.success), "iterations": int(result.nit),
                      "contact_fraction": float(np.count_nonzero(forces > 0)) / (nx * ny),
                      "force_N": float(forces.sum()), "offset_m": float(result.offset),
                      "nb_grid_pts": [nx, ny], "physical_sizes_m": list(map(float, topo.physical_sizes)),
                      "pentol_m": pentol}))
    if args.out:
        np.savez(args.out, pressure=forces / area, displacement=np.asarray(result.x)[:nx, :ny])
    return 0 if result.success else 1


if __name__ == "__main__":
    sys.exit(main())
