"""``.npy`` and HDF5 height files: (nx, ny) arrays of heights, read by rows.

``.npy`` files hold (nx, ny); a sidecar ``NAME.npy.json`` (written by ``contactpetsc import``
where h5py is missing) may give ``dx``, ``dy`` [m], ``unit`` and ``periodic``.  HDF5 datasets
hold (nx, ny) unless the dataset, or else its file, carries the attribute ``axes``: "y,x"
(stored (ny, nx), as contactpetsc's step files) or "x,y"; any other stamp is refused.
Attributes ``dx``, ``dy`` [m] give the spacing, ``unit`` the heights' unit, ``periodic``
whether the map is periodic (for a step file: its run's scene, attribute ``scene``) and
``heights_are`` what the heights are: "surface" (peaks up; the default) or "gap" (a
composite gap, as the ``heights`` of contactpetsc's step files).  Only
the metadata is read unless heights are asked for, and then only the rows asked for (each
MPI rank its own).
"""
from __future__ import annotations

import json
import os

import numpy as np

from .base import FormatError, Topography, heights_are

HDF5_EXTENSIONS = (".h5", ".hdf5", ".hdf")
AXES = {"x,y": False, "y,x": True}   #: the ``axes`` stamp -> stored transposed, (ny, nx)


def _attr_text(value) -> str:
    if isinstance(value, bytes):
        value = value.decode("utf-8", "replace")
    return str(value).replace(" ", "").lower()


def _scalar(value):
    """An attribute's value as a Python scalar: bytes decoded, one-element arrays unwrapped."""
    if isinstance(value, np.ndarray) and value.size == 1:
        value = value.reshape(()).item()
    if isinstance(value, np.generic):
        value = value.item()
    return value.decode("utf-8", "replace") if isinstance(value, bytes) else value


def flag(value, name: str) -> bool | None:
    """A boolean attribute read strictly: True/False, 1/0, numpy booleans, "true"/"false" (any
    case); None stays None; anything else is refused with ``name`` (``bool("false")`` is True)."""
    value = _scalar(value)
    if value is None or isinstance(value, bool):
        return value
    if isinstance(value, (int, float)) and value in (0, 1):
        return bool(value)
    if isinstance(value, str) and value.strip().lower() in ("true", "false"):
        return value.strip().lower() == "true"
    raise FormatError(f"{name} = {value!r}: not a boolean (true or false, 1 or 0)")


def spacing(value, name: str) -> float | None:
    """A spacing attribute [m]: a finite number > 0 (or None), refused with ``name`` otherwise."""
    value = _scalar(value)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value) or value <= 0:
        fix = ": write it without quotes" if isinstance(value, str) else ""
        raise FormatError(f"{name} = {value!r}: a spacing is a number > 0, in m{fix}")
    return float(value)


def _npy_header(path: str):
    """(shape, fortran_order, dtype, data offset) of a .npy file, without reading its data."""
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            raise FormatError("empty or not a .npy file (no .npy header)")
        f.seek(0)
        try:
            version = np.lib.format.read_magic(f)
            read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                    else np.lib.format.read_array_header_2_0)
            shape, fortran, dtype = read(f)
        except ValueError as exc:
            raise FormatError(f"a damaged .npy header ({exc})") from None
        return shape, fortran, dtype, f.tell()


def sidecar(path: str) -> str:
    """The metadata file of a ``.npy`` height file."""
    return path + ".json"


def read_npy(path: str, rows=None, **_) -> Topography:
    stored, _, dtype, offset = _npy_header(path)
    if len(stored) != 2:
        raise FormatError(f"a {len(stored)}-D array of shape {tuple(stored)}; heights are a 2-D "
                          f"(nx, ny) array")
    need = offset + int(np.prod(stored)) * dtype.itemsize
    if os.path.getsize(path) < need:
        raise FormatError(f"truncated: {os.path.getsize(path)} bytes, its header announces {need}")
    topo = Topography(shape=tuple(stored), dtype=dtype, format="npy", metadata={"axes": "x,y"})
    if os.path.exists(sidecar(path)):
        with open(sidecar(path)) as f:
            try:
                meta = json.load(f)
            except ValueError as exc:
                raise FormatError(f"{sidecar(path)} is not JSON ({exc})") from None
        if not isinstance(meta, dict):
            raise FormatError(f"{sidecar(path)} holds {type(meta).__name__}, not a JSON object")
        where = os.path.basename(sidecar(path))
        topo.dx = spacing(meta.get("dx"), f"{where}: dx")
        topo.dy = spacing(meta.get("dy"), f"{where}: dy") or topo.dx
        topo.lateral_unit = "m" if topo.dx is not None else None
        topo.height_unit = meta.get("unit")
        topo.periodic = flag(meta.get("periodic"), f"{where}: periodic")
        topo.heights_are = heights_are(meta.get("heights_are"), f"{where}: heights_are")
        topo.metadata.update(meta)
    if rows is not None:
        topo.heights = np.load(path, mmap_mode="r")[:, rows[0]:rows[1]]
    return topo


