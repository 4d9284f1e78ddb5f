"""The finite elastic layer on a rigid base (``operators/layer.py``, ``PeriodicLayer``).

Truths used: the plane-strain boundary-value problem of a layer under a sinusoidal pressure,
solved here numerically (Navier's equations as a first-order system in depth, propagated by a
matrix exponential, the base and surface conditions imposed) -- independent of the closed
forms; the half-space limit (t -> inf); the thin-layer limits (a laterally free strip
u = p t / E*, a confined layer u = p t / M with the oedometric modulus M, the incompressible
bonded layer u = t^3 q^2 p / (3 mu)); the exact response to a sinusoidal pressure; full
contact of a sinusoidal surface; and serial == MPI (the tests run under mpirun).
"""
import itertools

import numpy as np
import pytest
from petsc4py import PETSc
from scipy.linalg import expm

from contactpetsc.geometry import surfaces
from contactpetsc.grid import SurfaceGrid
from contactpetsc.operators import (Layer, PeriodicHalfSpace, PeriodicLayer, half_space, layer_factor)
from contactpetsc.solvers import ContactProblem

E_STAR = 2.0e11
PLANNER = "estimate"
_ids = itertools.count()


def prefix(name):
    return f"lay{next(_ids)}{name}_"


def boundary_value_factor(x, nu, interface):
    """-W(t) / (2 P (1 - nu^2) / (E q)) for a layer 0 < z < t = x (q = 1, E = 1) under the surface
    traction sigma_zz = -P cos(q x'): u_x = i U(z) e^{iqx'}, u_z = W(z) e^{iqx'} in Navier's
    equations, Y = (U, U', W, W') with Y' = A Y; base z = 0: W = 0 and U = 0 (bonded) or
    sigma_xz = 0 (frictionless); surface z = t: sigma_xz = 0 and sigma_zz = -P."""
    mu, lam, q = 1.0 / (2 * (1 + nu)), nu / ((1 + nu) * (1 - 2 * nu)), 1.0
    a = np.zeros((4, 4))
    a[0, 1] = a[2, 3] = 1.0
    a[1, 0], a[1, 3] = (lam + 2 * mu) * q * q / mu, -(lam + mu) * q / mu
    a[3, 2], a[3, 1] = mu * q * q / (lam + 2 * mu), (lam + mu) * q / (lam + 2 * mu)
    m = expm(a * x)
    free = [1, 3] if interface == "bonded" else [0, 3]     # unknowns of Y(0)
    shear = m[1] + q * m[2]                                  # U' + q W at the surface
    normal = (lam + 2 * mu) * m[3] - lam * q * m[0]          # sigma_zz at the surface
    y0 = np.zeros(4)
    y0[free] = np.linalg.solve(np.array([shear[free], normal[free]]), [0.0, -1.0])
    return -(m @ y0)[2] / (2 * (1 - nu ** 2) / q)


@pytest.mark.parametrize("interface", ["bonded", "frictionless"])
@pytest.mark.parametrize("nu", [0.0, 0.3, 0.45, -0.5])
def test_factor_solves_the_boundary_value_problem(coll, interface, nu):
    x = np.array([0.01, 0.1, 0.5, 1.0, 2.0, 5.0])
    ref = np.array([boundary_value_factor(v, nu, interface) for v in x])
    got = layer_factor(x, interface, nu)
    assert coll.max(np.abs(got / ref - 1)) <= 1e-10


