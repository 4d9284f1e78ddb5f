"""Atomic-scale tips (reference paper, section 3.3, Figs. 10-12).

    python examples/studies/atomic_tips.py [--size small|default|resolution] [--out DIR]
    mpirun -n 2 python examples/studies/atomic_tips.py

The four tips of Luan & Robbins (2006) as hard-sphere profiles
(``contactpetsc.geometry.tips``): bent commensurate, bent incommensurate, amorphous,
stepped; radius R = 100 sigma, counter-surface spacing d = 2^(1/6) sigma,
atom radius d / 2.  LJ units (sigma = epsilon = 1): tip-substrate epsilon_ts
= 0.5 epsilon and r0 = sigma give, by the paper's relations
(``lj_from_atomistic``), z0 = (2/15)^(1/6) sigma = 0.715 sigma and
w = 9 epsilon_ts / (2 pi z0^2) = 1.40 epsilon / sigma^2.  E* = 55 epsilon /
sigma^3 (our choice, the order of Luan & Robbins' substrate modulus; the
reference paper does not give it): Tabor parameter 0.56.  Full LJ law,
element-integrated.

For each tip: loading from separation to W_max and unloading past pull-off
(displacement control); contact radius sqrt(A / pi) (A: nodes with p > 0)
against load (Fig. 12a); the unloading (pull-off) curve (Fig. 12b) and the
effective work of adhesion, the area between its tensile part and the load
axis, -int min(W, 0) d delta down to 2 z0 beyond the first approach (with the
located jump-off and an error estimate, ``effective_work_estimate``); at W_max the pressure map (Fig. 10b) and the
force on each atom -- the pressure integrated over the nodes the atom forms
(its footprint) -- against the atom's distance from the axis (Fig. 11).

Outputs in --out: tips.csv (one row per tip), path_<tip>.csv, atoms_<tip>.csv,
states_<tip>.csv and history_<tip>.csv (``common.StudyRecorder``),
fig10.png, fig11.png, fig12.png, atomic_tips.json.
Sizes: default 256^2 nodes, dx = d / 6 (48 sigma window), W_max = 2 pi R w;
small 64^2, dx = d / 2, W_max = 0.3 (2 pi R w); approach steps of 0.5 z0.
``--size resolution``: the default run at dx = d / 2, d / 3, d / 4, d / 6, d / 8
(same window, load and protocol; resolution.csv, resolution.json,
fig12_resolution.png).  The paper does not state its grid.
"""
from __future__ import annotations

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

RADIUS, E_STAR, EPS_TS, SIGMA = 100.0, 55.0, 0.5, 1.0
REFINE = 4           #: jump bisections: jumps located to step / 16
SIZES = {
    "small": dict(n=64, per_d=2, load_star=0.3, step=0.5),
    "default": dict(n=256, per_d=6, load_star=1.0, step=0.5),
}
WINDOW = 48.0        #: resolution study: window [sigma] (the default run's)
RESOLUTIONS = (2, 3, 4, 6, 8)   #: resolution study: nodes per spacing d (dx = d / k)


def effective_work(path, every=1):
    """Effective work of adhesion [energy]: -int min(W, 0) d delta along the unloading
    (pull-off) curve, piecewise linear through every ``every``-th of its samples and the
    located jump-off end points, down to the last unloading approach."""
    import numpy as np
    un = sorted((p.approach, p.force) for p in path.points if p.converged and p.branch == "unloading")
    samples = dict(un[::every])
    for j in path.jumps:
        if j.kind == "jump-off":
            samples.setdefault(j.approach_before, j.force_before)
            samples.setdefault(j.approach_after, j.force_after)
    a, f = (np.array(v) for v in zip(*sorted(samples.items())))
    tensile = np.minimum(f, 0.0)
    return -float(np.sum(0.5 * (tensile[1:] + tensile[:-1]) * np.diff(a)))


def effective_work_estimate(path):
    """(effective work, its sampling error): |W(h) - W(2h)| (every and every other sample;
    the trapezoid error on the curved parts) plus half of each jump-off's bracket times
    its change of tensile force (the jump anywhere inside its bracket)."""
    fine = effective_work(path)
    located = sum(0.5 * abs(j.approach_after - j.approach_before)
                  * abs(min(j.force_after, 0.0) - min(j.force_before, 0.0))
                  for j in path.jumps if j.kind == "jump-off")
    return fine, abs(fine - effective_work(path, every=2)) + located


