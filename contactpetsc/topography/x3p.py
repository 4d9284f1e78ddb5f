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
1 for a measured point.
"""
from __future__ import annotations

import hashlib
import xml.etree.ElementTree as ET
import zipfile

import numpy as np

from .base import FormatError, Topography

DATA_TYPES = {"I": "<i2", "L": "<i4", "F": "<f4", "D": "<f8"}


def _find(root, path, required=True):
    node = root.find(path)
    if node is None or node.text is None:
        if required:
            raise FormatError(f"main.xml lacks {path}")
        return None
    return node.text.strip()


def read_x3p(path: str, **_) -> Topography:
    try:
        archive = zipfile.ZipFile(path)
    except zipfile.BadZipFile:
        raise FormatError("not a zip archive: an .x3p file is a zip with main.xml") from None
    with archive:
        try:
            root = ET.fromstring(archive.read("main.xml"))
        except KeyError:
            raise FormatError("the archive has no main.xml") from None
        except ET.ParseError as exc:
            raise FormatError(f"main.xml is not XML ({exc})") from None
        feature = _find(root, "Record1/FeatureType")
        if feature != "SUR":
            raise FormatError(f"Record1/FeatureType = {feature!r}: a height map is 'SUR' "
                              f"('PRF' is a profile, 'PCL' a point cloud)")
        nx, ny, nz = (int(_find(root, f"Record3/MatrixDimension/Size{a}")) for a in "XYZ")
        if nz != 1:
            raise FormatError(f"SizeZ = {nz}: layered maps are not height maps (SizeZ = 1)")
        axes = {}
        for a in ("CX", "CY", "CZ"):
            axes[a] = {k: _find(root, f"Record1/Axes/{a}/{k}", required=False)
                       for k in ("AxisType", "DataType", "Increment", "Offset")}
        for a in ("CX", "CY"):
            if axes[a]["AxisType"] != "I":
                raise FormatError(f"Record1/Axes/{a}/AxisType = {axes[a]['AxisType']!r}: only "
                                  f"incremental axes ('I') make a uniform grid")
        dtype = DATA_TYPES.get(axes["CZ"]["DataType"])
        if dtype is None:
            raise FormatError(f"Record1/Axes/CZ/DataType = {axes['CZ']['DataType']!r}; accepted: "
                              f"{', '.join(DATA_TYPES)}")
        link = _find(root, "Record3/DataLink/PointDataLink", required=False)
        if link is not None:
            try:
                data = archive.read(link)
            except KeyError:
                raise FormatError(f"the archive has no {link} (Record3/DataLink/PointDataLink)") from None
            md5 = _find(root, "Record3/DataLink/MD5ChecksumPointData", required=False)
            if md5 and hashlib.md5(data).hexdigest().lower() != md5.lower():
                raise FormatError(f"{link} does not match its MD5 checksum (a damaged file)")
            if len(data) != nx * ny * np.dtype(dtype).itemsize:
                raise FormatError(f"{link} holds {len(data)} bytes, SizeX x SizeY = {nx} x {ny} "
                                  f"values of type {axes['CZ']['DataType']} need "
                                  f"{nx * ny * np.dtype(dtype).itemsize}")
            values = np.frombuffer(data, dtype).astype(float)
        else:
            datums = root.findall("Record3/DataList/Datum")
            if len(datums) != nx * ny:
                raise FormatError(f"{len(datums)} Record3/DataList/Datum, SizeX x SizeY = {nx * ny}")
            values = np.array([float(d.text) if d.text and d.text.strip() else np.nan for d in datums])
        valid_link = _find(root, "Record3/DataLink/ValidPointsLink", required=False)
        if valid_link is not None:
            bits = np.unpackbits(np.frombuffer(archive.read(valid_link), np.uint8),
                                 bitorder="little")[:nx * ny]
            values[bits == 0] = np.nan
        meta = {k: v for k in ("Record2/Date", "Record2/Creator", "Record2/Instrument/Manufacturer",
                               "Record2/Instrument/Model", "Record2/Comment")
                if (v := _find(root, k, required=False))}
    z = axes["CZ"]
    scale = float(z["Increment"]) if z["Increment"] else 1.0
    offset = float(z["Offset"]) if z["Offset"] else 0.0
    heights = (values * scale + offset).reshape(ny, nx).T      # x fastest in the file
    missing = int(np.count_nonzero(~np.isfinite(heights)))
    if missing:
        raise FormatError(f"{missing} of the {nx} x {ny} points are not measured (invalid); fill "
                          f"them first (interpolate them, e.g. in Gwyddion or MountainsMap)")
    return Topography(shape=(nx, ny), dtype=np.dtype(dtype), heights=heights, height_unit="m",
                      dx=float(axes["CX"]["Increment"]), dy=float(axes["CY"]["Increment"]),
                      lateral_unit="m", format="x3p", metadata=meta)
