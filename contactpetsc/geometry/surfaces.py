"""Composite surface heights h on a ``SurfaceGrid`` (assumption 1 of the reference paper).

h is the separation of the undeformed bodies [m], min h = 0 (approach 0 is first touch).
Generated surfaces are gaps as built: a sphere's h = r^2 / 2R touches at its apex, a random
surface's field is the gap (its lowest points touch first; the counter-surface is z = -h,
statistically alike for Gaussian phases).  A measured map holds the sample's surface z, peaks
up, and ``from_topography`` turns it over: h = max(z) - z.  Every constructor returns a
global Vec and gives the same field on any number of ranks: arrays and files
are sliced by rows, generators are evaluated on each rank's nodes, and random
surfaces draw their Fourier coefficients per kx column from a generator seeded
by (seed, kx), so the draw does not depend on which rank owns the column.
"""
from __future__ import annotations

import hashlib
import warnings

import numpy as np
from petsc4py import PETSc

from ..collective import collective_call
from ..pencil_fft import grid_rfft
from ..grid import GridError, SurfaceGrid
from ..topography import HEIGHTS_ARE, centred_coordinates, grid_mismatch, read_topography, trend
from ..topography.detrend import check_size


class HeightDtypeWarning(UserWarning):
    """Heights given as integers: taken as metres, which is rarely what integer data mean."""


def check_height_dtype(dtype, what: str = "heights") -> None:
    """Refuse heights that are not real numbers (complex, bool, text, objects); warn for integers.

    Floating-point heights of any precision are taken as they are [m].  ``dtype`` is that of
    the heights as given: a reader that scales a file's integers (``.sur``, ``.x3p``) returns
    floats, so only integers really taken as raw numbers (``.npy``, HDF5, arrays) warn.
    """
    dtype = np.dtype(dtype)
    if dtype.kind == "f":
        return
    if dtype.kind in "iu":
        warnings.warn(f"{what}: heights of integer dtype {dtype} are taken as metres; convert them "
                      f"to float (in m) to silence this", HeightDtypeWarning, stacklevel=3)
        return
    kind = {"b": "boolean", "c": "complex"}.get(dtype.kind, "not numeric")
    raise GridError(f"{what}: heights of dtype {dtype} ({kind}); heights must be real numbers "
                    f"(float, in m)")


def _check_finite(grid: SurfaceGrid, vec: PETSc.Vec, what: str) -> PETSc.Vec:
    bad = int(np.count_nonzero(~np.isfinite(grid.rows(vec, readonly=True))))
    bad = grid.mpi_comm.allreduce(bad)
    if bad:
        raise GridError(f"{what}: {bad} heights are NaN or Inf; heights must be finite")
    return vec


def from_array(grid: SurfaceGrid, heights: np.ndarray) -> PETSc.Vec:
    """Heights [m] from a global (nx, ny) real array (the same array on every rank)."""
    heights = np.asarray(heights)
    check_height_dtype(heights.dtype, "heights array")
    return _check_finite(grid, grid.vec_from_array(heights.astype(float, copy=False), "heights"),
                         "heights array")


def from_file(grid: SurfaceGrid, path: str, dataset: str = "heights", *, format: str | None = None,
              height_unit: str | None = None, fill: str = "none", info: dict | None = None) -> PETSc.Vec:
    """Heights [m] from a file in any format of ``topography.FORMATS`` (``.npy``, HDF5
    ``dataset``, text matrix, ``.xyz``, ``.gsf``, ``.gwy`` channel ``dataset``, ``.x3p``,
    ``.sur``; ``format``: by extension unless named), as the file holds them (no shift, no
    detrending, no turning over: ``from_topography`` makes the composite gap of them).

    The map must have the grid's (nx, ny) points and, where the file gives its spacing, the
    grid's dx, dy (1e-9 relative); ``height_unit`` for files that state no unit (default m).
    ``.npy`` and HDF5 files are read by rows, each rank its own; the others whole on every
    rank (instrument files are small).  Errors (missing, unreadable, truncated, wrongly
    shaped or stamped files, heights that are not real numbers) are raised on every rank.
    Points not measured (NaN): ``fill`` "none" refuses them, "harmonic" fills them
    (``topography.fill``; every rank reads and fills the whole map, then takes its rows: the
    same field on any number of ranks); ``info["filled_points"]`` gets the count filled and
    ``info["heights_sha256"]`` the digest of the heights read (``_digest``).
    """
    return _read_file(grid, path, dataset, format, height_unit, fill, info)[0]


