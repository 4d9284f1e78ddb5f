"""Load control, the auto adhesive preconditioner and the paper's relaxation in any units: the
algorithms are unit-free.

Truths: scale invariance (lengths x s, moduli x e, loads x e, forces x e s^2, w x e s give the
same dimensionless state p / E*, g / s, delta / s, contact fraction, and the same snap number
and preconditioner picks; with s and e powers of two the scaled problem is the reference one
bit for bit, so it must take the same Newton steps and FFT pairs -- any difference is a
threshold in absolute units); Hertz (p0 = 2 E* a / (pi R), a = sqrt(R delta),
F = 4/3 E* R^1/2 delta^3/2); single-node contact at the smallest loads (p = n W at the lowest
node, delta = min h + K_ii n W); full contact at the largest (periodic cell: delta = mean h,
p - W independent of W).  Serially and under ``mpirun -n 2/3`` (the adhesive ones are heavy:
1 and 2 ranks).
"""
import itertools
import warnings

import numpy as np
import pytest
from mpi4py import MPI

from contactpetsc.geometry import surfaces
from contactpetsc.geometry.surfaces import sphere
from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.closed_forms import hertz_contact_radius, hertz_force
from contactpetsc.physics.interactions import make_law
from contactpetsc.physics.resolution import UnderResolvedWarning
from contactpetsc.solvers import ContactProblem
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.relaxation import RelaxationSolver
from contactpetsc.solvers.contact_load import MIN_LOAD

_ids = itertools.count()

#: (length factor, modulus factor): powers of two (exact scaling) and decimal ones
BINARY = [(2.0 ** -20, 2.0 ** -10), (2.0 ** -20, 2.0 ** 20), (2.0 ** 10, 2.0 ** -10), (2.0 ** 10, 2.0 ** 20)]
DECIMAL = [(1e-6, 1e-3), (1e-6, 1e6), (1e3, 1e-3), (1e3, 1e6)]


def prefix(name):
    return f"u{next(_ids)}{name}_"


def rough(s, n=64):
    """The reference rough periodic cell (unit side, rms slope 0.1) with lengths x s."""
    ref = SurfaceGrid(n, n, 1.0 / n)
    h_ref = surfaces.self_affine(ref, hurst=0.8, seed=5, rms_slope=0.1, rolloff_wavelength=0.25,
                                 short_cutoff_wavelength=4.0 / n)
    g = SurfaceGrid(n, n, s / n)
    h = g.create_vec()
    g.rows(h)[...] = s * ref.rows(h_ref, readonly=True)
    return g, h


def dimensionless(prob, st, s, e):
    """(p / E*, g / s) on this rank's rows, delta / s, contact fraction."""
    g = prob.grid
    return (g.rows(st.pressure, readonly=True) / e, g.rows(st.gap, readonly=True) / s, st.approach / s,
            st.contact_fraction)


def counts(st):
    return st.newton_iterations, st.linear_iterations, st.fft_pairs


def differences(coll, a, b):
    """Largest relative differences of two dimensionless states: pressure (of max p), gap (of
    max |g|), approach, contact fraction."""
    pmax, gmax = coll.max(np.abs(a[0])), coll.max(np.abs(a[1]))
    return (coll.max(np.abs(a[0] - b[0])) / pmax, coll.max(np.abs(a[1] - b[1])) / gmax,
            abs(a[2] - b[2]) / abs(a[2]), abs(a[3] - b[3]))


_reference = {}     # the reference units' solutions, solved once (every rank runs every test)


def load_path(s, e, name, loads=(0.004, 0.006), **options):
    """States of a loading path on the rough cell at mean pressures ``loads`` x E*
    (``options``: the problem's PETSc options)."""
    cached = (s, e) == (1.0, 1.0) and not options
    if cached and "load" in _reference:
        return _reference["load"]
    g, h = rough(s)
    prob = ContactProblem(g, h, e, prefix=prefix(name), petsc_options=options)
    out = prob, [prob.solve(mean_pressure=w * e) for w in loads]
    if cached:
        _reference["load"] = out
    return out


