"""The control node of ``AdhesiveProblem``'s central-gap control (Greenwood's device,
``solve(central_gap=...)``): which node's gap is prescribed, its owner, and its values
(docs/formulation.md, "Loading paths")."""
from __future__ import annotations

import numpy as np

from .adhesive_jacobian import minloc


class ControlNode:
    """Mixin of ``AdhesiveProblem``: the node whose gap central-gap control prescribes."""

    def set_control_node(self, node: tuple[int, int] | None = None) -> None:
        """The node (i, j) whose gap ``solve(central_gap=...)`` prescribes; None: the lowest
        node of h (the apex of a sphere), the smallest index on ties.  Past the point where
        the apex touches, the central gap no longer picks one state of the S-curve; the gap
        of a node further out, which the contact edge has not reached yet, does (the
        contact radius grows monotonically along the whole curve).  Collective."""
        grid, comm = self.grid, self.grid.mpi_comm
        if node is None:
            h = grid.rows(self.heights, readonly=True)
            k = int(np.argmin(h))
            _, index = minloc(comm, h.reshape(-1)[k], k + grid.nx * grid.ys)
        else:
            i, j = node
            if not (0 <= i < grid.nx and 0 <= j < grid.ny):
                raise ValueError(f"control node {node} outside the {grid.nx} x {grid.ny} grid")
            index = int(j) * grid.nx + int(i)
        self.centre_index = index
        j_c, i_c = divmod(index, grid.nx)
        self._centre_local = (j_c - grid.ys, i_c) if grid.ys <= j_c < grid.ye else None
        self._centre_rank = comm.allreduce(comm.Get_rank() if self._centre_local else 0)

    def control_gap(self) -> float:
        """The present state's gap [m] at the control node (``set_control_node``); collective."""
        if self._approach is None:
            raise RuntimeError("control_gap: no state yet (solve first)")
        return self.centre_value(self._current_gap(self.blocks(self._x, readonly=True)))

    def centre_value(self, rows: np.ndarray) -> float:
        """rows[centre] broadcast from its owner (collective)."""
        local = float(rows[self._centre_local]) if self._centre_local else 0.0
        return self.grid.mpi_comm.bcast(local, root=self._centre_rank)
