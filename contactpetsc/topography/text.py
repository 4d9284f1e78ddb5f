"""Plain-text height files: a matrix of heights, or a list of x y z points on a grid.

Text matrix (``.txt``, ``.asc``, ``.csv``, ``.dat``): one line per row of the image, a row
being one y (the first line y = 0), its columns along x: the number in line j, column i is
h(x_i, y_j), so a matrix of ny lines and nx columns is an nx x ny map.  Numbers are separated
by blanks, tabs, commas or semicolons.  Lines starting with ``#`` are comments; three of
them, as Gwyddion's "ASCII data matrix" export writes them, are read: ``# Width: 10 µm`` and
``# Height: 7.5 µm`` (the map's extent nx dx and ny dy) and ``# Value units: nm`` (the
heights' unit).

Point list (``.xyz``): one point per line, ``x y z`` (blanks, tabs or commas), in any order,
on a uniform grid, each node of the grid listed once; x, y and z are in one unit
(the heights' unit).
"""
from __future__ import annotations

import re

import numpy as np

from .base import FormatError, Topography

_SEPARATORS = re.compile(r"[,;\s]+")
_EXTENT = re.compile(r"^#\s*(Width|Height)\s*:\s*([-+0-9.eE]+)\s*(\S+)\s*$")
_UNITS = re.compile(r"^#\s*Value units\s*:\s*(\S+)\s*$")


def _numbers(path: str):
    """(rows of floats, comment lines) of a text file."""
    rows, comments = [], []
    with open(path, encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            text = line.strip()
            if not text:
                continue
            if text.startswith("#"):
                comments.append(text)
                continue
            try:
                rows.append([float(w) for w in _SEPARATORS.split(text) if w])
            except ValueError:
                raise FormatError(f"line {n} is not numbers: {text[:60]!r}") from None
    if not rows:
        raise FormatError("no numbers (an empty text file)")
    return rows, comments


def read_matrix(path: str, **_) -> Topography:
    rows, comments = _numbers(path)
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise FormatError(f"lines of different lengths ({sorted(widths)} numbers): a text matrix "
                          f"has the same number of columns (x) on every line (y)")
    matrix = np.array(rows, dtype=float)          # [j, i]: lines are y
    ny, nx = matrix.shape
    if nx == 3 and ny > 3:
        raise FormatError(f"3 columns on {ny} lines: an x y z point list? name the format xyz "
                          f"(geometry.format); a text matrix has one column per x")
    topo = Topography(shape=(nx, ny), dtype=np.dtype(float), heights=matrix.T.copy(), format="text",
                      metadata={"layout": "lines are y, columns are x"})
    extent, units = {}, set()
    for line in comments:
        if m := _EXTENT.match(line):
            extent[m.group(1)] = (float(m.group(2)), m.group(3))
        elif m := _UNITS.match(line):
            topo.height_unit = m.group(1)
    if "Width" in extent:
        (width, unit), (height, unit_y) = extent["Width"], extent.get("Height", extent["Width"])
        units = {unit, unit_y}
        if len(units) > 1:
            raise FormatError(f"# Width and # Height in different units ({', '.join(sorted(units))})")
        topo.dx, topo.dy, topo.lateral_unit = width / nx, height / ny, unit
    return topo


def read_xyz(path: str, **_) -> Topography:
    rows, _ = _numbers(path)
    if {len(r) for r in rows} != {3}:
        raise FormatError("every line of an .xyz file holds three numbers: x y z")
    x, y, z = np.array(rows, dtype=float).T
    i, nx, dx = _grid_index(x, "x")
    j, ny, dy = _grid_index(y, "y")
    heights = np.full((nx, ny), np.nan)
    count = np.zeros((nx, ny), int)
    np.add.at(count, (i, j), 1)
    if count.max() > 1:
        a, b = np.argwhere(count > 1)[0]
        raise FormatError(f"the point ({x.min() + a * dx:g}, {y.min() + b * dy:g}) is listed "
                          f"{count.max()} times")
    if count.min() == 0:
        raise FormatError(f"{int((count == 0).sum())} of the {nx} x {ny} grid points are missing: "
                          f"a height map needs every point of its grid")
    heights[i, j] = z
    return Topography(shape=(nx, ny), dtype=np.dtype(float), heights=heights, dx=dx, dy=dy,
                      format="xyz", metadata={"x0": float(x.min()), "y0": float(y.min())})


def _grid_index(c: np.ndarray, name: str):
    """(node index of each coordinate, number of nodes, spacing) of coordinates on a uniform
    grid; FormatError when they are not on one (to 1e-3 of the spacing)."""
    values = np.unique(c)
    span = values[-1] - values[0]
    if span == 0:
        raise FormatError(f"all points have the same {name}: a height map needs two or more")
    # coordinates printed with few digits differ by round-off: one node is a cluster of values
    nodes = 1 + int(np.count_nonzero(np.diff(values) > 1e-6 * span))
    spacing = span / (nodes - 1)
    index = np.rint((c - values[0]) / spacing).astype(int)
    off = np.abs(c - values[0] - index * spacing).max()
    if off > 1e-3 * spacing:
        raise FormatError(f"the {name} coordinates are not on a uniform grid (spacing {spacing:g}: "
                          f"a point lies {off:g} off its node)")
    return index, nodes, spacing
