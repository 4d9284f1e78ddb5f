"""Gwyddion Simple Field (``.gsf``), after the Gwyddion user guide's specification.

The magic line ``Gwyddion Simple Field 1.0``, then header lines ``name = value`` (``XRes``
and ``YRes`` required; ``XReal``, ``YReal`` the map's extent in ``XYUnits``, ``ZUnits`` the
values' unit, ``XOffset``, ``YOffset``, ``Title``, ...), then one to four NUL bytes that
align the data to a multiple of 4, then XRes x YRes little-endian float32 values, row after
row: a row is one y (the first y = 0), XRes values along x.
"""
from __future__ import annotations

import numpy as np

from .base import FormatError, Topography

MAGIC = b"Gwyddion Simple Field 1.0\n"


def _value(header: dict, key: str, kind):
    """Header value ``key`` as a positive ``kind`` (int or float): refused with the key named."""
    if key not in header:
        raise FormatError(f"the header lacks {key} (required)")
    try:
        value = kind(header[key])
    except ValueError:
        value = None
    if value is None or not np.isfinite(value) or value <= 0:
        raise FormatError(f"header {key} = {header[key]!r}: must be a {'whole ' if kind is int else ''}"
                          f"number > 0")
    return value


def read_gsf(path: str, **_) -> Topography:
    with open(path, "rb") as f:
        data = f.read()
    if not data.startswith(MAGIC):
        raise FormatError("no 'Gwyddion Simple Field 1.0' magic line: not a .gsf file")
    end = data.find(b"\0")
    if end < 0:
        raise FormatError("no NUL after the header")
    header = {}
    for line in data[len(MAGIC):end].decode("utf-8", "replace").splitlines():
        if line.strip():
            name, eq, value = line.partition("=")
            if not eq:
                raise FormatError(f"header line {line!r} is not 'name = value'")
            header[name.strip()] = value.strip()
    nx, ny = (_value(header, key, int) for key in ("XRes", "YRes"))
    start = (end // 4 + 1) * 4                      # one to four NULs: the next multiple of 4
    if data[end:start].strip(b"\0"):
        raise FormatError("the header's NUL padding holds other bytes")
    if len(data) - start != 4 * nx * ny:
        raise FormatError(f"{len(data) - start} data bytes, XRes x YRes = {nx} x {ny} float32 need "
                          f"{4 * nx * ny}")
    values = np.frombuffer(data, "<f4", nx * ny, start).reshape(ny, nx)
    topo = Topography(shape=(nx, ny), dtype=np.dtype("<f4"), heights=values.T.astype(float),
                      height_unit=header.get("ZUnits") or None, format="gsf",
                      metadata={k: v for k, v in header.items() if k not in ("XRes", "YRes")})
    if "XReal" in header:
        # Gwyddion writes SI base units; a file without XYUnits has its extent in metres
        lx = _value(header, "XReal", float)
        ly = _value(header, "YReal", float) if "YReal" in header else lx
        topo.dx, topo.dy, topo.lateral_unit = lx / nx, ly / ny, header.get("XYUnits") or "m"
    return topo
