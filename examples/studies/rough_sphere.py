"""Rough spheres (reference paper, section 3.2, Figs. 6-9).

    python examples/studies/rough_sphere.py [--size small|default|tabor5] [--rms Z ...] [--out DIR]
    python examples/studies/rough_sphere.py --collect DIR [DIR ...] [--out DIR]
    python examples/studies/rough_sphere.py [--size ...] --case reference|stiff|stiff-w --out DIR
    python examples/studies/rough_sphere.py --case-figures REF_DIR [STIFF_DIR STIFF_W_DIR] [--out DIR]
    mpirun -n 2 python examples/studies/rough_sphere.py

The paper: a sphere R = 100 um, E* = 50 GPa, z0 = 0.3 nm, w = 0.29 J/m^2
(Tabor parameter 5), net load 0.05 mN, against one Gaussian random surface
scaled vertically to rms = 0 ... 10 z0 (same pattern at every rms).  We keep
R, E*, z0 and the load and lower w to give Tabor parameters 2 (w = 0.0734)
and 1 (w = 0.0259): the elements must resolve the adhesive zone, and the
nodes that takes grow as mu^2 (p_peak dx / (E* z0) < ~1 with a window of a
few contact radii); mu = 5 needs ~6x finer grids than mu = 2 for the same
snap number K_ii max da/dg (0.80 at mu = 2, 64^2): ``--size tabor5``, 512^2,
rms 0, 1, 2, 4 and 10 z0, best run as one job per rms value (``--rms``) merged by
``--collect`` (measured with run_scripts/checks/tabor5_steps.py: at rms 0 every
loading step converges, the jump-in included, 20-25 s a step after it, 13 z0
of approach to the load; 384^2 fails at the jump-in; docs/studies.md).  The
roughness: Gaussian autocorrelation, correlation length a_JKR / 6.

For each Tabor parameter and rms: loading in displacement control from
separation to the load (Newton on the approach for the last step), the
adhesive load and area ratios there (1 % cut-off) and the pressure map
(Fig. 6); then unloading to separation: pull-off force (Fig. 7a), the
loading/unloading curves and their hysteresis (Fig. 9a).  Fig. 8: at
rms = 2 z0, cross-sections for the reference, a 4x stiffer material, and a
4x stiffer material with 4x the work of adhesion (same Tabor parameter), at
the same load and at the same approach.

``--case``: one case of Fig. 8 at rms = 2 z0 and the size's first Tabor parameter
(one job each, e.g. at ``--size tabor5``), every state's pressure and gap saved; the
reference unloads back to stage A of Fig. 9b.  ``--case-figures`` draws Fig. 9b (the
stages A-E, ``metrics.jump_in_stages``) and Fig. 8 from those saved fields.

Outputs in --out: rough_sphere.csv (one row per mu and rms), paths_*.csv,
states_*.csv and history_*.csv per path (``common.StudyRecorder``), fig6.png,
fig7.png, fig8.png, fig9.png, rough_sphere.json; with --case: case.json,
paths.csv, jumps.csv, states_path.csv, history_path.csv, path/step_NNNN.h5; with
--case-figures: fig9b.png, fig9b.csv, fig8.png, fig8.csv.
Sizes: default 64^2 (dx 35 nm, window 2.2 um), rms 0, 0.5, 1, 2, 4, 10 z0,
mu 2 and 1, approach steps of 0.5 z0; small 32^2, rms 0 and 2 z0, mu 1, steps of
1 z0.  The paper does not state its grid.
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

R, E_STAR, Z0, LOAD = 100e-6, 50e9, 0.3e-9, 0.05e-3      # the paper's (m, Pa, m, N)
W_PAPER = 0.29                                            # J/m^2: mu = 5
SIZES = {
    "small": dict(n=32, rms=[0.0, 2.0], tabor=[1.0], step=1.0, fig8=True),
    "default": dict(n=64, rms=[0.0, 0.5, 1.0, 2.0, 4.0, 10.0], tabor=[2.0, 1.0], step=0.5, fig8=True),
    # the paper's own Tabor parameter: K_ii max da/dg = 0.56, 1.9 nodes per cohesive zone
    # (384^2, 0.75 and 1.4, failed at the jump-in; 512^2 follows it)
    # 400 Newton steps: at rms = z0 the jump-in at -3 z0 needs more than 100 on the coarse
    # levels of the nested iteration (with 100 it failed, PTC too; with 400 it converged)
    # one rms value per job (--rms) and --collect afterwards: 0.5-2 h per value on one core
    "tabor5": dict(n=512, rms=[0.0, 1.0, 2.0, 4.0, 10.0], tabor=[5.0], step=1.0, fig8=False,
                   options=dict(max_it=400)),
}


def work_for(mu, radius=R, e_star=E_STAR, z0=Z0):
    """w [J/m^2] of Tabor parameter mu."""
    return (mu ** 3 * e_star ** 2 * z0 ** 3 / radius) ** 0.5


def make_grid(n, mu, comm=None):
    """The window for Tabor parameter mu at the load (the first of a run's, used for every
    case so that all share one roughness pattern)."""
    return common.sphere_grid(R, work_for(mu), E_STAR, Z0, n, load=LOAD, span=3.2, comm=comm)


def roughness(grid, seed=1):
    """The one random pattern (Gaussian autocorrelation, unit rms)."""
    from contactpetsc.geometry import surfaces
    corr = common.jkr_contact_radius(R, work_for(2.0), E_STAR, LOAD) / 6
    return surfaces.gaussian_correlated(grid, rms_height=1.0, correlation_length=corr, seed=seed)


def loading_start(mu):
    """First approach [m] of a loading path: below the smooth sphere's jump-off in
    displacement control (JKR: -3/4 pi^(2/3) mu z0, -3.2 z0 at mu = 2, -8.0 z0 at mu = 5)
    with a margin, and below its jump-on (-2.5 z0 at mu = 2): unloading back to it closes
    the hysteresis loop."""
    import numpy as np
    return -max(5.0, np.ceil(0.75 * np.pi ** (2 / 3) * mu + 1.5)) * Z0


def load_unload(grid, heights, e_star, w, step, prefix, unload=True, refine=4, out=None, name=None):
    """Loading path to LOAD (last step by load control), the state there, then unloading;
    with ``out`` every state and solver iteration recorded there under ``name``
    (``common.StudyRecorder``).

    Loading samples the approaches start + k step z0; unloading returns through the same
    approaches (from the largest below the state at the load), so that where the two
    curves coincide their samples do too and the hysteresis integrand vanishes there
    (``metrics.path_hysteresis``).  Jumps are located to step / 2^refine.
    Returns (path, state at the load (fields copied), problem)."""
    import numpy as np
    from contactpetsc.paths import sweep
    from contactpetsc.physics.interactions import make_law, tabor_parameter
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    law = make_law("lj", work_of_adhesion=w, z0=Z0)
    pb = AdhesiveProblem(grid, heights, e_star, law, prefix=prefix, element_integration=True)
    rec = None if out is None else common.StudyRecorder(out, name, grid, heights, pb)
    start = loading_start(tabor_parameter(R, w, e_star, Z0))
    path = common.load_until(pb, start, step * Z0, LOAD, refine, on_state=rec)
    st = common.reach_load(pb, LOAD, path.points[-1].approach)
    if rec is not None:
        rec.record(st, "at-load")
    at_load = dict(state=st, pressure=st.pressure.copy(), gap=st.gap.copy(), law=law)
    if unload:
        top = int(np.floor((st.approach - start) / (step * Z0) + 1e-9))
        sweep(pb, start + np.arange(top, -1, -1) * step * Z0, refine=refine, path=path, branch="unloading",
              on_state=rec)
    return path, at_load, pb


def run(size="default", outdir="rough-sphere-output", rms=None) -> dict:
    import numpy as np
    from contactpetsc import metrics
    from contactpetsc.geometry import surfaces
    from contactpetsc.physics.interactions import tabor_parameter

    cfg = dict(SIZES[size])
    if rms is not None:
        cfg["rms"] = [float(r) for r in rms]   # a subset of rms values [z0], e.g. one per job
    out = common.prepare(outdir)
    grid, _ = make_grid(cfg["n"], cfg["tabor"][0])
    base = roughness(grid)
    rows, maps, paths = [], {}, {}
    for mu in cfg["tabor"]:
        w = work_for(mu)
        resolution = 16 * w / (9 * np.sqrt(3) * Z0) * grid.dx / (E_STAR * Z0)
        set_defaults(f"rough_mu{mu:g}_", cfg.get("options", {}))
        for rms in cfg["rms"]:
            rough = surfaces.scale_to_rms(grid, base, rms * Z0)
            h = surfaces.rough_sphere(grid, R, rough)
            path, at, pb = load_unload(grid, h, E_STAR, w, cfg["step"], prefix=f"rough_mu{mu:g}_", out=out,
                                       name=f"mu{mu:g}_rms{rms:g}")
            st = at["state"]
            load_ratio, area_ratio = metrics.adhesion_ratios(grid, at["pressure"], at["law"].peak_attraction)
            scale = 2 * np.pi * R * w
            hyst, hyst_err = metrics.hysteresis_estimate(path)
            row = dict(tabor=tabor_parameter(R, w, E_STAR, Z0), w=w, rms_z0=rms, load=st.force,
                       approach_z0=st.approach / Z0, load_ratio=load_ratio, area_ratio=area_ratio,
                       adhesive_force=st.adhesive_force,
                       contact_area=metrics.contact_area(grid, at["pressure"]),
                       mean_gap_z0=metrics.mean_gap(grid, at["gap"], at["pressure"]) / Z0,
                       pull_off=path.pull_off_force, pull_off_star=path.pull_off_force / scale,
                       hysteresis=hyst, hysteresis_error=hyst_err,
                       hysteresis_star_z0=hyst / (scale * Z0), hysteresis_error_star_z0=hyst_err / (scale * Z0),
                       peak_pressure=float(at["pressure"].max()[1]), jumps=len(path.jumps),
                       max_jump_star=max([abs(j.force_after - j.force_before) for j in path.jumps] + [0.0]) / scale,
                       resolution=resolution, n=cfg["n"], dx=grid.dx)
            rows.append(row)
            common.say(f"mu={mu:g} rms={rms:4.1f} z0: load ratio {load_ratio:.3f}, area ratio {area_ratio:.3f}, "
                       f"pull-off {path.pull_off_force * 1e3:.4f} mN (W* {row['pull_off_star']:.3f}), "
                       f"jumps {len(path.jumps)}, largest jump W* {row['max_jump_star']:.3f}, "
                       f"hysteresis {hyst / (scale * Z0):.3f} +- {hyst_err / (scale * Z0):.3f} (2 pi R w z0)")
            maps[(mu, rms)] = grid.gather(at["pressure"], root=0)
            paths[(mu, rms)] = path
            common.write_csv(out / f"paths_mu{mu:g}_rms{rms:g}.csv", common.path_rows(path, tabor=mu, rms_z0=rms))
            common.write_csv(out / f"jumps_mu{mu:g}_rms{rms:g}.csv", common.jump_rows(path, tabor=mu, rms_z0=rms))
            for v in (at["pressure"], at["gap"]):
                v.destroy()
    common.write_csv(out / "rough_sphere.csv", rows)
    results = {"size": size, "rows": rows, "grid": dict(n=cfg["n"], dx=grid.dx)}
    if cfg["fig8"]:
        results["fig8"] = fig8(grid, base, out, mu=cfg["tabor"][0])
    common.write_json(out / "rough_sphere.json", results)
    if common.is_root():
        _plots(out, grid, cfg, rows, maps, paths)
    return results


def fig8(grid, base, out, rms=2.0, mu=2.0, stiff=4.0):
    """Reference, stiffer, and stiffer with w scaled (same mu) at rms = 2 z0: same load and
    same approach; gaps and ratios at the same approach compared."""
    import numpy as np
    from contactpetsc import metrics
    from contactpetsc.geometry import surfaces
    h = surfaces.rough_sphere(grid, R, surfaces.scale_to_rms(grid, base, rms * Z0))
    w = work_for(mu)
    cases = [("reference", E_STAR, w), ("E* x4", stiff * E_STAR, w), ("E* x4, w x4", stiff * E_STAR, stiff * w)]
    res, sections = {}, {}
    delta_ref = None
    for k, (name, e, ww) in enumerate(cases):
        path, at, pb = load_unload(grid, h, e, ww, 1.0, prefix=f"fig8_{k}_", unload=False, out=out,
                                   name=f"fig8_{k}")
        lr, ar = metrics.adhesion_ratios(grid, at["pressure"], at["law"].peak_attraction)
        entry = dict(e_star=e, w=ww, approach_z0=at["state"].approach / Z0, load_ratio=lr, area_ratio=ar,
                     contact_area=metrics.contact_area(grid, at["pressure"]))
        gap_load = grid.gather(at["gap"], root=0)
        p_load = grid.gather(at["pressure"], root=0)
        if delta_ref is None:
            delta_ref = at["state"].approach
        # the same approach as the reference at the load
        st = pb.solve(approach=delta_ref)
        lr2, ar2 = metrics.adhesion_ratios(grid, st.pressure, at["law"].peak_attraction)
        entry.update(same_approach_load_ratio=lr2, same_approach_area_ratio=ar2, same_approach_force=st.force)
        gap_appr = grid.gather(st.gap)
        if k == 0:
            gap0 = gap_appr
        entry["same_approach_max_gap_difference_z0"] = float(np.max(np.abs(gap_appr - gap0)) / Z0)
        res[name] = entry
        sections[name] = (gap_load, p_load)
        common.say(f"Fig 8 {name}: at the load: approach {entry['approach_z0']:.2f} z0, load ratio {lr:.3f}, "
                   f"area ratio {ar:.3f}; at the reference's approach: load ratio {lr2:.3f}, area ratio "
                   f"{ar2:.3f}, max gap difference {entry['same_approach_max_gap_difference_z0']:.2e} z0")
        for v in (at["pressure"], at["gap"]):
            v.destroy()
    if common.is_root():
        plt = common.plt()
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        j = grid.ny // 2
        x = (np.arange(grid.nx) - grid.nx // 2) * grid.dx * 1e9
        for name, (gap, p) in sections.items():
            a1.plot(x, gap[:, j] / Z0, label=name)
            a2.plot(x, p[:, j] / 1e9, label=name)
        a1.set_ylim(-1, 12)
        common.dress(a1, "", "gap / z0", f"Fig. 8: cross-sections at the load, rms = {rms:g} z0",
                     legend_size=7)
        common.dress(a2, "x [nm]", "pressure [GPa]", zero_line=True)
        common.savefig(fig, out / "fig8.png")
    return res


#: Fig. 8's cases: (factor on E*, factor on w)
CASES = {"reference": (1.0, 1.0), "stiff": (4.0, 1.0), "stiff-w": (4.0, 4.0)}


def set_defaults(prefix, options):
    """A size's code defaults for the options of ``prefix``; the command line wins."""
    from petsc4py import PETSc
    opts = PETSc.Options(prefix)
    for key, value in options.items():
        if not opts.hasName(key):
            opts.setValue(key, value)


