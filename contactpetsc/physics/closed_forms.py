"""Closed forms of sphere contact: Hertz, DMT, JKR and Maugis-Dugdale (docs/validation.md).

Units: SI.  K = 4 E* / 3.  Maugis-Dugdale in the nondimensional form of
Johnson & Greenwood (1997): A = a (K / (pi w R^2))^(1/3),
P_bar = P / (pi w R), lambda = 2 sigma0 (R / (pi w K^2))^(1/3), m = c / a:

    lambda A^2 / 2 [sqrt(m^2-1) + (m^2-2) arctan sqrt(m^2-1)]
      + 4 lambda^2 A / 3 [sqrt(m^2-1) arctan sqrt(m^2-1) - m + 1] = 1,
    P_bar = A^3 - lambda A^2 [sqrt(m^2-1) + m^2 arctan sqrt(m^2-1)],
    Delta = A^2 - 4 lambda A sqrt(m^2-1) / 3,

Delta = delta (K^2 / (pi^2 w^2 R))^(1/3) the approach.  Its limits: JKR
(lambda -> infinity) P_bar = A^3 - sqrt(6 A^3), Delta = A^2 - 2 sqrt(6 A) / 3;
DMT (lambda -> 0) P_bar = A^3 - 2, Delta = A^2; Hertz P_bar = A^3, Delta = A^2.

The Lennard-Jones law corresponds to lambda = 1.16 mu (Johnson & Greenwood;
the Dugdale stress equal to the LJ peak attraction gives 1.157 mu).
Pull-off (the most tensile load on the curve) runs from -2 pi R w (DMT,
lambda -> 0) to -1.5 pi R w (JKR, lambda -> infinity).
"""
from __future__ import annotations

import numpy as np


def hertz_force(e_star: float, radius: float, approach):
    """Hertz load (4/3) E* R^1/2 delta^3/2 [N] (zero for delta <= 0)."""
    d = np.maximum(np.asarray(approach, dtype=float), 0.0)
    return 4.0 / 3.0 * e_star * np.sqrt(radius) * d ** 1.5


def hertz_contact_radius(radius: float, approach):
    """Hertz contact radius a = sqrt(R delta) [m] (zero for delta <= 0)."""
    return np.sqrt(radius * np.maximum(np.asarray(approach, dtype=float), 0.0))


def hertz_gap_outside(radius: float, contact_radius: float, r):
    """Gap [m] outside a Hertz contact of radius a, at r >= a (Maugis 1992):
    h = a^2 / (pi R) [sqrt(m^2 - 1) + (m^2 - 2) arccos(1/m)], m = r / a."""
    m = np.asarray(r, dtype=float) / contact_radius
    return contact_radius ** 2 / (np.pi * radius) * (np.sqrt(m * m - 1.0) + (m * m - 2.0) * np.arccos(1.0 / m))


def dmt_force(law, e_star: float, radius: float, approach: float) -> tuple[float, float]:
    """(total load, adhesive force) [N] of the DMT model of Muller, Yushchenko and Derjaguin:
    the Hertz solution at approach delta, plus the law's traction integrated over the Hertz gap
    outside the contact (the surfaces are not deformed by adhesion).  For delta <= 0: the rigid
    sphere, 2 pi R Phi(-delta) by Derjaguin's approximation."""
    if approach <= 0:
        return 2.0 * np.pi * radius * float(law.energy(-approach)), 2.0 * np.pi * radius * float(law.energy(-approach))
    a = np.sqrt(radius * approach)
    m = 1.0 + np.logspace(-10, 5, 300001)
    h = hertz_gap_outside(radius, a, m * a)
    # numpy 2 renamed trapz to trapezoid (and removed trapz in 2.4)
    trapezoid = getattr(np, "trapezoid", None) or np.trapz
    adhesive = float(trapezoid(law.pressure(h) * 2.0 * np.pi * m * a * a, m))
    # beyond m = 1e5 the gap is r^2 / 2R: Derjaguin for the rest of the tail
    adhesive += 2.0 * np.pi * radius * float(law.energy(h[-1]))
    return float(hertz_force(e_star, radius, approach)) + adhesive, adhesive


def dmt_pull_off(radius: float, work_of_adhesion: float) -> float:
    """-2 pi R w [N]."""
    return -2.0 * np.pi * radius * work_of_adhesion


def jkr_pull_off(radius: float, work_of_adhesion: float) -> float:
    """-1.5 pi R w [N]."""
    return -1.5 * np.pi * radius * work_of_adhesion


