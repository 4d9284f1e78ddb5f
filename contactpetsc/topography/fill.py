"""Points not measured (NaN heights): refused, or filled by harmonic interpolation.

``FILLS``: ``none`` refuses a map with NaN heights (the count and the fix named);
``harmonic`` gives the NaN points the solution of Laplace's equation with the measured points
as boundary values, as Gwyddion's "Laplace" interpolation and SurfaceTopography's
``interpolate_undefined_data`` (harmonic) do: a filled point is the spacing-weighted mean of
its four neighbours, (h[i-1] + h[i+1]) / dx^2 + (h[j-1] + h[j+1]) / dy^2 =
2 (1/dx^2 + 1/dy^2) h[i, j], the 5-point Laplacian = 0.  A neighbour beyond the map's edge
is left out (a zero normal derivative there; a periodic map wraps instead).  Exact for
harmonic polynomials up to second order (a + b x + c y + d (x^2 - y^2) + e x y), to the
solver's tolerance.  The system, restricted to the unknown points, is symmetric positive
definite (each connected hole touches a measured point); it is solved by conjugate gradients
with a Jacobi preconditioner in numpy, matrix-free: memory a few arrays of the holes' size.
"""
from __future__ import annotations

import numpy as np

from .base import FormatError

FILLS = ("none", "harmonic")
FIX = ('fill them: geometry.fill = "harmonic" in a scene, contactpetsc import --fill harmonic '
       '(Laplace interpolation), or interpolate them in Gwyddion or MountainsMap')


def undefined(heights: np.ndarray) -> int:
    """The number of points not measured (NaN)."""
    return int(np.count_nonzero(np.isnan(heights)))


def refuse_undefined(heights: np.ndarray, shape: tuple) -> None:
    """FormatError with the count and the fix when ``heights`` hold NaN (points not measured)."""
    count = undefined(heights)
    if count:
        held = ("" if heights.shape == tuple(shape) else " in the rows read")
        raise FormatError(f"{count} of the {shape[0]} x {shape[1]} points{held} are not measured "
                          f"(NaN); {FIX}")


def harmonic(heights: np.ndarray, dx: float = 1.0, dy: float = 1.0, periodic: bool = False,
             rtol: float = 1e-13, maxiter: int | None = None) -> tuple[np.ndarray, int]:
    """(the map with its NaN points filled harmonically (module docstring), their count);
    ``heights`` (nx, ny) in any unit, ``dx``, ``dy`` the spacing in any one unit.  Converges to
    ``rtol`` of the right-hand side; FormatError when no point is measured."""
    h = np.array(heights, dtype=float)
    hole = np.isnan(h)
    n = int(np.count_nonzero(hole))
    if n == 0:
        return h, 0
    if n == h.size:
        raise FormatError("no point of the map is measured: nothing to interpolate from")
    nx, ny = h.shape
    number = np.full(h.shape, -1)
    number[hole] = np.arange(n)
    ii, jj = np.nonzero(hole)
    diag = np.zeros(n)
    rhs = np.zeros(n)
    links = []      # (weight, neighbour's unknown number or -1) per direction
    for di, dj, w in ((1, 0, dx ** -2), (-1, 0, dx ** -2), (0, 1, dy ** -2), (0, -1, dy ** -2)):
        ni, nj = ii + di, jj + dj
        if periodic:
            ni, nj, inside = ni % nx, nj % ny, np.ones(n, bool)
        else:
            inside = (ni >= 0) & (ni < nx) & (nj >= 0) & (nj < ny)
            ni, nj = np.where(inside, ni, 0), np.where(inside, nj, 0)
        other = np.where(inside, number[ni, nj], -1)
        known = inside & (other < 0)
        diag += w * inside
        rhs += w * np.where(known, h[ni, nj], 0.0)
        links.append((w, np.where(other >= 0, other, 0), other >= 0))

    def apply(u):
        out = diag * u
        for w, other, linked in links:
            out -= w * np.where(linked, u[other], 0.0)
        return out

    u = _conjugate_gradients(apply, rhs, 1.0 / diag, rtol, maxiter or 10 * n + 100)
    h[hole] = u
    return h, n


def _conjugate_gradients(apply, b, inverse_diagonal, rtol, maxiter):
    """x with apply(x) = b (symmetric positive definite), Jacobi-preconditioned CG from x = 0."""
    x = np.zeros_like(b)
    r = b.copy()
    z = inverse_diagonal * r
    p = z.copy()
    rz = float(r @ z)
    target = rtol * max(float(np.linalg.norm(b)), np.finfo(float).tiny)
    for _ in range(maxiter):
        if np.linalg.norm(r) <= target:
            return x
        q = apply(p)
        alpha = rz / float(p @ q)
        x += alpha * p
        r -= alpha * q
        z = inverse_diagonal * r
        rz, rz_old = float(r @ z), rz
        p = z + (rz / rz_old) * p
    raise FormatError(f"the harmonic fill did not converge in {maxiter} iterations")


def apply_fill(topo, fill: str, solve: bool = True) -> None:
    """``topo``'s NaN heights refused (``fill = "none"``) or filled (``"harmonic"``, the count in
    ``topo.metadata["filled_points"]``); nothing without heights.  ``solve`` False (a metadata
    read): the points to fill are only counted, in ``topo.metadata["undefined_points"]``."""
    if fill not in FILLS:
        raise ValueError(f"fill = {fill!r}; accepted: {', '.join(FILLS)}")
    if topo.heights is None:
        return
    if fill == "none":
        refuse_undefined(np.asarray(topo.heights), topo.shape)
        return
    if not solve:
        topo.metadata["undefined_points"] = undefined(np.asarray(topo.heights))
        return
    ratio = 1.0 if topo.dx is None else topo.dy / topo.dx       # only the ratio matters
    topo.heights, topo.metadata["filled_points"] = harmonic(topo.heights, 1.0, ratio, bool(topo.periodic))
