"""Atomic-scale tips (reference paper, section 3.3): hard-sphere profiles and forces per atom.

Truths: the spherical cap of one atom, z_a - sqrt(r_a^2 - s^2); the period of a
flat crystal face (its nearest-neighbour spacing); the nominal sphere the
atoms lie on; uniform pressure times each atom's Voronoi area; COMM_SELF ==
COMM_WORLD.
"""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc import metrics
from contactpetsc.geometry import tips
from contactpetsc.grid import GridError, SurfaceGrid
from contactpetsc.geometry.surfaces import centre

COMMS = (PETSc.COMM_WORLD, PETSc.COMM_SELF)


def gather_owner(grid, owner):
    return np.concatenate(grid.mpi_comm.allgather(np.ascontiguousarray(owner)), axis=0).T


def test_single_atom_gives_its_spherical_cap(coll):
    g = SurfaceGrid(40, 37, 0.1, periodic=False)
    r = 1.3
    tip = tips.Tip("one", np.array([[0.23, -0.11, 0.0]]), r, 100.0, 2 * r)
    h, owner = tips.profile(g, tip)
    h, owner = g.gather(h), gather_owner(g, owner)
    xc, yc = centre(g)
    x = np.arange(g.nx)[:, None] * g.dx - xc - 0.23
    y = np.arange(g.ny)[None, :] * g.dy - yc + 0.11
    s2 = x ** 2 + y ** 2
    inside = s2 < r * r
    cap = -np.sqrt(np.where(inside, r * r - s2, 0.0))
    cap -= cap[inside].min()
    assert coll.max(np.abs(h[inside] - cap[inside])) <= 1e-12
    assert coll.all(np.all(owner[inside] == 0) and np.all(owner[~inside] == -1))
    assert coll.max(np.abs(h[~inside] - cap[inside].max())) <= 1e-12   # uncovered: highest covered


def test_flat_crystal_face_is_periodic_with_its_spacing(coll):
    """A flat (001) face (no bending): the profile repeats every nearest-neighbour spacing d
    along x and y (8 nodes per d), away from the window's edge."""
    d = tips.LJ_SPACING
    g = SurfaceGrid(64, 64, d / 8, periodic=False)
    tip = tips.Tip("flat", tips.fcc_001(d, 5 * d, 3 * d / np.sqrt(2)), 0.5 * d, 1e9, d)
    h = g.gather(tips.profile(g, tip)[0])
    core = h[8:-16, 8:-16]
    assert coll.max(np.abs(h[16:-8, 8:-16] - core)) <= 1e-12
    assert coll.max(np.abs(h[8:-16, 16:-8] - core)) <= 1e-12
    assert coll.max(core) > 0.05 * d          # the atoms show: not a flat profile


@pytest.mark.parametrize("kind", tips.KINDS)
def test_tips_follow_the_nominal_sphere(coll, kind):
    """Every tip is a sphere of radius R to within atomic roughness: the profile minus the
    paraboloid has rms below d / 2 over the window (d for the amorphous tip, whose
    random packing leaves pits between its outer atoms); the commensurate tip's surface atoms
    sit on the counter-surface lattice (multiples of d in the plane)."""
    d, radius = tips.LJ_SPACING, 100.0
    g = SurfaceGrid(96, 96, 0.25, periodic=False)
    tip = tips.make_tip(kind, g, radius, d)
    h = g.gather(tips.profile(g, tip)[0])
    xc, yc = centre(g)
    x = np.arange(g.nx)[:, None] * g.dx - xc
    y = np.arange(g.ny)[None, :] * g.dy - yc
    dev = h - (x ** 2 + y ** 2) / (2 * radius)
    assert coll.max(np.std(dev)) < (1.0 if kind == "amorphous" else 0.5) * d
    if kind == "bent-commensurate":
        on_lattice = np.round(tip.atoms[:, :2] / (0.5 * d)) * 0.5 * d
        assert coll.max(np.abs(on_lattice - tip.atoms[:, :2])) <= 1e-12
    if kind == "bent-incommensurate":
        assert coll.max(abs(tip.spacing / d - 0.94)) <= 1e-12


@pytest.mark.parametrize("kind", tips.KINDS)
def test_tip_profiles_rank_independent(coll, kind):
    out = []
    for comm in COMMS:
        g = SurfaceGrid(48, 45, 0.3, periodic=False, comm=comm)
        tip = tips.make_tip(kind, g, 100.0, tips.LJ_SPACING, seed=5)
        h, owner = tips.profile(g, tip)
        out.append((g.gather(h), gather_owner(g, owner)))
    assert coll.max(np.abs(out[0][0] - out[1][0])) == 0.0
    assert coll.all(np.array_equal(out[0][1], out[1][1]))


def test_make_tip_errors(coll):
    g = SurfaceGrid(16, 16, 1.0, periodic=False)
    coll.raises(ValueError, "tip kind", tips.make_tip, "pyramid", g, 100.0, 1.0)
    coll.raises(GridError, "wider than the tip", tips.make_tip, "stepped", g, 5.0, 1.0)


def test_force_per_atom_of_a_uniform_pressure(coll):
    """Uniform pressure p0: each atom's force is p0 times its footprint (the Voronoi cell:
    a^2 for an atom of a square lattice of spacing a aligned with the grid), and the forces
    sum to the total force."""
    a, n_per = 1.0, 5                       # 5 x 5 nodes per atom: cells hold whole nodes
    g = SurfaceGrid(40, 35, a / n_per, periodic=False)
    ax, ay = np.meshgrid(np.arange(8) * a + 2 * g.dx, np.arange(7) * a + 2 * g.dy, indexing="ij")
    atoms = np.column_stack([ax.ravel(), ay.ravel()])
    owner = metrics.nearest_atom(g, atoms)
    p0 = 3.5e6
    f = metrics.atom_forces(g, g.create_vec(p0), owner, len(atoms))
    assert coll.max(np.abs(f / (p0 * a * a) - 1)) <= 1e-12
    assert coll.max(abs(f.sum() / (p0 * g.lengths[0] * g.lengths[1]) - 1)) <= 1e-12
