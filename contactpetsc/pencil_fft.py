"""Block ("pencil") decomposed real 2-D FFT: the surface split over a px x py process grid.

Rank r = b + px a owns the block of rows [ys, ye) (y-block a) and columns
[xs, xe) (x-block b) of the physical (nx, ny) field, as a C array
(ny_a, nx_b): the layout of a ``SurfaceGrid`` with ``px`` > 1.  The transform
size is (Nx, Ny) = (nx, ny), or (2 nx, 2 ny) with ``pad=True``; transforms are
unnormalised, as ``SlabRFFT``'s.

Forward, by transposes within the row communicator (the px ranks of one
y-block) and the column communicator (the py ranks of one x-block):

    1. row all-to-all: block (ny_a, nx_b) -> x-pencil (m_b, Nx), the b-th of
       px sub-blocks of the y-block's rows, with every column (sent straight
       from the input rows: no packing);
    2. a batch of real FFTs along x: (m_b, nkx), nkx = Nx/2 + 1;
    3. row all-to-all: -> (ny_a, nkx_b), the y-block's rows and the b-th of px
       blocks of Fourier columns (received straight into place);
    4. column all-to-all: -> (nkx_loc, ny), the a-th of py sub-blocks of those
       columns with every row, into the (nkx_loc, Ny) y-stage input;
    5. a batch of complex FFTs along y.

Each rank's Fourier columns [kx0, kx1) are contiguous, so the spectrum has
``SlabRFFT``'s multi-rank layout (nkx_loc, Ny) and its ``wavevectors``,
``spectral_layout`` and ``hermitian_weights``: kernels do not depend on the
decomposition.  Backward runs the same steps in reverse.  With px = 1 the
steps 1-3 are local and this is the slab algorithm.

Messages per transform and rank: 2 (px - 1) + (py - 1), against P - 1 for the
slab; bytes about 3x the slab's (docs/performance.md, the cluster model).
"""
from __future__ import annotations

import numpy as np
import pyfftw
from mpi4py import MPI

from .fft import PLANNER_FLAGS, SlabRFFT, split_range
from .log_events import log_event

_SUBCOMMS: dict = {}


def _sub_communicators(comm: MPI.Comm, px: int):
    """(row, column) communicators of the px x py process grid; made once per communicator
    (every grid of a hierarchy, every operator shares them)."""
    key = (comm.py2f(), comm.Get_size(), px)
    if key not in _SUBCOMMS:
        rank = comm.Get_rank()
        b, a = rank % px, rank // px
        _SUBCOMMS[key] = (comm.Split(a, b), comm.Split(b, a))
    return _SUBCOMMS[key]


def _offsets(counts) -> list[int]:
    return np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(int).tolist()


