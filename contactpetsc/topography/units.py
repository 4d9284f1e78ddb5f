"""Length units of topography files: a unit name to metres.

Instrument files write units in many spellings ("um", "µm", "micron", "nm", "Å"); a file's
unit string is matched case-sensitively after its spelling is normalised (``"MM"`` is not a
unit; ``"mm"`` is).  ``warn_units``: a ``TopographyUnitWarning`` when a map states no unit, or
its extent, rms height or spacing is implausible for a measured surface (``PLAUSIBLE``).
"""
from __future__ import annotations

import warnings

import numpy as np

#: the units a scene's ``geometry.height_unit`` accepts, in metres
HEIGHT_UNITS = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9, "A": 1e-10}

_SPELLINGS = {"µm": "um", "μm": "um", "micron": "um", "microns": "um", "micrometer": "um",
              "micrometre": "um", "Å": "A", "Angstrom": "A", "angstrom": "A", "pm": "pm",
              "cm": "cm", "km": "km", "meter": "m", "metre": "m", "nanometer": "nm",
              "nanometre": "nm", "millimeter": "mm", "millimetre": "mm"}
_METRES = dict(HEIGHT_UNITS, pm=1e-12, cm=1e-2, km=1e3)


def metres_per(unit: str) -> float:
    """Metres in one ``unit`` (a length unit as files write it); ValueError for anything else."""
    text = unit.strip()
    name = _SPELLINGS.get(text, text)
    if name not in _METRES:
        raise ValueError(f"unknown length unit {unit!r} (accepted: {', '.join(sorted(_METRES))}, "
                         f"and the spellings µm, micron, Å)")
    return _METRES[name]


def canonical(unit: str) -> str:
    """The unit's name as ``HEIGHT_UNITS`` (and messages) spell it: "µm" -> "um"."""
    metres_per(unit)
    text = unit.strip()
    return _SPELLINGS.get(text, text)


class TopographyUnitWarning(UserWarning):
    """A height map whose units the file does not state, or whose sizes are implausible for a
    measured surface (a unit misread or mistyped)."""


#: the bounds of a plausible measured map [m]: lateral extent, rms height, grid spacing
PLAUSIBLE = {"extent": 1.0, "rms": 1e-3, "spacing": 1e-12}


def unit_doubts(shape, dx, dy, heights=None, *, stated: bool, given: bool,
                keys=("geometry.height_unit", "geometry.dx")) -> list:
    """Why the units of a map read may be wrong, one sentence each (empty: plausible).

    ``shape`` (nx, ny), spacing ``dx``, ``dy`` [m] (None: not known yet), ``heights`` [m] or
    None (not read); ``stated``: the file states its height unit; ``given``: the user gave one;
    ``keys``: the names of the height-unit and spacing inputs, for the advice."""
    unit_key, dx_key = keys
    nx, ny = shape
    rms = None if heights is None else float(np.nanstd(np.asarray(heights, dtype=float)))
    sizes = []
    if dx is not None:
        sizes.append(f"extent {nx * dx:.4g} m x {ny * dy:.4g} m (dx = {dx:.4g} m, dy = {dy:.4g} m)")
    if rms is not None:
        sizes.append(f"rms height {rms:.4g} m")
    implies = f" ({', '.join(sizes)})" if sizes else ""
    doubts = []
    if not stated and not given:
        doubts.append(f"the file states no height unit and none was given: its heights are taken as "
                      f"metres{implies}; give {unit_key} if they are in another unit")
    if dx is not None and max(nx * dx, ny * dy) > PLAUSIBLE["extent"]:
        doubts.append(f"the map is {nx * dx:.4g} m x {ny * dy:.4g} m (dx = {dx:.4g} m), larger than "
                      f"{PLAUSIBLE['extent']:g} m: is the spacing in another unit? check {dx_key} "
                      f"(in m) and {unit_key}")
    if dx is not None and min(dx, dy) < PLAUSIBLE["spacing"]:
        doubts.append(f"the spacing dx = {dx:.4g} m, dy = {dy:.4g} m is below {PLAUSIBLE['spacing']:g} m: "
                      f"check {dx_key} (in m) and {unit_key}")
    if rms is not None and rms > PLAUSIBLE["rms"]:
        doubts.append(f"the rms height {rms:.4g} m is above {PLAUSIBLE['rms']:g} m: are the heights in "
                      f"another unit? check {unit_key}")
    return doubts


def warn_units(name: str, *args, **kwargs) -> None:
    """A ``TopographyUnitWarning`` naming file ``name`` for each of ``unit_doubts(*args,
    **kwargs)``."""
    for doubt in unit_doubts(*args, **kwargs):
        warnings.warn(f"{name}: {doubt}", TopographyUnitWarning, stacklevel=3)
