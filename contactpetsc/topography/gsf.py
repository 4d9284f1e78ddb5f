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
    try:
        nx, ny = int(header["XRes"]), int(header["YRes"])
    except KeyError as exc:
        raise FormatError(f"the header lacks {exc.args[0]} (required)") from None
    except ValueError:
        raise FormatError(f"XRes = {header['XRes']!r}, YRes = {header['YRes']!r}: not integers") from None
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
        lx, ly = float(header["XReal"]), float(header.get("YReal", header["XReal"]))
        topo.dx, topo.dy, topo.lateral_unit = lx / nx, ly / ny, header.get("XYUnits") or "m"
    return topo