def case_parameters(case, size="tabor5", rms=2.0):
    """(grid, parameters) of a ``case_run``: the window of the size's first Tabor parameter
    and the case's E* [Pa], w [J/m^2], Tabor parameter, rms [z0], n and dx [m] (what
    case.json holds before anything is solved)."""
    from contactpetsc.physics.interactions import tabor_parameter
    cfg = SIZES[size]
    grid, _ = make_grid(cfg["n"], cfg["tabor"][0])
    e, w = CASES[case][0] * E_STAR, CASES[case][1] * work_for(cfg["tabor"][0])
    return grid, dict(case=case, size=size, e_star=e, w=w, tabor=tabor_parameter(R, w, e, Z0), rms_z0=rms,
                      n=cfg["n"], dx=grid.dx)


def case_run(case, size="tabor5", outdir="rough-sphere-case", rms=2.0, refine=4) -> dict:
    """One case of Fig. 8 at rms [z0] (``CASES``), loaded to LOAD with every state's pressure
    and gap saved (``common.StudyRecorder``: ``path/step_NNNN.h5``); the reference then
    unloads from the state at the load (stage D of Fig. 9b) back through the loading
    approaches to stage A's (``metrics.jump_in_stages``), whose last state is stage E.
    Writes case.json (``case_parameters`` first, then the case at the load), paths.csv,
    jumps.csv, states_path.csv and history_path.csv into ``outdir``.  Collective."""
    import numpy as np
    from contactpetsc import metrics
    from contactpetsc.geometry import surfaces
    from contactpetsc.paths import sweep
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    cfg = SIZES[size]
    out = common.prepare(outdir)
    grid, res = case_parameters(case, size, rms)
    common.write_json(out / "case.json", res)
    h = surfaces.rough_sphere(grid, R, surfaces.scale_to_rms(grid, roughness(grid), rms * Z0))
    e, w, mu = res["e_star"], res["w"], res["tabor"]
    prefix = f"fig8_{case.replace('-', '_')}_"
    set_defaults(prefix, cfg.get("options", {}))
    law = make_law("lj", work_of_adhesion=w, z0=Z0)
    pb = AdhesiveProblem(grid, h, e, law, prefix=prefix, element_integration=True)
    rec = common.StudyRecorder(out, "path", grid, h, pb, fields=True)
    start, step = loading_start(mu), cfg["step"] * Z0
    path = common.load_until(pb, start, step, LOAD, refine, on_state=rec)
    n_loading = rec.states
    st = common.reach_load(pb, LOAD, path.points[-1].approach)
    at_load = rec.record(st, "at-load")
    load_ratio, area_ratio = metrics.adhesion_ratios(grid, st.pressure, law.peak_attraction)
    res.update(approach_z0=st.approach / Z0, load=st.force, load_ratio=load_ratio, area_ratio=area_ratio,
               contact_area=metrics.contact_area(grid, st.pressure), at_load_state=at_load,
               peak_pressure=float(st.pressure.max()[1]))
    common.say(f"{case}: mu {mu:.2f}, at the load approach {res['approach_z0']:.2f} z0, load ratio {load_ratio:.3f}, "
               f"area ratio {area_ratio:.3f}, contact area {res['contact_area'] * 1e12:.4f} um^2")
    if case == "reference":
        loading = path.points[:n_loading]
        stages = metrics.jump_in_stages([p.approach for p in loading], [p.force for p in loading],
                                        [p.contact_fraction for p in loading],
                                        jumps=[(j.approach_before, j.approach_after) for j in path.jumps
                                               if j.kind == "jump-on"])
        if stages is not None:
            top = int(np.floor((st.approach - start) / step + 1e-9))
            k_a = int(round((loading[stages[0]].approach - start) / step))
            sweep(pb, start + np.arange(top, k_a - 1, -1) * step, refine=refine, path=path, branch="unloading",
                  on_state=rec)
    common.write_csv(out / "paths.csv", common.path_rows(path, case=case, rms_z0=rms))
    common.write_csv(out / "jumps.csv", common.jump_rows(path, case=case, rms_z0=rms))
    common.write_json(out / "case.json", res)
    return res


