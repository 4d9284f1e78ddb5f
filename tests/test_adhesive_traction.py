"""Adhesive traction: its derivative and the element integration of the reference paper (Fig. 3).

Independent truths: finite differences of the traction, the law itself on a uniform gap, the
Derjaguin force on a rigid paraboloid (2 pi R Phi(g0)).  Units: z0 = 1, E* = 1 (Greenwood's).
"""
import numpy as np
import pytest

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.physics.traction import AdhesiveTraction
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import from_function


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("element", [False, True])
@pytest.mark.parametrize("law", ["lj", "hardwall-lj"])
def test_traction_derivative_matches_finite_differences(coll, periodic, element, law):
    grid = SurfaceGrid(24, 19, 0.7, periodic=periodic)
    tr = AdhesiveTraction(make_law(law, work_of_adhesion=0.3, z0=1.0), grid, element)
    x, y = grid.coordinates()
    g = (0.4 + 0.8 * np.sin(0.5 * x) * np.cos(0.3 * y) + 0.3 * np.cos(0.9 * x)).T.copy()
    dg = (np.cos(0.7 * x + 0.2) * np.sin(0.4 * y)).T.copy()
    tr.linearise(g)
    lin = tr.apply_derivative(dg, np.empty_like(g))
    eps = 1e-6
    fd = (tr.pressure(g + eps * dg) - tr.pressure(g - eps * dg)) / (2 * eps)
    assert coll.max(np.abs(lin - fd)) < 1e-6 * coll.max(np.abs(fd))


HARD_WALL_LAWS = {"hardwall-lj": {"z0": 1.0}, "exponential": {"rho": 1.0}, "dugdale": {"sigma0": 0.5}}


@pytest.mark.parametrize("law", sorted(HARD_WALL_LAWS))
def test_a_hard_wall_laws_traction_is_smooth_through_the_wall(coll, law):
    """Below a hard wall (g < 0), where only Newton's iterates go, the traction is the law's
    Taylor polynomial at g = 0: its slope there is the law's at the wall, its linearisation
    matches finite differences that cross the wall, -dPhi/dg is the pressure across it, and on
    g >= 0 it is the law itself.  With the pressure held at its contact value below and the
    slope jumping at the wall (0 to -6 p_s / z0 for hard-wall LJ), the VI Newton's direction
    was no descent direction where an inexact Krylov step moved contact nodes across it (a
    hard-wall sphere at Tabor 2 failed at 13 of 47 path states)."""
    grid = SurfaceGrid(16, 12, 0.5)
    lw = make_law(law, work_of_adhesion=0.3, **HARD_WALL_LAWS[law])
    tr = AdhesiveTraction(lw, grid)
    shape = (grid.ny_local, grid.nx)
    below = np.full(shape, -1e-3)
    assert coll.max(np.abs(tr.nodal_derivative(below) - lw.derivative(0.0))) == 0.0
    rng = np.random.default_rng(coll.rank)
    h = 1e-4
    g = rng.uniform(-0.5 * h, 0.5 * h, size=shape)     # every difference below crosses the wall
    dg = rng.choice([-1.0, 1.0], size=shape)
    tr.linearise(g)
    lin = tr.apply_derivative(dg, np.empty_like(g))
    fd = (tr.pressure(g + h * dg) - tr.pressure(g - h * dg)) / (2 * h)
    scale = max(abs(float(lw.derivative(0.0))), lw.peak_attraction)
    assert coll.max(np.abs(lin - fd)) < 1e-2 * scale
    dphi = (tr.energy(g + h) - tr.energy(g - h)) / (2 * h)
    assert coll.max(np.abs(dphi + tr.pressure(g))) < 1e-2 * lw.peak_attraction
    up = np.abs(g) + 0.01
    assert coll.max(np.abs(tr.pressure(up) - lw.pressure(up))) == 0.0


def test_element_integration_is_exact_for_uniform_gaps(coll):
    grid = SurfaceGrid(8, 6, 1.0)
    law = make_law("lj", work_of_adhesion=0.3, z0=1.0)
    g = np.full((grid.ny_local, grid.nx), 0.37)
    a = AdhesiveTraction(law, grid, True).pressure(g)
    assert coll.max(np.abs(a - law.pressure(0.37))) < 1e-12


