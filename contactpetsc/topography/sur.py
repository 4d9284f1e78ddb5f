"""Digital Surf (MountainsMap) surfaces (``.sur``), after the format's header layout as Gwyddion
(``surffile.c``) and SurfaceTopography (``IO/SUR.py``) read it.

A 512-byte little-endian header, then a comment zone and a private zone (their lengths in the
header), then the points: ``number of points per line`` (nx) times ``number of lines`` (ny)
signed integers of ``bits per point`` (16 or 32), line after line (a line is one y, the first
y = 0, its points along x): z = value * z spacing + z offset in the z step unit, x = i * x
spacing and y = j * y spacing in their step units.  With the "non-measured points" flag set,
the value zmin - 2 marks a point not measured (returned as NaN).  The inversion flag turns the
heights over (1), and also mirrors x (2, "flip") or y (3, "flop").

Header fields read (byte offset: type, content): 0: 12 chars "DIGITAL SURF"; 14: uint16
number of objects; 18: uint16 object type (2 = surface); 86: uint16 non-measured points flag;
98: uint16 bits per point; 100, 104: int32 zmin, zmax; 108: int32 points per line; 112: int32
number of lines; 116: uint32 total points; 120, 124, 128: float32 x, y, z spacing; 180, 196,
212: 16 chars x, y, z step units; 290: uint16 inversion; 334: uint16 comment zone length;
336: uint16 private zone length; 474: float32 z offset.  Every length and size is checked
against the others and the file's size before a byte past the header is taken as a height.
"""
from __future__ import annotations

import struct

import numpy as np

from .base import FormatError, Topography, UnsupportedFeature, header_text

HEADER = 512
SURFACE = 2
NON_MEASURED = -2      #: a point not measured holds zmin + NON_MEASURED
#: inversion flag -> (height sign, axis mirrored: 0 x, 1 y, None)
INVERSION = {0: (1.0, None), 1: (-1.0, None), 2: (-1.0, 0), 3: (-1.0, 1)}
#: field -> (byte offset, struct type), as the module docstring lists them
FIELDS = {"number of objects": (14, "H"), "object type": (18, "H"), "non-measured points flag": (86, "H"),
          "bits per point": (98, "H"), "zmin": (100, "i"), "zmax": (104, "i"),
          "points per line": (108, "i"), "number of lines": (112, "i"), "total points": (116, "I"),
          "x spacing": (120, "f"), "y spacing": (124, "f"), "z spacing": (128, "f"),
          "inversion": (290, "H"), "comment zone length": (334, "H"),
          "private zone length": (336, "H"), "z offset": (474, "f")}


def _unit(raw: bytes) -> str | None:
    # old files write the micro sign in an MS-DOS code page: 0xE6, "æ" in latin-1
    text = header_text(raw)
    return {"æm": "µm"}.get(text, text) or None


def _header(data: bytes) -> dict:
    """The header's fields (``FIELDS``), each checked: refused with the field named."""
    if len(data) < HEADER:
        raise FormatError(f"{len(data)} bytes: shorter than the 512-byte header")
    magic = data[:12]
    if magic == b"DSCOMPRESSED":
        raise UnsupportedFeature("a compressed Digital Surf file: save it uncompressed from "
                                 "MountainsMap")
    if magic != b"DIGITAL SURF":
        raise FormatError(f"no 'DIGITAL SURF' signature (found {magic!r}): not a .sur file")
    h = {name: struct.unpack_from("<" + fmt, data, offset)[0] for name, (offset, fmt) in FIELDS.items()}

    def bad(name, why):
        return FormatError(f"header field '{name}' (byte {FIELDS[name][0]}) = {h[name]!r}: {why}")

    if h["object type"] != SURFACE:
        raise UnsupportedFeature(f"object type {h['object type']}: only surfaces (type 2) are height maps")
    if h["bits per point"] not in (16, 32):
        raise bad("bits per point", "accepted: 16 or 32")
    for name in ("points per line", "number of lines"):
        if h[name] < 1:
            raise bad(name, "a map needs one or more")
    if h["total points"] != h["points per line"] * h["number of lines"]:
        raise bad("total points", f"not points per line x number of lines = "
                                  f"{h['points per line'] * h['number of lines']}")
    for name in ("x spacing", "y spacing"):
        if not (np.isfinite(h[name]) and h[name] > 0):
            raise bad(name, "a spacing is finite and > 0")
    for name in ("z spacing", "z offset"):
        if not np.isfinite(h[name]) or (name == "z spacing" and h[name] == 0):
            raise bad(name, "not finite" if name == "z offset" else "a z spacing is finite and != 0")
    if h["inversion"] not in INVERSION:
        raise bad("inversion", f"accepted: {', '.join(map(str, INVERSION))}")
    if h["number of objects"] < 1:
        raise bad("number of objects", "a file holds one or more")
    # the zones and the points account for the whole file (one object), or its start (several)
    end = HEADER
    for name in ("comment zone length", "private zone length"):
        end += h[name]
        if end > len(data):
            raise bad(name, f"the zone runs past the file's end ({len(data)} bytes)")
    need = end + h["total points"] * h["bits per point"] // 8
    if len(data) < need or (h["number of objects"] == 1 and len(data) != need):
        raise FormatError(f"{len(data)} bytes, but the header (512 bytes, comment zone "
                          f"{h['comment zone length']} and private zone {h['private zone length']} "
                          f"bytes, {h['points per line']} x {h['number of lines']} points of "
                          f"{h['bits per point']} bits) accounts for {need}: "
                          + ("truncated" if len(data) < need else "a damaged header"))
    h["data start"] = end
    return h


def read_sur(path: str, **_) -> Topography:
    with open(path, "rb") as f:
        data = f.read()
    h = _header(data)
    nx, ny = h["points per line"], h["number of lines"]
    stored = np.dtype("<i2" if h["bits per point"] == 16 else "<i4")
    values = np.frombuffer(data, stored, nx * ny, h["data start"]).reshape(ny, nx).T   # [x, y]
    heights = values * float(h["z spacing"]) + float(h["z offset"])
    missing = 0
    if h["non-measured points flag"]:
        unmeasured = values == h["zmin"] + NON_MEASURED
        missing = int(np.count_nonzero(unmeasured))
        heights[unmeasured] = np.nan
    sign, mirrored = INVERSION[h["inversion"]]
    heights = sign * (heights if mirrored is None else np.flip(heights, mirrored))
    units = [_unit(data[o:o + 16]) for o in (180, 196, 212)]
    if units[0] != units[1]:
        raise FormatError(f"x and y steps in different units ({units[0]!r}, {units[1]!r})")
    # the heights are scaled floats now (dtype float64): the integers are not metres
    return Topography(shape=(nx, ny), dtype=heights.dtype, heights=heights, height_unit=units[2],
                      dx=float(h["x spacing"]), dy=float(h["y spacing"]), lateral_unit=units[0],
                      format="sur",
                      metadata={"object": header_text(data[20:50]), "operator": header_text(data[50:80]),
                                "stored": f"int{h['bits per point']}", "not_measured": missing})
