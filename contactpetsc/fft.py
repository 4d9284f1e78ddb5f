"""Slab-decomposed real 2-D FFT with pyfftw and MPI all-to-all transposes.

The physical field is distributed in y-slabs: rank r owns rows j in
[ys, ye) with all x, as a C array (ny_loc, nx).  The transform size is
(Nx, Ny) = (nx, ny), or (2 nx, 2 ny) with ``pad=True`` (zero padding for the
linear convolution of isolated contacts).  Transforms are unnormalised; the
operators fold 1/(Nx Ny) into their kernels.

One rank
    FFTW's own 2-D r2c/c2r plans on the whole (padded) array.  The spectrum is
    laid out (Ny, Nx//2+1): axis 0 = ky, axis 1 = kx.

Several ranks
    1. a batch of real FFTs along x on the local rows (contiguous),
    2. pack: each other rank's kx columns, transposed to (nkx_q, ny_loc); the
       rank's own columns are copied (transposed) straight into its y-range,
    3. a contiguous all-to-all, then each received (nkx_loc, ny_q) block is
       copied into its y-range of the (nkx_loc, Ny) array,
    4. a batch of complex FFTs along y (contiguous).
    The spectrum is laid out (nkx_loc, Ny): axis 0 = this rank's kx, axis 1 = ky.
    Zero rows of the padding are neither transformed along x nor sent.

Both layouts are reached through ``spectral_layout``/``wavevectors``, so
kernels never depend on the rank count.  All buffers and FFTW plans are made
once in the constructor; ``forward`` and ``backward`` allocate nothing.
"""
from __future__ import annotations

import numpy as np
import pyfftw
from mpi4py import MPI

from .log_events import log_event


def split_range(n: int, parts: int) -> list[tuple[int, int]]:
    """Split range(n) into ``parts`` contiguous blocks, the first n % parts one longer (PETSc's rule)."""
    base, extra = divmod(n, parts)
    out, start = [], 0
    for r in range(parts):
        stop = start + base + (1 if r < extra else 0)
        out.append((start, stop))
        start = stop
    return out


PLANNER_FLAGS = {"estimate": "FFTW_ESTIMATE", "measure": "FFTW_MEASURE",
                 "patient": "FFTW_PATIENT", "exhaustive": "FFTW_EXHAUSTIVE"}


def plan_flags(threads: int, planner: str) -> tuple[dict, dict]:
    """FFTW plan keywords: forward plans keep their input (it holds the zero padding),
    backward plans may destroy theirs."""
    flag = PLANNER_FLAGS[planner]
    return dict(threads=threads, flags=(flag,)), dict(threads=threads, flags=(flag, "FFTW_DESTROY_INPUT"))


