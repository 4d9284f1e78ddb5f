"""The words and numbers of a plain-text height file: its encoding, header and decimal separator.

Encoding: UTF-8 (a byte-order mark is dropped), UTF-16 with its byte-order mark, else Latin-1
as older instruments and Windows programs write it ("µm" as the byte 0xB5).  Lines: blank lines are skipped; lines starting with
``#`` are comments, and so are the lines before the first line of numbers (an instrument's
header without ``#``).  Header keys read, each ``key`` then ``:``, ``=`` or ``：`` and its value:

- Gwyddion's "ASCII data matrix" export, in each language Gwyddion writes it (``GWYDDION``):
  ``Channel``, ``Width`` (the extent nx dx, with its unit), ``Height`` (ny dy) and
  ``Value units`` (the heights' unit), e.g. ``# Breite: 10 µm``, ``# Höhe: 7,5 µm``;
- an instrument's export: ``w=`` (values per line, nx) and ``h=`` (lines, ny), ``pixel size=``
  (dx = dy, with its unit), ``height conversion factor (-> UNIT)=`` (heights = value x factor,
  in UNIT) and ``data unit=`` (the stored values' unit, used when no factor is given).

Numbers are separated by blanks, tabs, commas or semicolons, with a decimal point; or, as
German-locale programs write them (Excel's CSV, Gwyddion), with a decimal comma and separated
by semicolons, blanks or tabs (``-7,00;-4,00``).  A file whose numbers mix decimal points and
commas, or whose commas are both inside and between numbers, is refused as ambiguous.
"""
from __future__ import annotations

import codecs
import re

from .base import FormatError
from .sniff import check_text
from .units import metres_per

#: Gwyddion's header labels in its user interface languages (en, cs, de, es, fr, it, ja, ko,
#: pt, ru), as SurfaceTopography's text reader knows them, and German's "Werteeinheiten"
GWYDDION = {
    "channel": ("Channel", "Kanál", "Kanal", "Canal", "Canale", "チャネル", "채널", "Канал"),
    "width": ("Width", "Šířka", "Breite", "Anchura", "Largeur", "Larghezza", "幅", "폭", "Largura",
              "Ширина"),
    "height": ("Height", "Výška", "Höhe", "Altura", "Hauteur", "Altezza", "高さ", "높이", "Высота"),
    "value_units": ("Value units", "Jednotky hodnot", "Werteeinheiten", "Einheiten", "Unités",
                    "Unità valore", "値の単位", "값 단위", "Unidades de valor", "Единицы измерения"),
}
_NUMBER = r"([-+]?(?:\d+(?:[.,]\d*)?|[.,]\d+)(?:[eE][-+]?\d+)?)"   # a decimal point or comma
_SEP = r"\s*[:=：]\s*"


def _label(words) -> str:
    return r"^#?\s*(?:" + "|".join(re.escape(w) for w in words) + ")" + _SEP


#: header key -> pattern; the groups are the value (and its unit where one is written)
_KEYS = {
    "channel": re.compile(_label(GWYDDION["channel"]) + r"(.*?)\s*$", re.I),
    "width": re.compile(_label(GWYDDION["width"]) + _NUMBER + r"\s*(\S*)", re.I),
    "height": re.compile(_label(GWYDDION["height"]) + _NUMBER + r"\s*(\S*)", re.I),
    "value_units": re.compile(_label(GWYDDION["value_units"]) + r"(\S+)", re.I),
    "nx": re.compile(r"(?:^|[\s#])w\s*=\s*(\d+)\b"),
    "ny": re.compile(r"(?:^|[\s#])h\s*=\s*(\d+)\b"),
    "pixel_size": re.compile(r"^#?\s*pixel size" + _SEP + _NUMBER + r"\s*(\S*)", re.I),
    "factor": re.compile(r"^#?\s*height conversion factor\s*\(->\s*([^)]*?)\s*\)" + _SEP + _NUMBER, re.I),
    "data_unit": re.compile(r"^#?\s*data unit" + _SEP + r"(\S+)", re.I),
}
_STARTS_NUMBER = re.compile(r"[-+]?(?:[.,]?\d|nan|inf)", re.I)
_DECIMAL_COMMA = re.compile(r"^[-+]?(?:\d+,\d*|,\d+)(?:[eE][-+]?\d+)?$")


def decode(raw: bytes) -> str:
    """The text of a file's bytes: UTF-8 (without its byte-order mark), UTF-16 (with one), else
    Latin-1; an ``UnsupportedFeature`` (a FormatError) for binary data (``sniff.check_text``)."""
    check_text(raw)          # a format named "text" is not sniffed by format_of: check here too
    if raw.startswith((codecs.BOM_UTF16_LE, codecs.BOM_UTF16_BE)):   # Windows' "Unicode" text
        return raw.decode("utf-16")
    if raw.startswith(codecs.BOM_UTF8):
        raw = raw[len(codecs.BOM_UTF8):]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def split_lines(text: str):
    """(header lines, [(line number, text)] of the data lines): the header is the comment
    lines and the lines before the first data line (one that starts with a number)."""
    header, data = [], []
    for n, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line:
            continue
        if line.startswith("#") or (not data and not _STARTS_NUMBER.match(line)):
            header.append(line)
        else:
            data.append((n, line))
    return header, data


def header_keys(lines) -> dict:
    """The header keys read (module docstring): name -> the matched groups."""
    keys = {}
    for line in lines:
        for name, pattern in _KEYS.items():
            if name not in keys and (m := pattern.search(line)):
                keys[name] = m.groups()
    return keys


def number(text: str) -> float:
    """A header's number, written with a decimal point or comma."""
    return float(text.replace(",", "."))


def length(value: str, unit: str, key: str) -> float:
    """``value`` ``unit`` (a header's length) in metres."""
    try:
        return number(value) * metres_per(unit)
    except ValueError as exc:
        raise FormatError(f"the header's {key} {value} {unit!r}: {exc}") from None


def _decimal_comma(data) -> bool:
    """Whether the numbers are written with a decimal comma (module docstring); FormatError
    when the file leaves it ambiguous."""
    fields = [(n, w) for n, line in data for w in re.split(r"[;\s]+", line) if w]
    commas = [(n, w) for n, w in fields if "," in w]
    if not commas or all(len(re.split(r"[;\s]+", line)) == 1 for _, line in data):
        return False            # no commas, or commas only: a comma-separated file
    inside = [(n, w) for n, w in commas if _DECIMAL_COMMA.match(w)]
    if not inside:
        return False            # "1, 2, 3": commas between numbers
    points = [(n, w) for n, w in fields if "." in w]
    between = [(n, w) for n, w in commas if not _DECIMAL_COMMA.match(w)]
    if points or between:
        n, w = (points or between)[0]
        raise FormatError(f"ambiguous decimal separator: line {inside[0][0]} has {inside[0][1]!r} (a "
                          f"decimal comma) and line {n} has {w!r}; save the file with decimal points "
                          f"and blanks, tabs or commas between the numbers")
    return True


def numbers(data):
    """Rows of floats of the data lines [(line number, text)]; and whether decimal commas."""
    comma = _decimal_comma(data)
    separators = re.compile(r"[;\s]+" if comma else r"[,;\s]+")
    rows = []
    for n, line in data:
        try:
            rows.append([float(w.replace(",", ".") if comma else w) for w in separators.split(line) if w])
        except ValueError:
            raise FormatError(f"line {n} is not numbers: {line[:60]!r} (a header line after the "
                              f"data, or a file of several images: export one)") from None
    if not rows:
        raise FormatError("no numbers (an empty text file)")
    return rows, comma
