"""The fields of one step: the pressure map, the pressure and gap distributions, and the power
spectrum of the heights (serial numpy on arrays (ny, nx), node (i, j) at (i dx, j dy))."""
from __future__ import annotations

import numpy as np

from .common import figure, prefix, save

ROUND_OFF = 1e-10   #: psd.png leaves out rings whose C(q) is below this share of the peak


def pressure_map(pressure: np.ndarray, dx: float, dy: float, path: str | None = None, title: str = ""):
    """A (ny, nx) pressure field [Pa] on a diverging scale centred at zero; returns the Figure."""
    fig, ax = figure()
    ny, nx = pressure.shape
    top = float(np.nanmax(np.abs(pressure))) if pressure.size else 0.0
    top = top if top > 0 and np.isfinite(top) else 1.0
    (sp, up), (sl, ul) = prefix([top], "Pa"), prefix([nx * dx, ny * dy], "m")
    extent = (-0.5 * dx / sl, (nx - 0.5) * dx / sl, -0.5 * dy / sl, (ny - 0.5) * dy / sl)
    im = ax.imshow(pressure / sp, origin="lower", extent=extent, cmap="RdBu_r",
                   vmin=-top / sp, vmax=top / sp, interpolation="nearest")
    fig.colorbar(im, ax=ax, label=f"pressure p [{up}] (compressive > 0)")
    ax.set_xlabel(f"x [{ul}]")
    ax.set_ylabel(f"y [{ul}]")
    ax.set_title(title or "pressure")
    return save(fig, path)


def histograms(pressure: np.ndarray, gap: np.ndarray, path: str | None = None, title: str = ""):
    """Two panels: the distribution of the nodal pressure over the nodes that carry any (p != 0),
    and of the gap over the nodes out of contact (p <= 0), each a density normalised by the
    number of all nodes (its integral is the share of the nodes drawn), on a log axis for the
    gap and for a pressure with tension (its long adhesive tail); returns the Figure."""
    fig, (left, right) = figure(1, 2, size=(10.0, 4.2))
    p, g = np.ravel(pressure), np.ravel(gap)
    n = max(p.size, 1)
    for ax, values, unit, what, log in ((left, p[p != 0], "Pa", "pressure p, nodes with p ≠ 0", np.any(p < 0)),
                                        (right, g[(p <= 0) & np.isfinite(g)], "m", "gap g, nodes with p ≤ 0", True)):
        if values.size == 0:
            ax.text(0.5, 0.5, "no such node", ha="center", va="center", transform=ax.transAxes)
        else:
            s, u = prefix(values, unit)
            counts, edges = np.histogram(values / s, bins=min(80, max(10, int(np.sqrt(values.size)))))
            density = counts / (n * np.diff(edges))
            ax.stairs(density, edges, fill=True, alpha=0.6, color="C0" if unit == "Pa" else "C2")
            ax.set_xlabel(f"{what} [{u}]")
            ax.set_ylabel(f"density [1/{u}] ({values.size / n:.3g} of the nodes)")
            if log:
                ax.set_yscale("log")
    left.axvline(0.0, color="0.6", lw=0.6)
    fig.suptitle(title or "pressure and gap distributions")
    return save(fig, path)


def radial_psd(heights: np.ndarray, dx: float, dy: float, periodic: bool = True, bins: int = 60):
    """(q [1/m], C(q) [m^4]): the isotropic power spectral density of heights (ny, nx), averaged
    over rings of log-spaced |q|, normalised so that <h^2> = sum over q of C(q) (2 pi)^2 /
    (Lx Ly) (Persson's convention, <h^2> = integral of C(q) d^2q):
    C(q) = dx dy / ((2 pi)^2 nx ny) |sum h e^(-i q.x)|^2.  A non-periodic window is tapered
    by a Hann window first (its power restored), so that its edges add no q^-2 tail."""
    ny, nx = heights.shape
    h = np.asarray(heights, float) - float(np.mean(heights))
    if not periodic:
        taper = np.outer(np.hanning(ny), np.hanning(nx))
        h = h * taper / np.sqrt(np.mean(taper ** 2))
    c = np.abs(np.fft.rfft2(h)) ** 2 * dx * dy / ((2 * np.pi) ** 2 * nx * ny)
    qx = 2 * np.pi * np.fft.rfftfreq(nx, dx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)
    q = np.hypot(*np.meshgrid(qx, qy))
    q_low, q_high = 2 * np.pi / max(nx * dx, ny * dy), np.pi / max(dx, dy)   # the cell, Nyquist
    edges = np.geomspace(q_low * 0.999, q_high * 1.001, bins + 1)
    k = np.digitize(q.ravel(), edges)
    keep = (k > 0) & (k <= bins)
    total = np.bincount(k[keep], c.ravel()[keep], minlength=bins + 1)[1:]
    count = np.bincount(k[keep], minlength=bins + 1)[1:]
    centre = np.sqrt(edges[1:] * edges[:-1])
    has = count > 0
    return centre[has], total[has] / count[has]


def rms_slope(heights: np.ndarray, dx: float, dy: float) -> float:
    """sqrt(<|grad h|^2>) [-], the gradient taken spectrally, |q| of the Nyquist modes included
    (as the generator's ``rms_slope``)."""
    ny, nx = heights.shape
    c = np.abs(np.fft.fft2(np.asarray(heights, float))) ** 2
    qx = 2 * np.pi * np.fft.fftfreq(nx, dx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)
    q2 = np.add.outer(qy ** 2, qx ** 2)
    return float(np.sqrt(np.sum(q2 * c)) / (nx * ny))


def psd(heights: np.ndarray, dx: float, dy: float, periodic: bool = True, hurst: float | None = None,
        cutoffs: tuple | None = None, path: str | None = None, title: str = ""):
    """The radially averaged C(q) of the heights (``radial_psd``), log-log; for a generated
    self-affine surface the slope -2(1 + H) between its roll-off and cut-off wavevectors
    ``cutoffs`` (q_r, q_s) [1/m] for reference; returns the Figure."""
    fig, ax = figure()
    q, c = radial_psd(heights, dx, dy, periodic)
    floor = ROUND_OFF * (c.max() if c.size else 0.0)   # beyond a generator's cut-off: round-off
    label = "C(q) of the heights (rings of |q|)" + (", rings below 1e-10 of the peak left out"
                                                    if np.any(c < floor) else "")
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
    ax.set_ylabel("C(q) [m⁴]")
    ax.set_title(title or "power spectrum of the surface")
    ax.legend(fontsize=8, loc="lower left")
    return save(fig, path)