def maugis_curve(lam: float, m):
    """(A, P_bar) of the Maugis-Dugdale solution for ratios m = c/a > 1 (nondimensional)."""
    m = np.asarray(m, dtype=float)
    s = np.sqrt(m * m - 1.0)
    at = np.arctan(s)
    c2 = 0.5 * lam * (s + (m * m - 2.0) * at)
    c1 = 4.0 * lam * lam / 3.0 * (s * at - m + 1.0)
    # c2 A^2 + c1 A - 1 = 0, positive root (written without cancellation)
    A = 2.0 / (c1 + np.sqrt(c1 * c1 + 4.0 * c2))
    P = A ** 3 - lam * A * A * (s + m * m * at)
    return A, P


def maugis_approach(lam: float, m):
    """(A, Delta, P_bar) of the Maugis-Dugdale solution for ratios m = c/a > 1: the contact
    radius, approach and load in Johnson & Greenwood's units (module docstring)."""
    A, P = maugis_curve(lam, m)
    return A, A * A - 4.0 * lam * A * np.sqrt(np.asarray(m, dtype=float) ** 2 - 1.0) / 3.0, P


def jkr_curve(A):
    """(Delta, P_bar) of JKR at contact radii A (Johnson & Greenwood's units)."""
    A = np.asarray(A, dtype=float)
    return A * A - 2.0 * np.sqrt(6.0 * A) / 3.0, A ** 3 - np.sqrt(6.0 * A ** 3)


def dmt_curve(A):
    """(Delta, P_bar) of DMT (Hertz plus the constant pull 2 pi R w) at contact radii A."""
    A = np.asarray(A, dtype=float)
    return A * A, A ** 3 - 2.0


def maugis_units(e_star: float, radius: float, work_of_adhesion: float) -> tuple[float, float]:
    """(delta per Delta [m], P per P_bar [N]): (pi^2 w^2 R / K^2)^(1/3) and pi w R, K = 4 E* / 3."""
    k = 4.0 * e_star / 3.0
    return (np.pi ** 2 * work_of_adhesion ** 2 * radius / k ** 2) ** (1.0 / 3.0), np.pi * work_of_adhesion * radius


def maugis_lambda(e_star: float, radius: float, work_of_adhesion: float, peak_stress: float) -> float:
    """The transition parameter lambda = 2 sigma0 (R / (pi w K^2))^(1/3) [-] of a law whose
    Dugdale stress sigma0 [Pa] is its peak attraction (Lennard-Jones: lambda = 1.157 mu)."""
    k = 4.0 * e_star / 3.0
    return 2.0 * peak_stress * (radius / (np.pi * work_of_adhesion * k * k)) ** (1.0 / 3.0)


#: A/A0 = kappa p / (E* h'_rms) at small loads, h'_rms = sqrt(<|grad h|^2>): Persson (J. Chem.
#: Phys. 115, 3840, 2001), kappa = sqrt(8 / pi); Bush, Gibson & Thomas (Wear 35, 87, 1975),
#: kappa = sqrt(2 pi) (their sqrt(pi) with the rms slope of a profile, h'_rms / sqrt(2)).
#: Exact numerics lie between (kappa ~ 2: Hyun, Pei, Molinari & Robbins, PRE 70, 026117, 2004).
KAPPA_PERSSON, KAPPA_BGT = float(np.sqrt(8.0 / np.pi)), float(np.sqrt(2.0 * np.pi))


def area_fraction_small_load(mean_pressure, e_star: float, rms_slope: float, kappa: float = KAPPA_PERSSON):
    """The small-load contact area fraction A/A0 = kappa p / (E* h'_rms) [-]."""
    return kappa * np.asarray(mean_pressure, dtype=float) / (e_star * rms_slope)


def maugis_pull_off_bar(lam: float) -> float:
    """The Maugis-Dugdale pull-off load P_bar_c = P_c / (pi w R) for transition parameter lambda."""
    if not (np.isfinite(lam) and lam > 0):
        raise ValueError(f"lambda must be finite and > 0, got {lam!r}")
    # the minimum over m: a log-spaced scan, then golden-section refinement
    m = 1.0 + np.logspace(-10, 6, 4000)
    _, P = maugis_curve(lam, m)
    k = int(np.argmin(P))
    lo, hi = np.log(m[max(k - 1, 0)] - 1.0), np.log(m[min(k + 1, m.size - 1)] - 1.0)
    f = lambda t: float(maugis_curve(lam, 1.0 + np.exp(t))[1])  # noqa: E731
    gr = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = lo, hi
    for _ in range(100):
        c, d = b - gr * (b - a), a + gr * (b - a)
        if f(c) < f(d):
            b = d
        else:
            a = c
    return min(f(0.5 * (a + b)), float(P[k]))


def maugis_pull_off(radius: float, work_of_adhesion: float, lam: float) -> float:
    """Maugis-Dugdale pull-off force [N]."""
    return maugis_pull_off_bar(lam) * np.pi * work_of_adhesion * radius


