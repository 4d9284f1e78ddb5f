"""Smooth spheres (reference paper, section 3.1, Figs. 4 and 5).

    python examples/studies/smooth_sphere.py [--size small|default] [--out DIR]
    mpirun -n 2 python examples/studies/smooth_sphere.py

Fig. 4: load-approach curves in Greenwood's scaling (alpha* = delta / z0,
W* = W / (2 pi R w)), in units z0 = 1, E* = 1, R = 1000 (mu = 0.02) and
R = 100 (mu = 2):
  (a, b) mu = 0.02, the full Lennard-Jones curve (eq. 8) and the hard-wall law
         (eq. 7a), loading and unloading, beside DMT (Muller et al.: Hertz plus
         the law over the Hertz gap) and the DMT pull-off -2 pi R w;
  (c)    mu = 2, the lj law (the paper's Fig. 4c), loading and unloading under
         displacement control (jump-on, jump-off), and the full S-curve by
         prescribing the central gap (Greenwood's device) and, once the apex
         touches, the gap of nodes further out (``paths.edge_gap_path``): the
         unstable branch, the jump-off fold and the adhered branch; pull-off beside
         Maugis-Dugdale with lambda = 1.16 mu.  The hard-wall law at mu = 2,
         loading and unloading, in steps of 0.1 z0: from 0.25 z0 away some of
         its compressed states are out of reach of Newton and both fallbacks
         (the sweep's sub-steps get there, slowly; docs/studies.md).  The small
         size leaves it out: 48^2 does not resolve its cohesive zone (1.2 grid
         spacings) and the compressed states fail.
Fig. 5: the adhesive load and area ratios (1 % cut-off) of smooth spheres
(SI units) for a reference contact and contacts with other E*, R, w and load,
among them one with the reference's Tabor parameter, R and load but w and E*
both four times larger.

Outputs in --out: fig4_*.csv (paths), states_*.csv and history_*.csv per path
(``common.StudyRecorder``), fig4.png, fig5.csv, fig5.png, smooth_sphere.json.
Sizes: default 128^2 (mu = 0.02, dx = 3 z0) and 96^2 (mu = 2) windows, 96^2 for
Fig. 5; small 64^2 / 48^2 / 48^2.  The paper does not state its grids.
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

SIZES = {
    #            n, dx (mu=0.02)  n (mu=2)  n (Fig. 5)  mu = 2: law -> approach step
    "small": dict(n_low=64, dx_low=4.0, n_high=48, n_ratio=48,
                  laws_high={"lj": 0.5}),
    "default": dict(n_low=128, dx_low=3.0, n_high=96, n_ratio=96,
                    laws_high={"lj": 0.25, "hardwall-lj": 0.1}),
}

# Fig. 5: (label, E* [Pa], R [m], w [J/m^2], load [N]); z0 = 0.3 nm
Z0_SI = 0.3e-9
RATIO_CASES = [
    ("reference", 10e9, 20e-9, 0.05, 2e-9),
    ("E* x4", 40e9, 20e-9, 0.05, 2e-9),
    ("R x4", 10e9, 80e-9, 0.05, 2e-9),
    ("load x4", 10e9, 20e-9, 0.05, 8e-9),
    ("w x4, E* x4 (same mu)", 40e9, 20e-9, 0.2, 2e-9),
    ("w x4", 10e9, 20e-9, 0.2, 2e-9),
]


def greenwood_case(mu, radius, law_name, n, dx, approaches, prefix, central_gaps=None, refine=6, out=None):
    """Loading and unloading (and optionally central-gap) paths of a sphere in z0 = E* = 1;
    with ``out`` each path's states and solver iterations recorded there
    (``common.StudyRecorder``, named by ``prefix``)."""
    import numpy as np
    from contactpetsc.geometry import surfaces
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.paths import central_gap_path, edge_gap_path, sweep
    from contactpetsc.pull_off import refine_pull_off
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    w = float(np.sqrt(mu ** 3 / radius))      # mu^3 = R w^2 / (E*^2 z0^3)
    grid = SurfaceGrid(n, n, dx, periodic=False, row_alignment=8)
    law = make_law(law_name, work_of_adhesion=w, z0=1.0)
    pb = AdhesiveProblem(grid, surfaces.sphere(grid, radius), 1.0, law, prefix=prefix,
                         element_integration=True)
    def recorder(problem, name):
        return None if out is None else common.StudyRecorder(out, name, grid, problem.heights, problem)

    rec = recorder(pb, prefix.rstrip("_"))
    path = sweep(pb, approaches, refine=refine, on_state=rec)
    pull = refine_pull_off(pb, path, xtol=0.01)
    if rec is not None:
        rec.flush()
    s_curve = None
    if central_gaps is not None:
        cg = AdhesiveProblem(grid, pb.heights, 1.0, law, prefix=prefix + "cg_", operator=pb.op,
                             element_integration=True)
        rec = recorder(cg, prefix + "cg")
        s_curve = central_gap_path(cg, central_gaps, on_state=rec)
        # the far end: the contact edge led outward node by node, until the curve is back on
        # the stable adhered branch 1 z0 above its fold (the jump-off)
        fold = [min(p.approach for p in s_curve.points if p.converged)]

        def back_on_adhered_branch(pt):
            fold[0] = min(fold[0], pt.approach)
            return bool(pt.stable) and pt.approach > fold[0] + 1.0

        edge_gap_path(cg, 0.1, 0.05, stop=back_on_adhered_branch, path=s_curve, on_state=rec)
        if rec is not None:
            rec.flush()
    return dict(w=w, law=law, grid=grid, path=path, pull_off=pull, s_curve=s_curve)


def ratio_case(label, e_star, radius, w, load, n, out=None, name="ratio"):
    """Adhesion ratios of a smooth sphere at a net load [N] (lj law): loaded from
    separation under displacement control, then load control to the target; with ``out``
    its states and solver iterations recorded there (``common.StudyRecorder``)."""
    from contactpetsc import metrics
    from contactpetsc.geometry import surfaces
    from contactpetsc.physics.interactions import make_law, tabor_parameter
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    grid, resolution = common.sphere_grid(radius, w, e_star, Z0_SI, n, load=load, span=4.0)
    law = make_law("lj", work_of_adhesion=w, z0=Z0_SI)
    pb = AdhesiveProblem(grid, surfaces.sphere(grid, radius), e_star, law, prefix="ratio_",
                         element_integration=True)
    rec = None if out is None else common.StudyRecorder(out, name, grid, pb.heights, pb)
    delta = -2.0 * Z0_SI
    st = pb.solve(approach=delta)
    while True:
        if rec is not None:
            rec.record(st, "loading")
        if st.force >= load:
            break
        delta += 0.5 * Z0_SI
        st = pb.solve(approach=delta)
    st = common.reach_load(pb, load, delta)
    if rec is not None:
        rec.record(st, "at-load")
    load_ratio, area_ratio = metrics.adhesion_ratios(grid, st.pressure, law.peak_attraction)
    return dict(case=label, e_star=e_star, radius=radius, w=w, load=load,
                tabor=tabor_parameter(radius, w, e_star, Z0_SI), load_ratio=load_ratio,
                area_ratio=area_ratio, force=st.force, adhesive_force=st.adhesive_force,
                contact_area=metrics.contact_area(grid, st.pressure), approach=st.approach,
                resolution=resolution, dx=grid.dx, n=n)


def run(size="default", outdir="smooth-sphere-output") -> dict:
    import numpy as np
    from contactpetsc.physics.closed_forms import dmt_force, maugis_pull_off_bar

    cfg = SIZES[size]
    out = common.prepare(outdir)
    results = {"size": size, "fig4": {}, "fig5": []}

    # -- Fig. 4a, b: mu = 0.02 -------------------------------------------------------------------
    r_low = 1000.0
    up = np.round(np.arange(-1.5, 0.401, 0.1), 10)
    approaches = np.concatenate([up, up[-2::-1]])
    low = {}
    for law_name in ("lj", "hardwall-lj"):
        c = greenwood_case(0.02, r_low, law_name, cfg["n_low"], cfg["dx_low"], approaches,
                           prefix=f"low_{law_name.replace('-', '')}_", out=out)
        low[law_name] = c
        scale = 2 * np.pi * r_low * c["w"]
        # DMT at the same approaches: the independent reference curve
        dmt = np.array([dmt_force(c["law"], 1.0, r_low, a)[0] for a in c["path"].column("approach")])
        err = np.max(np.abs(c["path"].column("force") - dmt)) / scale
        results["fig4"][f"mu0.02_{law_name}"] = dict(
            tabor=0.02, pull_off_star=c["pull_off"] / scale, jumps=len(c["path"].jumps),
            max_dev_from_dmt_star=float(err), hysteresis_star=_hyst(c["path"]) / scale)
        common.write_csv(out / f"fig4_mu0.02_{law_name}.csv", common.path_rows(c["path"], law=law_name))
        common.say(f"Fig 4a/b mu=0.02 {law_name}: pull-off W* = {c['pull_off'] / scale:.4f} "
                   f"(DMT -1), max |W - W_DMT| = {err:.4f} (2 pi R w)")

    # -- Fig. 4c: mu = 2 -------------------------------------------------------------------------
    r_high, mu_high = 100.0, 2.0
    high = {}
    for law_name, step in cfg["laws_high"].items():
        # loading from beyond the jump-off (alpha* = -3.37) and unloading back there: the
        # loop closes, and its area is the energy the two jumps lose (a path from -3 would
        # miss the adhered branch's stretch below -3)
        up = np.round(np.arange(-4.5, 3.0 + 1e-9, step), 10)
        down = np.round(np.arange(3.0 - step, -4.5 - 1e-9, -step), 10)
        # the S-curve with the lj law (the paper's); central gaps down to 0.05 z0: at g <= 0 the
        # apex is in LJ repulsion and the prescribed gap no longer picks one state (measured:
        # solves left the branch for full contact)
        gaps = np.round(np.concatenate([np.arange(3.0, 0.5, -0.1), np.arange(0.5, 0.04, -0.05)]), 10)
        dx = 3.2 * common.jkr_contact_radius(r_high, np.sqrt(mu_high ** 3 / r_high), 1.0) / cfg["n_high"]
        c = greenwood_case(mu_high, r_high, law_name, cfg["n_high"], dx, np.concatenate([up, down]),
                           prefix=f"high_{law_name.replace('-', '')}_",
                           central_gaps=gaps if law_name == "lj" else None, out=out)
        high[law_name] = c
        scale = 2 * np.pi * r_high * c["w"]
        path = c["path"]
        on = [j for j in path.jumps if j.kind == "jump-on"]
        off = [j for j in path.jumps if j.kind == "jump-off"]
        entry = dict(tabor=mu_high, pull_off_star=c["pull_off"] / scale,
                     pull_off_bar=c["pull_off"] / (np.pi * r_high * c["w"]),
                     maugis_pull_off_bar=maugis_pull_off_bar(1.16 * mu_high),
                     jumps=[dict(kind=j.kind, approach_before=j.approach_before,
                                 approach_after=j.approach_after, force_before_star=j.force_before / scale,
                                 force_after_star=j.force_after / scale) for j in path.jumps],
                     jump_on_approach=on[0].approach_before if on else None,
                     jump_off_approach=off[0].approach_before if off else None,
                     hysteresis_star=_hyst(path) / scale, states=len(path.points),
                     converged_states=sum(p.converged for p in path.points),
                     sub_stepped_states=sum("sub-step" in p.solver for p in path.points))
        if c["s_curve"] is not None:
            sc = c["s_curve"]
            stable = [p.stable for p in sc.points if p.converged]
            entry["s_curve_points"] = len(stable)
            entry["s_curve_unstable_points"] = int(sum(s is False for s in stable))
            common.write_csv(out / "fig4c_central_gap.csv", common.path_rows(sc, law=law_name))
        results["fig4"][f"mu2_{law_name}"] = entry
        common.write_csv(out / f"fig4c_mu2_{law_name}.csv", common.path_rows(path, law=law_name))
        common.say(f"Fig 4c mu=2 {law_name}: pull-off P/(pi R w) = {entry['pull_off_bar']:.3f} "
                   f"(Maugis-Dugdale {entry['maugis_pull_off_bar']:.3f}), jumps "
                   f"{[(j['kind'], round(j['approach_before'], 3)) for j in entry['jumps']]}, "
                   f"{entry['converged_states']} of {entry['states']} states converged")

    # -- Fig. 5: adhesion ratios -------------------------------------------------------------------
    for case in RATIO_CASES:
        row = ratio_case(*case, n=cfg["n_ratio"], out=out, name=f"fig5_{len(results['fig5'])}")
        results["fig5"].append(row)
        common.say(f"Fig 5 {row['case']:>22}: mu = {row['tabor']:.3f}, load ratio {row['load_ratio']:.3f}, "
                   f"area ratio {row['area_ratio']:.3f}")
    common.write_csv(out / "fig5.csv", results["fig5"])
    common.write_json(out / "smooth_sphere.json", results)
    if common.is_root():
        _plots(out, low, high, r_low, r_high, results["fig5"])
    return results


def _hyst(path) -> float:
    from contactpetsc.metrics import path_hysteresis
    return path_hysteresis(path)


def _plots(out, low, high, r_low, r_high, ratios):
    import numpy as np
    from contactpetsc.physics.closed_forms import dmt_force
    plt = common.plt()
    fig, axes = plt.subplots(1, 3, figsize=(16, 5))
    for ax, cases, r, title in ((axes[0], {"lj": low["lj"]}, r_low, "(a) mu = 0.02, full LJ"),
                                (axes[1], low, r_low, "(b) mu = 0.02, full LJ vs hard wall"),
                                (axes[2], high, r_high, "(c) mu = 2")):
        for (name, c), color in zip(cases.items(), ("C0", "C3")):
            scale = 2 * np.pi * r * c["w"]
            common.load_approach(ax, c["path"], 1.0, scale, name, color)
            if c["s_curve"] is not None:
                common.load_approach(ax, c["s_curve"], 1.0, scale, name, "C2")
        if r == r_low:
            c = next(iter(cases.values()))
            a = np.linspace(-1.5, 0.4, 80)
            ax.plot(a, [dmt_force(c["law"], 1.0, r, x)[0] / (2 * np.pi * r * c["w"]) for x in a],
                    "k--", lw=1, label="DMT (Muller et al.)")
        if r == r_high:
            ax.set_xlim(-4.7, 3.5)
            ax.set_ylim(-1.2, 1.5)
        common.dress(ax, "alpha* = delta / z0", "W* = W / (2 pi R w)", title, zero_line=True, legend_size=6)
    common.savefig(fig, out / "fig4.png")
    fig, ax = plt.subplots(figsize=(8, 4.5))
    x = np.arange(len(ratios))
    ax.bar(x - 0.2, [r["load_ratio"] for r in ratios], 0.4, label="adhesive load ratio")
    ax.bar(x + 0.2, [r["area_ratio"] for r in ratios], 0.4, label="adhesive area ratio")
    ax.set_xticks(x, [f"{r['case']}\nmu={r['tabor']:.2f}" for r in ratios], fontsize=7)
    ax.set_ylim(0, 1)
    ax.legend()
    ax.set_title("Fig. 5: adhesion ratios of smooth spheres (1 % cut-off)")
    common.savefig(fig, out / "fig5.png")


if __name__ == "__main__":
    args = common.parse(__doc__.splitlines()[0], "smooth-sphere-output")
    run(args.size, args.out)