def tip_study(kind, cfg, out):
    import numpy as np
    from contactpetsc import metrics
    from contactpetsc.geometry import tips
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.paths import sweep
    from contactpetsc.physics.interactions import lj_from_atomistic, make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    w, z0 = lj_from_atomistic(EPS_TS, SIGMA)
    d = tips.LJ_SPACING * SIGMA
    grid = SurfaceGrid(cfg["n"], cfg["n"], d / cfg["per_d"], periodic=False, row_alignment=8)
    tip = tips.make_tip(kind, grid, RADIUS, d, seed=1)
    h, owner = tips.profile(grid, tip)
    law = make_law("lj", work_of_adhesion=w, z0=z0)
    pb = AdhesiveProblem(grid, h, E_STAR, law, prefix=f"tip_{kind.replace('-', '')}_",
                         element_integration=True)
    scale = 2 * np.pi * RADIUS * w
    w_max = cfg["load_star"] * scale
    loading, radii = [], []
    rec = common.StudyRecorder(out, kind, grid, h, pb)

    def record(k, st, pt):
        rec(k, st, pt)
        if pt.branch == "loading":
            loading.append(st.force)
            radii.append(np.sqrt(metrics.contact_area(grid, st.pressure) / np.pi))

    start = -2.0 * z0
    path = common.load_until(pb, start, cfg["step"] * z0, w_max, REFINE, on_state=record)
    st = common.reach_load(pb, w_max, path.points[-1].approach)
    rec.record(st, "at-load")
    forces = metrics.atom_forces(grid, st.pressure, owner, len(tip.atoms))
    p_map = grid.gather(st.pressure, root=0)
    h_map = grid.gather(h, root=0)
    top = int(np.floor((st.approach - start) / (cfg["step"] * z0) + 1e-9))
    end = -int(round(2.0 / cfg["step"]))       # unload to 2 z0 beyond the start
    sweep(pb, start + np.arange(top, end - 1, -1) * cfg["step"] * z0, refine=REFINE, path=path,
          branch="unloading", on_state=rec)
    work, work_error = effective_work_estimate(path)
    touched = np.abs(forces) > 1e-6 * np.abs(forces).max()
    row = dict(tip=kind, atoms=len(tip.atoms), w=w, z0=z0, e_star=E_STAR, radius=RADIUS,
               load=st.force, contact_radius=float(np.sqrt(metrics.contact_area(grid, st.pressure) / np.pi)),
               pull_off=path.pull_off_force, pull_off_star=path.pull_off_force / scale,
               effective_work=work, effective_work_error=work_error, hysteresis=metrics.path_hysteresis(path),
               atom_force_sum=float(forces.sum()), net_force=st.force, jumps=len(path.jumps),
               atoms_repulsive=int((forces > 0).sum()), atoms_attractive=int((forces[touched] < 0).sum()),
               n=cfg["n"], dx=grid.dx)
    common.write_csv(out / f"path_{kind}.csv", common.path_rows(path, tip=kind))
    r_atom = tips.atom_radii(tip)
    common.write_csv(out / f"atoms_{kind}.csv",
                     [dict(x=a[0], y=a[1], z=a[2], radius=r, force=f)
                      for a, r, f in zip(tip.atoms[touched], r_atom[touched], forces[touched])])
    return row, dict(grid=grid, p=p_map, h=h_map, r=r_atom[touched], f=forces[touched], path=path,
                     loads=np.array(loading), radii=np.array(radii), scale=scale, z0=z0)


def resolution_study(outdir, resolutions=RESOLUTIONS, load_star=1.0, step=0.5) -> dict:
    """Effective work of adhesion of every tip at dx = d / k for k in ``resolutions``: the
    same window (WINDOW sigma), load (W_max = load_star 2 pi R w) and approach protocol
    (the default run's) at every dx.  Writes resolution.csv and fig12_resolution.png; the
    ranking at each dx, and the finest dx from which it no longer changes."""
    from contactpetsc.geometry import tips
    out = common.prepare(outdir)
    rows = []
    for k in resolutions:
        sub = common.prepare(out / f"d{k}")
        n = 2 * int(round(WINDOW * k / (2 * tips.LJ_SPACING * SIGMA)))
        cfg = dict(n=n, per_d=k, load_star=load_star, step=step)
        for kind in tips.KINDS:
            row, _ = tip_study(kind, cfg, sub)
            row.update(per_d=k)
            rows.append(row)
            common.say(f"dx = d/{k} ({n}^2) {kind:>20}: effective work {row['effective_work']:.1f} "
                       f"+- {row['effective_work_error']:.1f} eps, pull-off W* {row['pull_off_star']:.3f}")
    rankings = {k: [r["tip"] for r in sorted((r for r in rows if r["per_d"] == k),
                                             key=lambda r: -r["effective_work"])] for k in resolutions}
    settled = next(k for k in resolutions if all(rankings[m] == rankings[resolutions[-1]]
                                                 for m in resolutions if m >= k))
    results = {"resolutions": list(resolutions), "window_sigma": WINDOW, "load_star": load_star,
               "rows": rows, "rankings": {str(k): v for k, v in rankings.items()},
               "ranking_unchanged_from_per_d": settled}
    for k in resolutions:
        common.say(f"dx = d/{k}: " + " > ".join(rankings[k]))
    common.write_csv(out / "resolution.csv", rows)
    common.write_json(out / "resolution.json", results)
    if common.is_root():
        plt = common.plt()
        fig, ax = plt.subplots(figsize=(6.5, 4.2))
        for kind in tips.KINDS:
            sel = [r for r in rows if r["tip"] == kind]
            ax.errorbar([1.0 / r["per_d"] for r in sel], [r["effective_work"] for r in sel],
                        yerr=[r["effective_work_error"] for r in sel], fmt="o-", ms=4, capsize=3, label=kind)
        ax.set_xlim(left=0)
        common.dress(ax, "dx / d", "effective work of adhesion [epsilon]",
                     "Fig. 12: effective work against grid spacing", legend_size=7)
        common.savefig(fig, out / "fig12_resolution.png")
    return results


