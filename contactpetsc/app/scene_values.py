"""Scene values: the error a bad scene raises, the accepted ranges, and the check of one
key's value against its schema entry (type, choices, range), with the texts messages and
docs print for ranges and types."""
from __future__ import annotations

import math

POS = (0.0, math.inf, False, False)      # (low, high, low included?, high included?)
NONNEG = (0.0, math.inf, True, False)
TOL = (0.0, 1e-2, False, True)           # a tolerance: above 1e-2 a solve is not a solution
POISSON = (-1.0, 0.5, False, True)       # Poisson's ratio of an isotropic solid (0.5: incompressible)
LOAD_RESOLUTION = 1e-12   #: smallest non-zero load or approach, relative to E* or the grid spacing


class SceneError(ValueError):
    """An invalid scene (raised identically on every rank: scenes are read by all)."""


def _number_text(v) -> str:
    return str(v) if isinstance(v, int) else ("inf" if v == math.inf else f"{v:g}")


def range_text(rng) -> str:
    """An accepted range as printed in messages and docs: [ and ] include the bound."""
    lo, hi, lo_in, hi_in = rng
    return f"{'[' if lo_in else '('}{_number_text(lo)}, {_number_text(hi)}{']' if hi_in else ')'}"


def kind_name(kind) -> str:
    """A key's type as printed in messages and docs ("bool or list")."""
    return " or ".join(k.__name__ for k in kind) if isinstance(kind, tuple) else kind.__name__


def check_value(path: str, spec: dict, value):
    kind = spec["kind"]
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        quoted = ""
        if isinstance(value, str) and kind in (float, int):
            try:
                float(value)
                quoted = f" (a string: write the number without quotes, {path.split('.')[-1]} = {value})"
            except ValueError:
                pass
        raise SceneError(f"{path} = {value!r}: expected {kind_name(kind)}{quoted}")
    if spec["choices"] is not None and value not in spec["choices"]:
        raise SceneError(f"{path} = {value!r}: accepted values are {', '.join(spec['choices'])}")
    if spec["range"] is not None:
        lo, hi, lo_in, hi_in = spec["range"]
        ok = ((value >= lo if lo_in else value > lo) and (value <= hi if hi_in else value < hi)
              and math.isfinite(value))
        if not ok:
            raise SceneError(f"{path} = {value!r}: accepted range {range_text(spec['range'])} "
                             f"{spec['unit']}".rstrip())
    return value
