"""The fields of one step: the pressure map, the pressure and gap distributions, and the power
spectrum of the heights (serial numpy on arrays (ny, nx), node (i, j) at (i dx, j dy))."""
from __future__ import annotations

import numpy as np

from .common import figure, prefix, save
from .scales import PERCENTILE, histogram_range, pressure_limits
from .spectrum import radial_psd

ROUND_OFF = 1e-10   #: psd.png leaves out rings whose C(q) is below this share of the peak


def pressure_map(pressure: np.ndarray, dx: float, dy: float, path: str | None = None, title: str = ""):
    """A (ny, nx) pressure field [Pa] on the colour scale of ``scales.pressure_limits``: white at
    zero and red for compression, [0, top] without tension, a diverging [-top, top] with it
    (blue tensile), top a high percentile of the pressures so that one outlier node does not
    set it; values beyond are drawn at the end colour (the colorbar's arrow) and the extreme
    is named in the title; returns the Figure."""
    fig, ax = figure()
    ny, nx = pressure.shape
    lim = pressure_limits(pressure)
    (sp, up), (sl, ul) = prefix([lim.vmax], "Pa"), prefix([nx * dx, ny * dy], "m")
    extent = (-0.5 * dx / sl, (nx - 0.5) * dx / sl, -0.5 * dy / sl, (ny - 0.5) * dy / sl)
    im = ax.imshow(pressure / sp, origin="lower", extent=extent, cmap=_colours(lim.diverging),
                   vmin=lim.vmin / sp, vmax=lim.vmax / sp, interpolation="nearest")
    fig.colorbar(im, ax=ax, extend=lim.extend, label=f"pressure p [{up}] (compressive > 0)")
    ax.set_xlabel(f"x [{ul}]")
    ax.set_ylabel(f"y [{ul}]")
    note = ""
    if lim.clipped:   # the scale ends at a percentile: say what lies beyond it
        ends = [f"max {lim.high / sp:.4g} {up}" if lim.extend in ("max", "both") else "",
                f"min {lim.low / sp:.4g} {up}" if lim.extend in ("min", "both") else ""]
        note = (f"\ncolour scale to the {PERCENTILE:g}th percentile of "
                f"{'|p| on either side' if lim.diverging else 'p > 0'}; "
                f"{', '.join(e for e in ends if e)} drawn at its end")
    ax.set_title((title or "pressure") + note, fontsize=10 if note else None)
    return save(fig, path)


def _colours(diverging: bool):
    """RdBu_r (blue tensile, white 0, red compressive) or, without tension, its red half: zero
    white and compression red in both, so that maps with and without adhesion read alike."""
    from matplotlib import colormaps
    from matplotlib.colors import LinearSegmentedColormap
    full = colormaps["RdBu_r"]
    return full if diverging else LinearSegmentedColormap.from_list("RdBu_r_upper", full(np.linspace(0.5, 1.0, 128)))


def histograms(pressure: np.ndarray, gap: np.ndarray, path: str | None = None, title: str = ""):
    """Two panels: the distribution of the nodal pressure over the nodes that carry any (p != 0),
    and of the gap over the nodes out of contact (p <= 0), each a density normalised by the
    number of all nodes (its integral is the share of the nodes drawn), on a log axis for the
    gap and for a pressure with tension (its long adhesive tail).  The bins span
    ``scales.histogram_range``: a few outlier nodes (a contact edge's peak, a spike of a
    measured map) would otherwise widen the range until the bulk fills one bin; the nodes left
    out and their extreme are named on the panel.  Returns the Figure."""
    fig, (left, right) = figure(1, 2, size=(10.0, 4.2))
    p, g = np.ravel(pressure), np.ravel(gap)
    n = max(p.size, 1)
    for ax, values, unit, what, log in ((left, p[p != 0], "Pa", "pressure p, nodes with p ≠ 0", np.any(p < 0)),
                                        (right, g[(p <= 0) & np.isfinite(g)], "m", "gap g, nodes with p ≤ 0", True)):
        if values.size == 0:
            ax.text(0.5, 0.5, "no such node", ha="center", va="center", transform=ax.transAxes)
            continue
        lo, hi, out = histogram_range(values)
        s, u = prefix([lo, hi], unit)
        counts, edges = np.histogram(values / s, bins=min(80, max(10, int(np.sqrt(values.size)))),
                                     range=(lo / s, hi / s))
        density = counts / (n * np.diff(edges))
        ax.stairs(density, edges, fill=True, alpha=0.6, color="C0" if unit == "Pa" else "C2")
        ax.set_xlabel(f"{what} [{u}]")
        ax.set_ylabel(f"density [1/{u}] ({(values.size - out) / n:.3g} of the nodes)")
        if out:   # name what the range leaves out, each end apart
            ends = [f"{np.count_nonzero(values < lo)} below {lo / s:.4g} (to {values.min() / s:.4g})"
                    if values.min() < lo else "",
                    f"{np.count_nonzero(values > hi)} above {hi / s:.4g} (to {values.max() / s:.4g})"
                    if values.max() > hi else ""]
            ax.text(0.98, 0.97, f"outlier nodes left out [{u}]:\n" + "\n".join(e for e in ends if e),
                    transform=ax.transAxes, ha="right", va="top", fontsize=8, color="0.3")
        if log:
            ax.set_yscale("log")
    left.axvline(0.0, color="0.6", lw=0.6)
    fig.suptitle(title or "pressure and gap distributions")
    return save(fig, path)