class PencilRFFT(SlabRFFT):
    """Distributed real FFT of an (nx, ny) field stored in px x py blocks.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm
        px * py ranks.
    nx, ny : int
        Physical grid size.
    x_ranges, y_ranges : list of (start, stop)
        Columns of each x-block (px of them) and rows of each y-block (py), from the grid.
    pad, threads, planner
        As for ``SlabRFFT``.
    """

    def __init__(self, comm: MPI.Comm, nx: int, ny: int, x_ranges, y_ranges, *, pad: bool = False,
                 threads: int = 1, planner: str = "measure"):
        if planner not in PLANNER_FLAGS:
            raise ValueError(f"fft planner must be one of {sorted(PLANNER_FLAGS)}, got {planner!r}")
        self.comm = comm
        self.size, self.rank = comm.Get_size(), comm.Get_rank()
        self.x_ranges, self.y_ranges = list(x_ranges), list(y_ranges)
        px, py = self.px, self.py = len(self.x_ranges), len(self.y_ranges)
        if px * py != self.size:
            raise ValueError(f"a {px} x {py} process grid needs {px * py} ranks, the communicator has {self.size}")
        self.nx, self.ny, self.pad = nx, ny, pad
        self.Nx, self.Ny = (2 * nx, 2 * ny) if pad else (nx, ny)
        self.nkx = self.Nx // 2 + 1
        b, a = self.rank % px, self.rank // px
        self.xs, self.xe = self.x_ranges[b]
        self.ys, self.ye = self.y_ranges[a]
        nyb, nxb = self.ye - self.ys, self.xe - self.xs
        # rows of the y-block per rank of the row (x stage), Fourier columns per x-block
        # and per rank of the column (y stage)
        self.sub_ranges = split_range(nyb, px)
        self.kxb_ranges = split_range(self.nkx, px)
        kb0, kb1 = self.kxb_ranges[b]
        nkb = kb1 - kb0
        self.kx_sub = split_range(nkb, py)
        self.kx_ranges = []
        for r in range(self.size):
            k0 = self.kxb_ranges[r % px][0]
            lo, hi = split_range(self.kxb_ranges[r % px][1] - k0, py)[r // px]
            self.kx_ranges.append((k0 + lo, k0 + hi))
        self.kx0, self.kx1 = self.kx_ranges[self.rank]
        fits = (min(e - s for s, e in self.sub_ranges) >= 1
                and min(e - s for s, e in self.kx_sub) >= 1)
        if not comm.allreduce(bool(fits), op=MPI.LAND):
            raise ValueError(f"a {px} x {py} process grid does not fit a {nx} x {ny} grid: every y-block "
                             f"needs >= {px} rows and every x-block of the {self.nkx} Fourier columns "
                             f">= {py} columns")
        self.row_comm, self.col_comm = _sub_communicators(comm, px)
        self.fft_pairs = 0
        self.alltoall_bytes = 0   # payload passed to Alltoallv by this rank, self-blocks excluded
        empty = pyfftw.empty_aligned
        m0, m1 = self.sub_ranges[b]
        m = m1 - m0
        nkx_loc = self.kx1 - self.kx0
        self.block_shape = (nyb, nxb)

        self.real_in = empty((m, self.Nx), "float64")         # x-stage input, zero beyond nx
        self.real_out = self.real_in if not pad else empty((m, self.Nx), "float64")
        self.rows = empty((m, self.nkx), "complex128")
        self.band = empty((nyb, nkb), "complex128")            # the y-block's rows, x-block's kx
        self.cols = empty((nkx_loc, self.Ny), "complex128")   # y-stage input, zero beyond ny
        self.spectrum = empty((nkx_loc, self.Ny), "complex128")
        self.xbuf = empty(m * nx, "float64")                   # x-pencil pieces, per x-block
        self.kbuf = empty(m * self.nkx, "complex128")          # x-pencil spectrum, per kx-block
        self.tbuf = empty(nyb * nkb, "complex128")             # the band transposed, per rank of the column
        self.ybuf = empty(nkx_loc * ny, "complex128")          # column pieces, per y-block
        self._out = None                                       # backward output when out_rows is not contiguous

        widths = [e - s for s, e in self.x_ranges]
        kwidths = [e - s for s, e in self.kxb_ranges]
        heights = [e - s for s, e in self.sub_ranges]
        ksub = [e - s for s, e in self.kx_sub]
        yheights = [e - s for s, e in self.y_ranges]
        self.x_blocks = [self.xbuf[m * s:m * e].reshape(m, e - s) for s, e in self.x_ranges]
        self.k_blocks = [self.kbuf[m * s:m * e].reshape(m, e - s) for s, e in self.kxb_ranges]
        self.t_blocks = [self.tbuf[nyb * s:nyb * e].reshape(e - s, nyb) for s, e in self.kx_sub]
        w = ksub[a]
        self.y_blocks = [self.ybuf[w * s:w * e].reshape(w, e - s) for s, e in self.y_ranges]
        d, z = MPI.DOUBLE, MPI.C_DOUBLE_COMPLEX
        # (counts, offsets, type) of each side; the buffers are bound at the call
        self._spec1 = (([h * nxb for h in heights], _offsets([h * nxb for h in heights]), d),
                       ([m * wd for wd in widths], _offsets([m * wd for wd in widths]), d))
        self._spec2 = (([m * k for k in kwidths], _offsets([m * k for k in kwidths]), z),
                       ([h * nkb for h in heights], _offsets([h * nkb for h in heights]), z))
        self._spec3 = (([k * nyb for k in ksub], _offsets([k * nyb for k in ksub]), z),
                       ([w * h for h in yheights], _offsets([w * h for h in yheights]), z))
        # per direction: what this rank sends (forward); backward sends what forward received
        self._sent_fwd = (8 * (sum(self._spec1[0][0]) - self._spec1[0][0][b])
                          + 16 * (sum(self._spec2[0][0]) - self._spec2[0][0][b])
                          + 16 * (sum(self._spec3[0][0]) - self._spec3[0][0][a]))
        self._sent_bwd = (8 * (sum(self._spec1[1][0]) - self._spec1[1][0][b])
                          + 16 * (sum(self._spec2[1][0]) - self._spec2[1][0][b])
                          + 16 * (sum(self._spec3[1][0]) - self._spec3[1][0][a]))
        self._plan_stages(threads, planner)
        self.real_in[...] = 0
        self.cols[...] = 0

    @staticmethod
    def _exchange(comm, send, send_spec, recv, recv_spec):
        comm.Alltoallv([send, send_spec[:2], send_spec[2]], [recv, recv_spec[:2], recv_spec[2]])

    def forward(self, rows: np.ndarray) -> np.ndarray:
        """Spectrum of the local (ny_a, nx_b) block into ``self.spectrum`` (unnormalised)."""
        ev = log_event("CPFFTForward")
        ev.begin()
        block = np.ascontiguousarray(rows, dtype=np.float64)
        s1, s2, s3 = self._spec1, self._spec2, self._spec3
        self._exchange(self.row_comm, block, s1[0], self.xbuf, s1[1])
        for (a, b), blk in zip(self.x_ranges, self.x_blocks):
            np.copyto(self.real_in[:, a:b], blk)
        self._plans[0].execute()
        for (a, b), blk in zip(self.kxb_ranges, self.k_blocks):
            np.copyto(blk, self.rows[:, a:b])
        self._exchange(self.row_comm, self.kbuf, s2[0], self.band, s2[1])
        for (a, b), blk in zip(self.kx_sub, self.t_blocks):
            np.copyto(blk, self.band[:, a:b].T)
        self._exchange(self.col_comm, self.tbuf, s3[0], self.ybuf, s3[1])
        for (a, b), blk in zip(self.y_ranges, self.y_blocks):
            np.copyto(self.cols[:, a:b], blk)
        self._plans[1].execute()
        self.alltoall_bytes += self._sent_fwd
        ev.end()
        return self.spectrum

    def backward(self, out_rows: np.ndarray) -> np.ndarray:
        """Inverse transform of ``self.spectrum`` (destroyed) into ``out_rows`` (ny_a, nx_b), unnormalised."""
        ev = log_event("CPFFTBackward")
        ev.begin()
        s1, s2, s3 = self._spec1, self._spec2, self._spec3
        self._plans_bwd[0].execute()
        for (a, b), blk in zip(self.y_ranges, self.y_blocks):
            np.copyto(blk, self.cols[:, a:b])
        if self.pad:
            self.cols[:, self.ny:] = 0  # the y stage's output overwrote the padding
        self._exchange(self.col_comm, self.ybuf, s3[1], self.tbuf, s3[0])
        for (a, b), blk in zip(self.kx_sub, self.t_blocks):
            np.copyto(self.band[:, a:b], blk.T)
        self._exchange(self.row_comm, self.band, s2[1], self.kbuf, s2[0])
        for (a, b), blk in zip(self.kxb_ranges, self.k_blocks):
            np.copyto(self.rows[:, a:b], blk)
        self._plans_bwd[1].execute()
        for (a, b), blk in zip(self.x_ranges, self.x_blocks):
            np.copyto(blk, self.real_out[:, a:b])
        direct = out_rows.flags.c_contiguous and out_rows.dtype == np.float64
        if not direct and self._out is None:
            self._out = pyfftw.empty_aligned(self.block_shape[0] * self.block_shape[1], "float64")
        target = out_rows if direct else self._out
        self._exchange(self.row_comm, self.xbuf, s1[1], target, s1[0])
        if not direct:
            np.copyto(out_rows, self._out.reshape(self.block_shape))
        self.alltoall_bytes += self._sent_bwd
        ev.end()
        self.fft_pairs += 1
        return out_rows


def grid_rfft(grid, *, pad: bool = False, threads: int = 1, planner: str = "measure") -> SlabRFFT:
    """The distributed FFT of a ``SurfaceGrid``'s split: slabs, or pencils on a block grid."""
    if grid.px > 1:
        return PencilRFFT(grid.mpi_comm, grid.nx, grid.ny, grid.x_ranges, grid.y_ranges,
                          pad=pad, threads=threads, planner=planner)
    return SlabRFFT(grid.mpi_comm, grid.nx, grid.ny, grid.y_ranges, pad=pad, threads=threads,
                    planner=planner)
