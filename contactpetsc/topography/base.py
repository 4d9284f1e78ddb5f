"""What a format reader returns: the file's numbers and what the file says about them."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class Topography:
    """A height map on a uniform grid, indexed [i, j] = h(x_i, y_j) with x_i = i dx, y_j = j dy.

    From a format reader, ``heights`` are the file's numbers in ``height_unit`` and ``dx``,
    ``dy`` are in ``lateral_unit``; ``read_topography`` returns them in metres.  ``heights`` is
    None when only the metadata was read, or holds the rows j in [ys, ye) asked for.
    """
    shape: tuple                       #: (nx, ny)
    dtype: np.dtype                    #: the file's height dtype
    heights: np.ndarray | None = None  #: (nx, ny) or (nx, ye - ys)
    height_unit: str | None = None     #: the unit the file states for its heights; None: it states none
    dx: float | None = None            #: spacing along x; None: the file does not say
    dy: float | None = None
    lateral_unit: str | None = None    #: the unit of dx, dy; None: the heights' unit
    unit_stated: bool = False          #: read_topography: the file stated height_unit
    periodic: bool | None = None       #: the file says its map is periodic, or not; None: it says nothing
    #: what the heights are: "surface" (the sample's surface z, peaks up: instrument files and
    #: ``contactpetsc import``), "gap" (a composite gap h, lowest point first: contactpetsc's
    #: step files); None: the file does not say, which means "surface" (``HEIGHTS_ARE``)
    heights_are: str | None = None
    format: str = ""
    metadata: dict = field(default_factory=dict)   #: what else the file says (title, instrument, ...)


class FormatError(ValueError):
    """A file that does not follow its format's specification (the message says where)."""


#: what a height file's numbers may be (``Topography.heights_are``; scene key ``geometry.heights_are``)
HEIGHTS_ARE = ("surface", "gap")


def heights_are(value, where: str) -> str | None:
    """A file's stamp of what its heights are, checked: "surface", "gap" or None (unstated)."""
    if value is None:
        return None
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    if not isinstance(value, str) or value.strip().lower() not in HEIGHTS_ARE:
        raise FormatError(f"{where} = {value!r}; accepted: {', '.join(HEIGHTS_ARE)}")
    return value.strip().lower()


class HeightUnitConflict(ValueError):
    """A file that states its heights in a unit other than the one given (``stated``)."""

    def __init__(self, message: str, stated: str):
        super().__init__(message)
        self.stated = stated


def header_text(raw: bytes) -> str:
    """Bytes of a header (NUL-padded, maybe Windows-1252: "µm") as text."""
    return raw.split(b"\0", 1)[0].decode("latin-1").strip()


class UnsupportedFeature(FormatError):
    """A file that follows its format but uses a feature contactpetsc's reader does not read
    (a compressed .sur, a profile): ``contactpetsc import --reader auto`` passes it on to
    SurfaceTopography."""
