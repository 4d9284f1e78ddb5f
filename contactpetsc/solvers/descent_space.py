"""Where the energy descent's unknown lives (``descent.py``): a periodic cell, or an isolated
window's padded grid (docs/formulation.md, "Energy descent").

Periodic cell (``CellSpace``)
    The surface displacement u on the cell itself: K^-1 = E* |q| / 2 is diagonal in Fourier
    space, zero on the mean, which the approach fixes.

Isolated window (``PaddedWindow``)
    The window's operator is K_w = R C E (``operators.elastic.IsolatedHalfSpace``): E extends
    a pressure on the nx x ny window by zeros to the 2nx x 2ny padded grid, C is the circulant
    of Love's coefficients there (positive definite, checked where it is built) and R restricts
    to the window.  K_w^-1 is diagonal in no basis at hand, but the energy over the
    displacement u on the whole padded grid,

        E(u) / dA = 1/2 u . C^-1 u + sum_{i in window} Phi(h_i + u_i - delta),

    is stationary where C^-1 u = a(g) on the window and 0 outside it: u = C E a(g), which is the
    window's equilibrium u = K_w p with p = a(g), at the window's own energy (1/2 u . C^-1 u =
    1/2 p . K_w p).  C^-1 is diagonal in Fourier space on the padded grid and positive on every
    mode (no mean to fix), and the nodes outside the window carry no law.  So the periodic
    descent runs on the padded grid unchanged but for the window; a pair there is a transform
    pair of the window operator's own padded size, and counted as one of its pairs.

The law's fields (gaps, tractions, heights) are the window's nodes on this rank's rows of the
descent's grid: ``window``, a block of its local rows (the padded grid's middle rows).  Window fields move between that block
and the problem's own rows (``to_problem``, ``from_problem``) once per descent.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..grid import SurfaceGrid
from ..pencil_fft import grid_rfft
from ..operators.elastic import convolve


class CellSpace:
    """The periodic cell: the descent's unknown on the problem's own grid and operator."""

    projects_mean = True       #: the mean of u is K^-1's null mode

    def __init__(self, problem):
        self.grid, self.op = problem.grid, problem.op
        self.window = (slice(None), slice(None))

    def convolve(self, kernel_pairs, rows_in, rows_out):
        return self.op.convolve(kernel_pairs, rows_in, rows_out)

    def displacement(self, pressure_rows, out_rows):
        """u = K p [m] of a pressure [Pa] on the problem's rows, into the descent's rows."""
        return self.op.apply(pressure_rows, out_rows)

    def from_problem(self, rows):
        """A window field on the problem's rows, on the descent's ``window`` block (the same rows)."""
        return rows

    def to_problem(self, block, out_rows):
        """A window field on the descent's ``window`` block, into the problem's rows ``out_rows``."""
        np.copyto(out_rows, block)

    def outside_gap(self, pressure_rows) -> float:
        """The gap error [m] of a pressure outside the window: none on a cell."""
        return 0.0

    def create_vec(self):
        return self.grid.create_vec()


class PaddedWindow:
    """An isolated window's padded grid (module doc): a periodic 2nx x 2ny grid split along y
    over the problem's ranks, its FFT (threads and planner as the operator's) and the window's
    block of its rows.  ``problem``: anything with the window's ``grid`` and operator ``op``;
    ``grid``: the padded grid's split over the ranks where it is given (a finer padded grid
    halved, ``stability_pc.padded_levels``)."""

    projects_mean = False      #: C^-1 is positive on the mean

    def __init__(self, problem, grid: SurfaceGrid | None = None):
        window, self.op = problem.grid, problem.op
        window.require_slabs("the energy descent on an isolated window")
        self.nx, self.ny = window.nx, window.ny
        if grid is None:
            grid = SurfaceGrid(2 * window.nx, 2 * window.ny, window.dx, window.dy, periodic=True,
                               comm=window.comm, px=1)
        elif (grid.nx, grid.ny, grid.px) != (2 * window.nx, 2 * window.ny, 1):
            raise AssertionError(f"a {grid.nx} x {grid.ny} grid is not the padded grid of a {window.nx} x "
                                 f"{window.ny} window split along y")
        self.grid = grid
        self.fft = grid_rfft(self.grid, threads=self.op.threads, planner=self.op.planner)
        # the operator's padded kernels, laid out for this FFT: the same transform size and the
        # same split of the Fourier columns over the ranks
        if (self.fft.kx_ranges, self.fft.Ny) != (self.op.fft.kx_ranges, self.op.fft.Ny):
            raise AssertionError("the padded grid's spectrum is not laid out as the window operator's")
        # the window's rows are the padded grid's [o, o + ny) (the circulant does not see where):
        # centred, so that on an even split of the padded rows two ranks hold half of them each
        o = self.ny // 2
        ys, ye = self.grid.ys, self.grid.ye
        first, last = min(max(o - ys, 0), ye - ys), min(max(o + self.ny - ys, 0), ye - ys)
        self.window = (slice(first, last), slice(0, self.nx))
        # the window's rows per rank: as the problem splits them, and as this grid does
        self._problem_ranges = list(window.y_ranges)
        self._space_ranges = [(min(max(a - o, 0), self.ny), min(max(b - o, 0), self.ny))
                              for a, b in self.grid.y_ranges]
        self._outside = None         # a padded array for ``outside_gap``

    def convolve(self, kernel_pairs, rows_in, rows_out):
        """A convolution on the padded grid (``kernel_pairs`` in the operator's layout), counted
        as one of the operator's pairs: the same transform on one rank; on several the
        operator's skips the zero rows along x and sends none of them, this one cannot (u
        fills the padded grid), and costs more (about 1.4x on two ranks)."""
        convolve(self.fft, kernel_pairs, rows_in, rows_out)
        self.op.fft.fft_pairs += 1
        return rows_out

    def apply(self, rows_in, rows_out):
        """C of rows on the padded grid (one pair); with ``apply_inverse`` and ``grid`` the padded
        circulant as an operator (the window's stability check, ``stability_window.py``)."""
        return self.convolve(self.op.kernel_pairs, rows_in, rows_out)

    def apply_inverse(self, rows_in, rows_out):
        """C^-1 of rows on the padded grid (one pair)."""
        return self.convolve(self.op.inverse_pairs, rows_in, rows_out)

    def displacement(self, pressure_rows, out_rows):
        """u = C E p [m] on the whole padded grid of a window pressure p [Pa] on the problem's rows."""
        out_rows[...] = 0.0
        out_rows[self.window] = self.from_problem(pressure_rows)
        return self.apply(out_rows, out_rows)

    def _move(self, rows, src, dst):
        """Window rows split as ``src`` (start, stop) per rank, split as ``dst`` (collective)."""
        comm = self.grid.mpi_comm
        rank, nx = comm.Get_rank(), self.nx
        (s0, s1), (d0, d1) = src[rank], dst[rank]
        out = np.empty((d1 - d0, nx))
        send = [max(0, min(s1, b) - max(s0, a)) * nx for a, b in dst]
        recv = [max(0, min(d1, b) - max(d0, a)) * nx for a, b in src]
        offsets = lambda counts: np.concatenate([[0], np.cumsum(counts)[:-1]]).tolist()
        comm.Alltoallv([np.ascontiguousarray(rows), (send, offsets(send)), MPI.DOUBLE],
                       [out, (recv, offsets(recv)), MPI.DOUBLE])
        return out

    def from_problem(self, rows):
        return self._move(rows, self._problem_ranges, self._space_ranges)

    def to_problem(self, block, out_rows):
        np.copyto(out_rows, self._move(block, self._space_ranges, self._problem_ranges))

    def outside_gap(self, pressure_rows) -> float:
        """max over this rank's window nodes of |(C p_out)| [m], p_out the pressure [Pa] on the
        descent's rows ``pressure_rows`` outside the window (which must vanish there): what it
        moves the window's gaps by, the state's gaps under K_w being those without it (one FFT
        pair, collective; the max is the rank's)."""
        if self._outside is None:
            self._outside = np.empty(pressure_rows.shape)
        out = self._outside
        np.copyto(out, pressure_rows)
        out[self.window] = 0.0
        self.apply(out, out)
        return float(np.abs(out[self.window]).max(initial=0.0))

    def create_vec(self):
        """A Vec of the padded grid's rows: no DMDA (its index maps would cost five integers a
        padded node; nothing here needs ghosts)."""
        g = self.grid
        return PETSc.Vec().createMPI((g.n_local, g.nx * g.ny), comm=g.comm)


def descent_space(problem):
    """The space of ``problem``'s descent: its cell, or its window's padded grid."""
    return (CellSpace if problem.grid.periodic else PaddedWindow)(problem)
