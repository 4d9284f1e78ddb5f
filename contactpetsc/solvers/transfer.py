"""Transfers between a grid and the grid of half as many nodes each way (spacing doubled).

Coarse node (I, J) is the 2 x 2 block of fine nodes (2I..2I+1, 2J..2J+1).
Rows per rank are aligned to even numbers (``SurfaceGrid(row_alignment=...)``),
so every transfer but the bilinear one is rank-local.  On a block grid
(``grid.px`` > 1) the columns per rank are even too; the bilinear one needs
whole rows.
"""
from __future__ import annotations

import numpy as np

from ..grid import SurfaceGrid, block_grid_fits


def can_halve(grid: SurfaceGrid) -> bool:
    """Whether ``grid`` has a 2x coarser grid with rank-local transfers (even sizes, rows and
    columns per rank) on which the FFT still gives every rank a line (``block_grid_fits``;
    on slabs: at least as many Fourier columns as ranks)."""
    blocks = [b - a for a, b in grid.y_ranges + grid.x_ranges]
    if grid.nx % 2 or grid.ny % 2 or min(grid.nx, grid.ny) < 4 or any(r % 2 or r < 2 for r in blocks):
        return False
    return block_grid_fits(grid.nx // 2, grid.ny // 2, grid.px, grid.py,
                           [(b - a) // 2 for a, b in grid.y_ranges])


def halved(grid: SurfaceGrid) -> SurfaceGrid:
    """The 2x coarser grid (spacing doubled), each rank owning the parents of its nodes."""
    return SurfaceGrid(grid.nx // 2, grid.ny // 2, 2 * grid.dx, 2 * grid.dy, periodic=grid.periodic,
                       comm=grid.comm, y_ownership=[(b - a) // 2 for a, b in grid.y_ranges],
                       px=grid.px, x_ownership=[(b - a) // 2 for a, b in grid.x_ranges])


def restrict(fine: np.ndarray) -> np.ndarray:
    """2 x 2 block means of a (ny_loc, nx) array (heights, gaps, residuals)."""
    # strided sums, much faster than numpy's mean of the 4-d view, in the order that mean takes
    # (each row's pair first; bit for bit where nx >= 4): the full-LJ benchmark path depends on
    # round-off, and strided sums in another order had moved it to dearer states
    # (docs/journal/performance.md)
    a, b, c, d = children(fine)
    out = np.add(a, b)
    out += np.add(c, d)
    out *= 0.25
    return out


def children(fine: np.ndarray) -> tuple[np.ndarray, ...]:
    """The four (ny_loc / 2, nx / 2) strided views of a 2 x 2 block's children."""
    return fine[0::2, 0::2], fine[0::2, 1::2], fine[1::2, 0::2], fine[1::2, 1::2]


def block_all(fine: np.ndarray) -> np.ndarray:
    """Whether all four children of each 2 x 2 block are true (a mask's coarse set)."""
    a, b, c, d = children(fine)
    return a & b & c & d


def prolong_constant(coarse: np.ndarray) -> np.ndarray:
    """Piecewise-constant copy to the 2 x 2 children (pressure is a density: the mean is kept)."""
    ny, nx = coarse.shape
    out = np.empty((2 * ny, 2 * nx))
    # one broadcast copy: two np.repeat passes cost half as much again
    out.reshape(ny, 2, nx, 2)[...] = coarse[:, None, :, None]
    return out


def add_prolonged(fine: np.ndarray, coarse: np.ndarray) -> np.ndarray:
    """fine += the piecewise-constant copy of ``coarse``, child by child (no temporary)."""
    for child in children(fine):
        child += coarse
    return fine


def prolong_bilinear(coarse: np.ndarray, grid: SurfaceGrid) -> np.ndarray:
    """Cell-centred bilinear interpolation to the 2 x 2 children (weights 9/16, 3/16, 3/16, 1/16).

    A child lies a quarter of a coarse spacing from its parent: 3/4 parent +
    1/4 neighbour per direction.  The weights are positive (p >= 0 is kept)
    and, on a periodic cell, every coarse value is spread with total weight 4,
    so the mean is kept; at an isolated window's edge the edge value is
    repeated.  One halo row from each neighbour rank (``grid`` is the coarse grid).
    """
    grid.require_slabs("bilinear prolongation (-contact_fmg_prolong bilinear)")
    lo, hi = grid.halo_rows(coarse, np.empty(coarse.shape[1]), np.empty(coarse.shape[1]), edge="repeat")
    ext = np.concatenate([lo[None], coarse, hi[None]])
    if grid.periodic:
        left, right = np.roll(ext, 1, axis=1), np.roll(ext, -1, axis=1)
    else:
        left = np.concatenate([ext[:, :1], ext[:, :-1]], axis=1)
        right = np.concatenate([ext[:, 1:], ext[:, -1:]], axis=1)
    ny, nx = coarse.shape
    x = np.empty((ny + 2, 2 * nx))
    x[:, 0::2] = 0.75 * ext + 0.25 * left
    x[:, 1::2] = 0.75 * ext + 0.25 * right
    out = np.empty((2 * ny, 2 * nx))
    out[0::2] = 0.75 * x[1:-1] + 0.25 * x[:-2]
    out[1::2] = 0.75 * x[1:-1] + 0.25 * x[2:]
    return out