def stages_of(states, jumps=None) -> dict:
    """{stage: state number} of Fig. 9b from a ``case_run``'s states_path.csv columns: A, B, C
    on the loading rows (``metrics.jump_in_stages``, across the located jump-ons of
    jumps.csv's columns ``jumps`` when given), D the state at the load (the last loading
    state of a run that has not reached it), E the unloading state at A's approach (where
    the run got there).  Empty when no fall of the loading force qualifies."""
    import numpy as np
    from contactpetsc import metrics
    branch = np.array(states["branch"])
    load = np.flatnonzero(branch == "loading")
    ons = None if jumps is None else [(lo, hi) for k, lo, hi in zip(jumps["kind"], jumps["approach_before"],
                                                                    jumps["approach_after"]) if k == "jump-on"]
    found = metrics.jump_in_stages(states["approach"][load], states["force"][load],
                                   states["contact_fraction"][load], jumps=ons)
    if found is None:
        return {}
    out = {k: int(states["state"][load[i]]) for k, i in zip("ABC", found) if i is not None}
    at = np.flatnonzero(branch == "at-load")
    out["D"] = int(states["state"][at[0] if at.size else load[-1]])
    a = states["approach"][load[found[0]]]
    back = np.flatnonzero((branch == "unloading") & np.isclose(states["approach"], a, rtol=0, atol=1e-6 * Z0))
    if back.size:
        out["E"] = int(states["state"][back[0]])
    return out


