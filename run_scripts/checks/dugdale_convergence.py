"""The `dugdale` law's sphere against Maugis-Dugdale (closed_forms.maugis_approach) as the grid is
refined, nodal traction against element integration (docs/validation.md, "The Dugdale law").

Units E* = 1, R = 100, w = 0.1, sigma0 at lambda = 1 (range w / sigma0 = 1.13, cohesive zone
(pi/4) E* w / sigma0^2 = 10.0).  The law has compact support: the 96-wide window holds all of it.
Path: loading from delta = -2 to +2 in steps of 0.25, unloading to -3 in steps of 0.05 (displacement
control, warm starts).  Errors: the force at the same approach on the loading and on the unloading
branch against the stable Maugis-Dugdale branch, relative to pi w R; the pull-off (most tensile
sampled state) against Maugis-Dugdale's.

    python run_scripts/checks/dugdale_convergence.py --dx 0.4,0.2,0.1 --markdown
    python run_scripts/checks/dugdale_convergence.py --dx 0.4,0.2,0.1 --element --markdown
"""
import argparse
import json
import sys
import time

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402
import warnings  # noqa: E402

from contactpetsc.geometry.surfaces import sphere  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.physics import closed_forms as cf  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.physics.resolution import adhesive_zone_length  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

R, W, LAM, WINDOW = 100.0, 0.1, 1.0, 96.0


def sigma0_for(lam, radius=R, w=W, e_star=1.0):
    """The Dugdale stress giving transition parameter lambda (closed_forms.maugis_lambda inverted)."""
    return lam / cf.maugis_lambda(e_star, radius, w, 1.0)


def maugis_stable_force(lam, approach, radius=R, w=W, e_star=1.0):
    """Maugis-Dugdale force [N] at approach [m] on the stable branch (closed_forms.maugis_force)."""
    return cf.maugis_force(e_star, radius, w, lam, approach)


def run(frac, element, lam=LAM, window=WINDOW, load_step=0.25, unload_step=0.05, top=2.0, bottom=-3.0):
    s0 = sigma0_for(lam)
    law = make_law("dugdale", work_of_adhesion=W, sigma0=s0)
    zone = adhesive_zone_length(law, 1.0)["cohesive"]
    dx = frac * zone
    n = int(round(window / dx))
    grid = SurfaceGrid(n, n, dx, periodic=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pb = AdhesiveProblem(grid, sphere(grid, R), 1.0, law, element_integration=element,
                             stability_check=False, prefix=f"dug{n}{int(element)}_")
    load = np.arange(-2.0, top + 1e-9, load_step)
    unload = np.arange(top - unload_step, bottom - 1e-9, -unload_step)
    t = time.time()
    states = []
    for branch, path in (("load", load), ("unload", unload)):
        for a in path:
            st = pb.solve(approach=float(a), raise_on_failure=False)
            states.append((branch, float(a), st.force, st.contact_fraction > 0, st.converged))
    unit = np.pi * W * R
    err = {}
    for branch, a, f, touching, conv in states:
        md = maugis_stable_force(lam, a)
        if touching and conv and np.isfinite(md):
            err.setdefault(branch, {})[round(a, 4)] = (f - md) / unit
    common = sorted(set(err.get("load", {})) & set(err.get("unload", {})))
    pull = min(f for b, a, f, touching, conv in states if b == "unload" and conv)
    md_pull = cf.maugis_pull_off(R, W, lam)
    at = 1.0 if 1.0 in common else common[len(common) // 2]
    return dict(frac=frac, dx=dx, n=n, element=element, lam=lam, zone=zone,
                load_err_at=at, load_err=err["load"][at], unload_err=err["unload"][at],
                mean_err=0.5 * (err["load"][at] + err["unload"][at]),
                max_load_err=max(abs(v) for v in err["load"].values()),
                max_unload_err=max(abs(v) for v in err["unload"].values()),
                pull_off_rel=pull / md_pull - 1, pull_off=pull / unit, md_pull_off=md_pull / unit,
                converged=all(s[-1] for s in states), time=round(time.time() - t, 1))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--dx", default="0.4,0.2,0.1", help="dx as fractions of the cohesive zone")
    ap.add_argument("--element", action="store_true")
    ap.add_argument("--lam", type=float, default=LAM)
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    rows = []
    for frac in map(float, args.dx.split(",")):
        r = run(frac, args.element, args.lam)
        rows.append(r)
        print(json.dumps(r), flush=True)
    if args.markdown:
        print("\n| dx / zone | n | rule | load err | unload err | mean | max load | max unload | pull-off "
              "| MD pull-off | pull-off err | time [s] |")
        print("|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['frac']:g} | {r['n']} | {'element' if r['element'] else 'nodal'} | {r['load_err']:+.4f} "
                  f"| {r['unload_err']:+.4f} | {r['mean_err']:+.1e} | {r['max_load_err']:.4f} | {r['max_unload_err']:.4f} "
                  f"| {r['pull_off']:.4f} | {r['md_pull_off']:.4f} | {100 * r['pull_off_rel']:+.2f} % | {r['time']} |")


if __name__ == "__main__":
    main()
