"""Love's (1929) surface displacement under a uniformly loaded rectangle.

For a pressure p on the rectangle |x'| <= a, |y'| <= b of an elastic
half-space, the normal displacement at the surface point (x, y) is
(Johnson, Contact Mechanics, eq. 3.25, with both bodies' compliances in E*)

    u(x, y) = p / (pi E*) [f(x+a, y+b) - f(x+a, y-b) - f(x-a, y+b) + f(x-a, y-b)],
    f(X, Y) = X ln(Y + sqrt(X^2 + Y^2)) + Y ln(X + sqrt(X^2 + Y^2)).

Since ln(Y + R) = asinh(Y/|X|) + ln|X|, and the terms X ln|X|, Y ln|Y| cancel
in the four-corner sum, we evaluate F(X, Y) = X asinh(Y/|X|) + Y asinh(X/|Y|)
instead: no logarithm of a difference of nearly equal numbers, and F -> 0 on
the axes.  These are the influence coefficients K_ij of eq. (3) of the
reference paper for elements of size 2a x 2b.
"""
from __future__ import annotations

import numpy as np


def _corner(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    ax, ay = np.abs(X), np.abs(Y)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = np.where(ax > 0, X * np.arcsinh(Y / np.where(ax > 0, ax, 1.0)), 0.0)
        t2 = np.where(ay > 0, Y * np.arcsinh(X / np.where(ay > 0, ay, 1.0)), 0.0)
    return t1 + t2


def love_displacement(x, y, a: float, b: float, e_star: float = 1.0) -> np.ndarray:
    """Displacement [m] at (x, y) [m] under unit pressure [Pa] on |x'|<=a, |y'|<=b.

    Parameters
    ----------
    x, y : array_like
        Field point relative to the centre of the rectangle [m].
    a, b : float
        Half-widths of the rectangle [m] (dx/2, dy/2 for a grid element).
    e_star : float
        Effective modulus E* [Pa], 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2.
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    s = (_corner(x + a, y + b) - _corner(x + a, y - b)
         - _corner(x - a, y + b) + _corner(x - a, y - b))
    return s / (np.pi * e_star)
