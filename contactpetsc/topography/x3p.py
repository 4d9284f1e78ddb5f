"""ISO 25178-72 XML surface files (``.x3p``), after the ISO 5436-2 XML schema (openGPS).

An x3p file is a zip archive.  Its ``main.xml`` (root element ``ISO5436_2`` in the namespace
``http://www.opengps.eu/2008/ISO5436_2``, child elements unqualified) holds
``Record1/FeatureType`` (``SUR`` for an areal surface), ``Record1/Axes/CX, CY, CZ`` (each with
``AxisType``, ``DataType``, ``Increment``, ``Offset``; lengths in metres), ``Record2``
(date, creator, instrument) and ``Record3/MatrixDimension/SizeX, SizeY, SizeZ`` with
``Record3/DataLink/PointDataLink`` naming the binary member (``bindata/data.bin``), or the
points inline in ``Record3/DataList/Datum``.  The binary points are little-endian values of
CZ's DataType (I int16, L int32, F float32, D float64), x fastest then y:
z(i, j) = Increment_z * value[i + SizeX j] + Offset_z at x = i Increment_x, y = j Increment_y.
An optional ``ValidPointsLink`` member holds one bit per point, least significant bit first,
1 for a measured point; points not measured (and NaN float values) are returned as NaN.

Every member's size is checked from the archive's directory before it is inflated, and it is
inflated through a bounded stream: a member that would inflate beyond what the map needs (a
damaged or hostile archive) is refused without being held in memory.
"""
from __future__ import annotations

import hashlib
import os
import xml.etree.ElementTree as ET
import zipfile
import zlib

import numpy as np

from .base import FormatError, Topography, UnsupportedFeature

DATA_TYPES = {"I": "<i2", "L": "<i4", "F": "<f4", "D": "<f8"}
MAIN_XML_LIMIT = 64 * 2**20     #: bytes: main.xml with every point inline stays far below


def _find(root, path, required=True):
    node = root.find(path)
    if node is None or node.text is None or not node.text.strip():
        if required:
            raise FormatError(f"main.xml lacks {path}")
        return None
    return node.text.strip()


def _number(root, path, kind, required=True, positive=False):
    """The number at ``path`` of main.xml (``kind`` int or float), checked: named if not one."""
    text = _find(root, path, required)
    if text is None:
        return None
    try:
        value = kind(text)
    except ValueError:
        raise FormatError(f"main.xml {path} = {text!r}: not {'an integer' if kind is int else 'a number'}") from None
    if not np.isfinite(value) or (positive and value <= 0):
        raise FormatError(f"main.xml {path} = {text!r}: must be finite" + (" and > 0" if positive else ""))
    return value


def _member(archive: zipfile.ZipFile, name: str, size, what: str) -> bytes:
    """Member ``name`` of ``archive``, refused (before inflating it) unless its size is ``size``
    bytes (an int), or at most ``size[1]`` bytes (a (None, limit) pair); read through a bounded
    stream so that a directory entry that lies about the size inflates no more."""
    try:
        info = archive.getinfo(name)
    except KeyError:
        raise FormatError(f"the archive has no {name} ({what})") from None
    exact = isinstance(size, int)
    limit = size if exact else size[1]
    if info.file_size > limit or (exact and info.file_size != size):
        raise FormatError(f"{name} ({what}) inflates to {info.file_size} bytes; "
                          + (f"the map needs {size}" if exact else f"at most {limit} are accepted"))
    try:
        with archive.open(info) as stream:
            data = stream.read(limit + 1)
    except (zipfile.BadZipFile, zlib.error, EOFError, NotImplementedError) as exc:
        raise FormatError(f"{name} ({what}) cannot be inflated: {exc}") from None
    if len(data) > limit or (exact and len(data) != size):
        raise FormatError(f"{name} ({what}) holds {'more than' if len(data) > limit else ''} "
                          f"{min(len(data), limit)} bytes, not the {info.file_size} its directory entry says")
    return data