def psd(heights: np.ndarray, dx: float, dy: float, periodic: bool = True, hurst: float | None = None,
        cutoffs: tuple | None = None, path: str | None = None, title: str = ""):
    """The radially averaged C(q) of the heights (``radial_psd``; a non-periodic map
    Hann-windowed), log-log, with the wavelength 2 pi / |q| on the top axis; for a generated
    self-affine surface the slope -2(1 + H) between its roll-off and cut-off wavevectors
    ``cutoffs`` (q_r, q_s) [1/m] for reference; returns the Figure."""
    fig, ax = figure()
    q, c = radial_psd(heights, dx, dy, periodic)
    floor = ROUND_OFF * (c.max() if c.size else 0.0)   # beyond a generator's cut-off: round-off
    sh, uh = prefix([np.std(heights)], "m")
    label = (f"C(q) of the heights (rings of |q|), h_rms = {np.std(heights) / sh:.3g} {uh}"
             + ("" if periodic else "\nnon-periodic map: Hann-windowed, mean(w²) = 1")
             + ("\nrings below 1e-10 of the peak left out" if np.any(c < floor) else ""))
    q, c = q[c >= floor], c[c >= floor]
    ax.loglog(q, c, "o-", ms=3, color="C0", label=label)
    if hurst is not None and cutoffs is not None:
        q_r, q_s = cutoffs
        band = (q >= q_r) & (q <= q_s) & (c > 0)
        if np.count_nonzero(band) >= 2:
            slope = -2.0 * (1.0 + hurst)
            anchor = np.exp(np.mean(np.log(c[band]) - slope * np.log(q[band])))
            qs = q[band][[0, -1]]
            ax.loglog(qs, 2.0 * anchor * qs ** slope, "--", color="0.3",
                      label=f"slope -2(1 + H) = {slope:.2f} (H = {hurst:g}), shifted up 2x")
        for v, name in ((q_r, "roll-off"), (q_s, "cut-off")):
            ax.axvline(v, color="0.6", lw=0.8, ls=":")
            ax.annotate(name, (v, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -12),
                        textcoords="offset points", fontsize=8, color="0.4")
    ax.set_xlabel("wavevector |q| [1/m]")
    sl, ul = prefix([2 * np.pi / q.min()] if q.size else [1.0], "m")
    top = ax.secondary_xaxis("top", functions=(lambda v: _reciprocal(v, 2 * np.pi / sl),
                                               lambda v: _reciprocal(v, 2 * np.pi / sl)))
    top.set_xlabel(f"wavelength 2π / |q| [{ul}]")
    ax.set_ylabel("C(q) [m⁴]  (<h²> = ∫ C d²q)")
    ax.set_title(title or "power spectrum of the surface")
    ax.legend(fontsize=8, loc="lower left")
    return save(fig, path)


def _reciprocal(v, k: float):
    """k / v, inf at v = 0 without numpy's warning: the wavelength axis's map to and from |q|
    (matplotlib calls it on 0 and on tiny values while it sets the axis up)."""
    v = np.array(v, float)
    out = np.full(v.shape, np.inf)
    np.divide(k, v, out=out, where=np.abs(v) > 1e-300 * abs(k))
    return out