def test_factor_limits(coll):
    """f -> 1 (half-space; 1 - f ~ x^2 exp(-2x) < 1e-13 for qt >= 20); thin layers: the Winkler limits (module docstring)."""
    thick = np.array([20.0, 50.0, 400.0, 1e6])
    for interface, nu in (("bonded", 0.3), ("bonded", 0.5), ("frictionless", None)):
        assert coll.max(np.abs(layer_factor(thick, interface, nu) - 1)) <= 1e-13
        assert layer_factor(np.array([0.0]), interface, nu)[0] == 0.0
    x = 1e-4
    # a strip in plane strain free to expand along q: u = p t / E*, f = x / 2
    assert coll.max(abs(layer_factor(x, "frictionless") / (x / 2) - 1)) <= 1e-7
    for nu in (0.0, 0.25, 0.4):
        # a confined layer: u = p t (1 + nu)(1 - 2 nu) / (E (1 - nu)), f = 8 (1 - 2 nu) x / (kappa + 1)^2
        kappa = 3 - 4 * nu
        assert coll.max(abs(layer_factor(x, "bonded", nu) / (8 * (1 - 2 * nu) * x / (kappa + 1) ** 2) - 1)) <= 1e-7
    # incompressible bonded: u = t^3 q^2 p / (3 mu) (mu = E / 3, E* = 4 E / 3): f = 2 x^3 / 3
    for x in (1e-3, 1e-6):
        assert coll.max(abs(layer_factor(x, "bonded", 0.5) / (2 * x ** 3 / 3) - 1)) <= 1e-5


def test_bad_layers_are_refused(coll):
    for kw, message in ((dict(thickness=0.0), "thickness"), (dict(thickness=1.0, interface="glued"), "interface"),
                        (dict(thickness=1.0), "poisson_ratio"),
                        (dict(thickness=1.0, poisson_ratio=0.6), "(-1, 0.5]")):
        coll.raises(ValueError, message, Layer, **kw)
    g = SurfaceGrid(8, 8, 1.0, periodic=False)
    coll.raises(ValueError, ["periodic cell", "layer"], half_space, g, E_STAR,
                layer=Layer(1.0, "frictionless"), planner=PLANNER)


def test_a_layer_of_any_thickness_is_computed_or_refused_with_its_range(coll):
    """A layer far thicker than the cell is the half-space to the last bit (no overflow on the
    way: warnings are errors); a thin one the Winkler foundation u = p t / M (M = E* for a
    frictionless base, E* (kappa + 1)^2 / (16 (1 - 2 nu)) bonded) down to the thinnest the
    cell computes, f(2 pi t / L) = 1e-100 (here f = c x: t = 1e-100 L / (2 pi c)); thinner is
    refused with that range."""
    import warnings
    g = SurfaceGrid(16, 12, 1e-6, 1.5e-6)
    p = random_pressure(g)
    half = PeriodicHalfSpace(g, E_STAR, planner=PLANNER)
    u_half = half.apply(p, np.empty_like(p))
    x, y = g.coordinates()
    lx, ly = g.lengths
    smooth = np.cos(2 * np.pi * y / ly).T.copy()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for t in (1e3 * lx, 1e300):
            for interface in ("bonded", "frictionless"):
                thick = PeriodicLayer(g, E_STAR, Layer(t, interface, 0.3), planner=PLANNER)
                assert coll.max(np.abs(thick.apply(p, np.empty_like(p)) - u_half).max()) == 0.0
        for interface, nu in (("frictionless", None), ("bonded", 0.3)):
            c = 0.5 if nu is None else 8 * (1 - 2 * nu) / (4 - 4 * nu) ** 2       # f = c x
            t_min = 1e-100 * ly / (2 * np.pi * c)
            for t in (1e-3 * g.dx, 1e-30 * g.dx, 1.001 * t_min):
                thin = PeriodicLayer(g, E_STAR, Layer(t, interface, nu), planner=PLANNER)
                u = thin.apply(smooth, np.empty_like(smooth))
                assert coll.max(np.abs(u / (2 * c * t / E_STAR) - smooth).max()) <= 1e-5
            coll.raises(ValueError, ["layer thickness = ", f"accepted range [{t_min:.3g}, inf) m"],
                        PeriodicLayer, g, E_STAR, Layer(0.99 * t_min, interface, nu), planner=PLANNER)