@pytest.mark.parametrize("s, e", BINARY)
def test_load_control_is_unit_free_step_for_step(coll, s, e):
    """Powers of two: the same state and the same Newton steps, Krylov iterations and FFT pairs
    (the first solve nested, the second a step of the path: the predictor and the forcing)."""
    ref_prob, ref = load_path(1.0, 1.0, "ref")
    prob, states = load_path(s, e, "bin")
    for a, b in zip(ref, states):
        assert a.converged and b.converged
        assert counts(a) == counts(b), (counts(a), counts(b))
        assert max(differences(coll, dimensionless(ref_prob, a, 1.0, 1.0), dimensionless(prob, b, s, e))) <= 1e-12
    assert 0.05 < ref[0].contact_fraction < ref[1].contact_fraction < 0.5


@pytest.mark.parametrize("options", [{"load_joint": False}, {"newton_ksp_forcing": False},
                                     {"preconditioner": "mlmi"}], ids=["outer", "fixed_rtol", "mlmi"])
def test_every_load_control_variant_is_unit_free_step_for_step(coll, options):
    """The outer iteration on delta, fixed Krylov tolerances, the multilevel preconditioner:
    a path down to a load of 1e-8 E* step for step the same at 2^-20 m and 2^-10 Pa."""
    s, e = BINARY[0]
    loads = (0.004, 0.006, 1e-8)
    ref_prob, ref = load_path(1.0, 1.0, "vref", loads, **options)
    prob, states = load_path(s, e, "vbin", loads, **options)
    for a, b in zip(ref, states):
        assert a.converged and b.converged and counts(a) == counts(b), (counts(a), counts(b))
        assert max(differences(coll, dimensionless(ref_prob, a, 1.0, 1.0), dimensionless(prob, b, s, e))) <= 1e-12


@pytest.mark.parametrize("s, e", DECIMAL)
def test_load_control_is_unit_free_in_decimal_units(coll, s, e):
    """Decimal factors round the heights differently: the same state to the tolerance and the
    same number of Newton steps."""
    ref_prob, ref = load_path(1.0, 1.0, "ref")
    prob, states = load_path(s, e, "dec")
    for a, b in zip(ref, states):
        assert a.converged and b.converged and a.load_error <= 1e-10 and b.load_error <= 1e-10
        assert a.newton_iterations == b.newton_iterations
        assert abs(b.fft_pairs / a.fft_pairs - 1) <= 0.1
        assert max(differences(coll, dimensionless(ref_prob, a, 1.0, 1.0), dimensionless(prob, b, s, e))) <= 1e-8


# -- Hertz under force control --------------------------------------------------------------
R, A = 1.0, 1e-2          # reference sphere radius and Hertz contact radius
DELTA = A * A / R


@pytest.mark.parametrize("s, e", [(1.0, 1.0)] + DECIMAL)
def test_hertz_under_force_control_in_any_units(coll, s, e):
    """64^2 with 20 elements per Hertz radius: the load-controlled state carries the force and
    has Hertz's approach, peak pressure and contact radius within 1 % at every scale."""
    n = 64
    g = SurfaceGrid(n, n, s * A / 20, periodic=False)
    radius, delta, e_star = s * R, s * DELTA, e
    force = float(hertz_force(e_star, radius, delta))
    prob = ContactProblem(g, surfaces.sphere(g, radius), e_star, prefix=prefix("hertz"))
    st = prob.solve(force=force)
    a = float(hertz_contact_radius(radius, delta))
    p0 = 2.0 * e_star * a / (np.pi * radius)
    a_num = np.sqrt(st.contact_fraction * g.lengths[0] * g.lengths[1] / np.pi)
    assert st.converged and coll.max(st.load_error) <= 1e-9
    assert abs(st.force / force - 1) <= 1e-9
    errors = (abs(st.approach / delta - 1), abs(st.pressure.max()[1] / p0 - 1), abs(a_num / a - 1))
    assert coll.max(errors) <= 0.01, errors


