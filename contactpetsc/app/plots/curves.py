"""The curves of ``curve.csv``: load against approach (with the closed forms of a sphere),
contact area against load, mean gap against load."""
from __future__ import annotations

import numpy as np

from ...physics import closed_forms as cf
from .common import figure, prefix, save

BRANCH_STYLE = {"loading": dict(color="C0", marker="o"),
                "unloading": dict(color="C1", marker="s"),
                "central-gap": dict(color="C2", marker=".")}
OVERLAY_STYLE = {"Hertz": dict(color="0.3", ls="--"), "DMT": dict(color="C5", ls="-."),
                 "JKR": dict(color="C6", ls=":"), "Maugis-Dugdale": dict(color="C9", ls="-")}


def load_approach(curve: dict, jumps: dict | None = None, pull_off: float | None = None,
                  path: str | None = None, title: str = "", overlays: list = ()):
    """Force against approach from ``curve.csv`` (and ``jumps.csv``) columns; returns the Figure
    (saved to ``path``).  ``overlays``: (label, approach [m], force [N]) curves of closed forms
    (``sphere_overlays``), drawn within the data's limits."""
    fig, ax = figure()
    x, y = curve["approach_m"], curve["force_N"]
    (sx, ux), (sy, uy) = prefix(x, "m"), prefix(np.append(y, pull_off or np.nan), "N")
    branch = curve.get("branch") or ["loading"] * len(x)
    jumps = jumps if jumps and len(jumps.get("kind", [])) else None
    used, start = set(), 0
    for i in range(1, len(x) + 1):
        if i < len(x) and branch[i] == branch[start]:
            continue
        style = BRANCH_STYLE.get(branch[start], dict(color="C4", marker="o"))
        lo = max(start - 1, 0)   # the line joins the previous branch's last state
        kind = {"loading": "jump-on", "unloading": "jump-off"}.get(branch[start])
        xs, ys = _with_jumps(x[lo:i], y[lo:i], jumps, kind, used)
        ax.plot(xs / sx, ys / sy, color=style["color"])
        ax.plot(x[start:i] / sx, y[start:i] / sy, ls="none", ms=5,
                mfc="none" if branch[start] == "unloading" else style["color"], **style)
        start = i
    for name in dict.fromkeys(branch):
        style = BRANCH_STYLE.get(name, dict(color="C4", marker="o"))
        ax.plot([], [], ms=5, mfc="none" if name == "unloading" else style["color"], label=name, **style)
    for name, mask, mark in (("unstable", curve.get("stable", np.ones_like(x)) == 0, "x"),
                             ("not converged", curve.get("converged", np.ones_like(x)) == 0, "X")):
        if np.any(mask):
            ax.plot(x[mask] / sx, y[mask] / sy, mark, color="k", ms=7, ls="none", label=name)
    for k in range(len(jumps["kind"]) if jumps else 0):
        start_pt = (jumps["approach_before_m"][k] / sx, jumps["force_before_N"][k] / sy)
        end_pt = (jumps["approach_after_m"][k] / sx, jumps["force_after_N"][k] / sy)
        ax.annotate("", xy=end_pt, xytext=start_pt,
                    arrowprops=dict(arrowstyle="->", ls="--", color="C3", lw=1.5))
        ax.annotate(jumps["kind"][k], xy=end_pt, xytext=(5, -3), textcoords="offset points",
                    color="C3", fontsize=8)
    if jumps:
        ax.plot([], [], "--", color="C3", label="jump (located by bisection)")
    if pull_off is not None and np.isfinite(pull_off):
        ax.axhline(pull_off / sy, ls=":", color="C3", label=f"pull-off {pull_off / sy:.4g} {uy}")
    _overlay(ax, overlays, sx, sy)
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel(f"approach δ [{ux}]")
    ax.set_ylabel(f"force F [{uy}] (compressive > 0)")
    _greenwood_axes(ax, curve, sx, sy)
    ax.legend(fontsize=8)
    ax.set_title(title or "load against approach")
    return save(fig, path)


