"""The power spectrum of a height map (contactpetsc.app.plots.spectrum) against independent
truths: Parseval (the integral of C(q) over the plane is the mean-square height of the map it
transforms, windowed or not), a sinusoid's power at its wavevector, the Hann window's removal
of a non-periodic map's edge leakage, and the rms slope by finite differences.  numpy only, no
communicator: checked on one rank."""
import numpy as np
import pytest

from contactpetsc.app.plots import spectrum

pytestmark = pytest.mark.serial


def measure(nx, ny, dx, dy):
    """d^2q = (2 pi)^2 / (Lx Ly) [1/m^2], the area of one wavevector of the grid."""
    return (2 * np.pi) ** 2 / (nx * dx * ny * dy)


def rough_map(ny=48, nx=64, seed=3):
    """A non-periodic random map with a trend (ramp) and a bump: edges that do not match."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:ny, 0:nx]
    return 1e-9 * (rng.standard_normal((ny, nx)) + 0.05 * x + 3 * np.exp(-((x - 20) ** 2 + (y - 30) ** 2) / 40))


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("shape", [(48, 64), (33, 35)])
def test_parseval_holds_for_the_map_transformed(periodic, shape):
    """sum over the full plane of C d^2q = mean(h_w^2), h_w the map less its mean, times the
    Hann window (mean(w^2) = 1) when not periodic; even and odd sizes (the rfft's Nyquist
    column), dx != dy."""
    ny, nx = shape
    dx, dy = 1e-8, 2.5e-8
    h = rough_map(ny, nx)
    q, c, m = spectrum.power_spectrum(h, dx, dy, periodic)
    truth = np.mean(spectrum.windowed(h, periodic) ** 2)
    assert np.sum(m * c) * measure(nx, ny, dx, dy) / truth == pytest.approx(1.0, abs=1e-12)
    # the window keeps the mean-square height of a map without structure at its edges (w^2's mean is 1)
    w = spectrum.hann(ny, nx)
    assert np.mean(w ** 2) == pytest.approx(1.0, abs=1e-12) and w[0].max() == w[:, 0].max() == 0.0
    if periodic:
        assert truth / np.var(h) == pytest.approx(1.0, abs=1e-12)


def test_a_periodic_sinusoid_has_its_power_in_its_two_modes():
    """h = a cos(q0 . x) on a periodic cell, q0 on the grid (7, 3) cycles: C = a^2 / 4 / d^2q at
    +-q0 (the half plane's one mode, multiplicity 2) and 0 elsewhere; its radial ring mean is
    that mode's C times 2 over the ring's full-plane multiplicity."""
    nx, ny, dx, dy, a = 64, 32, 1e-8, 2e-8, 3e-9
    y, x = np.mgrid[0:ny, 0:nx]
    kx, ky = 2 * np.pi * 7 / (nx * dx), 2 * np.pi * 3 / (ny * dy)
    h = a * np.cos(kx * x * dx + ky * y * dy)
    q, c, m = spectrum.power_spectrum(h, dx, dy)
    peak = np.unravel_index(np.argmax(c), c.shape)
    assert q[peak] == pytest.approx(np.hypot(kx, ky), rel=1e-12)
    assert c[peak] * measure(nx, ny, dx, dy) / (a * a / 4) == pytest.approx(1.0, abs=1e-12)
    assert m[peak] == 2
    rest = np.ones(c.shape, bool)
    rest[peak] = False
    assert c[rest].max() < 1e-20 * c[peak]
    # the radial average: the ring through |q0|, narrow enough to hold only the modes at |q0|
    qr, cr = spectrum.radial_psd(h, dx, dy, bins=4000)
    ring = np.argmin(abs(qr / np.hypot(kx, ky) - 1))
    same = np.isclose(q, np.hypot(kx, ky), rtol=1e-12)
    assert cr[ring] / (c[peak] * 2 / m[same].sum()) == pytest.approx(1.0, abs=1e-9)


def test_a_windowed_sinusoid_off_the_grid_keeps_its_power_at_its_wavevector():
    """A non-periodic map of a sinusoid with 10.37 periods along x (not a grid wavevector: its
    periodic FFT leaks): the Hann-windowed spectrum peaks at q0 (to a grid spacing of q) and holds
    the sinusoid's power a^2 / 2 within a few grid wavevectors of it (to 0.2 %), while far from it
    (|q| > 3 q0) it is 1e-4 of the unwindowed (periodic) spectrum's leakage."""
    nx, ny, dx, dy, a = 128, 64, 1e-8, 1e-8, 2e-9
    q0 = 2 * np.pi * 10.37 / (nx * dx)
    h = np.tile(a * np.sin(q0 * np.arange(nx) * dx + 0.4), (ny, 1))
    q, c, m = spectrum.power_spectrum(h, dx, dy, periodic=False)
    dq = 2 * np.pi / (nx * dx)
    assert abs(q.flat[np.argmax(c)] - q0) <= dq
    near = np.abs(q - q0) < 4 * dq
    assert np.sum((m * c)[near]) * measure(nx, ny, dx, dy) / (a * a / 2) == pytest.approx(1.0, abs=2e-3)
    _, leaky, _ = spectrum.power_spectrum(h, dx, dy, periodic=True)
    far = q > 3 * q0
    assert np.sum(c[far]) < 1e-4 * np.sum(leaky[far])
    # and the radial average peaks in the ring of q0
    qr, cr = spectrum.radial_psd(h, dx, dy, periodic=False)
    assert abs(np.log(qr[np.argmax(cr)] / q0)) < np.log(qr[1] / qr[0])


def test_rms_slope_of_a_window_by_differences_and_of_a_cell_spectrally():
    """A plane h = s x has slope s: by differences on a window exactly (the spectral gradient of
    the same map, a periodic saw-tooth, is far off); a periodic sinusoid a sin(q x) has rms slope
    a q / sqrt(2) spectrally."""
    nx, ny, dx, s = 40, 30, 1e-8, 0.1
    plane = np.tile(s * np.arange(nx) * dx, (ny, 1))
    assert spectrum.rms_slope(plane, dx, dx, periodic=False) == pytest.approx(s, rel=1e-12)
    assert spectrum.rms_slope(plane, dx, dx, periodic=True) > 2 * s
    q = 2 * np.pi * 4 / (nx * dx)
    wave = np.tile(2e-9 * np.sin(q * np.arange(nx) * dx), (ny, 1))
    assert spectrum.rms_slope(wave, dx, dx) == pytest.approx(2e-9 * q / np.sqrt(2), rel=1e-12)
