"""A ``kind = "file"`` scene's height file: its metadata fills in and checks the grid keys."""
from __future__ import annotations

from ..topography import HEIGHT_UNITS
from .scene_values import SceneError


def read_height_file(g: dict, given: set) -> None:
    """A ``kind = file`` scene's grid from its height file, read once here (the metadata only,
    for .npy and HDF5) so that a run, and a dry run, start only on a file that fits: nx, ny
    and, where the file gives them, dx, dy, periodic and the format are filled in; the keys
    given must agree with the file; ``heights_are`` is the file's stamp where it has one, else
    "surface" (the heights are the sample's surface, peaks up)."""
    from ..topography import HeightUnitConflict, format_of, grid_mismatch, read_topography, warn_units

    def fail(message):
        raise SceneError(f"geometry.path = {g['path']!r}: {message}")

    try:
        named = format_of(g["path"], g["format"])
    except ValueError as exc:
        fail(exc)
    if "dataset" in given and named not in ("hdf5", "gwy") and g["dataset"] != "heights":
        raise SceneError(f"geometry.dataset = {g['dataset']!r} is used by HDF5 and .gwy files only; "
                         f"{g['path']!r} is {named}")
    try:
        # the scene's height unit is read with the file: an .xyz file's x, y are in it too
        topo = read_topography(g["path"], format=g["format"], dataset=g["dataset"],
                               height_unit=g["height_unit"], metadata_only=True, fill=g["fill"])
    except HeightUnitConflict as exc:
        raise SceneError(f"geometry.height_unit = {g['height_unit']!r}, but {g['path']!r} states its "
                         f"heights in {exc.stated!r}: remove the key") from None
    except (OSError, ValueError, KeyError) as exc:
        fail(exc.args[0] if isinstance(exc, KeyError) and exc.args else exc)
    g["format"] = topo.format                        # what was read: a .txt of x y z points is xyz
    if g["height_unit"] is None and topo.height_unit in HEIGHT_UNITS:
        g["height_unit"] = topo.height_unit          # the file's own (or metres): for the plan
    for key, value in zip(("nx", "ny"), topo.shape):
        if value < 2:
            fail(f"{key} = {value}: a height map needs 2 or more nodes along x and y")
        g[key] = g[key] if key in given else value
    if topo.dx is None and "dx" not in given:
        raise SceneError(f"geometry.dx is required: {g['path']!r} ({g['format']}) does not give its spacing")
    if topo.dx is not None:
        g["dx"] = g["dx"] if "dx" in given else topo.dx
        g["dy"] = g["dy"] if "dy" in given else topo.dy
    g["dy"] = g["dy"] or g["dx"]
    problem = grid_mismatch(topo, (g["nx"], g["ny"]), (g["dx"], g["dy"]))
    if problem:
        fail(problem)
    warn_units(f"geometry.path = {g['path']!r}", (g["nx"], g["ny"]), g["dx"], g["dy"], topo.heights,
               stated=topo.unit_stated, given="height_unit" in given)
    if g["periodic"] is None:
        g["periodic"] = bool(topo.periodic)
    if topo.heights_are is not None and g["heights_are"] not in (None, topo.heights_are):
        raise SceneError(f"geometry.heights_are = {g['heights_are']!r}, but {g['path']!r} is stamped "
                         f"heights_are = {topo.heights_are!r}: remove the key")
    g["heights_are"] = g["heights_are"] or topo.heights_are or "surface"


#: the scene key under which a run stores the digest of its height file's heights (scene.json, step
#: files; ``geometry.surfaces`` computes it as it reads them)
DIGEST = "heights_sha256"
