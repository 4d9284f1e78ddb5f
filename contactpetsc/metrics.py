"""Scalar results of a contact state, in the reference paper's terms (section 3.1).

``adhesion_ratios``: the adhesive load ratio, |adhesive force| / (|adhesive
force| + compressive force) (1: no compressive pressure; 0.5: no net force;
0: no adhesion), and the adhesive area ratio, the adhesive nodes over the
adhesive plus compressive nodes; both ignore nodes whose adhesive pressure is
below 1 % of the law's peak attraction (the paper's cut-off).
Greenwood's nondimensional sphere variables: alpha* = delta / z0 and
W* = W / (2 pi R w).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

CUTOFF = 0.01  #: the paper's cut-off, relative to the peak attraction


def adhesion_ratios(grid, pressure, peak_attraction: float) -> tuple[float, float]:
    """(adhesive load ratio, adhesive area ratio) of a pressure Vec [Pa]; collective."""
    p = grid.rows(pressure, readonly=True)
    adhesive = p < -CUTOFF * peak_attraction
    compressive = p > 0
    sums = np.array([-p[adhesive].sum(), p[compressive].sum(), adhesive.sum(), compressive.sum()], float)
    grid.mpi_comm.Allreduce(MPI.IN_PLACE, sums)
    f_adh, f_comp, n_adh, n_comp = sums
    load = f_adh / (f_adh + f_comp) if f_adh + f_comp > 0 else float("nan")
    area = n_adh / (n_adh + n_comp) if n_adh + n_comp > 0 else float("nan")
    return float(load), float(area)


def greenwood(approach: float, force: float, radius: float, work_of_adhesion: float, z0: float):
    """(alpha*, W*) of a sphere."""
    return approach / z0, force / (2.0 * np.pi * radius * work_of_adhesion)