def window_tail_force(law, radius: float, approach: float, edges, force: float = 0.0,
                      e_star: float | None = None) -> float:
    """The law's force [N] outside a rectangular window about a sphere's apex: the attraction a
    finite window leaves out (a sphere's pull-off on the window is short of it).

    The gap outside is the sphere's, g = r^2 / 2R - delta, plus with ``force`` F [N] and ``e_star``
    [Pa] the far field of the half-space, F / (pi E* r) (a point load: a tensile F pulls the
    surface towards the sphere); ``edges`` = (x-, x+, y-, y+) [m], the window's distances from the
    apex to its four sides.  In each quadrant, polar coordinates
    about the apex turn the area integral of p(g) beyond the side at rho(theta) into
    R Phi(rho(theta)^2 / 2R - delta) (p = -dPhi/dg, Phi(inf) = 0), so that

        F_out = R sum_quadrants int_0^(pi/2) Phi(rho(theta)^2 / 2R - delta) dtheta,
        rho = min(a / cos(theta), b / sin(theta)),

    one smooth integral either side of the corner angle arctan(b / a), by Gauss-Legendre.  A
    circle of radius a instead gives Derjaguin's 2 pi R Phi(a^2 / 2R - delta): a square of half-width
    a leaves out less (for an r^-6 tail 2 (1/4 + 3 pi / 32) / (pi / 2) = 0.69 of it).  With the
    far field, g = r^2 / 2R - delta + c / r (c = F / (pi E*)), r = R g'(r) + R c / r^2 splits each
    radial integral into R Phi(g(rho)) and (R c / rho) int_0^1 p(g(rho / s)) ds.
    """
    xm, xp, ym, yp = (float(e) for e in edges)
    t, wq = np.polynomial.legendre.leggauss(64)
    c = 0.0 if not force else float(force) / (np.pi * float(e_star))
    total = 0.0
    for a, b in ((xp, yp), (xm, yp), (xm, ym), (xp, ym)):
        corner = np.arctan2(b, a)
        for lo, hi, side in ((0.0, corner, "a"), (corner, 0.5 * np.pi, "b")):
            th = lo + 0.5 * (hi - lo) * (t + 1.0)
            rho = a / np.cos(th) if side == "a" else b / np.sin(th)
            g = rho * rho / (2.0 * radius) - approach + c / rho
            total += 0.5 * (hi - lo) * radius * float(wq @ law.energy(g))
            if c:   # int_rho^inf p(g) r dr = R Phi(g(rho)) + int_rho^inf p(g) (r - R g'(r)) dr, r - R g' = R c / r^2
                total += 0.5 * (hi - lo) * float(wq @ _far_correction(law, radius, approach, c, rho))
    return total


def _far_correction(law, radius, approach, c, rho):
    """int_rho^inf p(r^2/2R - delta + c/r) R c / r^2 dr for each rho: r = rho / s, Gauss-Legendre in s."""
    s, ws = np.polynomial.legendre.leggauss(48)
    s = 0.5 * (s + 1.0)
    r = rho[:, None] / s[None, :]
    g = r * r / (2.0 * radius) - approach + c / r
    # dr = rho / s^2 ds, and R c / r^2 = R c s^2 / rho^2: the integrand is p(g) R c / rho ds
    return 0.5 * (law.pressure(g) @ ws) * radius * c / rho


def sphere_window_edges(nx: int, ny: int, dx: float, dy: float) -> tuple[float, float, float, float]:
    """(x-, x+, y-, y+) [m]: the distances from a sphere's apex (``geometry.surfaces.centre``, node
    (nx//2, ny//2)) to the sides of its window, each node's element dx x dy included."""
    i, j = nx // 2, ny // 2
    return (i + 0.5) * dx, (nx - i - 0.5) * dx, (j + 0.5) * dy, (ny - j - 0.5) * dy


def maugis_force(e_star: float, radius: float, work_of_adhesion: float, lam: float, approach: float) -> float:
    """Maugis-Dugdale force [N] at approach [m] on the branch stable under displacement control
    (the larger contact radius, beyond the fold of the approach, Delta's minimum); nan below that
    fold (no contact state)."""
    m = 1.0 + np.logspace(-8, 3, 20001)
    A, D, P = maugis_approach(lam, m)
    d_unit, p_unit = maugis_units(e_star, radius, work_of_adhesion)
    order = np.argsort(A)
    D, P = D[order], P[order]
    k = int(np.argmin(D))
    D, P = D[k:], P[k:]
    x = approach / d_unit
    return float("nan") if x < D[0] else float(np.interp(x, D, P)) * p_unit
