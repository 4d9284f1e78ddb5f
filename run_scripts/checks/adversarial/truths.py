"""Expected outcomes computed without the package: the laws written out from
docs/formulation.md, the rigid-sphere sum, Hertz, the signature of PETSc's random vector."""
from __future__ import annotations

import math

import numpy as np

from .harness import Z0


# --------------------------------------------------------------------------------------------
# interaction laws, written out from docs/formulation.md (pressure [Pa], compressive positive)
def law_pressure(law: str, g, w: float, z0: float = Z0, rho: float | None = None,
                 sigma0: float | None = None):
    """p(g) [Pa] of a law at gap g [m] (hard-wall laws: the adhesive part for g >= 0)."""
    g = np.asarray(g, dtype=float)
    if law in ("lj", "hardwall-lj"):
        t = z0 / (g + z0)
        return 8 * w / (3 * z0) * (t ** 9 - t ** 3)
    if law == "exponential":
        return -(w / rho) * np.exp(-g / rho)
    if law == "dugdale":
        return np.where(g < w / sigma0, -sigma0, 0.0)
    return np.zeros_like(g)


def law_peak(law: str, w: float, z0: float = Z0, rho=None, sigma0=None) -> float:
    """The law's largest tension [Pa] (> 0)."""
    return {"lj": 16 * w / (9 * math.sqrt(3) * z0), "hardwall-lj": 16 * w / (9 * math.sqrt(3) * z0),
            "exponential": w / rho if rho else 0.0, "dugdale": sigma0 or 0.0}[law]


def sphere_heights(nx: int, ny: int, dx: float, dy: float, radius: float) -> np.ndarray:
    """Paraboloid heights [m], indexed [j, i] (row = y), apex at node (nx//2, ny//2)."""
    x = (np.arange(nx) - nx // 2) * dx
    y = (np.arange(ny) - ny // 2) * dy
    return (x[None, :] ** 2 + y[:, None] ** 2) / (2 * radius)


def rigid_force(h: np.ndarray, delta: float, dx: float, dy: float, law: str, w: float,
                **kw) -> float:
    """F = sum p(h - delta) dx dy [N] of a rigid surface at approach delta [m]."""
    return float(np.sum(law_pressure(law, h - delta, w, **kw)) * dx * dy)


def rigid_force_bounds(h: np.ndarray, delta: float, dx: float, dy: float, law: str, w: float,
                       **kw) -> tuple[float, float]:
    """(lo, hi) [N]: ``rigid_force``, widened for the Dugdale law by the nodes whose rigid gap
    sits on its cut-off w / sigma0 (to 1e-6 z0): any deformation, however small, puts such a
    node on either side of the discontinuity."""
    f = rigid_force(h, delta, dx, dy, law, w, **kw)
    if law != "dugdale":
        return f, f
    on_edge = np.count_nonzero(np.abs(h - delta - w / kw["sigma0"]) <= 1e-6 * Z0)
    return f - kw["sigma0"] * on_edge * dx * dy, f


def peak_approach(law: str, z0: float = Z0, **kw) -> float:
    """The approach [m] at which a flat cell's tension peaks (gap 3^(1/6) z0 - z0 for the LJ
    laws, contact for the exponential one)."""
    return -(3 ** (1 / 6) - 1) * z0 if law in ("lj", "hardwall-lj") else 0.0


# --------------------------------------------------------------------------------------------
# class 4: PETSc's random vector must never be written
def random_signature(p: np.ndarray) -> bool:
    """The output of VecSetRandom: every value in [0, 1), spread uniformly."""
    p = p[np.isfinite(p)]
    return (p.size > 16 and p.min() >= 0 and p.max() < 1 and p.std() > 0.2
            and abs(p.mean() - 0.5) < 0.06)


def hertz_force(e_star, radius, delta):
    return 4 / 3 * e_star * math.sqrt(radius) * delta ** 1.5
