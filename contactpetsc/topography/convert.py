"""``contactpetsc import SRC DST``: a measured topography to a height file that a ``kind = "file"``
scene reads with nothing restated.

SRC is read by contactpetsc's own readers when it is in one of their formats (``FORMATS``:
tested against the formats' specifications), otherwise by SurfaceTopography (about 40
instrument formats) where it is installed; ``--reader`` chooses.  ``auto`` also hands on to
SurfaceTopography a file whose extension names one of contactpetsc's formats but whose
content is another (a binary Zygo MetroPro ``.dat``) or uses a feature contactpetsc's reader
does not read (``UnsupportedFeature``: a compressed ``.sur``); a damaged file is refused as
contactpetsc's reader finds it.  ``--fill harmonic`` fills the points not measured
(``fill.harmonic``), whichever reader read them.  DST is HDF5 (``.h5``:
dataset ``heights`` stored (nx, ny) in m, attributes axes = "x,y", unit = "m", dx, dy [m],
periodic, and the source's name, format and channel) or, where h5py is missing, ``.npy``
with the same metadata in ``DST.npy.json``.  Nothing here imports MPI or PETSc: the command
runs in SurfaceTopography's own environment (docs/topography.md).
"""
from __future__ import annotations

import argparse
import os
import sys

import numpy as np

from . import FILLS, FORMATS, HEIGHT_UNITS, Topography, UnsupportedFeature, arrays, format_of, read_topography, warn_units
from .fill import apply_fill
from .units import canonical, metres_per

READERS = ("auto", "native", "surfacetopography")
INSTALL = ("SurfaceTopography is not installed here: make its own venv (python3 -m venv ~/st && "
           "~/st/bin/pip install SurfaceTopography) and run the converter there: PYTHONPATH=/path/to/"
           "contactpetsc ~/st/bin/python -m contactpetsc import SRC DST (docs/topography.md)")


def add_arguments(p: argparse.ArgumentParser) -> argparse.ArgumentParser:
    p.add_argument("source", help="the measured topography (any format SurfaceTopography reads, or "
                                  + ", ".join(FORMATS) + ")")
    p.add_argument("destination", help="the height file to write: NAME.h5 (or NAME.npy without h5py)")
    p.add_argument("--reader", choices=READERS, default="auto",
                   help="auto: contactpetsc's readers for their formats, SurfaceTopography for the rest")
    p.add_argument("--format", choices=tuple(FORMATS), default=None,
                   help="the source's format for contactpetsc's readers (default: by extension)")
    p.add_argument("--channel", type=int, default=None,
                   help="SurfaceTopography: the channel index (default: the file's default channel)")
    p.add_argument("--dataset", default="heights",
                   help="contactpetsc's readers: the HDF5 dataset or .gwy channel title (default: "
                        "heights, a .gwy file's first channel)")
    p.add_argument("--height-unit", default=None,
                   help=f"the heights' unit where the file states none ({', '.join(HEIGHT_UNITS)})")
    p.add_argument("--dx", type=float, default=None, help="spacing along x [m] where the file gives none")
    p.add_argument("--dy", type=float, default=None, help="spacing along y [m] (default dx)")
    p.add_argument("--fill", choices=FILLS, default="none",
                   help="points not measured: none (refuse the file) or harmonic (Laplace interpolation)")
    return p


def read_with_surfacetopography(path: str, channel: int | None, height_unit: str | None,
                                spacing: tuple | None, fill: str = "none") -> Topography:
    """``path`` through SurfaceTopography's ``open_topography``: heights and spacing in m.
    ``height_unit`` and ``spacing`` [m] are passed on only where the file lacks them; points
    not measured (masked) are NaN, then refused or filled as ``fill`` says."""
    import SurfaceTopography
    from SurfaceTopography import open_topography
    reader = open_topography(path)
    info = reader.default_channel if channel is None else reader.channels[channel]
    kw = {"channel_index": info.index}
    unit = info.unit or height_unit or "m"
    if info.unit is None:
        kw["unit"] = unit
    if spacing is not None and info.physical_sizes is None:
        nx, ny = info.nb_grid_pts
        kw["physical_sizes"] = (nx * spacing[0] / metres_per(unit), ny * spacing[1] / metres_per(unit))
    topo = reader.topography(**kw)
    if topo.dim != 2:
        raise ValueError(f"{path}: channel {info.index} ({info.name}) is a {topo.dim}-D topography "
                         f"(a line scan); contact needs a 2-D map")
    scale = metres_per(topo.unit)
    heights = np.ma.filled(np.ma.asarray(topo.heights(), dtype=float), np.nan) * scale
    (lx, ly), (nx, ny) = topo.physical_sizes, heights.shape
    out = Topography(shape=(nx, ny), dtype=np.dtype(float), heights=heights, height_unit="m",
                     dx=lx * scale / nx, dy=ly * scale / ny, lateral_unit="m", unit_stated=info.unit is not None,
                     periodic=bool(topo.is_periodic), format=str(reader.format()),
                     metadata={"channel": f"{info.index} ({info.name})",
                               "converter": f"SurfaceTopography {SurfaceTopography.__version__}"})
    apply_fill(out, fill)
    return out