def _with_jumps(x, y, jumps, kind, used: set):
    """The polyline through (x, y) with each jump of ``kind`` found between two of its points
    drawn where it was located: the old branch up to the jump, a break, the new branch on.
    ``used`` collects the jumps drawn (each is drawn once)."""
    xs, ys = [x[0]], [y[0]]
    for k in range(1, len(x)):
        for j in range(len(jumps["kind"]) if jumps else 0):
            a0 = jumps["approach_before_m"][j]
            if j not in used and jumps["kind"][j] == kind and min(x[k - 1], x[k]) <= a0 <= max(x[k - 1], x[k]):
                used.add(j)
                xs += [a0, np.nan, jumps["approach_after_m"][j]]
                ys += [jumps["force_before_N"][j], np.nan, jumps["force_after_N"][j]]
        xs.append(x[k])
        ys.append(y[k])
    return np.array(xs), np.array(ys)


def _greenwood_axes(ax, curve: dict, sx: float, sy: float) -> None:
    """Top and right axes in Greenwood's alpha* = delta / z0 and W* = F / (2 pi R w) (spheres)."""
    x, y = curve["approach_m"], curve["force_N"]
    a, w = np.asarray(curve.get("alpha_star", np.nan * x)), np.asarray(curve.get("W_star", np.nan * x))
    ix, iy = np.argmax(np.where(np.isfinite(a), np.abs(x), 0)), np.argmax(np.where(np.isfinite(w), np.abs(y), 0))
    if not (np.isfinite(a[ix]) and x[ix] != 0 and np.isfinite(w[iy]) and y[iy] != 0):
        return
    fx, fy = a[ix] / x[ix] * sx, w[iy] / y[iy] * sy
    ax.secondary_xaxis("top", functions=(lambda v: v * fx, lambda v: v / fx)).set_xlabel("α* = δ / z0")
    ax.secondary_yaxis("right", functions=(lambda v: v * fy, lambda v: v / fy)).set_ylabel("W* = F / (2π R w)")




def sphere_overlays(scene: dict, approach) -> list:
    """The closed forms of a smooth sphere on an isolated half-space, as (label, approach [m],
    force [N]) over the approaches of the run (``approach``): Hertz without adhesion; with
    adhesion DMT, JKR and Maugis-Dugdale with lambda = 2 sigma0 (R / (pi w K^2))^(1/3), sigma0
    the law's peak attraction (Lennard-Jones: lambda = 1.157 mu).  Empty for other scenes."""
    from ...physics.interactions import make_law
    from ..scenes import law_keys
    from ..scenes import e_star as e_star_of   # E* or E, nu (the scene module needs PETSc)
    g, it, e_star = scene["geometry"], scene["interaction"], e_star_of(scene)
    if g["kind"] != "sphere" or g["periodic"]:
        return []
    lo, hi = float(np.min(approach)), float(np.max(approach))
    if it["law"] == "none" or it["work_of_adhesion"] == 0:
        d = np.linspace(0.0, max(hi, 0.0), 200)
        return [("Hertz", d, cf.hertz_force(e_star, g["radius"], d))] if hi > 0 else []
    w, r = it["work_of_adhesion"], g["radius"]
    law = make_law(it["law"], work_of_adhesion=w, **{k: it[k] for k in law_keys(it["law"])})
    lam = cf.maugis_lambda(e_star, r, w, law.peak_attraction)
    d_unit, f_unit = cf.maugis_units(e_star, r, w)
    top = np.sqrt(max(hi / d_unit, 0.0) + 4.0) + 1.0     # A^2 beyond the largest approach
    a = np.linspace(0.0, top, 600)[1:]
    m = 1.0 + np.logspace(-8, 4, 1200)
    curves = [("DMT",) + cf.dmt_curve(a), ("JKR",) + cf.jkr_curve(a),
              (f"Maugis-Dugdale, λ = {lam:.3g}",) + cf.maugis_approach(lam, m)[1:]]
    out = []
    for label, d, p in curves:
        d, f = d * d_unit, p * f_unit
        keep = (d >= lo - 0.05 * (hi - lo)) & (d <= hi + 0.05 * (hi - lo))
        out.append((label, np.where(keep, d, np.nan), np.where(keep, f, np.nan)))
    return out


def _overlay(ax, overlays, sx: float, sy: float) -> None:
    """The closed forms, thin, under the data (``sphere_overlays`` keeps them within the run's
    approaches)."""
    for label, d, f in overlays:
        style = OVERLAY_STYLE.get(label.split(",")[0], dict(color="C7", ls="-"))
        ax.plot(np.asarray(d) / sx, np.asarray(f) / sy, lw=1.0, label=label, zorder=1, **style)


