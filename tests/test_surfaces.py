"""Height fields: exact input paths, rank independence, random-surface statistics, errors.

Truths used: the input arrays/functions themselves, numpy's FFT of the gathered
field (spectral rms height and slope, power spectrum), the stated power law
C(q) ~ q^(-2(1+H)), and serial (COMM_SELF) == MPI (COMM_WORLD).
"""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid

COMMS = (("world", PETSc.COMM_WORLD), ("self", PETSc.COMM_SELF))


def write_on_root(coll, func):
    """Write a file on rank 0 only, then let every rank see it."""
    if coll.rank == 0:
        func()
    coll.comm.Barrier()


def spectral_stats(h, dx, dy):
    """(rms height, rms slope sqrt(<|grad h|^2>)) of a periodic field, from numpy's FFT."""
    nx, ny = h.shape
    hh = np.abs(np.fft.fft2(h)) ** 2 / (nx * ny) ** 2
    hh[0, 0] = 0.0
    qx = 2 * np.pi * np.fft.fftfreq(nx, dx)
    qy = 2 * np.pi * np.fft.fftfreq(ny, dy)
    q2 = qx[:, None] ** 2 + qy[None, :] ** 2
    return np.sqrt(hh.sum()), np.sqrt((q2 * hh).sum())


# -- exact input paths, any rank count ------------------------------------------------------
def test_inputs_rank_independent(coll, shared_tmp):
    """from_array, from_file (.npy, .h5) and from_function give the exact field on
    COMM_WORLD (uneven split of ny = 37) and on COMM_SELF."""
    import h5py

    nx, ny, dx, dy = 9, 37, 0.2e-6, 0.3e-6
    heights = np.random.default_rng(4).uniform(0, 1e-6, (nx, ny))
    npy, h5 = shared_tmp / "h.npy", shared_tmp / "h.h5"

    def write():
        np.save(npy, heights)
        with h5py.File(h5, "w") as f:
            f["heights"] = heights
            f["other"] = 2 * heights

    write_on_root(coll, write)

    def func(x, y):
        return 1e-7 * np.sin(x / 1e-6) * np.cos(y / 2e-6) + y ** 2 / 1e-5

    xg, yg = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dy, indexing="ij")
    errs = []
    for _, comm in COMMS:
        g = SurfaceGrid(nx, ny, dx, dy, periodic=False, comm=comm)
        for got, ref in ((surfaces.from_array(g, heights), heights),
                         (surfaces.from_file(g, str(npy)), heights),
                         (surfaces.from_file(g, str(h5)), heights),
                         (surfaces.from_file(g, str(h5), dataset="other"), 2 * heights),
                         (surfaces.from_function(g, func), func(xg, yg))):
            errs.append(np.max(np.abs(g.gather(got) - ref)) / np.max(np.abs(ref)))
    assert coll.max(errs) <= 1e-12