def convert(source: str, destination: str, *, reader: str = "auto", format: str | None = None,
            channel: int | None = None, dataset: str = "heights", height_unit: str | None = None,
            dx: float | None = None, dy: float | None = None, fill: str = "none") -> Topography:
    """Read ``source`` and write ``destination`` (module docstring); the map written."""
    if height_unit is not None:
        height_unit = canonical(height_unit)
    spacing = None if dx is None else (dx, dy or dx)
    topo, why_not = None, None
    if reader != "surfacetopography":
        try:
            try:
                format_of(source, format)
            except UnsupportedFeature:
                raise
            except ValueError:          # an extension none of contactpetsc's formats has
                if reader == "native":
                    raise
                why_not = f"not a format contactpetsc reads ({', '.join(FORMATS)})"
            else:
                topo = read_topography(source, format=format, dataset=dataset, height_unit=height_unit,
                                       fill=fill)
                topo.metadata["converter"] = "contactpetsc"
        except UnsupportedFeature as exc:     # content or a feature that is not ours: hand it on
            if reader == "native":
                raise
            why_not = f"contactpetsc's readers: {exc}"
    if topo is None:
        try:
            topo = read_with_surfacetopography(source, channel, height_unit, spacing, fill)
        except ImportError:
            raise ValueError(f"{source}: {why_not or 'read by SurfaceTopography'}; {INSTALL}") from None
        except Exception as exc:  # noqa: BLE001 - SurfaceTopography's errors have many types
            if why_not is None:
                raise
            first = (str(exc).strip().splitlines() or [""])[0][:200]     # its tries of every reader: long
            raise ValueError(f"{source}: {why_not}; SurfaceTopography cannot read it either "
                             f"({type(exc).__name__}: {first})") from None
    if spacing is not None:
        if topo.dx is not None and not np.allclose((topo.dx, topo.dy), spacing, rtol=1e-9, atol=0):
            raise ValueError(f"{source} gives its spacing ({topo.dx!r}, {topo.dy!r}) m, not "
                             f"--dx, --dy = {spacing}")
        topo.dx, topo.dy = spacing
    if topo.dx is None:
        raise ValueError(f"{source} does not give its spacing: give --dx (and --dy) in m")
    warn_units(os.path.basename(source) or source, topo.shape, topo.dx, topo.dy, topo.heights,
               stated=topo.unit_stated, given=height_unit is not None, keys=("--height-unit", "--dx"))
    if not np.isfinite(topo.heights).all():
        raise ValueError(f"{source}: some heights are Inf")
    topo.metadata.update(source=os.path.basename(source), source_format=topo.format)
    ext = os.path.splitext(destination)[1].lower()
    if ext in arrays.HDF5_EXTENSIONS:
        try:
            import h5py  # noqa: F401 - only to say clearly that it is missing
        except ImportError:
            raise ValueError("h5py is not installed here: write NAME.npy (its metadata goes to "
                             "NAME.npy.json), or pip install h5py") from None
        arrays.write_hdf5(destination, topo)
    elif ext == ".npy":
        arrays.write_npy(destination, topo)
    else:
        raise ValueError(f"destination {destination!r}: NAME.h5 or NAME.npy")
    return topo


def main(argv) -> int:
    """The ``contactpetsc import`` command; exit status 0, 1 (an error) or 2 (usage)."""
    args = add_arguments(argparse.ArgumentParser(
        prog="contactpetsc import", description="convert a measured topography to a height file "
        "for a kind = \"file\" scene (docs/topography.md)")).parse_args(argv)
    try:
        topo = convert(args.source, args.destination, reader=args.reader, format=args.format,
                       channel=args.channel, dataset=args.dataset, height_unit=args.height_unit,
                       dx=args.dx, dy=args.dy, fill=args.fill)
    except (OSError, ValueError, KeyError) as exc:
        text = str(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc)
        if args.source not in text:     # the file the cause is in, named once
            text = f"{args.source}: {text}"
        sys.stderr.write(f"contactpetsc import: error: {text}\n")
        return 1
    nx, ny = topo.shape
    h = topo.heights
    print(f"wrote {args.destination}: {nx} x {ny} nodes, dx = {topo.dx:.6g} m, dy = {topo.dy:.6g} m, "
          f"heights {h.min():.6g} .. {h.max():.6g} m, periodic {topo.periodic}, "
          f"read by {topo.metadata['converter']} ({topo.format})"
          + (f", {topo.metadata['filled_points']} points not measured filled ({args.fill})"
             if topo.metadata.get("filled_points") else ""))
    return 0