def load_axis_label(window: bool) -> str:
    """The label of the load axis p / E*: on an isolated window (``window``) p is the force
    over the window's nominal area nx dx ny dy, which ``curve.csv``'s mean_pressure_Pa is."""
    return ("p / E*,  p = F / (nx dx ny dy): force over the window's area" if window
            else "p / E*  (mean pressure over the effective modulus)")


def contact_area(curve: dict, e_star: float, rms_slope: float | None = None, path: str | None = None,
                 title: str = "", window: bool = False):
    """A/A0 (``contact_fraction``) against p / E* (``mean_pressure_Pa``), log-log, with the
    small-load laws A/A0 = kappa p / (E* h'_rms) of Persson and of Bush, Gibson & Thomas
    (``closed_forms.KAPPA_*``) for the surface's rms slope h'_rms; returns the Figure.
    ``window``: an isolated window, whose nominal area A0 is nx dx ny dy (the axes say so).
    The laws hold there too (they count the area each asperity's load makes, whatever the
    nominal area), as long as the window holds many contact spots away from its edge."""
    fig, ax = figure()
    x, y = curve["mean_pressure_Pa"] / e_star, curve["contact_fraction"]
    keep = (x > 0) & (y > 0) & (curve.get("converged", np.ones_like(x)) == 1)
    label = "computed"
    if rms_slope and np.any(keep):
        k = np.flatnonzero(keep)[np.argmin(x[keep])]
        label += f" (lowest load: κ = {y[k] * rms_slope / x[k]:.3g})"
    ax.loglog(x[keep], y[keep], "o-", color="C0", ms=5, label=label)
    if rms_slope and np.any(keep):
        xs = np.geomspace(x[keep].min(), x[keep].max(), 50)
        for name, kappa, style in (("Persson", cf.KAPPA_PERSSON, "--"), ("Bush-Gibson-Thomas", cf.KAPPA_BGT, ":")):
            ax.loglog(xs, cf.area_fraction_small_load(xs * e_star, e_star, rms_slope, kappa), style, color="0.3",
                      label=f"{name}: κ p / (E* h'rms), κ = {kappa:.3f}")
    ax.set_xlabel(load_axis_label(window))
    ax.set_ylabel("A / A0,  A0 = nx dx ny dy: the window's area" if window else "A / A0  (contact area fraction)")
    ax.set_title(title or "contact area against load")
    ax.legend(fontsize=8, title=f"h'rms = {rms_slope:.4g}" if rms_slope else None, title_fontsize=8)
    return save(fig, path)


def mean_gap(curve: dict, e_star: float, rms_height: float | None = None, path: str | None = None,
             title: str = "", window: bool = False):
    """The mean gap (``mean_gap_m``, error bars ``mean_gap_error_m``) against p / E* on a log
    axis (Persson's regime: p ~ exp(-u / u0), a straight line); returns the Figure.
    ``window``: an isolated window, p and the mean over its nodes (the axes say so)."""
    fig, ax = figure()
    x, u = curve["mean_pressure_Pa"] / e_star, curve["mean_gap_m"]
    err = curve.get("mean_gap_error_m", np.zeros_like(u))
    keep = (x > 0) & np.isfinite(u) & (curve.get("converged", np.ones_like(x)) == 1)
    su, uu = prefix(u[keep], "m")
    ax.errorbar(x[keep], u[keep] / su, yerr=np.nan_to_num(err[keep]) / su, fmt="o-", ms=5, capsize=3,
                color="C0", label="mean gap ū (error bar: mean_gap_error_m)")
    ax.set_xscale("log")
    if rms_height:
        f = su / rms_height
        ax.secondary_yaxis("right", functions=(lambda v: v * f, lambda v: v / f)).set_ylabel("ū / h_rms")
    ax.set_xlabel(load_axis_label(window))
    ax.set_ylabel(f"mean gap ū [{uu}]" + (", over the window's nodes" if window else ""))
    ax.set_title(title or "mean gap against load")
    ax.legend(fontsize=8)
    return save(fig, path)
