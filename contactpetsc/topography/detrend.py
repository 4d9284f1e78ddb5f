"""Detrending a measured map: the least-squares plane or quadratic subtracted.

A measured topography carries the sample's tilt (and, for curved samples or scanner bow, a
curvature) that the contact would feel as a wedge or a lens.  ``trend`` is the least-squares
fit of h by

- ``mean-plane``: a + b u + c v,
- ``curvature``: a + b u + c v + d u^2 + e u v + f v^2,

with u = x / Lx - 1/2, v = y / Ly - 1/2 the centred, scaled coordinates (which keep the normal
equations well conditioned); ``none`` fits nothing.  The fit is made from sums over the
nodes, so a map split in rows across MPI ranks is fitted from each rank's rows and an
all-reduce of the sums (``allreduce``): the same fit as on the whole map, to round-off.
"""
from __future__ import annotations

import numpy as np

DETREND = ("none", "mean-plane", "curvature")
#: nodes along each axis a fit needs: a plane 2 (3 nodes not on a line), a quadric 3 (u^2, v^2)
MIN_NODES = {"none": 1, "mean-plane": 2, "curvature": 3}


def check_size(nx: int, ny: int, mode: str, name: str = "detrend") -> None:
    """ValueError naming ``name`` when an nx x ny map has too few nodes for ``mode``'s fit (its
    normal equations would be singular)."""
    need = MIN_NODES.get(mode, 1)
    if min(nx, ny) < need:
        terms = "a + b u + c v" + (" + d u^2 + e u v + f v^2" if mode == "curvature" else "")
        raise ValueError(f"{name} = {mode!r} fits {terms}: it needs at least {need} nodes along each axis "
                         f"({need * need} nodes, not on one line), this map is {nx} x {ny}; accepted for it: "
                         + ", ".join(m for m in DETREND if min(nx, ny) >= MIN_NODES[m]))


def _basis(u: np.ndarray, v: np.ndarray, mode: str) -> list:
    one = np.ones_like(u)
    if mode == "mean-plane":
        return [one, u, v]
    return [one, u, v, u * u, u * v, v * v]


def trend(heights: np.ndarray, u: np.ndarray, v: np.ndarray, mode: str,
          allreduce=lambda a: a) -> np.ndarray:
    """The fitted surface at the nodes of ``heights`` (same shape, same unit); ``u``, ``v`` the
    nodes' centred coordinates (module docstring); zeros for ``mode = "none"``."""
    if mode not in DETREND:
        raise ValueError(f"detrend = {mode!r}; accepted: {', '.join(DETREND)}")
    if mode == "none":
        return np.zeros_like(heights, dtype=float)
    basis = _basis(u, v, mode)
    normal = np.array([[float(np.sum(p * q)) for q in basis] for p in basis])
    rhs = np.array([float(np.sum(p * heights)) for p in basis])
    coeffs = np.linalg.solve(allreduce(normal), allreduce(rhs))
    return sum(c * p for c, p in zip(coeffs, basis))


def centred_coordinates(nx: int, ny: int, columns=slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of an nx x ny map's nodes, indexed [i, j] for the columns j in ``columns``."""
    u = np.arange(nx) / nx - 0.5
    v = np.arange(ny)[columns] / ny - 0.5
    return np.meshgrid(u, v, indexing="ij")
