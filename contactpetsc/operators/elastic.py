"""Elastic half-space operators as Python-context PETSc Mats (v = K p, eq. 3).

Both kinds cost one distributed FFT pair per apply.

Periodic cell (``PeriodicHalfSpace``)
    K is diagonal in Fourier space.  We use the continuum kernel
    K(q) = 2 / (E* |q|) sampled at the cell's wavevectors, not the periodised
    Love kernel.  Reasons: it is exact for the band-limited pressure that the
    nodal values define, so a sinusoidal pressure gives the exact Westergaard
    amplitude; it is the kernel of the peer codes (Tamaas, contact.engineering),
    so a benchmark against them solves the same discrete problem; and the two
    differ only near the grid's Nyquist wavelength, where a converged contact
    solution must not depend on the choice anyway.  The mean (q = 0) mode has
    no bounded displacement on an infinite periodic half-space; K maps it to 0
    and the rigid-body approach (or the load, under load control) fixes it.
    K^-1 = E* |q| / 2 is the inverse on zero-mean fields and returns zero-mean
    pressures.

Finite layer on a rigid base (``PeriodicLayer``, periodic cells only)
    K(q) = 2 f(|q| t) / (E* |q|), f the layer's factor (``layer.py``; bonded or frictionless
    base), f -> 1 for |q| t -> inf.  The mean mode is treated as for the half-space.

Isolated contact (``IsolatedHalfSpace``)
    Love's influence coefficients (``love.py``) for the physical nx x ny
    window, convolved linearly by zero padding to 2nx x 2ny (a circulant of
    the padded size).  The padded circulant's spectrum is computed without a
    padded FFT: its coefficients are even in x and y, so the spectrum is the
    2-D DCT-I of the coefficients for offsets 0..nx, 0..ny.  Its inverse,
    1/K_hat on the padded grid, restricted to the window, is a cheap
    approximation of the window operator's inverse (the Stanley-Kato
    preconditioner); it is exact for the padded circulant only.
"""
from __future__ import annotations

import numpy as np
import pyfftw
from mpi4py import MPI
from petsc4py import PETSc

from ..pencil_fft import grid_rfft
from ..log_events import log_event
from ..collective import collective_guard
from ..grid import SurfaceGrid
from ..lifetime import destroy_at_exit
from .layer import Layer, check_thickness
from .love import love_displacement