# -- the extremes of the load ---------------------------------------------------------------
@pytest.mark.parametrize("s, e", [(1.0, 1.0)] + DECIMAL)
def test_smallest_loads_touch_the_lowest_node_alone(coll, s, e):
    """Mean pressures of MIN_LOAD E* and 1e-8 E*: only the lowest node is loaded (the next one
    is further away than K_ii n W), p = n W there, delta = min h + K_ii n W."""
    g, h = rough(s)
    n = g.nx * g.ny
    rows = g.rows(h, readonly=True)
    h_min = g.mpi_comm.allreduce(float(rows.min()), op=MPI.MIN)
    second = g.mpi_comm.allreduce(float(np.min(rows[rows > h_min], initial=np.inf)), op=MPI.MIN)
    prob = ContactProblem(g, h, e, prefix=prefix("tiny"))
    for w in (1e-8, MIN_LOAD):
        load = w * e
        assert second - h_min > 2 * prob.kappa * n * load     # the single-node state exists
        st = prob.solve(mean_pressure=load)
        assert st.converged and st.contact_fraction == 1.0 / n
        p = g.rows(st.pressure, readonly=True)
        assert abs(coll.max(p) / (n * load) - 1) <= 1e-9
        exact = h_min + prob.kappa * n * load
        assert abs(st.approach - exact) <= 1e-9 * prob.kappa * n * load + 1e-15 * s


@pytest.mark.parametrize("s, e", [(1.0, 1.0)] + DECIMAL)
def test_largest_loads_give_full_contact(coll, s, e):
    """Mean pressures 1 E* and 1e3 E* (full contact from about 0.15 E*): delta = mean h, g = 0
    everywhere, and p - W the same field at both loads (the problem is linear there)."""
    g, h = rough(s)
    mean_h = g.mpi_comm.allreduce(float(g.rows(h, readonly=True).sum())) / (g.nx * g.ny)
    prob = ContactProblem(g, h, e, prefix=prefix("full"))
    shapes = []
    for w in (1.0, 1e3):
        st = prob.solve(mean_pressure=w * e)
        assert st.converged and st.contact_fraction == 1.0
        assert abs(st.approach - mean_h) <= 1e-10 * prob.length_scale
        assert coll.max(np.abs(g.rows(st.gap, readonly=True))) <= 1e-10 * prob.length_scale
        shapes.append(g.rows(st.pressure, readonly=True) / e - w)
    amplitude = coll.max(np.abs(shapes[0]))
    assert coll.max(np.abs(shapes[0] - shapes[1])) <= 1e-8 * amplitude


@pytest.mark.parametrize("e", [1e-3, 1e6])
def test_a_load_below_the_smallest_is_refused_in_units_of_e_star(coll, e):
    g, h = rough(1.0, n=32)
    prob = ContactProblem(g, h, e, prefix=prefix("refuse"))
    coll.raises(ValueError, ["mean_pressure", "accepted range"], prob.solve, mean_pressure=0.5 * MIN_LOAD * e)


# -- adhesion: the auto preconditioner and the converged state --------------------------------
#: (law, Tabor parameter, the coarse grid's pick): on 32^2, dx = z0, snap numbers 0.12 (hard wall,
#: window 0.01-0.2: mlmi) and 0.28 (full LJ curve, window 0.2-0.4: mlmi); the 16^2 grid of the
#: nested iteration (snap doubled) picks for itself with a hard wall (spectral), and takes the
#: finest grid's pick with the full LJ curve
ADHESIVE = [("hardwall-lj", 0.9, "spectral"), ("lj", 1.6, "mlmi")]
APPROACHES = (-0.5, 0.5)      # apex gap 0.5 z0, then an overlap of 0.5 z0


