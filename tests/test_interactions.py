"""Interaction laws against independent truths: p = -dPhi/dg, the LJ closed forms, quadrature."""
import mpmath
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from contactpetsc.physics import (Dugdale, Exponential, HardWallLennardJones, LennardJones,
                                  NoAdhesion, lj_from_atomistic, make_law, tabor_parameter)

W, Z0 = 0.29, 0.3e-9          # the reference paper's w [J/m^2] and z0 [m]
LAWS = {
    "lj": LennardJones(W, Z0),
    "hardwall-lj": HardWallLennardJones(W, Z0),
    "exponential": Exponential(W, 0.5e-9),
    "dugdale": Dugdale(W, 1e8),
}
#: laws on numpy arrays, no communicator: checked on one rank
pytestmark = pytest.mark.serial

# no example database: ranks under mpirun would share and race on one directory
fast = settings(max_examples=60, deadline=None, database=None)


def lj_exact(z):
    """Eq. (2) evaluated with mpmath, independently of the library."""
    return 8 * W / (3 * Z0) * ((Z0 / z) ** 9 - (Z0 / z) ** 3)


@fast
@given(t=st.floats(min_value=-0.4, max_value=8.0))
def test_lj_pressure_is_minus_energy_slope(t):
    law = LennardJones(W, Z0)
    g = t * Z0
    h = 1e-6 * Z0
    slope = (law.energy(g + h) - law.energy(g - h)) / (2 * h)
    assert law.pressure(g) == pytest.approx(-slope, rel=1e-6, abs=1e-9 * law.peak_attraction)
    dp = (law.pressure(g + h) - law.pressure(g - h)) / (2 * h)
    assert law.derivative(g) == pytest.approx(dp, rel=1e-5, abs=1e-6 * law.peak_attraction / Z0)
    assert law.pressure(g) == pytest.approx(float(lj_exact(mpmath.mpf(g) + Z0)), rel=1e-12,
                                            abs=1e-12 * law.peak_attraction)


@pytest.mark.parametrize("name", ["hardwall-lj", "exponential", "dugdale"])
@fast
@given(t=st.floats(min_value=0.01, max_value=5.0))
def test_hard_wall_laws_pressure_is_minus_energy_slope(name, t):
    law = LAWS[name]
    g = t * law.length_scale()
    if name == "dugdale" and abs(g - law.range) < 1e-3 * law.range:
        return  # the Dugdale step: no derivative there
    h = 1e-6 * law.length_scale()
    slope = (law.energy(g + h) - law.energy(g - h)) / (2 * h)
    scale = W / law.length_scale()
    assert law.pressure(g) == pytest.approx(-slope, rel=1e-6, abs=1e-9 * scale)
    dp = (law.pressure(g + h) - law.pressure(g - h)) / (2 * h)
    assert law.derivative(g) == pytest.approx(dp, rel=1e-5, abs=1e-6 * scale / law.length_scale())
    assert law.pressure(g) <= 0  # attraction only away from the wall


@pytest.mark.parametrize("name", sorted(LAWS))
def test_energy_at_contact_is_minus_w_and_vanishes_far_away(name):
    law = LAWS[name]
    assert float(law.energy(0.0)) == pytest.approx(-W, rel=1e-12)
    far = 1e4 * law.length_scale()
    if name in ("lj", "hardwall-lj"):  # van der Waals tail: Phi ~ -(4w/3) (z0/z)^2
        assert float(law.energy(far)) == pytest.approx(-4 * W / 3 * (Z0 / (far + Z0)) ** 2, rel=1e-6)
    else:
        assert abs(float(law.energy(far))) < 1e-12 * W


def test_lj_work_of_separation_by_quadrature():
    law = LennardJones(W, Z0)
    mpmath.mp.dps = 30
    work = mpmath.quad(lambda z: lj_exact(z), [Z0, 2 * Z0, 10 * Z0, mpmath.inf])
    assert float(work) == pytest.approx(-W, rel=1e-12)
    assert float(law.pressure(0.0)) == 0.0  # equilibrium at z = z0


def test_lj_peak_attraction_location_and_value():
    law = LennardJones(W, Z0)
    z = np.linspace(1.0, 1.5, 2_000_001) * Z0
    p = law.pressure(z - Z0)
    k = np.argmin(p)
    assert z[k] == pytest.approx(3 ** (1 / 6) * Z0, rel=1e-6)          # not (1/3)^(1/6) z0
    assert -p[k] == pytest.approx(16 * W / (9 * np.sqrt(3) * Z0), rel=1e-10)
    assert law.peak_attraction == pytest.approx(16 * W / (9 * np.sqrt(3) * Z0), rel=1e-14)
    # 4 % of the peak at z = 4 z0 (reference paper, section 1)
    assert -law.pressure(3 * Z0) / law.peak_attraction == pytest.approx(0.04, abs=0.005)


@fast
@given(a=st.floats(min_value=-0.3, max_value=6.0), b=st.floats(min_value=-0.3, max_value=6.0))
def test_segment_mean_pressure_equals_quadrature(a, b):
    """The element integral of Fig. 3: mean of p along a linear gap profile."""
    law = LennardJones(W, Z0)
    ga, gb = a * Z0, b * Z0
    if abs(gb - ga) < 1e-9 * Z0:
        # a segment too short for the quadrature: its midpoint value (error ~ p'' (gb - ga)^2 / 24;
        # an end's value would be off by p' (gb - ga) / 2, up to 8e-9 w / z0)
        exact = float(lj_exact((mpmath.mpf(ga) + mpmath.mpf(gb)) / 2 + Z0))
    else:
        exact = float(mpmath.quad(lambda g: lj_exact(g + Z0), [ga, gb]) / (gb - ga))
    got = float(law.segment_mean_pressure(ga, gb))
    assert got == pytest.approx(exact, rel=1e-8, abs=1e-9 * law.peak_attraction)


def test_tabor_parameter_of_the_reference_paper():
    # R = 100 um, E* = 50 GPa, z0 = 0.3 nm, w = 0.29 J/m^2 "giving mu = 5" (section 3.2)
    assert tabor_parameter(100e-6, W, 50e9, Z0) == pytest.approx(5.0, abs=0.01)


def test_atomistic_conversion():
    eps, r0 = 1.6e-21, 0.34e-9
    w, z0 = lj_from_atomistic(eps, r0)
    assert z0 ** 6 == pytest.approx(2 / 15 * r0 ** 6, rel=1e-14)
    assert w * 2 * np.pi * z0 ** 2 == pytest.approx(9 * eps, rel=1e-14)


def test_no_adhesion_and_bad_parameters():
    law = make_law("none")
    assert isinstance(law, NoAdhesion) and not law.adhesive
    assert np.all(law.pressure(np.linspace(0, 1, 5)) == 0)
    assert not make_law("none", work_of_adhesion=0.0).adhesive
    with pytest.raises(ValueError, match=r"work_of_adhesion = 0.3 J/m\^2 with law 'none'.*accepted value 0"):
        make_law("none", work_of_adhesion=0.3)
    with pytest.raises(ValueError, match="work_of_adhesion"):
        make_law("lj", work_of_adhesion=-1.0, z0=Z0)
    with pytest.raises(ValueError, match="z0"):
        make_law("hardwall-lj", work_of_adhesion=W, z0=0.0)
    with pytest.raises(ValueError, match="interaction law"):
        make_law("morse", work_of_adhesion=W, z0=Z0)
    with pytest.raises(FloatingPointError, match="atomic separation"):
        LennardJones(W, Z0).pressure(-1.5 * Z0)
