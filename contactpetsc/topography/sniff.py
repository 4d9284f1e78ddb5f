"""What a file's first bytes say it is: a text matrix, or a binary format (named where its
magic is known).

Extensions such as ``.dat`` are used for text exports and for instruments' binary files alike
(Zygo MetroPro writes ``.dat``), so a file is taken as text only when its first ``HEAD``
bytes hold no NUL and no control characters other than white space (text in UTF-8 or in a
one-byte code page, "µm" in latin-1, passes), or when it starts with a UTF-16 byte-order mark
(Windows' "Unicode" text, whose NULs are half of every character).
"""
from __future__ import annotations

import codecs

from .base import UnsupportedFeature

HEAD = 1024
#: leading bytes -> the format they start (SurfaceTopography reads the ones contactpetsc does not)
MAGICS = {b"\x88\x1b\x03\x6f": "Zygo MetroPro", b"\x88\x1b\x03\x70": "Zygo MetroPro",
          b"\x88\x1b\x03\x71": "Zygo MetroPro", b"DIGITAL SURF": "Digital Surf (.sur)",
          b"DSCOMPRESSED": "compressed Digital Surf", b"GWYP": "Gwyddion (.gwy)",
          b"Gwyddion Simple Field": "Gwyddion simple field (.gsf)", b"\x89HDF\r\n\x1a\n": "HDF5",
          b"\x93NUMPY": "numpy (.npy)", b"PK\x03\x04": "a zip archive (.x3p?)",
          b"\\*File list": "Bruker NanoScope", b"II*\x00": "TIFF", b"MM\x00*": "TIFF"}
_WHITE = set(b"\t\n\r\f\v")


def kind(head: bytes) -> str | None:
    """The binary format ``head`` (a file's first bytes) starts, "binary" for an unknown one,
    None for text."""
    for magic, name in MAGICS.items():
        if head.startswith(magic):
            return name
    if head.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):
        return None
    if any(b < 32 and b not in _WHITE for b in head):     # NUL and other control bytes
        return "binary"
    return None


def refuse_binary(path: str) -> None:
    """``check_text`` of the first bytes of ``path``; nothing when it cannot be opened (the
    reader says why)."""
    try:
        with open(path, "rb") as f:
            head = f.read(HEAD)
    except OSError:
        return
    check_text(head)


def check_text(head: bytes) -> None:
    """FormatError (an ``UnsupportedFeature``: ``contactpetsc import`` hands the file on) when a
    file's first bytes ``head`` are not text."""
    name = kind(head[:HEAD])
    if name is None:
        return
    looks = "" if name == "binary" else f" (looks like {name})"
    raise UnsupportedFeature(f"a binary file{looks}, not a text matrix: convert it with `contactpetsc "
                             f"import` (SurfaceTopography; docs/topography.md)")