def _read_file(grid: SurfaceGrid, path: str, dataset: str, format: str | None, height_unit: str | None,
               fill: str = "none", info: dict | None = None) -> tuple[PETSc.Vec, str | None]:
    """(``from_file``'s Vec, the file's ``heights_are`` stamp or None)."""
    def read():
        topo = read_topography(path, format=format, dataset=dataset, height_unit=height_unit,
                               metadata_only=True, fill=fill)
        problem = grid_mismatch(topo, grid.shape, (grid.dx, grid.dy))
        if problem:
            raise ValueError(problem)
        check_height_dtype(topo.dtype, path)
        stamp = topo.heights_are
        topo = read_topography(path, format=format, dataset=dataset, height_unit=height_unit,
                               rows=(grid.ys, grid.ye), fill=fill)
        return np.asarray(topo.heights, dtype=float), stamp, topo.metadata.get("filled_points", 0)

    grid.require_slabs("reading heights from a file (by rows)")
    v = grid.create_vec()
    local, stamp, filled = collective_call(grid.mpi_comm, GridError, f"cannot read heights from {path}: {{error}}",
                                           read)
    grid.local_array(v)[...] = local
    if info is not None:
        info["filled_points"] = filled
        info["heights_sha256"] = _digest(grid, local)
    return _check_finite(grid, v, path), stamp


def _digest(grid: SurfaceGrid, local: np.ndarray) -> str:
    """SHA-256 of a file's heights as read (float64 [m]): each rank hashes its whole y-lines,
    rank 0 hashes the lines' digests in y order, so the digest does not depend on the number of
    ranks and no rank gathers the map (collective)."""
    lines = [hashlib.sha256(np.ascontiguousarray(local[:, k], dtype=np.float64).tobytes()).digest()
             for k in range(local.shape[1])]
    gathered = grid.mpi_comm.gather(lines, root=0)
    value = (hashlib.sha256(b"".join(d for part in gathered for d in part)).hexdigest()
             if grid.mpi_comm.Get_rank() == 0 else None)
    return grid.mpi_comm.bcast(value, root=0)


def detrended(grid: SurfaceGrid, h: PETSc.Vec, mode: str = "none") -> PETSc.Vec:
    """A new surface: ``h`` minus its least-squares ``mode`` trend ("none", "mean-plane" or
    "curvature"; ``topography.detrend``), shifted so that min h = 0 (assumption 1: approach 0
    is first touch).  The fit is made from every rank's rows (an all-reduce)."""
    grid.check_vec(h, "heights")
    grid.require_slabs("detrending")
    check_size(grid.nx, grid.ny, mode)
    local = grid.local_array(h, readonly=True)
    u, v = centred_coordinates(grid.nx, grid.ny, slice(grid.ys, grid.ye))
    fit = collective_call(grid.mpi_comm, GridError, "detrend: {error}", trend, local, u, v, mode,
                          grid.mpi_comm.allreduce)
    out = h.copy()
    grid.local_array(out)[...] -= fit
    out.shift(-out.min()[1])
    return out


def from_topography(grid: SurfaceGrid, path: str, dataset: str = "heights", *, format: str | None = None,
                    height_unit: str | None = None, detrend: str = "none",
                    heights_are: str | None = None, fill: str = "none", info: dict | None = None) -> PETSc.Vec:
    """A measured topography as the composite gap h [m] that a rigid flat meets.

    The file's numbers are read by ``from_file`` (the same arguments, ``fill`` and ``info``
    too) and detrended (``detrend``: "none", "mean-plane" or "curvature").  ``heights_are``
    says what they are:

    - "surface": the sample's surface z, peaks up (instrument files, ``contactpetsc import``):
      h = max(z) - z, the highest point touches first;
    - "gap": already a composite gap (the ``heights`` of contactpetsc's step files):
      h = z - min(z), the lowest point touches first.

    Default (None): what the file says (attribute or sidecar key ``heights_are``), else
    "surface"; a value that contradicts the file's stamp is refused.  Files in formats read
    only by SurfaceTopography: convert them with ``contactpetsc import`` (docs/topography.md).
    """
    if heights_are is not None and heights_are not in HEIGHTS_ARE:
        raise GridError(f"heights_are = {heights_are!r}; accepted: {', '.join(HEIGHTS_ARE)}")
    z, stamp = _read_file(grid, path, dataset, format, height_unit, fill, info)
    if heights_are is not None and stamp is not None and stamp != heights_are:
        raise GridError(f"{path} holds heights_are = {stamp!r} (its stamp), not {heights_are!r}")
    if (heights_are or stamp or "surface") == "surface":
        z.scale(-1.0)   # peaks up: the highest point is the smallest gap (detrending commutes)
    return detrended(grid, z, detrend)


