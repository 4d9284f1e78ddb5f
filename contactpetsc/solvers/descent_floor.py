"""The full LJ curve's gap floor of the energy descent (``descent.py``'s module doc): TAO's
lower bound on v = u / z0 at the gap where the law's repulsion is F times the start's largest
pressure, lowered where it holds nodes that the state needs below it."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

#: the floor's repulsion grows by this factor each time it is lowered ...
LOWER_FACTOR = 8.0
#: ... and the floor is removed the time it would be lowered this often
MAX_LOWERINGS = 3


class GapFloor:
    """The floor of ``descent`` (an ``EnergyDescent`` at its approach) from the start's largest
    pressure ``largest`` [Pa]: its repulsion ``pressure`` [Pa] (infinite: no floor) and how
    often it was ``lowered``.  It keeps what it needs of the descent, not the descent: a
    reference back would make a cycle that holds the descent's grid arrays until Python's
    cyclic collector happens to run (a path grew by ten doubles per point a state)."""

    def __init__(self, descent, largest: float):
        self.traction, self.grid, self.comm = descent.p.traction, descent.grid, descent.comm
        self.h, self.delta, self.length, self.n = descent.h, descent.delta, descent.length, descent.n
        # the window's nodes (the law's) and whether the gaps move with the mean of v (a cell)
        self.win, self.cell = descent.win, descent.space.projects_mean
        self.pressure = descent.floor_factor * max(descent.p.pressure_scale, largest)
        self.lowered = 0

    @property
    def active(self) -> bool:
        return bool(np.isfinite(self.pressure))

    def set_bound(self, lower: np.ndarray, v: np.ndarray) -> None:
        """TAO's lower bound (rows ``lower`` of v = u / z0): the gap where the law's repulsion is
        ``pressure`` (none where that is infinite, or outside a window), on a cell at the present
        mean of v (the rows ``v``)."""
        lower[...] = PETSc.NINFINITY
        if not self.active:
            return
        floor = float(self.traction.repulsive_gap(np.array([self.pressure]))[0][0])
        mean_v = self.comm.allreduce(float(v.sum())) / self.n if self.cell else 0.0
        lower[self.win] = (floor - self.h + self.delta) / self.length + mean_v

    def lower(self, lower: np.ndarray, v: np.ndarray) -> None:
        """Lower the floor (its pressure LOWER_FACTOR x, removed the MAX_LOWERINGS-th time) and
        set TAO's bound again (as ``set_bound``)."""
        self.lowered += 1
        self.pressure = self.pressure * LOWER_FACTOR if self.lowered < MAX_LOWERINGS else np.inf
        self.set_bound(lower, v)

    def holds(self, tao, k_inv_u, p0, a) -> bool:
        """Whether the floor holds a node: at its bound with the gradient p - a pushing it
        below (collective).  A node that snaps onto the floor is pushed back up (its repulsion
        there is F times the start's largest pressure); one that is held needs a lower floor,
        and the bounded Newton steps, which do not drop it from the system, would crawl."""
        lower = tao.getVariableBounds()[0]
        v = self.grid.rows(tao.getSolution(), readonly=True)   # rank-local rows: reduced below
        at_floor = v[self.win] <= self.grid.rows(lower, readonly=True)[self.win]
        held = bool(np.any(at_floor & (k_inv_u[self.win] + p0 > a)))
        return self.comm.allreduce(held, op=MPI.LOR)
