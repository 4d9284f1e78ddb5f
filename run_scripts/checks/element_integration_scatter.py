"""Where the paper's element integration (Fig. 3) helps: the scatter of a sphere's force over the
apex position relative to the grid, nodal sampling against element integration, for both LJ laws,
detached and in contact, on two spheres (docs/validation.md, "Element integration").

Units E* = z0 = 1.  For each case the sphere's apex is shifted by (0.5 s, 0.37 s) dx, s = 0 ... 1
(six sub-grid positions), and the force at one approach is solved on a fresh problem (the contact
state by a loading path in steps of 1 z0 from -1 z0).  Scatter = (max - min) / |mean| of the six
forces; bias = mean / truth - 1, the truth the independent axisymmetric solver
(tests/axisymmetric_lj.py) at the same approach, its load taken over the same square window.

    python run_scripts/checks/element_integration_scatter.py --markdown
    python run_scripts/checks/element_integration_scatter.py --cases A --laws lj --markdown
"""
import argparse
import json
import os
import sys
import time

import petsc4py
petsc4py.init(sys.argv[:1])
import numpy as np  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir, "tests"))
import axisymmetric_lj as axi  # noqa: E402
from adhesive_setup import shifted_sphere_forces  # noqa: E402
from contactpetsc.physics.interactions import make_law  # noqa: E402
from contactpetsc.physics.resolution import adhesive_zone_length  # noqa: E402

#: label: (R, w, dx, n, detached approach, contact approach) in z0 = E* = 1
CASES = {"A": (20.0, 0.01, 2.0, 64, -0.5, 4.0),      # mu = 0.13, DMT-like, zone sqrt(2 R z0) = 3.2 dx
         "B": (100.0, 0.2828, 1.0, 64, -3.0, 2.0)}   # mu = 2, cohesive zone 2.7 dx (jump-on at -2.55 z0:
                                                     # detached only below it)


def tabor(R, w):
    return (R * w * w) ** (1.0 / 3.0)


def forces(R, w, dx, n, law_name, element, approach, shifts, tag):
    law = make_law(law_name, work_of_adhesion=w, z0=1.0)
    path = [approach] if approach <= 0 else list(np.arange(-1.0, approach + 0.5, 1.0))
    return shifted_sphere_forces(R, law, dx, n, element, path, shifts, tag, raise_on_failure=False)


def truth(R, w, n, dx, law_name, approach):
    edges = axi.default_mesh(R, w, 1.0, 1.0, max(approach, 0.5))
    sph = axi.AxisymmetricSphere(R, 1.0, w, 1.0, edges, law=law_name)
    st = None
    try:       # from far out in steps of z0/4 (Newton from the undeformed gap fails near a fold)
        for a in np.append(np.arange(-3.0, approach, 0.25), approach):
            st = sph.solve_approach(a, start=st)
    except RuntimeError:
        return float("nan")
    return sph.rings.load_in_square(st.pressure, 0.5 * n * dx)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cases", default="A,B")
    ap.add_argument("--laws", default="hardwall-lj,lj")
    ap.add_argument("--states", default="detached,contact")
    ap.add_argument("--positions", type=int, default=6)
    ap.add_argument("--markdown", action="store_true")
    args = ap.parse_args()
    shifts = np.linspace(0.0, 1.0, args.positions)
    rows = []
    for case in args.cases.split(","):
        R, w, dx, n, detached, contact = CASES[case]
        zone = adhesive_zone_length(make_law("lj", work_of_adhesion=w, z0=1.0), 1.0, radius=R)["zone"]
        for law in args.laws.split(","):
            for state in args.states.split(","):
                approach = detached if state == "detached" else contact
                ref = truth(R, w, n, dx, law, approach)
                row = dict(case=case, R=R, mu=round(tabor(R, w), 3), dx=dx, zone_nodes=round(zone / dx, 2),
                           law=law, state=state, approach=approach, truth=ref)
                for element in (False, True):
                    t = time.time()
                    f, conv = forces(R, w, dx, n, law, element, approach, shifts,
                                     f"ei{case}{law[0]}{state[0]}{int(element)}_")
                    key = "element" if element else "nodal"
                    row[key] = dict(scatter=float(np.ptp(f) / abs(f.mean())), bias=float(f.mean() / ref - 1),
                                    forces=f.tolist(), converged=conv, time=round(time.time() - t, 1))
                row["ratio"] = row["element"]["scatter"] / row["nodal"]["scatter"]
                rows.append(row)
                print(json.dumps(row), flush=True)
    if args.markdown:
        print("\n| sphere | mu | zone / dx | law | state | approach / z0 | scatter nodal | scatter element "
              "| element / nodal | bias nodal | bias element |")
        print("|---|---:|---:|---|---|---:|---:|---:|---:|---:|---:|")
        for r in rows:
            print(f"| {r['case']} (R = {r['R']:g}, dx = {r['dx']:g}) | {r['mu']:g} | {r['zone_nodes']:g} | {r['law']} "
                  f"| {r['state']} | {r['approach']:g} | {100 * r['nodal']['scatter']:.3f} % "
                  f"| {100 * r['element']['scatter']:.3f} % | {r['ratio']:.2f} "
                  f"| {100 * r['nodal']['bias']:+.2f} % | {100 * r['element']['bias']:+.2f} % |")


if __name__ == "__main__":
    main()