def from_function(grid: SurfaceGrid, func) -> PETSc.Vec:
    """Heights [m] = func(x, y) on the local nodes; x, y [m] arrays of shape (nx_local, ny_local)."""
    v = grid.create_vec()   # first: a grid too big for memory is refused in its own terms
    x, y = grid.coordinates()
    values = collective_call(grid.mpi_comm, GridError, "height function failed: {error!r}", func, x, y)
    grid.local_array(v)[...] = values
    return _check_finite(grid, v, "height function")


def centre(grid: SurfaceGrid) -> tuple[float, float]:
    """The node nearest the middle of the grid, (nx//2 dx, ny//2 dy) [m]: a sphere's apex."""
    return (grid.nx // 2) * grid.dx, (grid.ny // 2) * grid.dy


def sphere(grid: SurfaceGrid, radius: float) -> PETSc.Vec:
    """Paraboloid h = ((x-xc)^2 + (y-yc)^2) / (2R) of a sphere of radius R [m] (Hertz geometry)."""
    if not (np.isfinite(radius) and radius > 0):
        raise GridError(f"radius (m) must be finite and > 0, got {radius!r}")
    xc, yc = centre(grid)
    return from_function(grid, lambda x, y: ((x - xc) ** 2 + (y - yc) ** 2) / (2 * radius))



def self_affine_band(lx: float, ly: float, dx: float, dy: float, rolloff_wavelength: float | None = None,
                     short_cutoff_wavelength: float | None = None) -> tuple[float, float]:
    """(q_r, q_s) [1/m]: the roll-off and short cut-off wavevectors of ``self_affine`` on a cell
    lx x ly [m] of spacing dx, dy [m], the defaults filled in (the cell size; 2 max(dx, dy))."""
    rolloff = max(lx, ly) if rolloff_wavelength is None else rolloff_wavelength
    cutoff = 2 * max(dx, dy) if short_cutoff_wavelength is None else short_cutoff_wavelength
    return 2 * np.pi / rolloff, 2 * np.pi / cutoff


def self_affine(grid: SurfaceGrid, *, hurst: float, seed: int,
                rms_height: float | None = None, rms_slope: float | None = None,
                rolloff_wavelength: float | None = None,
                short_cutoff_wavelength: float | None = None) -> PETSc.Vec:
    """Periodic self-affine random surface with Gaussian random phases, min(h) = 0.

    Power spectrum C(q) ~ q^(-2(1+H)) between the roll-off wavevector
    q_r = 2 pi / rolloff_wavelength (constant below it) and the short cut-off
    q_s = 2 pi / short_cutoff_wavelength (zero above it).  Amplitudes are
    sqrt(C(q)) times complex Gaussian numbers; exactly one of ``rms_height``
    [m] or ``rms_slope`` [-] fixes the scale (both computed spectrally, the
    slope as sqrt(<|grad h|^2>)).  Defaults: roll-off at the cell size, cut-off
    at 2 grid spacings (Nyquist).
    """
    if not 0 < hurst < 1:
        raise GridError(f"hurst must lie in (0, 1), got {hurst!r}")
    if (rms_height is None) == (rms_slope is None):
        raise GridError("give exactly one of rms_height (m) or rms_slope")
    scale_to = rms_height if rms_height is not None else rms_slope
    if not (np.isfinite(scale_to) and scale_to >= 0):
        raise GridError(f"rms_height / rms_slope must be finite and >= 0, got {scale_to!r}")
    q_r, q_s = self_affine_band(*grid.lengths, grid.dx, grid.dy, rolloff_wavelength, short_cutoff_wavelength)

    def psd_amplitude(q):
        with np.errstate(divide="ignore"):
            amp = np.maximum(q, q_r) ** (-(1 + hurst))
        amp[(q == 0) | (q > q_s)] = 0.0
        return amp

    return _random_surface(grid, seed, psd_amplitude, rms_height, rms_slope)


def gaussian_correlated(grid: SurfaceGrid, *, rms_height: float, correlation_length: float,
                        seed: int) -> PETSc.Vec:
    """Periodic random surface with Gaussian autocorrelation exp(-r^2/l^2), given rms [m], min(h) = 0."""
    if not (np.isfinite(correlation_length) and correlation_length > 0):
        raise GridError(f"correlation_length (m) must be finite and > 0, got {correlation_length!r}")

    def psd_amplitude(q):
        amp = np.exp(-(q * correlation_length) ** 2 / 8.0)  # sqrt of exp(-q^2 l^2 / 4)
        amp[q == 0] = 0.0
        return amp

    return _random_surface(grid, seed, psd_amplitude, rms_height, None)


def _random_surface(grid: SurfaceGrid, seed: int, psd_amplitude, rms_height, rms_slope) -> PETSc.Vec:
    h = grid.create_vec()   # first: a grid too big for memory is refused in its own terms
    fft = grid_rfft(grid, planner="estimate")
    qx, qy = fft.wavevectors(*grid.lengths)
    # draw per kx column, [kx_local, ky], from a stream keyed by (seed, kx): rank-independent
    cols = np.empty((fft.kx1 - fft.kx0, fft.Ny), complex)
    for i, kx in enumerate(range(fft.kx0, fft.kx1)):
        z = np.random.default_rng([int(seed), kx]).standard_normal((fft.Ny, 2))
        col = z[:, 0] + 1j * z[:, 1]
        if kx == 0 or 2 * kx == fft.Nx:
            # these columns are their own mirror: make them Hermitian in ky
            col = (col + np.conj(col[(-np.arange(fft.Ny)) % fft.Ny])) / np.sqrt(2.0)  # keeps E|c|^2 = 2
        cols[i] = col
    spec = fft.spectral_layout(cols) * psd_amplitude(np.hypot(qx, qy))
    w = fft.hermitian_weights()
    n2 = float(fft.Nx * fft.Ny) ** 2
    if rms_height is not None:
        current = np.sqrt(grid.mpi_comm.allreduce(float(np.sum(w * np.abs(spec) ** 2))) / n2)
        target = rms_height
    else:
        current = np.sqrt(grid.mpi_comm.allreduce(
            float(np.sum(w * (qx ** 2 + qy ** 2) * np.abs(spec) ** 2))) / n2)
        target = rms_slope
    if current == 0:
        raise GridError("random surface: the spectrum is empty (cut-offs leave no modes)")
    # unnormalised transforms: h = (1/N) * backward(h_hat)
    fft.spectrum[...] = spec * (target / current / (fft.Nx * fft.Ny))
    fft.backward(grid.rows(h))
    h.shift(-h.min()[1])
    return h


def rms_height(grid: SurfaceGrid, h: PETSc.Vec) -> float:
    """Root-mean-square deviation of h from its mean [m]."""
    grid.check_vec(h, "heights")
    n = grid.nx * grid.ny
    mean = h.sum() / n
    # two passes: <h^2> - <h>^2 cancels (a flat h far from 0 would give round-off, not 0)
    dev = grid.rows(h, readonly=True) - mean
    return float(np.sqrt(grid.mpi_comm.allreduce(float(np.vdot(dev, dev))) / n))


# -- the reference paper's surfaces: one random pattern at many rms, sphere plus roughness ----------
def scale_to_rms(grid: SurfaceGrid, h: PETSc.Vec, rms: float) -> PETSc.Vec:
    """A new surface with the spatial pattern of ``h`` scaled vertically to rms height ``rms`` [m].

    The reference paper's method (section 3.2): one random surface scaled to
    several rms values, so that peaks and valleys stay where they are.
    h' = (h - mean h) * rms / rms(h), shifted so that min h' = 0.  ``rms = 0``
    gives a flat zero surface.
    """
    if not (np.isfinite(rms) and rms >= 0):
        raise GridError(f"rms (m) must be finite and >= 0, got {rms!r}")
    grid.check_vec(h, "heights")
    current = rms_height(grid, h)
    if current == 0 and rms > 0:
        raise GridError("scale_to_rms: the surface is flat (rms 0), it has no pattern to scale")
    out = h.copy()
    out.shift(-h.sum() / (grid.nx * grid.ny))
    out.scale(rms / current if current > 0 else 0.0)
    out.shift(-out.min()[1])
    return out


def composite(grid: SurfaceGrid, *parts: PETSc.Vec) -> PETSc.Vec:
    """The composite surface (assumption 1): the sum of height fields, shifted so min h = 0."""
    if not parts:
        raise GridError("composite: give at least one height field")
    for k, p in enumerate(parts):
        grid.check_vec(p, f"height field {k + 1} of the composite")
    out = parts[0].copy()
    for p in parts[1:]:
        out.axpy(1.0, p)
    out.shift(-out.min()[1])
    return _check_finite(grid, out, "composite surface")


def rough_sphere(grid: SurfaceGrid, radius: float, roughness: PETSc.Vec) -> PETSc.Vec:
    """A sphere of radius R [m] about the centre node plus ``roughness``, min h = 0 (Figs. 6-9)."""
    return composite(grid, sphere(grid, radius), roughness)