def test_sphere_and_rms_height(coll):
    """sphere() is the paraboloid about the centre node; rms_height() is numpy's std."""
    nx, ny, dx, dy, radius = 16, 37, 0.5e-6, 0.25e-6, 1e-3
    g = SurfaceGrid(nx, ny, dx, dy, periodic=False)
    h = g.gather(surfaces.sphere(g, radius))
    x = (np.arange(nx) - nx // 2) * dx
    y = (np.arange(ny) - ny // 2) * dy
    ref = (x[:, None] ** 2 + y[None, :] ** 2) / (2 * radius)
    assert coll.max(np.max(np.abs(h - ref)) / ref.max()) <= 1e-13 and coll.max(h.min()) == 0.0
    a = np.random.default_rng(8).standard_normal((nx, ny)) + 3.0
    rms = surfaces.rms_height(g, g.vec_from_array(a))
    assert coll.max(abs(rms / a.std() - 1)) <= 1e-12


# -- random surfaces ------------------------------------------------------------------------------
def test_random_surfaces_rank_independent(coll):
    """Same seed => same field on COMM_WORLD and COMM_SELF (1e-12); another seed differs."""
    nx, ny, dx, dy = 24, 37, 1e-6, 0.8e-6
    fields = {}
    for name, comm in COMMS:
        g = SurfaceGrid(nx, ny, dx, dy, comm=comm)
        fields[name] = [g.gather(surfaces.self_affine(g, hurst=0.7, seed=42, rms_slope=0.2)),
                        g.gather(surfaces.self_affine(g, hurst=0.4, seed=3, rms_height=1e-6,
                                                      rolloff_wavelength=8e-6,
                                                      short_cutoff_wavelength=3e-6)),
                        g.gather(surfaces.gaussian_correlated(g, rms_height=1e-6,
                                                              correlation_length=4e-6, seed=9))]
        if name == "world":
            other = g.gather(surfaces.self_affine(g, hurst=0.7, seed=43, rms_slope=0.2))
    errs = [np.max(np.abs(w - s)) / np.max(np.abs(s)) for w, s in zip(fields["world"], fields["self"])]
    assert coll.max(errs) <= 1e-12
    assert coll.max(-np.max(np.abs(other - fields["world"][0])) / np.max(fields["world"][0])) < -0.1


@pytest.mark.parametrize("target, kw", [
    ("rms_slope", {}),                                            # default cut-offs
    ("rms_slope", dict(short_cutoff_wavelength=0.5e-6)),          # whole band incl. Nyquist lines
    ("rms_slope", dict(rolloff_wavelength=10e-6, short_cutoff_wavelength=3e-6)),
    ("rms_height", {}),
    ("rms_height", dict(rolloff_wavelength=10e-6, short_cutoff_wavelength=2.5e-6)),
])
def test_self_affine_targets(coll, target, kw):
    """The requested rms slope / rms height is the spectral one of the field (1e-10); min h = 0."""
    nx, ny, dx, dy = 64, 37, 1e-6, 0.7e-6      # even nx (an x-Nyquist column), odd ny, dx != dy
    g = SurfaceGrid(nx, ny, dx, dy)
    value = 0.15 if target == "rms_slope" else 2e-7
    h = g.gather(surfaces.self_affine(g, hurst=0.6, seed=17, **{target: value}, **kw))
    rms_h, rms_s = spectral_stats(h, dx, dy)
    got = rms_s if target == "rms_slope" else rms_h
    assert coll.max(abs(got / value - 1)) <= 1e-10
    assert coll.max(abs(h.min())) == 0.0
    if target == "rms_height":   # the library's real-space rms agrees with the spectral one
        rms = surfaces.rms_height(g, g.vec_from_array(h))
        assert coll.max(abs(rms / value - 1)) <= 1e-10


def test_gaussian_correlated_rms_height(coll):
    nx, ny, dx = 32, 37, 1e-6
    g = SurfaceGrid(nx, ny, dx)
    h = g.gather(surfaces.gaussian_correlated(g, rms_height=3e-7, correlation_length=5e-6, seed=1))
    assert coll.max(abs(spectral_stats(h, dx, dx)[0] / 3e-7 - 1)) <= 1e-10
    assert coll.max(abs(h.min())) == 0.0


def radial_psd(h):
    """|h_hat|^2 and |k| (in units of 2 pi / L) of a square periodic field."""
    n = h.shape[0]
    k = np.fft.fftfreq(n, 1.0 / n)
    kx, ky = np.meshgrid(k, k, indexing="ij")
    return np.abs(np.fft.fft2(h)) ** 2, np.hypot(kx, ky), kx, ky


@pytest.mark.parametrize("hurst", [0.3, 0.8])
def test_self_affine_power_law(coll, hurst):
    """The radially averaged PSD falls as q^(-2(1+H)) between roll-off and cut-off (+-0.15),
    is flat below the roll-off, empty above the cut-off, and isotropic (the kx = 0 line
    carries the same power as the rest)."""
    n, dx = 256, 1e-6
    k_r, k_s = 8, 100                 # roll-off and cut-off mode numbers
    g = SurfaceGrid(n, n, dx)
    slopes, plateau, axis, above = [], [], [], []
    for seed in (1, 2, 3):
        h = g.gather(surfaces.self_affine(g, hurst=hurst, seed=seed, rms_height=1e-6,
                                          rolloff_wavelength=n * dx / k_r,
                                          short_cutoff_wavelength=n * dx / k_s))
        psd, k, kx, ky = radial_psd(h)
        edges = np.arange(k_r + 0.5, k_s - 0.5, 1.0)       # unit-width radial bins
        which = np.digitize(k.ravel(), edges)
        centres = np.array([k.ravel()[which == b].mean() for b in range(1, len(edges))])
        means = np.array([psd.ravel()[which == b].mean() for b in range(1, len(edges))])
        slopes.append(np.polyfit(np.log(centres), np.log(means), 1)[0])
        # |h_hat|^2 / C(q) is statistically constant if C(q) = max(q, q_r)^(-2(1+H))
        ratio = psd / np.maximum(k, k_r) ** (-2 * (1 + hurst))
        band = (k > 0) & (k <= k_s)
        bulk = band & (kx != 0) & (ky != 0)
        plateau.append(ratio[(k > 0) & (k < k_r)].mean() / ratio[bulk].mean())
        axis.append(ratio[band & (kx == 0)].mean() / ratio[bulk].mean())
        above.append(psd[k > k_s * 1.0001].sum() / psd.sum())
    expected = -2 * (1 + hurst)
    assert coll.max(abs(np.array(slopes) - expected)) <= 0.15, (slopes, expected)
    assert coll.max(abs(np.mean(slopes) - expected)) <= 0.08, (slopes, expected)
    assert coll.max(abs(np.mean(plateau) - 1)) <= 0.25, plateau
    assert coll.max(abs(np.mean(axis) - 1)) <= 0.25, axis
    assert coll.max(above) <= 1e-28


def test_self_affine_parameter_errors(coll):
    g = SurfaceGrid(8, 8, 1.0)
    coll.raises(GridError, "hurst", surfaces.self_affine, g, hurst=1.2, seed=0, rms_height=1.0)
    coll.raises(GridError, "exactly one", surfaces.self_affine, g, hurst=0.5, seed=0)
    coll.raises(GridError, "exactly one", surfaces.self_affine, g, hurst=0.5, seed=0,
                rms_height=1.0, rms_slope=0.1)
    coll.raises(GridError, "empty", surfaces.self_affine, g, hurst=0.5, seed=0, rms_height=1.0,
                short_cutoff_wavelength=100.0)
    coll.raises(GridError, "radius", surfaces.sphere, g, -1.0)


# -- input errors: a GridError on every rank, no deadlock ------------------------------------------
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_non_finite_heights(coll, bad):
    nx, ny = 6, 37
    g = SurfaceGrid(nx, ny, 1.0)
    h = np.zeros((nx, ny))
    h[2, 5] = bad
    coll.raises(GridError, ["NaN", "finite"], surfaces.from_array, g, h)
    # a bad value in the last row only: seen by the last rank, reported by every rank
    h = np.zeros((nx, ny))
    h[0, ny - 1] = bad
    coll.raises(GridError, "NaN", surfaces.from_array, g, h)
    coll.raises(GridError, "NaN", surfaces.from_function, g, lambda x, y: np.where(y > 30, bad, x))


def test_wrong_shape_array(coll):
    g = SurfaceGrid(6, 37, 1.0)
    coll.raises(GridError, ["shape", "(37, 6)", "(6, 37)"], surfaces.from_array, g, np.zeros((37, 6)))
    coll.raises(GridError, "shape", surfaces.from_array, g, np.zeros(6 * 37))


def test_bad_files(coll, shared_tmp):
    """Truncated/corrupt .npy, wrong shape, missing file or HDF5 dataset, unknown type."""
    import h5py

    nx, ny = 6, 37
    g = SurfaceGrid(nx, ny, 1.0)
    good, trunc, corrupt = (shared_tmp / n for n in ("good.npy", "trunc.npy", "corrupt.npy"))
    shape, h5 = shared_tmp / "shape.npy", shared_tmp / "h.h5"

    def write():
        np.save(good, np.ones((nx, ny)))
        raw = good.read_bytes()
        trunc.write_bytes(raw[: len(raw) - 40])
        corrupt.write_bytes(b"\x93NUMPY garbage" + bytes(range(200)))
        np.save(shape, np.ones((ny, nx)))
        with h5py.File(h5, "w") as f:
            f["elevation"] = np.ones((nx, ny))
        (shared_tmp / "h.txt").write_text("1 2 3")

    write_on_root(coll, write)
    assert coll.max(np.max(np.abs(g.gather(surfaces.from_file(g, str(good))) - 1))) == 0.0
    coll.raises(GridError, "trunc.npy", surfaces.from_file, g, str(trunc))
    coll.raises(GridError, "corrupt.npy", surfaces.from_file, g, str(corrupt))
    coll.raises(GridError, ["shape", "(37, 6)"], surfaces.from_file, g, str(shape))
    coll.raises(GridError, ["heights", "elevation"], surfaces.from_file, g, str(h5))
    coll.raises(GridError, "missing.npy", surfaces.from_file, g, str(shared_tmp / "missing.npy"))
    coll.raises(GridError, "missing.h5", surfaces.from_file, g, str(shared_tmp / "missing.h5"))
    coll.raises(GridError, ".txt", surfaces.from_file, g, str(shared_tmp / "h.txt"))


def test_rms_height_two_pass_and_flat_surface(coll):
    """<h^2> - <h>^2 would cancel for a flat surface far from 0; the rms must be ~0 and rank-free."""
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.solvers import ContactProblem
    g = SurfaceGrid(16, 13, 1e-8, periodic=True)
    h = surfaces.from_function(g, lambda x, y: 3.7e-7 + 0 * x)
    assert coll.max(surfaces.rms_height(g, h)) <= 1e-13 * 3.7e-7  # <h^2>-<h>^2 gave 4e-7 relative
    assert coll.max(abs(ContactProblem(g, h, 1e9).length_scale - g.dx)) == 0.0
    # a known sinusoid: rms = amplitude / sqrt(2) exactly on whole periods
    s = surfaces.from_function(g, lambda x, y: 1.0 + 2e-9 * np.cos(2 * np.pi * x / g.lengths[0]))
    # on a unit offset: the one-pass formula loses everything (variance 2e-18 vs eps 2e-16)
    assert coll.max(abs(surfaces.rms_height(g, s) - 2e-9 / np.sqrt(2))) <= 1e-6 * 2e-9


def test_height_function_failing_on_one_rank_raises_everywhere(coll):
    from contactpetsc.grid import GridError, SurfaceGrid
    g = SurfaceGrid(8, 9, 1e-8, periodic=False)
    last = g.mpi_comm.Get_size() - 1

    def func(x, y):
        if g.mpi_comm.Get_rank() == last:
            raise ValueError("bad heights here")
        return 0 * x

    msgs = coll.raises(GridError, "height function failed", surfaces.from_function, g, func)
    assert all("bad heights here" in m for m in msgs)


# -- the reference paper's surfaces: rescaled patterns, sphere plus roughness, instrument files ------
def test_scale_to_rms_keeps_the_pattern(coll):
    """One random pattern at several rms (section 3.2): the rms is the target (1e-12), the
    pattern is the same (correlation 1 with the original), min h = 0, and the field is the
    same on COMM_WORLD and COMM_SELF."""
    nx, ny, dx = 32, 37, 1e-8
    fields = {}
    for name, comm in COMMS:
        g = SurfaceGrid(nx, ny, dx, periodic=False, comm=comm)
        base = surfaces.gaussian_correlated(g, rms_height=1e-9, correlation_length=5e-8, seed=3)
        fields[name] = [g.gather(surfaces.scale_to_rms(g, base, r)) for r in (0.0, 0.3e-9, 3e-9)]
        ref = g.gather(base)
    for (flat, small, big) in fields.values():
        assert coll.max(np.abs(flat)) == 0.0
        for h, r in ((small, 0.3e-9), (big, 3e-9)):
            assert coll.max(abs(h.std() / r - 1)) <= 1e-12
            assert coll.max(abs(np.corrcoef(h.ravel(), ref.ravel())[0, 1] - 1)) <= 1e-12
            assert coll.max(abs(h.min())) == 0.0
    errs = [np.max(np.abs(w - s)) for w, s in zip(fields["world"], fields["self"])]
    assert coll.max(errs) <= 1e-12 * 3e-9
    g = SurfaceGrid(8, 8, 1.0)
    coll.raises(GridError, "flat", surfaces.scale_to_rms, g, g.create_vec(0.0), 1.0)
    coll.raises(GridError, "rms", surfaces.scale_to_rms, g, g.create_vec(0.0), -1.0)


def test_rough_sphere_is_the_composite_surface(coll):
    """sphere + roughness, shifted to min h = 0 (assumption 1)."""
    nx, ny, dx, radius = 24, 37, 1e-8, 1e-6
    g = SurfaceGrid(nx, ny, dx, periodic=False)
    rough = surfaces.self_affine(g, hurst=0.8, rms_height=1e-9, seed=2)
    h = g.gather(surfaces.rough_sphere(g, radius, rough))
    ref = g.gather(surfaces.sphere(g, radius)) + g.gather(rough)
    ref -= ref.min()
    assert coll.max(np.abs(h - ref)) <= 1e-12 * ref.max() and coll.max(abs(h.min())) == 0.0
    coll.raises(GridError, "at least one", surfaces.composite, g)