def adhesive_path(law_name, mu, s, e, name):
    """An adhesive sphere (32^2, R = 100 dx, dx = z0) in Greenwood's units (E* = z0 = 1) with
    lengths x s, E* x e, and w x e s so that the Tabor parameter (R w^2 / (E*^2 z0^3))^(1/3)
    stays mu; (problem, its coarse problem or None, states along APPROACHES)."""
    key = (law_name, mu)
    if (s, e) == (1.0, 1.0) and key in _reference:
        return _reference[key]
    g = SurfaceGrid(32, 32, s, periodic=False)
    law = make_law(law_name, work_of_adhesion=np.sqrt(mu ** 3 / 100.0) * e * s, z0=s)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)   # the full LJ case is stiff by design
        pb = AdhesiveProblem(g, sphere(g, 100.0 * s), e, law, prefix=prefix(name), stability_check=False,
                             petsc_options={"fmg_min_size": 16})
        pb.snes()
        coarse = pb.coarse_levels.coarse()
        states = [pb.solve(approach=d * s) for d in APPROACHES]
    if (s, e) == (1.0, 1.0):
        _reference[key] = pb, coarse, states
    return pb, coarse, states


def adhesive_dimensionless(pb, st, s, e):
    g = pb.grid
    return (g.rows(st.pressure, readonly=True) / e, g.rows(st.gap, readonly=True) / s, st.force / (e * s * s),
            st.contact_fraction)


def check_same_choice(ref, scaled):
    """The snap number, the auto pick per grid and the solver recorded in the states and the
    histories (the coarse grid's own) are those of the reference units."""
    (pb0, c0, st0), (pb, c, st) = ref, scaled
    assert abs(pb.snap_number / pb0.snap_number - 1) <= 1e-12
    assert pb.preconditioner == pb0.preconditioner and (c is None) == (c0 is None)
    assert [x.solver for x in st] == [x.solver for x in st0]
    assert pb.history.column("solver") == pb0.history.column("solver")
    if c is not None:
        assert c.preconditioner == c0.preconditioner
        assert c.history.column("solver") == c0.history.column("solver")


@pytest.mark.heavy
@pytest.mark.parametrize("law_name, mu, coarse_pick", ADHESIVE)
@pytest.mark.parametrize("s, e", [(2.0 ** -10, 2.0 ** -20), (2.0 ** 10, 2.0 ** 20)])
def test_auto_preconditioner_is_unit_free_step_for_step(coll, law_name, mu, coarse_pick, s, e):
    """Powers of two: the same picks, states, Newton steps, Krylov iterations and FFT pairs."""
    ref = adhesive_path(law_name, mu, 1.0, 1.0, "aref")
    scaled = adhesive_path(law_name, mu, s, e, "abin")
    check_same_choice(ref, scaled)
    # (a grid that the ranks cannot halve evenly has no coarse level)
    assert ref[0].preconditioner == "mlmi" and (ref[1] is None or ref[1].preconditioner == coarse_pick)
    for a, b in zip(ref[2], scaled[2]):
        assert a.converged and b.converged
        assert counts(a) == counts(b), (counts(a), counts(b))
        da = differences(coll, adhesive_dimensionless(ref[0], a, 1.0, 1.0), adhesive_dimensionless(scaled[0], b, s, e))
        assert max(da) <= 1e-12, da


@pytest.mark.heavy
@pytest.mark.parametrize("law_name, mu, coarse_pick", ADHESIVE)
@pytest.mark.parametrize("s, e", [(1e-3, 1e-3), (1e-9, 1e10)])
def test_auto_preconditioner_is_unit_free_in_decimal_units(coll, law_name, mu, coarse_pick, s, e):
    """Decimal factors (the last: nm and 10 GPa, SI): the same picks, and the same state to 1e-8."""
    ref = adhesive_path(law_name, mu, 1.0, 1.0, "aref")
    scaled = adhesive_path(law_name, mu, s, e, "adec")
    check_same_choice(ref, scaled)
    for a, b in zip(ref[2], scaled[2]):
        assert a.converged and b.converged and a.newton_iterations == b.newton_iterations
        da = differences(coll, adhesive_dimensionless(ref[0], a, 1.0, 1.0), adhesive_dimensionless(scaled[0], b, s, e))
        assert max(da) <= 1e-8, da