class SlabRFFT:
    """Distributed real FFT of an (nx, ny) field stored in y-slabs.

    Parameters
    ----------
    comm : mpi4py.MPI.Comm
    nx, ny : int
        Physical grid size.
    y_ranges : list of (start, stop)
        Rows owned by each rank (from the DMDA).
    pad : bool
        Zero-pad to (2 nx, 2 ny) for linear convolution.
    threads : int
        FFTW threads per rank.
    planner : str
        FFTW planner effort: estimate, measure, patient, exhaustive.
    """

    def __init__(self, comm: MPI.Comm, nx: int, ny: int, y_ranges, *, pad: bool = False,
                 threads: int = 1, planner: str = "measure"):
        if planner not in PLANNER_FLAGS:
            raise ValueError(f"fft planner must be one of {sorted(PLANNER_FLAGS)}, got {planner!r}")
        self.comm = comm
        self.size, self.rank = comm.Get_size(), comm.Get_rank()
        self.nx, self.ny, self.pad = nx, ny, pad
        self.Nx, self.Ny = (2 * nx, 2 * ny) if pad else (nx, ny)
        self.nkx = self.Nx // 2 + 1
        self.y_ranges = list(y_ranges)
        if self.size > self.nkx:
            raise ValueError(f"{self.size} ranks exceed the {self.nkx} Fourier columns of the grid")
        self.kx_ranges = split_range(self.nkx, self.size)
        self.ys, self.ye = self.y_ranges[self.rank]
        self.kx0, self.kx1 = self.kx_ranges[self.rank]
        self.fft_pairs = 0
        self.alltoall_bytes = 0   # payload passed to Alltoallv by this rank, self-block excluded
        keep, kill = plan_flags(threads, planner)
        empty = pyfftw.empty_aligned
        ny_loc, nkx_loc = self.ye - self.ys, self.kx1 - self.kx0

        # without padding the forward input is rewritten whole at every apply, so the
        # backward transform may write into it: one large buffer fewer in cache
        if self.size == 1:
            self.real_in = empty((self.Ny, self.Nx), "float64")
            self.real_out = self.real_in if not pad else empty((self.Ny, self.Nx), "float64")
            self.spectrum = empty((self.Ny, self.nkx), "complex128")
            self._plans = (pyfftw.FFTW(self.real_in, self.spectrum, axes=(0, 1), **keep),)
            self._plans_bwd = (pyfftw.FFTW(self.spectrum, self.real_out, axes=(0, 1),
                                           direction="FFTW_BACKWARD", **kill),)
        else:
            self.real_in = empty((ny_loc, self.Nx), "float64")
            self.real_out = self.real_in if not pad else empty((ny_loc, self.Nx), "float64")
            self.rows = empty((ny_loc, self.nkx), "complex128")
            self.cols = empty((nkx_loc, self.Ny), "complex128")   # y-stage input, zero beyond ny
            self.spectrum = empty((nkx_loc, self.Ny), "complex128")
            # Contiguous all-to-all with local (un)packing: on shared memory faster than
            # Alltoallw with strided datatypes (docs/performance.md).  The rank's own block
            # is copied straight between rows and cols, not through the buffers and MPI.
            widths = [b - a for a, b in self.kx_ranges]
            heights = [b - a for a, b in self.y_ranges]
            own = [q == self.rank for q in range(self.size)]
            send_counts = [0 if mine else ny_loc * w for w, mine in zip(widths, own)]
            recv_counts = [0 if mine else nkx_loc * h for h, mine in zip(heights, own)]
            send_off = np.concatenate([[0], np.cumsum(send_counts)]).tolist()
            recv_off = np.concatenate([[0], np.cumsum(recv_counts)]).tolist()
            self.sendbuf = empty(send_off[-1], "complex128")
            self.recvbuf = empty(recv_off[-1], "complex128")
            # to rank q: my rows' kx columns of q, transposed to (nkx_q, ny_loc);
            # from rank q: my kx columns of q's rows, (nkx_loc, ny_q)
            self.peers = [q for q in range(self.size) if q != self.rank]
            self.send_blocks = [self.sendbuf[send_off[q]:send_off[q + 1]].reshape(widths[q], ny_loc)
                                for q in self.peers]
            self.recv_blocks = [self.recvbuf[recv_off[q]:recv_off[q + 1]].reshape(nkx_loc, heights[q])
                                for q in self.peers]
            # backward, the same memory the other way round: to rank q its rows of my kx
            # columns, packed y-major (ny_q, nkx_loc); from rank q my rows of its columns,
            # (ny_loc, nkx_q).  The transpose is a strided read on the sender, cheaper than
            # the strided write an unpack would make.
            self.send_blocks_bwd = [self.recvbuf[recv_off[q]:recv_off[q + 1]].reshape(heights[q], nkx_loc)
                                    for q in self.peers]
            self.recv_blocks_bwd = [self.sendbuf[send_off[q]:send_off[q + 1]].reshape(ny_loc, widths[q])
                                    for q in self.peers]
            z = MPI.C_DOUBLE_COMPLEX
            self._fwd = ([self.sendbuf, (send_counts, send_off[:-1]), z],
                         [self.recvbuf, (recv_counts, recv_off[:-1]), z])
            self._bwd = (self._fwd[1], self._fwd[0])
            itemsize = self.sendbuf.itemsize
            self._sent_fwd = itemsize * sum(send_counts)
            self._sent_bwd = itemsize * sum(recv_counts)
            self._plan_stages(threads, planner)
        # planning may scribble on the buffers: zero what must start at zero
        self.real_in[...] = 0
        if self.size > 1:
            self.cols[...] = 0

    # -- spectral layout -----------------------------------------------------

    def _plan_stages(self, threads, planner) -> None:
        """The 1-D FFTW plans of the transposed transform: along x of the real rows and along
        y of the columns, forward (inputs kept) and backward (inputs destroyed)."""
        keep, kill = plan_flags(threads, planner)
        self._plans = (pyfftw.FFTW(self.real_in, self.rows, axes=(1,), **keep),
                       pyfftw.FFTW(self.cols, self.spectrum, axes=(1,), **keep))
        self._plans_bwd = (pyfftw.FFTW(self.spectrum, self.cols, axes=(1,), direction="FFTW_BACKWARD", **kill),
                           pyfftw.FFTW(self.rows, self.real_out, axes=(1,), direction="FFTW_BACKWARD", **kill))

    def spectral_layout(self, kx_ky: np.ndarray) -> np.ndarray:
        """Put an array indexed [kx_local, ky] (shape (nkx_local, Ny)) into the spectrum's layout."""
        kx_ky = np.asarray(kx_ky)
        return np.ascontiguousarray(kx_ky.T if self.size == 1 else kx_ky)

    def wavevectors(self, lx: float, ly: float) -> tuple[np.ndarray, np.ndarray]:
        """(qx, qy) [rad/m] of the local spectrum for a cell lx x ly, in the spectrum's layout."""
        qx = 2 * np.pi * np.fft.rfftfreq(self.Nx, d=lx / self.Nx)[self.kx0:self.kx1]
        qy = 2 * np.pi * np.fft.fftfreq(self.Ny, d=ly / self.Ny)
        QX, QY = np.meshgrid(qx, qy, indexing="ij")
        return self.spectral_layout(QX), self.spectral_layout(QY)

    def hermitian_weights(self) -> np.ndarray:
        """Multiplicity of each local rfft mode in the full spectrum (1 or 2), spectrum layout."""
        kx = np.arange(self.kx0, self.kx1)
        w = np.where((kx == 0) | (2 * kx == self.Nx), 1.0, 2.0)
        return self.spectral_layout(np.repeat(w[:, None], self.Ny, axis=1))

    # -- transforms ------------------------------------------------------------
    def forward(self, rows: np.ndarray) -> np.ndarray:
        """Spectrum of the local (ny_loc, nx) rows into ``self.spectrum`` (unnormalised)."""
        ev = log_event("CPFFTForward")
        ev.begin()
        if self.size == 1:
            self.real_in[:self.ny, :self.nx] = rows
            self._plans[0].execute()
        else:
            self.real_in[:, :self.nx] = rows
            self._plans[0].execute()
            for q, blk in zip(self.peers, self.send_blocks):
                a, b = self.kx_ranges[q]
                np.copyto(blk, self.rows[:, a:b].T)
            np.copyto(self.cols[:, self.ys:self.ye], self.rows[:, self.kx0:self.kx1].T)
            self.comm.Alltoallv(*self._fwd)
            self.alltoall_bytes += self._sent_fwd
            for q, blk in zip(self.peers, self.recv_blocks):
                a, b = self.y_ranges[q]
                np.copyto(self.cols[:, a:b], blk)
            self._plans[1].execute()
        ev.end()
        return self.spectrum

    def backward(self, out_rows: np.ndarray) -> np.ndarray:
        """Inverse transform of ``self.spectrum`` (destroyed) into ``out_rows`` (ny_loc, nx), unnormalised."""
        ev = log_event("CPFFTBackward")
        ev.begin()
        if self.size == 1:
            self._plans_bwd[0].execute()
            np.copyto(out_rows, self.real_out[:self.ny, :self.nx])
        else:
            self._plans_bwd[0].execute()
            for q, blk in zip(self.peers, self.send_blocks_bwd):
                a, b = self.y_ranges[q]
                np.copyto(blk, self.cols[:, a:b].T)
            np.copyto(self.rows[:, self.kx0:self.kx1], self.cols[:, self.ys:self.ye].T)
            if self.pad:
                self.cols[:, self.ny:] = 0  # the y stage's output overwrote the padding
            self.comm.Alltoallv(*self._bwd)
            self.alltoall_bytes += self._sent_bwd
            for q, blk in zip(self.peers, self.recv_blocks_bwd):
                a, b = self.kx_ranges[q]
                np.copyto(self.rows[:, a:b], blk)
            self._plans_bwd[1].execute()
            np.copyto(out_rows, self.real_out[:, :self.nx])
        ev.end()
        self.fft_pairs += 1
        return out_rows