@pytest.mark.parametrize("interface, nu", [("bonded", 0.3), ("frictionless", None), ("bonded", 0.5)])
@pytest.mark.parametrize("mx, my", [(1, 0), (0, 1), (3, -2), (7, 5)])
def test_sinusoidal_pressure_is_exact(coll, interface, nu, mx, my):
    """p0 cos(q.x) -> 2 p0 f(|q| t) / (E* |q|) cos(q.x) on a 24 x 15 cell with dx != dy."""
    nx, ny, dx, dy, p0 = 24, 15, 0.4e-6, 0.9e-6, 3.0e6
    t = 0.7e-6
    g = SurfaceGrid(nx, ny, dx, dy)
    op = PeriodicLayer(g, E_STAR, Layer(t, interface, nu), planner=PLANNER)
    lx, ly = g.lengths
    qx, qy = 2 * np.pi * mx / lx, 2 * np.pi * my / ly
    x, y = g.coordinates()
    phase = qx * x + qy * y
    u = op.apply(np.ascontiguousarray((p0 * np.cos(phase)).T), np.empty((g.ny_local, nx))).T
    q = np.hypot(qx, qy)
    amp = 2 * p0 / (E_STAR * q) * layer_factor(q * t, interface, nu)
    assert coll.max(np.abs(u - amp * np.cos(phase)) / amp) <= 1e-12


def random_pressure(g, seed=5):
    field = np.random.default_rng(seed).standard_normal((g.ny, g.nx))
    return np.ascontiguousarray(field[g.ys:g.ye])


def test_thick_layer_is_the_half_space_and_a_thin_one_a_winkler_foundation(coll):
    g = SurfaceGrid(32, 24, 1e-6, 1.3e-6)
    p = random_pressure(g)
    half = PeriodicHalfSpace(g, E_STAR, planner=PLANNER)
    u_half = half.apply(p, np.empty_like(p))
    scale = coll.max(np.abs(u_half).max())
    for interface in ("bonded", "frictionless"):
        thick = PeriodicLayer(g, E_STAR, Layer(30 * max(g.lengths), interface, 0.3), planner=PLANNER)
        u = thick.apply(p, np.empty_like(p))
        assert coll.max(np.abs(u - u_half).max()) <= 1e-14 * scale
        assert coll.max(abs(thick.self_influence / half.self_influence - 1)) <= 1e-14
        assert coll.max(abs(thick.lowest_mode_stiffness() / half.lowest_mode_stiffness() - 1)) <= 1e-14
    # a thin frictionless layer under a smooth pressure (the cell's lowest modes): u = (p - mean p) t / E*
    t = 1e-4 * max(g.lengths)
    x, y = g.coordinates()
    lx, ly = g.lengths
    smooth = (np.cos(2 * np.pi * x / lx) + 0.5 * np.sin(2 * np.pi * (x / lx + 2 * y / ly))).T.copy()
    thin = PeriodicLayer(g, E_STAR, Layer(t, "frictionless"), planner=PLANNER)
    u = thin.apply(smooth, np.empty_like(smooth))
    assert coll.max(np.abs(u - smooth * t / E_STAR).max()) <= 1e-5 * t / E_STAR


def test_coarse_grids_keep_the_layer(coll):
    """The nested iteration and MLMI rediscretise the same body (``on_grid``)."""
    g = SurfaceGrid(32, 32, 1e-6)
    layer = Layer(2e-6, "bonded", 0.35)
    op = PeriodicLayer(g, E_STAR, layer, planner=PLANNER)
    gc = SurfaceGrid(16, 16, 2e-6)
    coarse = op.on_grid(gc, planner=PLANNER)
    assert isinstance(coarse, PeriodicLayer) and coarse.layer == layer and coarse.e_star == E_STAR
    ref = PeriodicLayer(gc, E_STAR, layer, planner=PLANNER)
    assert coll.max(abs(coarse.self_influence / ref.self_influence - 1)) <= 1e-15


