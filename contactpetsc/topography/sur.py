"""Digital Surf (MountainsMap) surfaces (``.sur``), after the format's published header layout.

A 512-byte little-endian header, then a comment zone and a private zone (their lengths in the
header), then the points: ``number of points per line`` (nx) times ``number of lines`` (ny)
integers of ``bits per point`` (16 or 32), line after line (a line is one y, the first y =
0, its points along x): z = value * z spacing + z offset in the z step unit, x = i * x
spacing and y = j * y spacing in their step units.  With the "non-measured points" flag,
values outside [zmin, zmax] mark points not measured.

Header fields read (byte offset: type, content): 0: 12 chars "DIGITAL SURF"; 14: int16
number of objects; 18: int16 object type (2 = surface); 86: int16 non-measured points flag;
98: int16 bits per point; 100, 104: int32 zmin, zmax; 108: int32 points per line; 112: int32
number of lines; 116: int32 total points; 120, 124, 128: float32 x, y, z spacing; 180, 196,
212: 16 chars x, y, z step units; 290: int16 inversion; 334: int16 comment zone length; 336:
int16 private zone length; 474: float32 z offset.
"""
from __future__ import annotations

import struct

import numpy as np

from .base import FormatError, Topography, header_text

HEADER = 512
SURFACE = 2


def _get(data: bytes, offset: int, fmt: str):
    return struct.unpack_from("<" + fmt, data, offset)[0]


def read_sur(path: str, **_) -> Topography:
    with open(path, "rb") as f:
        data = f.read()
    if len(data) < HEADER:
        raise FormatError(f"{len(data)} bytes: shorter than the 512-byte header")
    magic = data[:12]
    if magic == b"DSCOMPRESSED":
        raise FormatError("a compressed Digital Surf file: save it uncompressed from MountainsMap, "
                          "or convert it with contactpetsc import")
    if magic != b"DIGITAL SURF":
        raise FormatError(f"no 'DIGITAL SURF' signature (found {magic!r}): not a .sur file")
    kind = _get(data, 18, "h")
    if kind != SURFACE:
        raise FormatError(f"object type {kind}: only surfaces (type 2) are height maps")
    bits = _get(data, 98, "h")
    if bits not in (16, 32):
        raise FormatError(f"{bits} bits per point; accepted: 16 or 32")
    nx, ny = _get(data, 108, "i"), _get(data, 112, "i")
    if nx < 1 or ny < 1:
        raise FormatError(f"{nx} points per line, {ny} lines")
    if _get(data, 290, "h") != 0:
        raise FormatError("an inverted (or flipped) surface: save it without inversion")
    start = HEADER + _get(data, 334, "h") + _get(data, 336, "h")
    need = start + nx * ny * bits // 8
    if len(data) < need:
        raise FormatError(f"truncated: {len(data)} bytes, the header announces {need}")
    values = np.frombuffer(data, "<i2" if bits == 16 else "<i4", nx * ny, start)
    if _get(data, 86, "h"):
        zmin, zmax = _get(data, 100, "i"), _get(data, 104, "i")
        missing = int(np.count_nonzero((values < zmin) | (values > zmax)))
        if missing:
            raise FormatError(f"{missing} of the {nx} x {ny} points are not measured; fill them "
                              f"first (interpolate them, e.g. in MountainsMap or Gwyddion)")
    dz, z0 = _get(data, 128, "f"), _get(data, 474, "f")
    heights = (values.reshape(ny, nx).T * float(dz) + float(z0))
    units = [header_text(data[o:o + 16]) for o in (180, 196, 212)]
    if units[0] != units[1]:
        raise FormatError(f"x and y steps in different units ({units[0]!r}, {units[1]!r})")
    return Topography(shape=(nx, ny), dtype=values.dtype, heights=heights, height_unit=units[2] or None,
                      dx=abs(float(_get(data, 120, "f"))), dy=abs(float(_get(data, 124, "f"))),
                      lateral_unit=units[0] or None, format="sur",
                      metadata={"object": header_text(data[20:50]), "operator": header_text(data[50:80])})
