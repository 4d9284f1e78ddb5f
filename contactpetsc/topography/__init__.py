"""Measured topographies: height maps from files, with their grid, spacing and units.

``read_topography(path)`` reads a height map from any of the formats in ``FORMATS`` (chosen
by the file's extension, or named) and returns a ``Topography`` with heights [m] indexed
[i, j] = h(x_i, y_j), shape (nx, ny), and the spacing dx, dy [m] where the file gives it.
Heights of formats that state no unit (``.npy``, text, ``.xyz``) are in ``height_unit``
(default metres).  The readers follow the formats' published specifications (each module's
docstring); nothing here needs more than numpy (h5py for HDF5 files, imported when one is
read), so the converter ``contactpetsc import`` runs in an environment without MPI or PETSc.
Detrending: ``detrend.trend`` (used by ``geometry.surfaces.detrended``).  Files in the ~40
instrument formats of SurfaceTopography: ``contactpetsc import`` (docs/topography.md).
"""
from __future__ import annotations

import os

import numpy as np

from . import arrays, gsf, gwy, sniff, sur, text, x3p
from .base import HEIGHTS_ARE, FormatError, Topography, UnsupportedFeature
from .fill import FILLS, apply_fill
from .detrend import DETREND, centred_coordinates, trend
from .units import HEIGHT_UNITS, canonical, metres_per

__all__ = ["Topography", "FormatError", "UnsupportedFeature", "FILLS", "FORMATS", "read_topography", "format_of",
           "DETREND", "HEIGHT_UNITS", "HEIGHTS_ARE", "trend", "centred_coordinates", "grid_mismatch"]

#: format name -> (reader, file extensions)
FORMATS = {
    "npy": (arrays.read_npy, (".npy",)),
    "hdf5": (arrays.read_hdf5, arrays.HDF5_EXTENSIONS),
    "text": (text.read_matrix, (".txt", ".asc", ".csv", ".dat")),
    "xyz": (text.read_xyz, (".xyz",)),
    "gsf": (gsf.read_gsf, (".gsf",)),
    "gwy": (gwy.read_gwy, (".gwy",)),
    "x3p": (x3p.read_x3p, (".x3p",)),
    "sur": (sur.read_sur, (".sur",)),
}
#: formats read by rows (each MPI rank its own); the others are read whole
BY_ROWS = ("npy", "hdf5")


def format_of(path: str, format: str | None = None) -> str:
    """The format of ``path``: ``format`` if given, else the one its extension names."""
    if format is not None:
        if format not in FORMATS:
            raise ValueError(f"format {format!r}; accepted: {', '.join(FORMATS)}")
        return format
    ext = os.path.splitext(path)[1].lower()
    for name, (_, extensions) in FORMATS.items():
        if ext in extensions:
            if name == "text":
                sniff.refuse_binary(path)     # ".dat" is also many instruments' binary extension
            return name
    known = ", ".join(e for _, exts in FORMATS.values() for e in exts)
    raise ValueError(f"unknown height file type {ext!r} (accepted: {known}; or name the format)")


def read_topography(path: str, *, format: str | None = None, dataset: str = "heights",
                    height_unit: str | None = None, rows=None, metadata_only: bool = False,
                    fill: str = "none") -> Topography:
    """The height map in ``path``, heights and spacing in metres.

    ``height_unit``: the unit of the file's heights when the file states none (default "m");
    a file that states a different one is refused.  The x, y of a ``.xyz`` file are in the
    heights' unit.  ``rows`` = (ys, ye): only the columns j in [ys, ye) of the heights (read
    from the file alone for ``.npy`` and HDF5).  ``metadata_only``: shape, spacing and units
    without the heights where the format allows (``.npy``, HDF5).  Points not measured are NaN
    in the readers; ``fill``: "none" refuses them (the count and the fix named), "harmonic"
    fills them (``fill.harmonic``; the count in ``metadata["filled_points"]``; the whole map is
    read for it, then the rows asked for are cut).  Raises ValueError (a
    ``FormatError`` for a file that breaks its format), KeyError or OSError with the cause.
    """
    name = format_of(path, format)
    reader = FORMATS[name][0]
    if fill not in FILLS:
        raise ValueError(f"fill = {fill!r}; accepted: {', '.join(FILLS)}")
    whole = name not in BY_ROWS or fill == "harmonic"    # a fill needs every point: read all, cut after
    if name in BY_ROWS:
        topo = reader(path, dataset=dataset,
                      rows=None if metadata_only else ((0, None) if whole else (rows or (0, None))))
    else:
        topo = reader(path, dataset=dataset)
    if topo.dtype.kind not in "iuf":
        kind = {"b": "boolean", "c": "complex"}.get(topo.dtype.kind, "not numeric")
        raise ValueError(f"heights of dtype {topo.dtype} ({kind}); heights must be real numbers")
    if height_unit is not None:
        metres_per(height_unit)
    if topo.height_unit is not None and height_unit is not None and \
            metres_per(topo.height_unit) != metres_per(height_unit):
        raise ValueError(f"the file states its heights in {topo.height_unit!r}, not {height_unit!r}")
    unit = topo.height_unit or height_unit or "m"
    try:
        metres_per(unit)
    except ValueError:
        channel = f" (channel {topo.metadata['channel']!r})" if "channel" in topo.metadata else ""
        raise ValueError(f"the file's values are in {unit!r}, not a length: not a height map{channel}") from None
    lateral = topo.lateral_unit or unit
    scale = metres_per(unit)
    if topo.heights is not None:
        topo.heights = np.asarray(topo.heights) * scale if scale != 1.0 else np.asarray(topo.heights)
    if topo.dx is not None:
        topo.dx, topo.dy = topo.dx * metres_per(lateral), topo.dy * metres_per(lateral)
        if not (np.isfinite([topo.dx, topo.dy]).all() and topo.dx > 0 and topo.dy > 0):
            raise FormatError(f"the file's spacing ({topo.dx!r}, {topo.dy!r}) m is not positive")
    topo.unit_stated = topo.height_unit is not None
    topo.height_unit, topo.lateral_unit = canonical(unit), "m"
    apply_fill(topo, fill, solve=not metadata_only)
    if rows is not None and whole and topo.heights is not None:
        topo.heights = topo.heights[:, rows[0]:rows[1]]
    return topo


def grid_mismatch(topo: Topography, shape: tuple, spacing: tuple) -> str | None:
    """Why the map ``topo`` does not fit a grid of ``shape`` (nx, ny) and ``spacing`` (dx, dy)
    [m] (named as a scene's geometry keys), or None when it fits; the spacing is compared, to
    1e-9 relative, only where the file gives one."""
    if tuple(topo.shape) != tuple(shape):
        stamp = topo.metadata.get("axes")
        hint = ""
        if tuple(topo.shape) == tuple(shape)[::-1]:
            hint = {"npy": "; a .npy file holds (nx, ny): save the transpose",
                    "hdf5": "; if the dataset's rows are y, stamp it with the attribute axes = 'y,x'"
                    if stamp == "x,y" else ""}.get(topo.format, "")
        held = f"heights of shape (nx, ny) = {tuple(topo.shape)}" + (f" (stored as {stamp})" if stamp else "")
        return f"{held}, the grid (geometry.nx, geometry.ny) is {tuple(shape)}{hint}"
    if topo.dx is not None:
        for key, got, want in (("dx", topo.dx, spacing[0]), ("dy", topo.dy, spacing[1])):
            if not np.isclose(got, want, rtol=1e-9, atol=0.0):
                return f"the file's {key} = {got!r} m, the scene's geometry.{key} = {want!r} m"
    return None