def rigid_tip_forces(coll, element, radius, dx, gap0, shifts, n=64):
    """Total traction [N] on a rigid paraboloid at apex gap ``gap0`` for sub-node apex shifts."""
    law = make_law("lj", work_of_adhesion=0.01, z0=1.0)
    grid = SurfaceGrid(n, n, dx, periodic=False)
    tr = AdhesiveTraction(law, grid, element)
    out = []
    for s in shifts:
        x0, y0 = (n // 2 + 0.5 * s) * dx, (n // 2 + 0.37 * s) * dx
        h = from_function(grid, lambda x, y: ((x - x0) ** 2 + (y - y0) ** 2) / (2 * radius) + gap0)
        g = grid.rows(h, readonly=True).copy()
        out.append(grid.mpi_comm.allreduce(float(tr.pressure(g).sum())) * dx * dx)
    return np.array(out) / (2 * np.pi * radius * law.energy(gap0))   # Derjaguin: 2 pi R Phi(g0)


def test_element_integration_removes_node_position_dependence(coll):
    """An under-resolved tip (adhesive zone ~ one element): element integration cuts the
    scatter of the total adhesive force over apex positions by > 4x (reference paper, Fig. 3)."""
    shifts = np.linspace(0.0, 1.0, 6)
    nodal = rigid_tip_forces(coll, False, radius=8.0, dx=4.0, gap0=0.0, shifts=shifts)
    element = rigid_tip_forces(coll, True, radius=8.0, dx=4.0, gap0=0.0, shifts=shifts)
    assert np.ptp(nodal) > 4 * np.ptp(element)
    # resolved (and the window wide enough for the z^-2 tail): the Derjaguin force
    for element in (False, True):
        resolved = rigid_tip_forces(coll, element, radius=20.0, dx=0.5, gap0=0.2, shifts=[0.0, 0.5], n=128)
        assert np.max(np.abs(resolved - 1.0)) < 5e-3


def test_element_integration_on_a_deformable_sphere(coll):
    """The same under-resolved sphere (R = 20 z0, dx = 4 z0, mu = 0.13, lj) as an elastic body held
    at an apex gap of z0/2: over sub-node apex positions the total force scatters less with
    element integration (measured 0.09 % against 0.30 % of the force), and both stay near the
    rigid sphere's Derjaguin force 2 pi R Phi(z0/2), which the body's deformation towards the
    plane exceeds by a few per cent (measured: nodal +6.8 %, element integration -2.4 %: its
    linear gap between nodes lies above a curved surface, a bias of order (dx / R)^2 that
    sampling at the nodes does not have; docs/validation.md)."""
    law = make_law("lj", work_of_adhesion=0.01, z0=1.0)
    n, dx, radius = 64, 4.0, 20.0
    forces = {}
    for element in (False, True):
        out = []
        for s in np.linspace(0.0, 1.0, 6):
            grid = SurfaceGrid(n, n, dx, periodic=False)
            x0, y0 = (n // 2 + 0.5 * s) * dx, (n // 2 + 0.37 * s) * dx
            h = from_function(grid, lambda x, y: ((x - x0) ** 2 + (y - y0) ** 2) / (2 * radius))
            pb = AdhesiveProblem(grid, h, 1.0, law, element_integration=element, prefix=f"eid{int(element)}_",
                                 stability_check=False)
            st = pb.solve(approach=-0.5)
            out.append(st.force)
        forces[element] = np.array(out)
    scatter = {k: np.ptp(f) / abs(f.mean()) for k, f in forces.items()}
    assert coll.max(scatter[True]) < 0.5 * scatter[False], scatter
    derjaguin = 2 * np.pi * radius * law.energy(0.5)
    for f in forces.values():
        assert coll.max(np.abs(f / derjaguin - 1).max()) < 0.1, (f, derjaguin)


@pytest.mark.parametrize("law", ["lj", "hardwall-lj", "exponential"])
def test_the_law_into_a_callers_array_is_the_law(coll, monkeypatch, law):
    """The nodal law written into a caller's array a block of nodes at a time (blocks of 37
    nodes here, so that they split rows) is the law evaluated on the whole array, value for
    value, into a contiguous array or a strided one; below the full LJ curve's safe gap too."""
    from contactpetsc.physics import traction as traction_module
    monkeypatch.setattr(traction_module, "BLOCK", 37)
    grid = SurfaceGrid(24, 20, 1.0, periodic=True)
    tr = AdhesiveTraction(make_law(law, work_of_adhesion=0.05, **({"rho": 1.0} if law == "exponential" else {"z0": 1.0})), grid)
    rng = np.random.default_rng(3)
    g = rng.uniform(-0.8, 3.0, size=(grid.ny_local, grid.nx))
    for method in ("pressure", "energy", "nodal_derivative"):
        whole = getattr(tr, method)(g)
        out = np.empty_like(g)
        strided = np.empty((g.shape[1], g.shape[0])).T
        for target in (out, strided):
            assert getattr(tr, method)(g, out=target) is target
            assert np.array_equal(target, whole), method
