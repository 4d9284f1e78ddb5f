"""Gwyddion native files (``.gwy``), after the Gwyddion user guide's "Format of Gwyddion Files".

Little-endian throughout.  The magic ``GWYP``, then one serialized object: its type name
(NUL-terminated), the size of its components in bytes (uint32), then the components, each a
NUL-terminated name, a type character and the value: ``b`` bool (1 byte), ``c`` char, ``i``
int32, ``q`` int64, ``d`` double, ``s`` NUL-terminated string, ``o`` an object; the upper-case
letters ``C I Q D S O`` are arrays, a uint32 count then the items.  The top object is a
``GwyContainer`` whose component ``/N/data`` is channel N, a ``GwyDataField``: ``xres``,
``yres`` (int32), ``xreal``, ``yreal`` (the extent, double), ``si_unit_xy``, ``si_unit_z``
(``GwySIUnit`` objects with a ``unitstr``) and ``data``, xres x yres doubles row after row
(a row is one y, the first y = 0); ``/N/data/title`` names the channel.  Objects nest
(container, data field, unit): nesting deeper than ``MAX_DEPTH`` is refused, not recursed into.
"""
from __future__ import annotations

import struct

import numpy as np

from .base import FormatError, Topography

_ATOMS = {"b": "<?", "c": "<c", "i": "<i4", "q": "<i8", "d": "<f8"}
MAX_DEPTH = 32     #: Gwyddion's own files nest 3 or 4 objects deep


class _Reader:
    def __init__(self, data: bytes):
        self.data, self.pos, self.depth = data, 0, 0

    def take(self, n: int) -> bytes:
        if self.pos + n > len(self.data):
            raise FormatError(f"truncated at byte {self.pos}: {n} more bytes needed")
        chunk = self.data[self.pos:self.pos + n]
        self.pos += n
        return chunk

    def string(self) -> str:
        end = self.data.find(b"\0", self.pos)
        if end < 0:
            raise FormatError(f"a string at byte {self.pos} has no NUL")
        text = self.data[self.pos:end].decode("utf-8", "replace")
        self.pos = end + 1
        return text

    def count(self) -> int:
        return struct.unpack("<I", self.take(4))[0]

    def value(self, kind: str):
        if kind in _ATOMS:
            dtype = np.dtype(_ATOMS[kind])
            return np.frombuffer(self.take(dtype.itemsize), dtype)[0].item()
        if kind == "s":
            return self.string()
        if kind == "o":
            return self.object()
        if kind.lower() in _ATOMS and kind.isupper() and kind != "B":
            dtype = np.dtype(_ATOMS[kind.lower()])
            n = self.count()
            return np.frombuffer(self.take(n * dtype.itemsize), dtype)
        if kind in "SO":
            return [self.value(kind.lower()) for _ in range(self.count())]
        raise FormatError(f"unknown component type {kind!r} at byte {self.pos - 1}")

    def object(self) -> tuple:
        if self.depth >= MAX_DEPTH:
            raise FormatError(f"objects nested more than {MAX_DEPTH} deep at byte {self.pos} (a "
                              f"damaged file: Gwyddion's nest 3 or 4)")
        self.depth += 1
        try:
            return self._object()
        finally:
            self.depth -= 1

    def _object(self) -> tuple:
        name = self.string()
        size = self.count()
        end = self.pos + size
        if end > len(self.data):
            raise FormatError(f"object {name} announces {size} bytes beyond the file's end")
        components = {}
        while self.pos < end:
            key = self.string()
            components[key] = self.value(self.take(1).decode("latin-1"))
        if self.pos != end:
            raise FormatError(f"object {name}: its components overrun its size")
        return name, components


def _unit(field: dict, key: str) -> str | None:
    unit = field.get(key)
    return unit[1].get("unitstr") or None if isinstance(unit, tuple) else None


def read_gwy(path: str, dataset: str = "heights", **_) -> Topography:
    """Channel ``dataset`` (its title) of a .gwy file; the default "heights": its first channel."""
    with open(path, "rb") as f:
        data = f.read()
    if data[:4] != b"GWYP":
        raise FormatError("no 'GWYP' magic: not a .gwy file (or the old GWYO format)")
    name, container = _Reader(data[4:]).object()
    if name != "GwyContainer":
        raise FormatError(f"the top object is {name}, not GwyContainer")
    channels = sorted((int(k.split("/")[1]), k) for k, v in container.items()
                      if k.count("/") == 2 and k.endswith("/data") and k.split("/")[1].isdigit()
                      and isinstance(v, tuple) and v[0] == "GwyDataField")
    if not channels:
        raise FormatError("no image channel (/N/data GwyDataField)")
    titles = {k: container.get(k + "/title", f"channel {n}") for n, k in channels}
    if dataset == "heights":
        key = channels[0][1]
    else:
        matching = [k for k, title in titles.items() if title == dataset]
        if not matching:
            raise KeyError(f"no channel titled {dataset!r} (geometry.dataset) in {path} "
                           f"(has {sorted(titles.values())})")
        key = matching[0]
    field = container[key][1]
    try:
        nx, ny, lx, ly, values = (field[k] for k in ("xres", "yres", "xreal", "yreal", "data"))
    except KeyError as exc:
        raise FormatError(f"{key} lacks its {exc.args[0]}") from None
    for k, v in (("xres", nx), ("yres", ny)):
        if not isinstance(v, int) or v < 1:
            raise FormatError(f"{key}: {k} = {v!r}; a map needs 1 or more")
    for k, v in (("xreal", lx), ("yreal", ly)):
        if not (isinstance(v, float) and np.isfinite(v) and v > 0):
            raise FormatError(f"{key}: {k} = {v!r}; an extent is finite and > 0")
    if not isinstance(values, np.ndarray) or len(values) != nx * ny:
        raise FormatError(f"{key}: {len(values)} data values, xres x yres = {nx} x {ny}")
    return Topography(shape=(nx, ny), dtype=np.dtype("<f8"),
                      heights=np.asarray(values, float).reshape(ny, nx).T.copy(),
                      height_unit=_unit(field, "si_unit_z"), dx=lx / nx, dy=ly / ny,
                      lateral_unit=_unit(field, "si_unit_xy") or "m", format="gwy",
                      metadata={"channel": titles[key]})