def _fits_in_memory(nx: int, ny: int) -> None:
    """Refuse a map whose float64 heights alone exceed this machine's memory (a damaged SizeX)."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        return
    if 8 * nx * ny > total:
        raise FormatError(f"SizeX x SizeY = {nx} x {ny}: {8 * nx * ny / 2**30:.3g} GiB of heights, more "
                          f"than this machine's {total / 2**30:.3g} GiB of memory")


def read_x3p(path: str, **_) -> Topography:
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise FormatError("not a zip archive: an .x3p file is a zip with main.xml") from None
    with archive:
        try:
            root = ET.fromstring(_member(archive, "main.xml", (None, MAIN_XML_LIMIT), "the file's index"))
        except ET.ParseError as exc:
            raise FormatError(f"main.xml is not XML ({exc})") from None
        feature = _find(root, "Record1/FeatureType")
        if feature != "SUR":
            raise UnsupportedFeature(f"Record1/FeatureType = {feature!r}: a height map is 'SUR' "
                                     f"('PRF' is a profile, 'PCL' a point cloud)")
        nx, ny = (_number(root, f"Record3/MatrixDimension/Size{a}", int, positive=True) for a in "XY")
        nz = _number(root, "Record3/MatrixDimension/SizeZ", int)
        if nz != 1:
            raise UnsupportedFeature(f"SizeZ = {nz}: layered maps are not height maps (SizeZ = 1)")
        _fits_in_memory(nx, ny)
        for a, kind in (("CX", "I"), ("CY", "I"), ("CZ", "A")):
            axis_type = _find(root, f"Record1/Axes/{a}/AxisType")
            if axis_type != kind:
                raise UnsupportedFeature(f"Record1/Axes/{a}/AxisType = {axis_type!r}: a height map has "
                                         f"incremental x, y axes ('I') and an absolute z axis ('A')")
        # x, y: the spacing [m], required; z: value * Increment + Offset, Increment 1 if absent
        dx, dy = (_number(root, f"Record1/Axes/{a}/Increment", float, positive=True) for a in ("CX", "CY"))
        z_type = _find(root, "Record1/Axes/CZ/DataType", required=False)
        z_scale = _number(root, "Record1/Axes/CZ/Increment", float, required=False)
        z_offset = _number(root, "Record1/Axes/CZ/Offset", float, required=False) or 0.0
        if z_scale == 0:
            raise FormatError("main.xml Record1/Axes/CZ/Increment = 0: every height would be the offset")
        link = _find(root, "Record3/DataLink/PointDataLink", required=False)
        if link is not None:
            dtype = DATA_TYPES.get(z_type)
            if dtype is None:
                raise FormatError(f"Record1/Axes/CZ/DataType = {z_type!r}; accepted: {', '.join(DATA_TYPES)}")
            data = _member(archive, link, nx * ny * np.dtype(dtype).itemsize,
                           f"Record3/DataLink/PointDataLink: {nx} x {ny} values of type {z_type}")
            md5 = _find(root, "Record3/DataLink/MD5ChecksumPointData", required=False)
            if md5 and hashlib.md5(data).hexdigest().lower() != md5.lower():
                raise FormatError(f"{link} does not match its MD5 checksum (a damaged file)")
            values = np.frombuffer(data, dtype).astype(float)
        else:
            datums = root.findall("Record3/DataList/Datum")
            if len(datums) != nx * ny:
                raise FormatError(f"{len(datums)} Record3/DataList/Datum, SizeX x SizeY = {nx * ny}")
            values = np.array([float(d.text) if d.text and d.text.strip() else np.nan for d in datums])
        valid_link = _find(root, "Record3/DataLink/ValidPointsLink", required=False)
        if valid_link is not None:
            packed = _member(archive, valid_link, (nx * ny + 7) // 8,
                             f"Record3/DataLink/ValidPointsLink: one bit per point of {nx} x {ny}")
            bits = np.unpackbits(np.frombuffer(packed, np.uint8), bitorder="little")[:nx * ny]
            values[bits == 0] = np.nan
        meta = {k: v for k in ("Record2/Date", "Record2/Creator", "Record2/Instrument/Manufacturer",
                               "Record2/Instrument/Model", "Record2/Comment")
                if (v := _find(root, k, required=False))}
    heights = (values * (1.0 if z_scale is None else z_scale) + z_offset).reshape(ny, nx).T   # x fastest
    meta.update(stored=z_type or "inline", not_measured=int(np.count_nonzero(np.isnan(heights))))
    # the heights are scaled floats (float64) whatever the stored type: in m, not raw integers
    return Topography(shape=(nx, ny), dtype=heights.dtype, heights=heights, height_unit="m",
                      dx=dx, dy=dy, lateral_unit="m", format="x3p", metadata=meta)