def _read_case(case_dir):
    """(case.json, states_path.csv columns) of a ``case_run`` output directory."""
    import json
    from pathlib import Path
    from contactpetsc.app.plots import read_csv
    d = Path(case_dir)
    with open(d / "case.json") as f:
        info = json.load(f)
    return info, read_csv(str(d / "states_path.csv"))


def _crop(ax, pressures, dx, threshold):
    """Limits of a map panel [nm]: the box of nodes with |p| > threshold in any of ``pressures``
    ((nx, ny) arrays), with a margin of a tenth of its size."""
    import numpy as np
    mask = np.any([np.abs(p) > threshold for p in pressures], axis=0)
    i, j = np.nonzero(mask)
    if i.size == 0:
        return
    lo, hi = min(i.min(), j.min()), max(i.max(), j.max()) + 1
    pad = 0.1 * (hi - lo)
    ax.set_xlim((lo - pad) * dx * 1e9, (hi + pad) * dx * 1e9)
    ax.set_ylim((lo - pad) * dx * 1e9, (hi + pad) * dx * 1e9)


def stage_maps(case_dir, outdir) -> dict:
    """Fig. 9b from a reference ``case_run`` (its saved fields; nothing is solved): the
    load-approach curve of its states with the stages A-E marked, and the pressure maps of
    the five stages, each circled where its pressure fell most since A (B, E: the asperity
    that jumped in and holds on) or rose most since C (D: new contact), where that change
    exceeds 1 % of the law's peak attraction.  Writes
    fig9b.png and fig9b.csv (the stages' approach, force, ratios) into ``outdir``; returns
    the rows."""
    import numpy as np
    from pathlib import Path
    from types import SimpleNamespace
    from contactpetsc.app.plots import read_csv
    info, states = _read_case(case_dir)
    jumps = Path(case_dir) / "jumps.csv"
    # no jumps.csv (a run not finished, or no jumps): the falls of force are taken as they are
    stages = stages_of(states, read_csv(str(jumps)) if jumps.exists() else None)
    if not stages:
        raise SystemExit(f"{case_dir}: no stages (not a reference case, or its force never fell in contact)")
    out = common.prepare(outdir)
    fields = {k: common.read_state_fields(Path(case_dir) / "path", s) for k, s in stages.items()}
    p_peak = 16 * info["w"] / (9 * np.sqrt(3) * Z0)
    rows = []
    for k, f in fields.items():
        p = f["pressure"]
        rows.append(dict(stage=k, state=stages[k], approach_z0=f["approach"] / Z0, force_mN=f["force"] * 1e3,
                         adhesive_force_mN=p[p < 0].sum() * info["dx"] ** 2 * 1e3,
                         contact_area_um2=(p > 0).sum() * info["dx"] ** 2 * 1e12))
    common.write_csv(out / "fig9b.csv", rows)
    if not common.is_root():
        return rows
    plt = common.plt()
    fig = plt.figure(figsize=(15, 8.5))
    ax = fig.add_subplot(2, 3, 1)
    for branch, style in (("loading", "o-"), ("at-load", "s"), ("unloading", "v-")):
        sel = [i for i, b in enumerate(states["branch"]) if b == branch]
        ax.plot(states["approach"][sel] / Z0, states["force"][sel] * 1e3, style, ms=3, lw=0.8,
                mfc="none" if branch == "unloading" else None, label=branch)
    for r in rows:
        ax.annotate(r["stage"], (r["approach_z0"], r["force_mN"]), textcoords="offset points",
                    xytext=(4, -14) if r["stage"] == "E" else (4, 6),
                    fontsize=11, color="C3", weight="bold")
        ax.plot(r["approach_z0"], r["force_mN"], "o", color="C3", ms=6, mfc="none")
    lo = min(r["approach_z0"] for r in rows) - 3
    ax.set_xlim(lo, max(r["approach_z0"] for r in rows) + 1)
    sel = states["approach"] / Z0 >= lo
    ax.set_ylim(states["force"][sel].min() * 1e3 - 0.005, states["force"][sel].max() * 1e3 + 0.005)
    common.dress(ax, "approach / z0", "force [mN]", f"Fig. 9b: stages, mu = {info['tabor']:.2g}, "
                 f"rms = {info['rms_z0']:g} z0, {info['n']}^2", zero_line=True, legend_size=7)
    grid = SimpleNamespace(lengths=(info["n"] * info["dx"], info["n"] * info["dx"]))
    marks = {"B": ("A", -1), "E": ("A", -1), "D": ("C", 1)}
    reached = "at-load" in states["branch"]
    for m, (k, f) in enumerate(fields.items()):
        ax = fig.add_subplot(2, 3, m + 2)
        ax.set_xlabel("x [nm]")
        name = k if reached or k != "D" else "D (the run's last state)"
        common.pressure_map(ax, grid, f["pressure"], f"{name}: approach {f['approach'] / Z0:.2f} z0, "
                            f"force {f['force'] * 1e3:.4f} mN", scale=1e9, unit="GPa")
        _crop(ax, [g["pressure"] for g in fields.values()], info["dx"], 0.01 * p_peak)
        if k in marks and marks[k][0] in fields:
            change = marks[k][1] * (f["pressure"] - fields[marks[k][0]]["pressure"])
            i, j = np.unravel_index(np.argmax(change), change.shape)
            x0, x1 = ax.get_xlim()
            if change[i, j] >= 0.01 * p_peak:     # else nothing changed there (E = A: nothing holds on)
                ax.add_patch(plt.Circle(((i + 0.5) * info["dx"] * 1e9, (j + 0.5) * info["dx"] * 1e9),
                                        0.06 * (x1 - x0), fill=False, color="k", lw=1.2))
    common.savefig(fig, out / "fig9b.png")
    return rows


