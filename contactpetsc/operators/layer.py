"""A finite elastic layer of thickness t on a rigid base: the factor f(q t) of its Fourier kernel.

A pressure mode p cos(q . x) on the layer's free surface displaces it by

    u(q) = 2 / (E* |q|) * f(|q| t) * p          (E* = E / (1 - nu^2) of the layer)

(plane strain along q).  With kappa = 3 - 4 nu and x = |q| t, the two interfaces of the
layer with its rigid base (docs/formulation.md, "Finite elastic layer"):

* frictionless (the base carries no shear):  f(x) = (cosh 2x - 1) / (sinh 2x + 2x);
* bonded (no slip at the base):
  f(x) = (kappa sinh 2x - 2x) / (kappa cosh 2x + 2 x^2 + (1 + kappa^2) / 2).

Both tend to 1 as x -> inf (the half-space) and vanish as x -> 0: the frictionless layer
like x / 2 (u = p t / E*, a laterally free strip in plane strain), the bonded one like
8 (1 - 2 nu) x / (kappa + 1)^2 (u = p t (1 + nu)(1 - 2 nu) / (E (1 - nu)), a laterally
confined layer), and the incompressible bonded layer like 2 x^3 / 3 (u = t^3 q^2 p / (3 mu)).
tests/test_layer.py checks both against the boundary-value problem solved numerically.
The formulas are evaluated in e = exp(-2x), free of overflow and of cancellation at small x;
beyond x = ``HALF_SPACE_X`` (40: 1 - f ~ x^2 e^{-2x} < 1e-31) f is 1, the half-space, so a
layer of any finite thickness is computable.  Thin layers are computable while the
relative compliance of the cell's longest mode, f(2 pi t / L), is at least ``MIN_FACTOR``
(1e-100): the layer's pressures are those of the half-space over f, and with f below that
they, their squares in the solvers' norms, or the stiffness E* |q| / (2 f) leave the
floating-point range (``thinnest``, checked by ``PeriodicLayer`` and the scene).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

INTERFACES = ("bonded", "frictionless")
#: f(x) = 1 to round-off beyond this x = |q| t (the half-space)
HALF_SPACE_X = 40.0
#: the smallest relative compliance f of a mode that the solvers compute in floating point
MIN_FACTOR = 1e-100


@dataclass(frozen=True)
class Layer:
    """An elastic layer on a rigid base: ``thickness`` t [m], ``interface`` bonded or
    frictionless, ``poisson_ratio`` nu of the layer (in (-1, 0.5]; needed when bonded, the
    frictionless factor does not depend on it)."""
    thickness: float
    interface: str = "bonded"
    poisson_ratio: float | None = None

    def __post_init__(self):
        t = self.thickness
        if isinstance(t, bool) or not isinstance(t, (int, float)) or not (math.isfinite(t) and t > 0):
            raise ValueError(f"layer thickness (m) must be finite and > 0, got {t!r}")
        if self.interface not in INTERFACES:
            raise ValueError(f"layer interface must be one of {', '.join(INTERFACES)}, got {self.interface!r}")
        nu = self.poisson_ratio
        if nu is None:
            if self.interface == "bonded":
                raise ValueError("a bonded layer needs its poisson_ratio, in (-1, 0.5]")
        elif isinstance(nu, bool) or not isinstance(nu, (int, float)) or not -1.0 < nu <= 0.5:
            raise ValueError(f"layer poisson_ratio = {nu!r}: accepted range (-1, 0.5]")

    def factor(self, q: np.ndarray) -> np.ndarray:
        """f(|q| t) for wavenumbers |q| [1/m] (0 at q = 0)."""
        return layer_factor(np.asarray(q, float) * self.thickness, self.interface, self.poisson_ratio)


def _sinh_minus_identity(y: np.ndarray) -> np.ndarray:
    """sinh(y) - y for 0 <= y < 1 without cancellation: its Taylor series (8 terms, error
    below 1e-17 relative)."""
    term = y ** 3 / 6.0
    out = term.copy()
    y2 = y * y
    for k in range(2, 9):
        term = term * y2 / ((2 * k) * (2 * k + 1))
        out += term
    return out


def layer_factor(x: np.ndarray, interface: str, poisson_ratio: float | None = None) -> np.ndarray:
    """f(x), x = |q| t >= 0, of the layer's kernel (module docstring); f(0) = 0."""
    x_in = np.asarray(x, float)
    x = np.minimum(x_in, HALF_SPACE_X)     # beyond it f = 1; x^2 e^{-2x} would be inf * 0
    e = np.exp(-2.0 * x)
    one_minus_e2 = -np.expm1(-4.0 * x)
    if interface == "frictionless":
        # (cosh 2x - 1) / (sinh 2x + 2x) times 2 e on top and bottom
        num = np.expm1(-2.0 * x) ** 2
        den = one_minus_e2 + 4.0 * x * e
    elif interface == "bonded":
        kappa = 3.0 - 4.0 * poisson_ratio
        # kappa (1 - e^2) - 4 x e = (kappa - 1)(1 - e^2) + 2 e (sinh 2x - 2x); the last bracket
        # cancels at small x (it is all that is left of the numerator when nu = 1/2)
        small = x < 0.5
        bracket = np.where(small, 2.0 * e * _sinh_minus_identity(np.where(small, 2.0 * x, 0.0)),
                           one_minus_e2 - 4.0 * x * e)
        num = (kappa - 1.0) * one_minus_e2 + bracket
        den = kappa * (1.0 + e * e) + (4.0 * x * x + 1.0 + kappa * kappa) * e
    else:
        raise ValueError(f"layer interface must be one of {', '.join(INTERFACES)}, got {interface!r}")
    # f(0) = 0 (the frictionless ratio is 0/0 there)
    f = np.where(x > 0, num / np.where(x > 0, den, 1.0), 0.0)
    return np.where(x_in >= HALF_SPACE_X, 1.0, f)


def thinnest(lengths, interface: str, poisson_ratio: float | None = None) -> float:
    """The smallest thickness [m] a cell of side ``lengths`` computes: f(2 pi t / max(lengths))
    = ``MIN_FACTOR`` (f rises with t; bisection in log t)."""
    q = 2.0 * math.pi / max(lengths)
    lo, hi = -400.0, math.log(HALF_SPACE_X / q)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if layer_factor(q * math.exp(mid), interface, poisson_ratio) < MIN_FACTOR:
            lo = mid
        else:
            hi = mid
    return math.exp(hi)


def check_thickness(layer: "Layer", lengths, name: str = "layer thickness") -> None:
    """Refuse a layer too thin for the cell (``thinnest``), naming ``name`` and the range."""
    t_min = thinnest(lengths, layer.interface, layer.poisson_ratio)
    if layer.thickness < t_min:
        raise ValueError(
            f"{name} = {layer.thickness!r} m: accepted range [{t_min:.3g}, inf) m on a "
            f"{lengths[0]:.6g} x {lengths[1]:.6g} m cell ({layer.interface} layer); thinner, the layer's "
            f"compliance relative to a half-space, f(2 pi t / L), is below {MIN_FACTOR:g} and its "
            f"pressures and stiffness leave the floating-point range")
