"""Length units of topography files: a unit name to metres.

Instrument files write units in many spellings ("um", "µm", "micron", "nm", "Å"); a file's
unit string is matched case-sensitively after its spelling is normalised (``"MM"`` is not a
unit; ``"mm"`` is).
"""
from __future__ import annotations

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