def case_figures(dirs, outdir) -> list[dict]:
    """Fig. 8 from ``case_run`` outputs (the three cases, any order; saved fields, nothing
    solved): the gap and pressure through the apex row at the load, and fig8.csv (each case
    at the load: approach, force, ratios and contact area from its saved state, with
    ``metrics``).  A case whose run has not reached the load is left out.  Returns the rows."""
    import numpy as np
    from pathlib import Path
    from petsc4py import PETSc
    from contactpetsc import metrics
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.physics.interactions import make_law
    cases = []
    for d in dirs:
        info, states = _read_case(d)
        at = [int(k) for k, b in zip(states["state"], states["branch"]) if b == "at-load"]
        if not at:
            common.say(f"{d}: the {info['case']} case has not reached the load: left out of Fig. 8")
            continue
        cases.append((info, common.read_state_fields(Path(d) / "path", at[0])))
    cases.sort(key=lambda c: list(CASES).index(c[0]["case"]))
    out = common.prepare(outdir)
    rows = []
    for info, f in cases:
        grid = SurfaceGrid(info["n"], info["n"], info["dx"], periodic=False, comm=PETSc.COMM_SELF)
        p = grid.vec_from_array(f["pressure"])
        lr, ar = metrics.adhesion_ratios(grid, p, make_law("lj", work_of_adhesion=info["w"], z0=Z0).peak_attraction)
        rows.append(dict(case=info["case"], e_star=info["e_star"], w=info["w"], tabor=info["tabor"],
                         approach_z0=f["approach"] / Z0, load=f["force"], load_ratio=lr, area_ratio=ar,
                         contact_area=metrics.contact_area(grid, p), peak_pressure=float(f["pressure"].max()),
                         n=info["n"], dx=info["dx"]))
        p.destroy()
    common.write_csv(out / "fig8.csv", rows)
    if common.is_root() and cases:
        plt = common.plt()
        fig, (a1, a2) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
        info0 = cases[0][0]
        n, dx = info0["n"], info0["dx"]
        j = n // 2
        x = (np.arange(n) - n // 2) * dx * 1e9
        for info, f in cases:
            label = f"{info['case']} (mu = {info['tabor']:.2g})"
            a1.plot(x, f["gap"][:, j] / Z0, label=label, lw=0.9)
            a2.plot(x, f["pressure"][:, j] / 1e9, label=label, lw=0.9)
        reach = max(np.abs(x[np.abs(f["pressure"][:, j]) > 1e-3 * np.abs(f["pressure"]).max()]).max()
                    for _, f in cases)
        a1.set_xlim(-1.2 * reach, 1.2 * reach)
        a1.set_ylim(-1, 12)
        common.dress(a1, "", "gap / z0", f"Fig. 8: through the apex at {LOAD * 1e3:g} mN, rms = "
                     f"{info0['rms_z0']:g} z0, {n}^2", legend_size=7)
        common.dress(a2, "x [nm]", "pressure [GPa]", zero_line=True)
        common.savefig(fig, out / "fig8.png")
    return rows


def collect(dirs, outdir) -> list[dict]:
    """Figs. 7 and 9a over the outputs of several runs (e.g. one job per rms value at
    ``--size tabor5``): their rough_sphere.csv rows and paths_*.csv, merged into --out."""
    from pathlib import Path
    from types import SimpleNamespace
    from contactpetsc.app.plots import read_csv

    def read(path):
        cols = read_csv(path)
        return [dict(zip(cols, values)) for values in zip(*cols.values())]

    rows, paths = [], {}
    for d in dirs:
        for r in read(Path(d) / "rough_sphere.csv"):
            mu, rms = round(r["tabor"], 6), r["rms_z0"]
            pts = [SimpleNamespace(converged=True, **p)
                   for p in read(Path(d) / f"paths_mu{round(mu):g}_rms{rms:g}.csv")]
            rows.append(r)
            paths[(mu, rms)] = SimpleNamespace(points=pts)
    if not rows:
        raise SystemExit(f"--collect: no rough_sphere.csv rows in {', '.join(map(str, dirs))}")
    rows.sort(key=lambda r: (r["tabor"], r["rms_z0"]))
    out = common.prepare(outdir)
    common.write_csv(out / "rough_sphere.csv", rows)
    if common.is_root():
        tabor = sorted({round(r["tabor"], 6) for r in rows}, reverse=True)
        cfg = dict(tabor=tabor, rms=sorted({r["rms_z0"] for r in rows}))
        _plots(out, None, cfg, rows, None, paths)
    return rows


def _plots(out, grid, cfg, rows, maps, paths):
    """Figs. 6 (when ``maps``), 7 and 9a."""
    import numpy as np
    plt = common.plt()
    mu0 = cfg["tabor"][0]
    rms_list = cfg["rms"]
    if maps is not None:
        fig, axes = plt.subplots(1, len(rms_list), figsize=(3.6 * len(rms_list), 3.4))
        for ax, rms in zip(np.atleast_1d(axes), rms_list):
            common.pressure_map(ax, grid, maps[(mu0, rms)], f"rms = {rms:g} z0", scale=1e9, unit="GPa",
                                extent_unit=1e-9)
            ax.set_xlabel("x [nm]")
        common.savefig(fig, out / "fig6.png")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for mu, color in zip(cfg["tabor"], ("C0", "C3")):
        sel = [r for r in rows if r["tabor"] and abs(r["tabor"] - mu) < 0.01]
        x = [r["rms_z0"] for r in sel]
        a1.plot(x, [r["pull_off"] * 1e3 for r in sel], "o-", color=color, label=f"mu = {mu:g}")
        a2.plot(x, [r["load_ratio"] for r in sel], "o-", color=color, label=f"load ratio, mu = {mu:g}")
        a2.plot(x, [r["area_ratio"] for r in sel], "s--", color=color, mfc="none", label=f"area ratio, mu = {mu:g}")
    a2.set_ylim(0, 1)
    common.dress(a1, "rms / z0", "pull-off force [mN]", "Fig. 7a: pull-off against rms", legend_size=8)
    common.dress(a2, "rms / z0", "ratio", "Fig. 7b: adhesion ratios at 0.05 mN", legend_size=7)
    common.savefig(fig, out / "fig7.png")
    fig, ax = plt.subplots(figsize=(7, 5))
    for rms, color in zip(rms_list, [f"C{k}" for k in range(10)]):
        common.load_approach(ax, paths[(mu0, rms)], Z0, 1e-3, f"rms {rms:g} z0", color)
    common.dress(ax, "approach / z0", "force [mN]", f"Fig. 9a: loading and unloading, mu = {mu0:g}",
                 zero_line=True, legend_size=6)
    common.savefig(fig, out / "fig9.png")


def _extra(ap):
    ap.add_argument("--rms", type=float, nargs="+", help="rms values [z0] instead of the size's")
    ap.add_argument("--case", choices=tuple(CASES),
                    help="one case of Fig. 8 at rms 2 z0 (the reference with Fig. 9b's stages), every state saved")
    ap.add_argument("--case-figures", nargs="+", metavar="DIR",
                    help="no run: Fig. 9b from the first --case output (the reference) and Fig. 8 from all "
                         "given (the three cases), into --out")
    ap.add_argument("--collect", nargs="+", metavar="DIR",
                    help="no run: Figs. 7 and 9a from these runs' outputs (one job per rms), into --out")


if __name__ == "__main__":
    args = common.parse(__doc__.splitlines()[0], "rough-sphere-output", sizes=tuple(SIZES),
                        extra=_extra)
    if args.collect:
        collect(args.collect, args.out)
    elif args.case_figures:
        stage_maps(args.case_figures[0], args.out)
        if len(args.case_figures) > 1:
            case_figures(args.case_figures, args.out)
    elif args.case:
        case_run(args.case, args.size, args.out)
    else:
        run(args.size, args.out, rms=args.rms)