def run(size="default", outdir="atomic-tips-output") -> dict:
    from contactpetsc.geometry import tips
    if size == "resolution":
        return resolution_study(outdir)
    cfg = SIZES[size]
    out = common.prepare(outdir)
    rows, data = [], {}
    for kind in tips.KINDS:
        row, data[kind] = tip_study(kind, cfg, out)
        rows.append(row)
        common.say(f"{kind:>20}: contact radius {row['contact_radius']:.2f} sigma at W* = "
                   f"{row['load'] / data[kind]['scale']:.2f}, pull-off W* {row['pull_off_star']:.3f}, "
                   f"effective work {row['effective_work']:.1f} eps, jumps {row['jumps']}, "
                   f"sum of atom forces / net force {row['atom_force_sum'] / row['net_force']:.12f}")
    ranking = sorted(rows, key=lambda r: -r["effective_work"])
    results = {"size": size, "tips": rows, "ranking_effective_work": [r["tip"] for r in ranking]}
    common.say("effective work of adhesion, largest first: " + " > ".join(results["ranking_effective_work"]))
    common.write_csv(out / "tips.csv", rows)
    common.write_json(out / "atomic_tips.json", results)
    if common.is_root():
        _plots(out, data)
    return results


def _plots(out, data):
    import numpy as np
    plt = common.plt()
    kinds = list(data)
    fig, axes = plt.subplots(2, 4, figsize=(16, 7.5))
    for k, kind in enumerate(kinds):
        dd = data[kind]
        g = dd["grid"]
        m = g.nx // 4
        sl = (slice(m, g.nx - m), slice(m, g.ny - m))
        ext = (-(g.nx // 2 - m) * g.dx, (g.nx // 2 - m) * g.dx) * 2
        im = axes[0, k].imshow(dd["h"][sl].T / dd["z0"], origin="lower", extent=ext, cmap="viridis",
                               vmax=np.percentile(dd["h"][sl] / dd["z0"], 99))
        fig.colorbar(im, ax=axes[0, k], shrink=0.8, label="h / z0")
        axes[0, k].set_title(f"(a) {kind}", fontsize=9)
        common.pressure_map(axes[1, k], g, dd["p"][sl], f"(b) {kind}", unit="eps/sigma^3", extent_unit=1.0)
    common.savefig(fig, out / "fig10.png")
    fig, axes = plt.subplots(1, 4, figsize=(16, 4), sharey=True)
    for ax, kind in zip(axes, kinds):
        ax.plot(data[kind]["r"], data[kind]["f"], ".", ms=3)
        common.dress(ax, "r [sigma]", "force per atom [eps / sigma]" if ax is axes[0] else "", kind,
                     zero_line=True)
    common.savefig(fig, out / "fig11.png")
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for kind, color in zip(kinds, ("C0", "C1", "C2", "C3")):
        dd = data[kind]
        a1.plot(dd["loads"] / dd["scale"], dd["radii"], "o-", ms=3, color=color, label=kind)
        common.load_approach(a2, dd["path"], dd["z0"], dd["scale"], kind, color)
    common.dress(a1, "W / (2 pi R w)", "contact radius [sigma]", "Fig. 12a: contact radius against load",
                 legend_size=7)
    common.dress(a2, "approach / z0", "W / (2 pi R w)", "Fig. 12b: loading and pull-off curves",
                 zero_line=True, legend_size=5)
    common.savefig(fig, out / "fig12.png")


if __name__ == "__main__":
    args = common.parse(__doc__.splitlines()[0], "atomic-tips-output", sizes=("small", "default", "resolution"))
    run(args.size, args.out)