# -- the paper's relaxation ------------------------------------------------------------------
def relaxed_path(law_name, s, e, name):
    """The relaxation (its default tolerances) along APPROACHES on the sphere of
    ``adhesive_path`` at Tabor parameter 0.5; (problem, states)."""
    key = ("relaxation", law_name)
    if (s, e) == (1.0, 1.0) and key in _reference:
        return _reference[key]
    g = SurfaceGrid(32, 32, s, periodic=False)
    law = make_law(law_name, work_of_adhesion=np.sqrt(0.5 ** 3 / 100.0) * e * s, z0=s)
    pb = AdhesiveProblem(g, sphere(g, 100.0 * s), e, law, prefix=prefix(name), stability_check=False)
    relax = RelaxationSolver(pb)
    out = pb, [relax.solve(approach=d * s) for d in APPROACHES]
    if (s, e) == (1.0, 1.0):
        _reference[key] = out
    return out


@pytest.mark.heavy
@pytest.mark.parametrize("law_name", ["hardwall-lj", "lj"])
@pytest.mark.parametrize("s, e", [(2.0 ** -10, 2.0 ** -20), (1e-9, 1e10)])
def test_relaxation_is_unit_free(coll, law_name, s, e):
    """The same cycles, contact relaxations and FFT pairs on binary scales, the same state to
    1e-8 on decimal ones (nm and 10 GPa)."""
    pb0, ref = relaxed_path(law_name, 1.0, 1.0, "rref")
    pb, states = relaxed_path(law_name, s, e, "rsc")
    binary = np.log2(s).is_integer() and np.log2(e).is_integer()
    for a, b in zip(ref, states):
        assert a.converged and b.converged and a.solver == b.solver == "relaxation-mlmi"
        if binary:
            assert counts(a) == counts(b), (counts(a), counts(b))
        da = differences(coll, adhesive_dimensionless(pb0, a, 1.0, 1.0), adhesive_dimensionless(pb, b, s, e))
        assert max(da) <= (1e-12 if binary else 1e-8), da



# -- the energy descent ------------------------------------------------------------------------
def descended_path(law_name, s, e, name):
    """``strategy descent`` (every state a descent from the last, then Newton's confirmation)
    on the rough periodic cell of tests/test_descent.py, w = 0.05 E* dx, dx = z0 = s, E* = e,
    at approaches min h + (0.25, 0.75) z0; (problem, states)."""
    key = ("descent", law_name)
    if (s, e) == (1.0, 1.0) and key in _reference:
        return _reference[key]
    g = SurfaceGrid(64, 64, s, periodic=True)
    h = surfaces.self_affine(g, hurst=0.8, rms_height=s, seed=7)
    law = make_law(law_name, work_of_adhesion=0.05 * e * s, z0=s)
    pb = AdhesiveProblem(g, h, e, law, prefix=prefix(name), stability_check=False,
                         petsc_options={"strategy": "descent"})
    hmin = h.min()[1]
    out = pb, [pb.solve(approach=hmin + d * s) for d in (0.25, 0.75)]
    if (s, e) == (1.0, 1.0):
        _reference[key] = out
    return out


@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
@pytest.mark.parametrize("s, e", [(1e-9, 1e9), (1e6, 1e-3)])
def test_energy_descent_is_unit_free(coll, law_name, s, e):
    """nm and GPa, Mm and mPa: the descent takes the same TAO iterations, Newton confirms its
    state in the same steps, and the states are the reference one to 1e-8."""
    pb0, ref = descended_path(law_name, 1.0, 1.0, "dref")
    pb, states = descended_path(law_name, s, e, "dsc")
    assert pb.history.column("solver") == pb0.history.column("solver")
    for a, b in zip(ref, states):
        assert a.converged and b.converged and a.solver == b.solver and a.solver.startswith("descent+")
        assert a.newton_iterations == b.newton_iterations
        da = differences(coll, adhesive_dimensionless(pb0, a, 1.0, 1.0), adhesive_dimensionless(pb, b, s, e))
        assert max(da) <= 1e-8, da
