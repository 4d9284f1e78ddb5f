"""The power spectrum and the rms slope of a height map (ny, nx), node (i, j) at (i dx, j dy)
(numpy only: importing this module imports no matplotlib).

One spectrum, ``power_spectrum``: the 2-D power spectral density C(q) [m^4] in Persson's
convention, <h^2> = integral of C(q) d^2q, so that on the grid's wavevectors
q = 2 pi (i / Lx, j / Ly), Lx = nx dx, Ly = ny dy, with d^2q = (2 pi)^2 / (Lx Ly),

    C(q) = dx dy / ((2 pi)^2 nx ny) |sum_x h(x) e^(-i q.x)|^2,
    sum over q of C(q) (2 pi)^2 / (Lx Ly) = <h^2>            (Parseval).

A periodic cell is transformed as it is.  A non-periodic map (a measured window) is not
periodic: its FFT sees a jump at the edges, whose power falls as |q|^-2 and buries the
spectrum's tail.  It is multiplied by a Hann window w first, normalised to mean(w^2) = 1 so that
a stationary surface keeps its mean-square height (Gwyddion's PSDF and SurfaceTopography's
``window="hann"`` do the same); Parseval then holds for the windowed map h w.
``radial_psd`` averages C over rings of |q|.
"""
from __future__ import annotations

import numpy as np


def hann(ny: int, nx: int) -> np.ndarray:
    """The 2-D Hann window (ny, nx), w = w_y(j) w_x(i) with w(k) = sin^2(pi k / (n - 1)), zero on
    the edge rows and columns, scaled to mean(w^2) = 1 (the map's mean-square height is kept)."""
    w = np.outer(np.hanning(ny), np.hanning(nx))
    return w / np.sqrt(np.mean(w ** 2))


def windowed(heights: np.ndarray, periodic: bool = True) -> np.ndarray:
    """The map whose spectrum ``power_spectrum`` takes: the heights less their mean, times
    ``hann`` unless periodic.  (The mean is taken off first so that the window does not turn
    the map's offset into power at the lowest wavevectors.)"""
    h = np.asarray(heights, float)
    h = h - float(np.mean(h))
    return h if periodic else h * hann(*h.shape)


def power_spectrum(heights: np.ndarray, dx: float, dy: float, periodic: bool = True):
    """(q [1/m], C [m^4], m): the 2-D PSD of ``windowed(heights, periodic)`` on the half plane of
    numpy's ``rfft2`` (shape (ny, nx // 2 + 1)), |q| of each mode, and each mode's multiplicity
    m in the full plane (2 for the columns 0 < i < nx / 2, whose mirror -q is left out; else 1),
    so that sum(m C) (2 pi)^2 / (Lx Ly) = mean(windowed^2) exactly (Parseval)."""
    ny, nx = np.shape(heights)
    c = np.abs(np.fft.rfft2(windowed(heights, periodic))) ** 2 * dx * dy / ((2 * np.pi) ** 2 * nx * ny)
    qx = 2 * np.pi * np.fft.rfftfreq(nx, dx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)
    m = np.full(qx.size, 2.0)
    m[0] = 1.0
    if nx % 2 == 0:
        m[-1] = 1.0                       # the Nyquist column is its own mirror
    return np.hypot(*np.meshgrid(qx, qy)), c, np.broadcast_to(m, c.shape)


def radial_psd(heights: np.ndarray, dx: float, dy: float, periodic: bool = True, bins: int = 60):
    """(q [1/m], C(q) [m^4]): ``power_spectrum`` averaged over rings of log-spaced |q| from the
    cell's 2 pi / max(Lx, Ly) to the Nyquist pi / max(dx, dy) (the corners beyond it and q = 0
    left out), each mode weighted by its multiplicity (the ring's mean over the full plane);
    empty rings are left out.  Non-periodic maps are Hann-windowed (module docstring)."""
    ny, nx = np.shape(heights)
    q, c, m = power_spectrum(heights, dx, dy, periodic)
    q_low, q_high = 2 * np.pi / max(nx * dx, ny * dy), np.pi / max(dx, dy)   # the cell, Nyquist
    edges = np.geomspace(q_low * 0.999, q_high * 1.001, bins + 1)
    k = np.digitize(q.ravel(), edges)
    keep = (k > 0) & (k <= bins)
    total = np.bincount(k[keep], (m * c).ravel()[keep], minlength=bins + 1)[1:]
    count = np.bincount(k[keep], m.ravel()[keep], minlength=bins + 1)[1:]
    centre = np.sqrt(edges[1:] * edges[:-1])
    has = count > 0
    return centre[has], total[has] / count[has]


def rms_slope(heights: np.ndarray, dx: float, dy: float, periodic: bool = True) -> float:
    """h'rms = sqrt(<|grad h|^2>) [-].  Periodic: the gradient taken spectrally, |q| of the
    Nyquist modes included (as the generator's ``rms_slope``).  Not periodic: by forward
    differences inside the window, <(dh/dx)^2> + <(dh/dy)^2> each over its nx - 1 (ny - 1)
    differences: a spectral gradient would see the jump between opposite edges as a cliff."""
    h = np.asarray(heights, float)
    if not periodic:
        return float(np.sqrt(np.mean((np.diff(h, axis=1) / dx) ** 2) + np.mean((np.diff(h, axis=0) / dy) ** 2)))
    ny, nx = h.shape
    c = np.abs(np.fft.fft2(h)) ** 2
    qx = 2 * np.pi * np.fft.fftfreq(nx, dx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)
    q2 = np.add.outer(qy ** 2, qx ** 2)
    return float(np.sqrt(np.sum(q2 * c)) / (nx * ny))
