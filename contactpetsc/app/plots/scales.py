"""Colour and histogram limits that one outlier node does not set (numpy only).

A contact pressure field has a few nodes far above the rest: the edge of a contact spot on a
grid (a square-root singularity sampled at a node), a measured map's spike.  Scaled to its
maximum, a map of 90 % contact shows the bulk in the palest colour and looks empty.  The
limits here are a high percentile of the values instead where a tail stands out
(``robust_max``, each sign apart); what lies beyond is drawn at the limit's colour (a colorbar with
``extend``) and named on the plot.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PERCENTILE = 99.5   #: the bulk: the values up to this percentile
STANDOUT = 0.5      #: a tail is clipped only where it reaches this share of the bulk's end beyond it


def robust_max(values) -> float:
    """The largest of the positive ``values`` [any unit] without outliers: the bulk's end b,
    their PERCENTILE-th percentile (numpy's "higher" method, a value of the sample: with fewer
    than 1 / (1 - PERCENTILE / 100) = 200 values their maximum), where the maximum exceeds
    (1 + STANDOUT) b; else the maximum itself (a smooth tail, a Hertzian peak, is not clipped
    for nothing).  0 for no values."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0
    b, top = float(np.percentile(v, PERCENTILE, method="higher")), float(v.max())
    return b if top > (1.0 + STANDOUT) * b else top


@dataclass(frozen=True)
class Limits:
    """A colour scale: ``vmin``, ``vmax`` [the field's unit], the colorbar's ``extend``
    ("neither", "min", "max" or "both"), the field's extreme values ``low``, ``high`` (what a
    clipped end stands for), and ``diverging`` (a scale centred at zero, tension in it)."""
    vmin: float
    vmax: float
    extend: str
    low: float
    high: float
    diverging: bool

    @property
    def clipped(self) -> bool:
        return self.extend != "neither"


def pressure_limits(pressure) -> Limits:
    """The colour scale of a pressure field p [Pa], compressive positive.  Without tension
    (p >= 0 everywhere): [0, top], top the ``robust_max`` of the contact pressures p > 0.
    With tension (adhesion): a diverging scale [-top, top] centred at zero, top the larger of
    the ``robust_max`` of p over p > 0 and of -p over p < 0 (each side's outliers clipped
    alike; zero stays in the middle).  ``extend`` says which ends clip a value; a field
    without pressure gets [0, 1]."""
    p = np.asarray(pressure, float)
    p = p[np.isfinite(p)]
    high = float(p.max()) if p.size else 0.0
    low = float(p.min()) if p.size else 0.0
    diverging = low < 0
    top = max(robust_max(p[p > 0]), robust_max(-p[p < 0]))
    if not top > 0:
        top = 1.0
    over, under = high > top, diverging and low < -top
    extend = {(False, False): "neither", (True, False): "max", (False, True): "min", (True, True): "both"}[
        (bool(over), bool(under))]
    return Limits(-top if diverging else 0.0, top, extend, low, high, diverging)


def histogram_range(values) -> tuple[float, float, int]:
    """(lo, hi, n_out): the span of a histogram of ``values`` whose bins the bulk fills, each
    sign apart as on the pressure map (an adhesive field's many small tensile values must not
    make its compressive tail an outlier): hi the ``robust_max`` of the positive values (else
    the maximum), lo minus that of the negative ones (else the minimum); and the number of
    values outside it, which the histogram leaves out and names.  None: (0, 1, 0)."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 1.0, 0
    hi = robust_max(v[v > 0]) if np.any(v > 0) else float(v.max())
    lo = -robust_max(-v[v < 0]) if np.any(v < 0) else float(v.min())
    return lo, hi, int(np.count_nonzero((v < lo) | (v > hi)))