def read_hdf5(path: str, rows=None, dataset: str = "heights", **_) -> Topography:
    import h5py
    with h5py.File(path, "r") as f:
        if dataset not in f or not isinstance(f[dataset], h5py.Dataset):
            raise KeyError(f"no dataset {dataset!r} (geometry.dataset) in {path} "
                           f"(has {sorted(f.keys())})")
        ds = f[dataset]
        if ds.ndim != 2:
            raise FormatError(f"dataset {dataset!r} is {ds.ndim}-D, shape {ds.shape}; heights are 2-D")
        raw = ds.attrs.get("axes", f.attrs.get("axes"))
        if raw is None and "approach" in f.attrs and "complementarity_error" in f.attrs:
            raise FormatError("a contactpetsc step file without an axes stamp: its fields are "
                              "stored (ny, nx); set the attribute axes = 'y,x' on the file to read it")
        stamp = "x,y" if raw is None else _attr_text(raw)
        if stamp not in AXES:
            raise FormatError(f"dataset {dataset!r} has axes = {raw!r}; accepted: 'x,y' (stored "
                              f"(nx, ny)) or 'y,x' (stored (ny, nx))")
        transposed = AXES[stamp]
        shape = ds.shape[::-1] if transposed else ds.shape

        def attr(name):
            value = ds.attrs.get(name, f.attrs.get(name))
            return value.decode() if isinstance(value, bytes) else value

        dx = spacing(attr("dx"), f"attribute dx of {dataset!r}")
        dy = spacing(attr("dy"), f"attribute dy of {dataset!r}")
        periodic = flag(attr("periodic"), f"attribute periodic of {dataset!r}")
        if periodic is None and attr("scene") is not None:   # a step file: its run's grid
            try:
                periodic = flag(json.loads(attr("scene"))["geometry"]["periodic"],
                                "the step file's scene: geometry.periodic")
            except (ValueError, KeyError, TypeError):
                periodic = None
        topo = Topography(shape=tuple(shape), dtype=ds.dtype, format="hdf5",
                          dx=dx, dy=None if dx is None else (dy or dx),
                          lateral_unit="m" if dx is not None else None,
                          height_unit=attr("unit"), periodic=periodic,
                          heights_are=heights_are(attr("heights_are"), f"attribute heights_are of {dataset!r}"),
                          metadata={"axes": stamp, "dataset": dataset})
        for key in ("source", "source_format", "converter", "channel"):
            if attr(key) is not None:
                topo.metadata[key] = str(attr(key))
        if rows is not None:
            ys, ye = rows
            topo.heights = ds[ys:ye, :].T if transposed else ds[:, ys:ye]
    return topo


def write_hdf5(path: str, topo: Topography) -> None:
    """``topo`` (heights and spacing in m) as an HDF5 file that ``read_hdf5`` reads with nothing
    restated: dataset ``heights`` stored (nx, ny), attributes axes = "x,y", unit = "m", dx,
    dy [m], periodic, heights_are = "surface" and the source's metadata."""
    import h5py
    with h5py.File(path, "w") as f:
        ds = f.create_dataset("heights", data=np.asarray(topo.heights, dtype=float))
        ds.attrs.update(axes="x,y", unit="m", dx=topo.dx, dy=topo.dy, heights_are=topo.heights_are or "surface")
        if topo.periodic is not None:
            ds.attrs["periodic"] = bool(topo.periodic)
        for key, value in topo.metadata.items():
            if key not in ("axes", "dataset", "heights_are"):
                ds.attrs[key] = str(value)


def write_npy(path: str, topo: Topography) -> None:
    """``topo`` as ``.npy`` (nx, ny) heights [m] and its sidecar ``NAME.npy.json`` (dx, dy [m],
    unit, periodic, heights_are, the source's metadata), for installations without h5py."""
    np.save(path, np.asarray(topo.heights, dtype=float))
    meta = {k: str(v) for k, v in topo.metadata.items() if k not in ("axes", "dataset")}
    meta.update(dx=topo.dx, dy=topo.dy, unit="m", periodic=topo.periodic,
                heights_are=topo.heights_are or "surface")
    with open(sidecar(path), "w") as f:
        json.dump(meta, f, indent=1)
