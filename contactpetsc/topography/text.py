"""Plain-text height files: a matrix of heights, or a list of x y z points on a grid.

Text matrix (``.txt``, ``.asc``, ``.csv``, ``.dat``): one line per row of the image, a row
being one y (the first line y = 0), its columns along x: the number in line j, column i is
h(x_i, y_j), so ny lines of nx numbers are an nx x ny map.  Encoding, header keys (Gwyddion's
export in its languages; an instrument's ``w= h=``, ``pixel size=``, ``height conversion
factor (-> m)=``) and decimal separators: ``textdata``.  Spacing: Gwyddion's ``Width`` / nx
and ``Height`` / ny, or the ``pixel size``; height unit: the conversion factor's, else
``Value units``, else ``data unit``; a file with none of them states no unit.

A map has two or more columns and lines.  A single column or line, and without a header that
declares a matrix two columns (x, z pairs) or two lines, are a line scan and refused: contact
needs a 2-D map.  Three columns on four or more lines without a header are read as an x y z
point list when their points make a full grid and the format was not named (``sniff``); named
``text``, they are a matrix of three columns.

Point list (``.xyz``): one point per line, ``x y z`` (blanks, tabs, commas or semicolons), in
any order, on a uniform grid, each node of the grid listed once; x, y and z are in one unit
(the heights' unit).
"""
from __future__ import annotations

import numpy as np

from . import textdata
from .base import FormatError, Topography


def _lines(path: str):
    """(header keys, rows of floats, metadata) of a text height file."""
    with open(path, "rb") as f:
        header, data = textdata.split_lines(textdata.decode(f.read()))
    rows, comma = textdata.numbers(data)
    widths = {len(r) for r in rows}
    if len(widths) != 1:
        raise FormatError(f"lines of different lengths ({sorted(widths)} numbers): a text matrix "
                          f"has the same number of columns (x) on every line (y)")
    return textdata.header_keys(header), rows, {"decimal comma": True} if comma else {}


def _refuse_line_scan(ncols: int, nlines: int, declared: bool) -> None:
    """FormatError for the shapes of a line scan (module docstring)."""
    what = None
    if ncols == 1:
        what = f"a single column of {nlines} numbers: a line scan (one profile)"
    elif nlines == 1:
        what = f"a single line of {ncols} numbers: a line scan (one profile)"
    elif ncols == 2 and not declared:
        what = f"{nlines} lines of 2 numbers: a line scan (x, z pairs)"
    elif nlines == 2 and not declared:
        what = f"2 lines of {ncols} numbers and no header: a line scan (x and z lines)"
    if what:
        raise FormatError(f"{what}: contact needs a 2-D map (a matrix with one line per y and one "
                          f"column per x, or an x y z point list on a full grid)")


def read_matrix(path: str, sniff: bool = False, **_) -> Topography:
    keys, rows, meta = _lines(path)
    matrix = np.array(rows, dtype=float)          # [j, i]: lines are y
    ny, nx = matrix.shape
    if nx == 3 and ny > 3 and not keys and sniff:    # named "text": a matrix of 3 columns
        try:
            return _points(matrix, meta)
        except FormatError as exc:
            raise FormatError(f"3 columns on {ny} lines and no header: not an x y z point list "
                              f"({exc}); if it is a matrix of 3 columns (x), name the format "
                              f"text (geometry.format, --format)") from None
    _refuse_line_scan(nx, ny, bool(keys))
    topo = Topography(shape=(nx, ny), dtype=np.dtype(float), heights=matrix.T.copy(), format="text",
                      metadata=dict(meta, layout="lines are y, columns are x"))
    _apply_header(topo, keys)
    return topo


def _apply_header(topo: Topography, keys: dict) -> None:
    """The grid, spacing [m] and height unit that the header keys give (module docstring)."""
    nx, ny = topo.shape
    for key, n in (("nx", nx), ("ny", ny)):
        if key in keys and int(keys[key][0]) != n:
            raise FormatError(f"the header announces {'w' if key == 'nx' else 'h'} = {keys[key][0]} "
                              f"({'values per line' if key == 'nx' else 'lines'}), the file has {n}: "
                              f"truncated, or lines wrapped?")
    if ("width" in keys) != ("height" in keys):
        given, missing = ("Width", "Height") if "width" in keys else ("Height", "Width")
        raise FormatError(f"the header gives # {given} but not # {missing}: add '# {missing}: "
                          f"<extent> <unit>' (the map's extent along {'y' if missing == 'Height' else 'x'})")
    if "width" in keys:
        topo.dx = textdata.length(*keys["width"], "Width") / nx
        topo.dy = textdata.length(*keys["height"], "Height") / ny
    elif "pixel_size" in keys:
        topo.dx = topo.dy = textdata.length(*keys["pixel_size"], "pixel size")
    topo.lateral_unit = "m" if topo.dx is not None else None
    if "factor" in keys:
        unit, factor = keys["factor"]
        topo.heights *= textdata.number(factor)
        topo.height_unit = unit
    elif "value_units" in keys:
        topo.height_unit = keys["value_units"][0]
    elif "data_unit" in keys:
        topo.height_unit = keys["data_unit"][0]
    for key in ("channel", "data_unit"):
        if key in keys:
            topo.metadata[key] = keys[key][0]


def read_xyz(path: str, **_) -> Topography:
    _, rows, meta = _lines(path)
    ncols = len(rows[0])
    if ncols != 3:
        _refuse_line_scan(ncols, len(rows), False)
        raise FormatError(f"{ncols} numbers on each line: every line of an x y z point list holds "
                          f"three numbers, x y z")
    return _points(np.array(rows, dtype=float), meta)


def _points(points: np.ndarray, meta: dict) -> Topography:
    """The map of x y z points (rows of ``points``) on a full uniform grid."""
    x, y, z = points.T
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
                      format="xyz", metadata=dict(meta, x0=float(x.min()), y0=float(y.min())))


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