def fft_threads(comm, value, name: str = "fft_threads") -> int:
    """FFTW threads per rank: an integer >= 1, or ``auto``: the cores this rank may run on
    (its CPU affinity), shared with the other ranks of its node when they see the same cores;
    1 for ranks bound to one core each, all of a node's cores for one rank per node."""
    if str(value).lower() == "auto":
        import os
        cores = len(os.sched_getaffinity(0))
        node = comm.Split_type(MPI.COMM_TYPE_SHARED)
        ranks = node.Get_size()
        node.Free()
        return max(1, cores // ranks if cores >= (os.cpu_count() or cores) else cores)
    try:
        n = int(value)
    except ValueError:
        n = 0
    if n < 1:
        raise ValueError(f"{name} must be an integer >= 1 or auto, got {value!r}")
    return n


def convolve(fft, kernel_pairs: np.ndarray, rows_in: np.ndarray, rows_out: np.ndarray) -> np.ndarray:
    """rows_out = the transform ``fft``'s convolution of rows_in with a real spectrum given as
    (re, im) pairs (``HalfSpaceOperator.as_pairs``); one FFT pair."""
    spec = fft.forward(rows_in)
    pairs = spec.view(np.float64).reshape(kernel_pairs.shape)
    np.multiply(pairs, kernel_pairs, out=pairs)
    return fft.backward(rows_out)


class HalfSpaceOperator:
    """Common part: v = K p and its inverse through one distributed FFT pair.

    Subclasses set ``self.kernel`` (K_hat / (Nx Ny), spectral layout of
    ``self.fft``), ``self.inverse_kernel`` and ``self.self_influence`` (K_ii).
    """

    def __init__(self, grid: SurfaceGrid, e_star: float, *, pad: bool,
                 threads: int | None = None, planner: str | None = None,
                 prefix: str = "elastic_"):
        if not (np.isfinite(e_star) and e_star > 0):
            raise ValueError(f"e_star (effective modulus E*, Pa) must be finite and > 0, got {e_star!r}")
        opts = PETSc.Options(prefix)
        threads = opts.getString("fft_threads", str(1 if threads is None else threads))
        threads = fft_threads(grid.mpi_comm, threads, f"{prefix}fft_threads")
        planner = opts.getString("fft_planner", "measure" if planner is None else planner)
        self.grid, self.e_star, self.prefix = grid, float(e_star), prefix
        self.threads, self.planner = threads, planner
        self.fft = grid_rfft(grid, pad=pad, threads=threads, planner=planner)

    def on_grid(self, grid: SurfaceGrid, **kw) -> "HalfSpaceOperator":
        """The same elastic body discretised on another grid (the coarse grids of the nested
        iteration and of MLMI); ``kw`` as for the constructor."""
        return type(self)(grid, self.e_star, **kw)

    def _set_pairs(self):
        # the kernels are kept only as views of their pairs (one double per point less each)
        self._kernel_pairs = self.as_pairs(self.kernel)
        self.kernel = self._kernel_pairs[..., 0]
        self._inverse_pairs = self.as_pairs(self.inverse_kernel)
        self.inverse_kernel = self._inverse_pairs[..., 0]

    @property
    def kernel_pairs(self) -> np.ndarray:
        """K's spectrum in the pair layout of ``convolve`` (read-only use)."""
        return self._kernel_pairs

    @property
    def inverse_pairs(self) -> np.ndarray:
        """K^-1's spectrum in the pair layout of ``convolve`` (read-only use)."""
        return self._inverse_pairs

    @property
    def fft_pairs(self) -> int:
        """FFT pairs done so far (one per apply): the unit of cost."""
        return self.fft.fft_pairs

    def lowest_mode_stiffness(self) -> float:
        """min over modes of 1/K_hat [Pa/m] (the mean mode of a periodic cell left out):
        E*|q_min|/2 on a periodic half-space, 1/K_hat(0) when isolated; collective."""
        norm = 1.0 / (self.fft.Nx * self.fft.Ny)
        inv = self.inverse_kernel
        local = float(inv[inv > 0].min()) if (inv > 0).any() else np.inf
        return self.grid.mpi_comm.allreduce(local, op=MPI.MIN) / norm

    @staticmethod
    def as_pairs(kernel: np.ndarray) -> np.ndarray:
        """A real kernel duplicated for (re, im) pairs: a float*float multiply, faster than
        numpy's complex*real loop, for one extra double per grid point."""
        return np.ascontiguousarray(np.repeat(kernel[..., None], 2, axis=-1))

    def convolve(self, kernel_pairs: np.ndarray, rows_in: np.ndarray, rows_out: np.ndarray) -> np.ndarray:
        return convolve(self.fft, kernel_pairs, rows_in, rows_out)

    def apply(self, pressure_rows: np.ndarray, out_rows: np.ndarray) -> np.ndarray:
        """Displacement v = K p [m] for pressure p [Pa], both local (ny_loc, nx_loc) rows."""
        ev = log_event("CPElasticMult")
        ev.begin()
        self.convolve(self._kernel_pairs, pressure_rows, out_rows)
        ev.end()
        return out_rows

    def apply_inverse(self, displacement_rows: np.ndarray, out_rows: np.ndarray) -> np.ndarray:
        """Pressure p = K^-1 v [Pa] (see the class notes for where K^-1 is exact)."""
        ev = log_event("CPElasticSolve")
        ev.begin()
        self.convolve(self._inverse_pairs, displacement_rows, out_rows)
        ev.end()
        return out_rows

    def as_mat(self, inverse: bool = False) -> PETSc.Mat:
        """K (or K^-1) as a matrix-free Python-context Mat on the grid's global Vecs."""
        n_local = self.grid.n_local
        n = self.grid.nx * self.grid.ny
        mat = PETSc.Mat().createPython(((n_local, n), (n_local, n)),
                                       _OperatorContext(self, inverse), comm=self.grid.comm)
        mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        mat.setUp()
        return destroy_at_exit(mat)

    def as_dense(self, inverse: bool = False) -> np.ndarray:
        """K [m/Pa] (or K^-1) as a dense (n, n) matrix in global row-major order, one apply per
        column; every rank holds it (collective).  For small grids: the coarsest level of a
        multilevel cycle, and tests."""
        g = self.grid
        n = g.nx * g.ny
        e = np.zeros((g.ny_local, g.nx))
        out = np.empty_like(e)
        dense = np.zeros((n, n))
        apply = self.apply_inverse if inverse else self.apply
        for col in range(n):
            e[...] = 0.0
            jc, ic = divmod(col, g.nx)
            if g.ys <= jc < g.ye:
                e[jc - g.ys, ic] = 1.0
            apply(e, out)
            dense[:, col] = np.concatenate(g.mpi_comm.allgather(out.reshape(-1)))
        return dense

    def spectral_sum(self, kernel_hat: np.ndarray) -> float:
        """(1 / (Nx Ny)) * sum over all modes of a real, even spectrum given on the rfft half."""
        local = float(np.sum(kernel_hat * self.fft.hermitian_weights()))
        return self.grid.mpi_comm.allreduce(local) / (self.fft.Nx * self.fft.Ny)


class _OperatorContext:
    """Python-context Mat: applies K (or K^-1) through the FFT; K is symmetric."""

    def __init__(self, op: HalfSpaceOperator, inverse: bool):
        self.op, self.inverse = op, inverse

    @collective_guard
    def mult(self, mat, x, y):
        g = self.op.grid
        f = self.op.apply_inverse if self.inverse else self.op.apply
        f(g.rows(x, readonly=True), g.rows(y))

    multTranspose = mult

    @collective_guard
    def getDiagonal(self, mat, d):
        if self.inverse:
            raise NotImplementedError("diagonal of K^-1")
        d.set(self.op.self_influence)


class PeriodicHalfSpace(HalfSpaceOperator):
    """Periodic elastic half-space, K_hat(q) = 2 / (E* |q|), mean mode -> 0."""

    def __init__(self, grid: SurfaceGrid, e_star: float, **kw):
        if not grid.periodic:
            raise ValueError(f"{type(self).__name__} needs a periodic grid")
        super().__init__(grid, e_star, pad=False, **kw)
        lx, ly = grid.lengths
        qx, qy = self.fft.wavevectors(lx, ly)
        q = np.hypot(qx, qy)
        norm = 1.0 / (self.fft.Nx * self.fft.Ny)
        depth = self.depth_factor(q)
        with np.errstate(divide="ignore", invalid="ignore"):
            k_hat = np.where(q > 0, 2.0 / (self.e_star * q) * depth, 0.0)
            self.inverse_kernel = np.where(q > 0, 0.5 * self.e_star * q / depth, 0.0) * norm
        self.kernel = k_hat * norm
        self._set_pairs()
        self.self_influence = self.spectral_sum(k_hat)

    def depth_factor(self, q: np.ndarray):
        """f(|q| t) of a body of finite depth (``PeriodicLayer``); 1 for the half-space."""
        return 1.0


class PeriodicLayer(PeriodicHalfSpace):
    """Periodic elastic layer of thickness t on a rigid base (``layer.py``):
    K_hat(q) = 2 f(|q| t) / (E* |q|), mean mode -> 0 as for the half-space (the layer's uniform
    compression by the mean pressure is a rigid shift, taken up by the approach)."""

    def __init__(self, grid: SurfaceGrid, e_star: float, layer: Layer, **kw):
        if not isinstance(layer, Layer):
            raise ValueError(f"layer must be a contactpetsc.operators.Layer, got {layer!r}")
        check_thickness(layer, grid.lengths)
        self.layer = layer
        super().__init__(grid, e_star, **kw)

    def depth_factor(self, q):
        return self.layer.factor(q)

    def on_grid(self, grid: SurfaceGrid, **kw) -> "PeriodicLayer":
        return PeriodicLayer(grid, self.e_star, self.layer, **kw)


class IsolatedHalfSpace(HalfSpaceOperator):
    """Isolated half-space: Love coefficients, linear convolution on the 2nx x 2ny padded grid."""

    def __init__(self, grid: SurfaceGrid, e_star: float, **kw):
        super().__init__(grid, e_star, pad=True, **kw)
        nx, ny, dx, dy = grid.nx, grid.ny, grid.dx, grid.dy
        # coefficients for offsets (m dx, l dy), m = 0..nx, l = 0..ny: the even padded
        # circulant's spectrum is their 2-D DCT-I (FFTW REDFT00, unnormalised).
        m = np.arange(nx + 1) * dx
        l = np.arange(ny + 1) * dy
        coeff = love_displacement(m[None, :], l[:, None], 0.5 * dx, 0.5 * dy, self.e_star)
        self.self_influence = float(coeff[0, 0])
        f = self.fft
        along_x = pyfftw.empty_aligned(coeff.shape, "float64")
        pyfftw.FFTW(coeff, along_x, axes=(1,), direction="FFTW_REDFT00", flags=("FFTW_ESTIMATE",))()
        cols = np.ascontiguousarray(along_x[:, f.kx0:f.kx1])
        half = np.empty_like(cols)
        pyfftw.FFTW(cols, half, axes=(0,), direction="FFTW_REDFT00", flags=("FFTW_ESTIMATE",))()
        # ky = ny+1..2ny-1 mirror ky = ny-1..1; then [ky, kx] -> the spectrum's layout
        k_hat = f.spectral_layout(np.concatenate([half, half[-2:0:-1]], axis=0).T)
        k_min = grid.mpi_comm.allreduce(float(k_hat.min()), op=MPI.MIN)
        if not k_min > 0:
            raise ArithmeticError(f"padded Love circulant is not positive definite (min eigenvalue {k_min:g})")
        norm = 1.0 / (f.Nx * f.Ny)
        self.kernel = k_hat * norm
        self.inverse_kernel = norm / k_hat
        self._set_pairs()
        self.min_eigenvalue = k_min


def half_space(grid: SurfaceGrid, e_star: float, layer: Layer | None = None, **kw) -> HalfSpaceOperator:
    """The elastic operator that fits the grid: periodic cell or isolated window, or with
    ``layer`` a finite layer on a rigid base (periodic cells only)."""
    if layer is not None:
        if not grid.periodic:
            raise ValueError("a finite elastic layer (layer thickness) needs a periodic cell: its kernel "
                             "is a Fourier kernel; set periodic = true")
        return PeriodicLayer(grid, e_star, layer, **kw)
    return (PeriodicHalfSpace if grid.periodic else IsolatedHalfSpace)(grid, e_star, **kw)
