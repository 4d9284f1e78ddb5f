"""Measured topographies: height maps from files, with their grid, spacing and units.

``read_topography(path)`` reads a height map from any of the formats in ``FORMATS`` (chosen
by the file's extension, or named) and returns a ``Topography`` with heights [m] indexed
[i, j] = h(x_i, y_j), shape (nx, ny), and the spacing dx, dy [m] where the file gives it.
Heights of formats that state no unit (``.npy``, text, ``.xyz``) are in ``height_unit``
(default metres).  The readers follow the formats' published specifications (each module's
docstring); nothing here needs more than numpy (h5py for HDF5 files, imported when one is
read), so the converter ``contactpetsc import`` runs in an environment without MPI or PETSc.
Every reader failure is reported with the file's name and its cause (``read_topography``);
``units.warn_units`` warns of unstated or implausible units.  Detrending: ``detrend.trend``
(used by ``geometry.surfaces.detrended``).  Files in the ~40 instrument formats of
SurfaceTopography: ``contactpetsc import`` (docs/topography.md).
"""
from __future__ import annotations

import os
import struct
import zipfile
import zlib

import numpy as np

from . import arrays, gsf, gwy, sniff, sur, text, x3p
from .base import HEIGHTS_ARE, FormatError, HeightUnitConflict, Topography, UnsupportedFeature
from .detrend import DETREND, centred_coordinates, trend
from .fill import FILLS, apply_fill
from .units import HEIGHT_UNITS, TopographyUnitWarning, canonical, metres_per, warn_units

__all__ = ["Topography", "FormatError", "HeightUnitConflict", "UnsupportedFeature", "TopographyUnitWarning",
           "warn_units", "FILLS", "FORMATS", "HEIGHTS_ARE", "read_topography", "format_of", "DETREND",
           "HEIGHT_UNITS", "trend", "centred_coordinates", "grid_mismatch"]

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

    ``format``: by the file's extension when None (then a ``.txt``-like file of x y z points
    on a grid is read as ``xyz``; ``Topography.format`` says which was read).  ``height_unit``:
    the unit of the file's heights when the file states none (default "m"); a file that states
    a different one is refused (``HeightUnitConflict``).  The x, y of a ``.xyz`` file are in the
    heights' unit.  ``rows`` = (ys, ye): only the columns j in [ys, ye) of the heights (read
    from the file alone for ``.npy`` and HDF5).  ``metadata_only``: shape, spacing and units
    without the heights where the format allows (``.npy``, HDF5).  Points not measured are NaN
    in the readers; ``fill``: "none" refuses them (the count and the fix named), "harmonic"
    fills them (``fill.harmonic``; the count in ``metadata["filled_points"]``; the whole map is
    read for it, then the rows asked for are cut).

    Errors start with the file's name and say the cause: KeyError for a missing dataset or
    channel, OSError for a file that cannot be opened, else ValueError (a ``FormatError`` for a
    file that breaks its format or that its reader fails on, whatever the reader raised).
    """
    name = os.path.basename(path) or path
    try:
        return _read(path, format, dataset, height_unit, rows, metadata_only, fill)
    except KeyError:
        raise
    except Exception as exc:  # noqa: BLE001 - every reader failure, named and explained
        raise _named(name, _format_name(path, format), exc) from exc


def _format_name(path: str, format: str | None) -> str:
    """The format of ``path`` for messages ("height" when it has none)."""
    try:
        return format_of(path, format)
    except ValueError:
        return "height"


#: reader failures that are not ValueErrors, and the cause in words
_CAUSES = ((struct.error, "its data end before the sizes its header announces (truncated?)"),
           (EOFError, "it ends early (truncated?)"),
           (ZeroDivisionError, "its header gives a size or scale of zero"),
           (RecursionError, "its structure is nested too deeply (damaged?)"),
           (zipfile.BadZipFile, "it is not a readable zip archive (damaged, or another format?)"),
           (zlib.error, "its compressed data are damaged"),
           (OverflowError, "a number or size in it is out of range (a damaged header?)"),
           (MemoryError, "its header announces more data than fits in memory (a damaged header?)"),
           (ImportError, "reading it needs a package that is not installed"))


def _named(name: str, fmt: str, exc: Exception) -> Exception:
    """``exc`` of reading file ``name`` as an error whose message starts with the name."""
    text = str(exc) if str(exc).startswith(name) else f"{name}: {exc}"
    if isinstance(exc, OSError):
        return exc if exc.filename is not None else OSError(text)
    if isinstance(exc, HeightUnitConflict):
        return HeightUnitConflict(text, exc.stated)
    if isinstance(exc, ValueError) and not isinstance(exc, UnicodeError):
        # the class is kept: an UnsupportedFeature sends ``contactpetsc import`` to SurfaceTopography
        return type(exc)(text) if type(exc) in (ValueError, FormatError, UnsupportedFeature) else ValueError(text)
    cause = next((words for kind, words in _CAUSES if isinstance(exc, kind)),
                 "its reader failed on it (damaged, or another format?)")
    return FormatError(f"{name}: cannot be read as a {fmt} file: {cause} [{type(exc).__name__}: "
                       f"{exc}]; check that the file is whole and of this format (or name its format)")


def _read(path, format, dataset, height_unit, rows, metadata_only, fill) -> Topography:
    name = format_of(path, format)
    reader = FORMATS[name][0]
    if fill not in FILLS:
        raise ValueError(f"fill = {fill!r}; accepted: {', '.join(FILLS)}")
    whole = name not in BY_ROWS or fill == "harmonic"    # a fill needs every point: read all, cut after
    if name in BY_ROWS:
        topo = reader(path, dataset=dataset,
                      rows=None if metadata_only else ((0, None) if whole else (rows or (0, None))))
    else:
        topo = reader(path, dataset=dataset, sniff=format is None)
    if min(topo.shape) < 1:
        raise FormatError(f"an empty map ({' x '.join(map(str, topo.shape))} points)")
    if topo.dtype.kind not in "iuf":
        kind = {"b": "boolean", "c": "complex"}.get(topo.dtype.kind, "not numeric")
        raise ValueError(f"heights of dtype {topo.dtype} ({kind}); heights must be real numbers")
    if height_unit is not None:
        metres_per(height_unit)
    if topo.height_unit is not None and height_unit is not None and \
            metres_per(topo.height_unit) != metres_per(height_unit):
        raise HeightUnitConflict(f"the file states its heights in {topo.height_unit!r}, not "
                                 f"{height_unit!r}", topo.height_unit)
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