@pytest.mark.parametrize("preconditioner", ["spectral", "mlmi"])
def test_full_contact_of_a_sinusoid_on_a_layer(coll, preconditioner):
    """h = H0 (1 - cos qx) pressed flat: p = pbar + H0 / K(q) cos qx, K(q) = 2 f(qt) / (E* q)."""
    n, lam, h0, t = 64, 1e-6, 1e-9, 0.08e-6
    layer = Layer(t, "bonded", 0.3)
    g = SurfaceGrid(n, n // 2, lam / n)
    q = 2 * np.pi / lam
    h = surfaces.from_function(g, lambda x, y: h0 * (1 - np.cos(q * x)))
    amp = h0 * E_STAR * q / (2 * layer_factor(q * t, "bonded", 0.3))
    op = PeriodicLayer(g, E_STAR, layer)
    prob = ContactProblem(g, h, E_STAR, operator=op, preconditioner=preconditioner, prefix=prefix("full"))
    st = prob.solve(mean_pressure=1.5 * amp)
    x, _ = g.coordinates()
    err = np.abs(g.local_array(st.pressure, readonly=True) - (1.5 * amp + amp * np.cos(q * x))).max() / amp
    assert coll.all(st.converged) and coll.max(st.contact_fraction) == 1.0
    assert coll.max(err) <= 1e-9


def test_partial_contact_on_a_thick_layer_is_the_half_space_one(coll):
    """A rough surface on a layer 30 cells deep gives the half-space's solution; a thinner layer
    is stiffer: less approach for the same load (a closed-form-free, monotone check)."""
    g = SurfaceGrid(64, 64, 1.0 / 64)
    h = surfaces.self_affine(g, hurst=0.8, seed=3, rms_slope=0.1, rolloff_wavelength=0.25,
                             short_cutoff_wavelength=4.0 / 64)
    load = 0.005 * E_STAR
    kw = dict(tol=1e-12, load_tol=1e-12)
    ref = ContactProblem(g, h, E_STAR, prefix=prefix("half"), **kw).solve(mean_pressure=load)
    deep = ContactProblem(g, h, E_STAR, operator=PeriodicLayer(g, E_STAR, Layer(30.0, "bonded", 0.3)),
                          prefix=prefix("deep"), **kw).solve(mean_pressure=load)
    d = deep.pressure.copy()
    d.axpy(-1.0, ref.pressure)
    assert coll.max(d.norm(PETSc.NormType.INFINITY) / ref.pressure.max()[1]) <= 1e-8
    thin = ContactProblem(g, h, E_STAR, operator=PeriodicLayer(g, E_STAR, Layer(0.01, "bonded", 0.3)),
                          prefix=prefix("thin"), **kw).solve(mean_pressure=load)
    assert coll.all(thin.converged) and thin.contact_fraction < ref.contact_fraction


def test_adhesive_contact_on_a_layer(coll):
    """With adhesion too: a layer 30 cells deep gives the half-space's adhesive state; a thin
    bonded layer, stiffer, converges to a stable state with less contact at the same approach."""
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    n = 32
    g = SurfaceGrid(n, n, 1.0)
    h = surfaces.self_affine(g, hurst=0.8, rms_height=1.0, seed=7)
    law = make_law("hardwall-lj", work_of_adhesion=0.05, z0=1.0)
    delta = h.min()[1] + 0.8
    states = []
    for name, op in (("half", None), ("deep", PeriodicLayer(g, 1.0, Layer(30.0 * n, "bonded", 0.3))),
                     ("thin", PeriodicLayer(g, 1.0, Layer(2.0, "bonded", 0.3)))):
        pb = AdhesiveProblem(g, h, 1.0, law, operator=op, prefix=prefix("adh" + name))
        st = pb.solve(approach=delta)
        assert coll.all(st.converged and st.stable)
        assert coll.max(max(st.complementarity_error, st.adhesive_error)) <= 1e-8
        states.append(st)
    half, deep, thin = states
    assert coll.max(abs(deep.force - half.force)) <= 1e-7 * abs(half.force)
    assert coll.max(np.abs(g.rows(deep.gap, readonly=True) - g.rows(half.gap, readonly=True))) <= 1e-6
    assert thin.contact_fraction < half.contact_fraction and thin.force > half.force
