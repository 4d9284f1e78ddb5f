"""Colour and histogram limits that one outlier node does not set (numpy only).

A contact pressure field has a few nodes far above the rest: the edge of a contact spot on a
grid (a square-root singularity sampled at a node), a measured map's spike.  Scaled to its
maximum, a map of 90 % contact shows the bulk in the palest colour and looks empty.  The
limits here are a high percentile of the values instead where a tail stands out
(``robust_range``); what lies beyond is drawn at the limit's colour (a colorbar with
``extend``) and named on the plot.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PERCENTILE = 99.5   #: the bulk: the values up to this percentile (and from 100 minus it)
STANDOUT = 0.5      #: a tail is clipped only when it reaches this share of the bulk's span beyond it


def _percentile(v: np.ndarray, share: float) -> float:
    """numpy's "higher" (below 50 %: "lower") percentile, a value of the sample: with fewer than
    1 / (1 - PERCENTILE / 100) = 200 values the bulk's ends are the extremes."""
    return float(np.percentile(v, share, method="higher" if share >= 50 else "lower"))


def robust_range(values) -> tuple[float, float]:
    """(lo, hi): the range of the finite ``values`` without their outliers.  The bulk spans the
    (100 - PERCENTILE)-th to the PERCENTILE-th percentile, [b_lo, b_hi]; an end is the bulk's
    where a value lies more than STANDOUT * max(b_hi - b_lo, |b_lo|, |b_hi|) beyond it, else
    the extreme value (a smooth tail, a Hertzian peak, is not clipped for nothing).  (0, 0) for
    no values."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 0.0
    lo, hi = _percentile(v, 100 - PERCENTILE), _percentile(v, PERCENTILE)
    reach = STANDOUT * max(hi - lo, abs(hi), abs(lo))
    return (lo if v.min() < lo - reach else float(v.min())), (hi if v.max() > hi + reach else float(v.max()))


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
    (p >= 0 everywhere): [0, top], top the upper end of the ``robust_range`` of the contact
    pressures p > 0.  With tension (adhesion): a diverging scale [-top, top] centred at zero,
    top the larger of that end for p over p > 0 and for -p over p < 0 (each side's outliers
    clipped alike; zero stays in the middle).  ``extend`` says which ends clip a value; a field
    without pressure gets [0, 1]."""
    p = np.asarray(pressure, float)
    p = p[np.isfinite(p)]
    high = float(p.max()) if p.size else 0.0
    low = float(p.min()) if p.size else 0.0
    diverging = low < 0
    top = max(robust_range(p[p > 0])[1], robust_range(-p[p < 0])[1])
    if not top > 0:
        top = 1.0
    over, under = high > top, diverging and low < -top
    extend = {(False, False): "neither", (True, False): "max", (False, True): "min", (True, True): "both"}[
        (bool(over), bool(under))]
    return Limits(-top if diverging else 0.0, top, extend, low, high, diverging)


def histogram_range(values) -> tuple[float, float, int]:
    """(lo, hi, n_out): the ``robust_range`` of ``values``, the span of a histogram whose bins the
    bulk fills, and the number of values outside it, which the histogram leaves out and names.
    All values equal: that value twice (numpy widens it); none: (0, 1, 0)."""
    v = np.asarray(values, float).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        return 0.0, 1.0, 0
    lo, hi = robust_range(v)
    return lo, hi, int(np.count_nonzero((v < lo) | (v > hi)))
