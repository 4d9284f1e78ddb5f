"""A hardness cap p <= H (perfectly plastic asperities) on the contact pressure: its check and
what a state reports about it (docs/formulation.md, "Hardness").

Where a node carries p = H the VI releases its gap constraint: the gap g = h + K p - delta may
be negative there, and -g is the node's plastic displacement (the height of asperity
material flattened away, with an elastic body and a rigid-plastic counter-surface alike).
"""
from __future__ import annotations

import math

import numpy as np
from mpi4py import MPI


def check_hardness(hardness) -> float:
    """H [Pa] as a float in (0, inf] (None: inf, no cap); a ValueError naming ``hardness``."""
    if hardness is None:
        return math.inf
    if isinstance(hardness, (bool, np.bool_)) or not isinstance(hardness, (int, float, np.integer, np.floating)):
        raise ValueError(f"hardness (Pa) must be a real number in (0, inf], got {hardness!r}")
    if not hardness > 0:   # NaN too
        raise ValueError(f"hardness = {hardness!r} Pa: accepted range (0, inf] (inf: no cap)")
    return float(hardness)


def plastic_measures(grid, pressure, gap, hardness: float) -> dict:
    """``plastic_fraction`` (fraction of nodes at p = H), ``plastic_volume`` [m^3] (the sum of
    the plastic displacements -g over those nodes times the element area dx dy) and
    ``max_plastic_displacement`` [m]; all zero without a hardness.  Collective."""
    if not math.isfinite(hardness):
        return dict(plastic_fraction=0.0, plastic_volume=0.0, max_plastic_displacement=0.0)
    p, g = grid.rows(pressure, readonly=True), grid.rows(gap, readonly=True)
    # the VI projects onto the bound: a node at the cap carries exactly H
    at_cap = p >= hardness
    overlap = np.where(at_cap, np.maximum(-g, 0.0), 0.0)
    comm = grid.mpi_comm
    count, depth = comm.allreduce(np.array([np.count_nonzero(at_cap), overlap.sum()], float))
    deepest = comm.allreduce(float(overlap.max()) if overlap.size else 0.0, op=MPI.MAX)
    return dict(plastic_fraction=count / (grid.nx * grid.ny), plastic_volume=depth * grid.dx * grid.dy,
                max_plastic_displacement=deepest)
