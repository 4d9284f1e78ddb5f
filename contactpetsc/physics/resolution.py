"""Grid resolution of the adhesive zone: the one criterion a scene or a solver checks.

The adhesive traction acts in a band near each contact edge; a grid that samples that band
with too few nodes gives forces that depend on where the nodes fall (docs/robustness.md,
"The resolution criterion").
"""
from __future__ import annotations

import warnings

import numpy as np

from .interactions import InteractionLaw

#: the adhesive zone must span at least this many grid spacings (docs/robustness.md)
RESOLUTION_NODES = 4.0


class UnderResolvedWarning(UserWarning):
    """The grid is too coarse for the adhesive zone (``check_resolution``)."""


def adhesive_zone_length(law: InteractionLaw, e_star: float, *, radius: float | None = None,
                         rms_slope: float | None = None) -> dict:
    """Estimates [m] of the width of the band near a contact edge where the adhesive traction acts.

    ``cohesive``  (pi/4) E* w / sigma_max^2: the cohesive-zone length at the tip of the adhesive
                  crack (Dugdale-Barenblatt with the law's peak attraction sigma_max; for LJ
                  0.75 E* z0^2 / w): the zone at the JKR end (large Tabor parameter).
    ``sphere``    sqrt(2 R range): where a rigid sphere's gap is below the law's range (DMT end).
    ``slope``     range / rms_slope: where a rough surface's gap changes by one range.
    ``zone``      the smallest of those given: the zone is no wider than any of them.
    """
    if not law.adhesive:
        return {"zone": np.inf}
    rng = law.length_scale()
    out = {"cohesive": np.pi / 4.0 * e_star * law.work_of_adhesion / law.peak_attraction ** 2}
    if radius is not None:
        out["sphere"] = np.sqrt(2.0 * radius * rng)
    if rms_slope:
        out["slope"] = rng / rms_slope
    out["zone"] = min(out.values())
    return out


def _gaps(law: InteractionLaw) -> np.ndarray:
    """Gaps [m] on which a law's slope is probed: 0 to 20 ranges."""
    return np.linspace(0.0, 20.0, 20001) * law.length_scale()


def snap_number(law: InteractionLaw, self_influence: float) -> float:
    """K_ii max da/dg of the pointwise law (dimensionless; K_ii [m/Pa] the self-influence).

    Above one a single node is unstable on its own (its adhesive stiffness beats its elastic
    one): the discrete problem has an equilibrium for every subset of snapped nodes, the
    adhesive range is under-resolved.  Well below one the adhesive rows of the Newton system
    are nearly local (the preconditioner's choice, ``pc_registry.auto_adhesive_preconditioner``).
    The maximum lies on the attractive tail, g > 0, probed to 20 ranges.
    """
    return float(self_influence * max(0.0, float(np.max(law.derivative(_gaps(law)[1:])))))


def steepest_slope(law: InteractionLaw) -> float:
    """max |da/dg| of the pointwise law over g >= 0, probed to 20 ranges [Pa/m]: how far a gap
    error moves the law's pressure (for the hard-wall LJ law at the wall, 15.6 peak
    attractions per z0)."""
    return float(np.max(np.abs(law.derivative(_gaps(law)))))


def check_resolution(law: InteractionLaw, e_star: float, dx: float, *, radius: float | None = None,
                     rms_slope: float | None = None, warn: bool = True) -> float:
    """Nodes per adhesive zone, l_zone / dx (``adhesive_zone_length``, dx the larger spacing).

    Below ``RESOLUTION_NODES`` the adhesive traction is sampled too coarsely: forces depend on
    where the nodes fall, and Newton may stall; an ``UnderResolvedWarning`` states the criterion.
    The same on every rank (it depends on the parameters only).
    """
    zl = adhesive_zone_length(law, e_star, radius=radius, rms_slope=rms_slope)
    nodes = zl["zone"] / dx
    if warn and nodes < RESOLUTION_NODES:
        parts = ", ".join(f"{k} {v:.3g} m" for k, v in zl.items() if k != "zone")
        warnings.warn(
            f"under-resolved adhesion ({law.name}, range {law.length_scale():.3g} m): the adhesive zone "
            f"l_zone = {zl['zone']:.3g} m (smallest of: {parts}) spans {nodes:.2g} grid spacings of "
            f"{dx:.3g} m; the criterion is l_zone >= {RESOLUTION_NODES:g} dx (docs/robustness.md). "
            f"Refine the grid (dx <= {zl['zone'] / RESOLUTION_NODES:.3g} m) or expect grid-dependent "
            f"forces and slow or failed convergence", UnderResolvedWarning, stacklevel=2)
    return nodes


def resolution_note(snap: float, nodes: float) -> str:
    """What a failed solve's reason adds where the adhesion is under-resolved: the snap number
    ``snap`` (K_ii max da/dg) above 1, or ``nodes`` (nodes per adhesive zone) below
    ``RESOLUTION_NODES``; empty where it is resolved."""
    if snap > 1.0:
        return (f" [under-resolved adhesion: K_ii max da/dg = {snap:.2f} > 1, every node can snap on "
                f"its own; refine the grid until this is below 1]")
    if nodes < RESOLUTION_NODES:
        return (f" [under-resolved adhesion: the adhesive zone spans {nodes:.2g} grid spacings, the "
                f"criterion is {RESOLUTION_NODES:g}]")
    return ""


#: the sawtooth of a sphere's force along its unloading path against the nodes per adhesive zone:
#: (nodes, lowest, highest deviation from the smooth curve, relative to the pull-off), measured by
#: run_scripts/checks/sawtooth_amplitude.py (docs/validation.md, "The sawtooth of an under-resolved pull-off"; the LJ laws)
#: (mu = 5 at 1.34, about the axisymmetric curve; mu = 2 at the others.  The amplitude depends on the
#: Tabor parameter too: at mu = 5 and 2 nodes it is +-0.10 %, a quarter of mu = 2's, so the values
#: are an upper estimate at larger mu; both fall as about e^(-2 nodes))
SAWTOOTH_MEASURED = ((1.34, -0.0041, 0.0036),    # mu = 5, 256^2, dx = z0/2
                     (1.98, -0.0048, 0.0042),    # mu = 2, dx = 1.33 z0
                     (2.64, -0.0012, 0.0011),    # mu = 2, dx = z0
                     (3.99, -0.00008, 0.00009))  # mu = 2, dx = 0.66 z0


def sawtooth_amplitude(nodes: float) -> tuple[float, float]:
    """(low, high): the expected deviation of the force from the smooth curve along a path of a
    grid with ``nodes`` spacings per adhesive zone, relative to the pull-off (negative: more
    tensile).  Where the zone spans few spacings the contact edge moves node by node and the force
    jumps between states of one set of adhered nodes each; the most tensile sampled state, the
    reported pull-off, is the deepest tooth.  Interpolated in ``SAWTOOTH_MEASURED``, held at its
    ends; zero from ``RESOLUTION_NODES`` on."""
    if nodes >= RESOLUTION_NODES:
        return 0.0, 0.0
    n, lo, hi = (np.array(c) for c in zip(*SAWTOOTH_MEASURED))
    return float(np.interp(nodes, n, lo)), float(np.interp(nodes, n, hi))
