"""Property tests (hypothesis) of the interaction laws and the elastic operators.

Properties that hold for any parameters: dimensional scaling, symmetry, positivity, energy
consistency (the mean value theorem for element-integrated pressures), monotonicity where it
holds, and rank-count independence (COMM_WORLD against COMM_SELF).

Collective-safe under mpirun: ``derandomize=True`` gives every rank the same examples, and
every verdict is reduced over the ranks before it is asserted, so all ranks pass or fail (and
shrink) together.
"""
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.operators import IsolatedHalfSpace, PeriodicHalfSpace
from contactpetsc.physics.interactions import make_law
from contactpetsc.physics.traction import AdhesiveTraction

WORLD = PETSc.COMM_WORLD.tompi4py()
SIZE = WORLD.Get_size()
prop = settings(max_examples=20, deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow])
log_float = lambda lo, hi: st.floats(lo, hi).map(lambda e: 10.0 ** e)  # noqa: E731
LAWS = ["lj", "hardwall-lj", "exponential", "dugdale"]


def law_of(name, w, length):
    """A law of work w [J/m^2] and range ``length`` [m] (Dugdale: sigma0 = w / length)."""
    key = {"lj": "z0", "hardwall-lj": "z0", "exponential": "rho", "dugdale": "sigma0"}[name]
    return make_law(name, work_of_adhesion=w, **{key: w / length if name == "dugdale" else length})


# -- interaction laws ------------------------------------------------------------------------------
@pytest.mark.parametrize("name", LAWS)
@prop
@given(w=log_float(-6, 3), length=log_float(-12, -3), scale=log_float(-3, 3),
       t=st.lists(st.floats(-0.4, 6.0), min_size=1, max_size=8))
def test_laws_scale_with_w_and_the_range(coll, name, w, length, scale, t):
    """p(s g; w, s L) = p(g; w, L) / s, Phi(s g; w, s L) = Phi(g; w, L), p(g; c w, L) = c p(g; w, L):
    the laws depend on g / L and w only, at any magnitude (no overflow or lost digits)."""
    g = np.array(t) * length
    a, b, c = law_of(name, w, length), law_of(name, w, scale * length), law_of(name, 7.0 * w, length)
    p = a.pressure(g)
    ref = np.abs(p).max() + a.peak_attraction * 1e-12
    errs = [np.abs(b.pressure(scale * g) * scale - p).max() / ref,
            np.abs(b.energy(scale * g) - a.energy(g)).max() / w,
            np.abs(c.pressure(g) - 7.0 * p).max() / (7.0 * ref)]
    assert coll.max(errs) <= 1e-10


@pytest.mark.parametrize("name", LAWS)
@prop
@given(ta=st.floats(-0.4, 5.0), tb=st.floats(-0.4, 5.0))
def test_segment_mean_pressure_is_symmetric_and_a_mean(coll, name, ta, tb):
    """Element integration (Phi(a) - Phi(b)) / (b - a): the same for a <-> b, and between the
    smallest and largest pressure on [a, b] (mean value theorem: energy consistency of p = -Phi').
    Hard-wall laws on their domain g >= 0 (below it p and Phi are extended apart: p by its
    contact value, Phi as a constant)."""
    law = law_of(name, 0.2, 1.0)
    if law.hard_wall:
        ta, tb = abs(ta), abs(tb)
    ab, ba = law.segment_mean_pressure(ta, tb), law.segment_mean_pressure(tb, ta)
    p = law.pressure(np.linspace(min(ta, tb), max(ta, tb), 20001))
    slack = 1e-3 * law.peak_attraction + 1e-6 * np.abs(p).max()   # the sampled extremes
    ok = (abs(ab - ba) <= 1e-12 * max(1.0, abs(ab))
          and p.min() - slack <= ab <= p.max() + slack)
    assert coll.all(ok), (ab, ba, p.min(), p.max())


@prop
@given(t=st.lists(st.floats(-0.45, 20.0), min_size=2, max_size=40, unique=True))
def test_lj_signs_and_monotonicity(coll, t):
    """Full LJ: p > 0 below z0, < 0 above (positivity of the repulsion); p falls up to the peak
    attraction at z = 3^(1/6) z0 and rises towards 0 beyond it; Phi >= -w, equality at z = z0."""
    law = law_of("lj", 0.3, 1.0)
    g = np.sort(np.array(t))
    z = g + 1.0
    p, dp, phi = law.pressure(g), law.derivative(g), law.energy(g)
    z_peak = 3 ** (1 / 6)
    near = lambda v: np.abs(z - v) < 1e-9  # noqa: E731
    ok = [np.all((np.sign(p) == np.sign(1.0 - z)) | near(1.0)),
          np.all((dp <= 0) | (z > z_peak) | near(z_peak)),
          np.all((dp >= 0) | (z < z_peak) | near(z_peak)),
          np.all(np.diff(p[z <= z_peak]) <= 0), np.all(np.diff(p[z >= z_peak]) >= 0),
          np.all(phi >= -0.3 * (1 + 1e-12)), np.all(np.diff(phi[z >= 1.0]) >= 0)]
    assert coll.all(all(ok)), ok


@pytest.mark.parametrize("name", ["hardwall-lj", "exponential", "dugdale"])
@prop
@given(t=st.lists(st.floats(0.0, 30.0), min_size=2, max_size=40, unique=True))
def test_hard_wall_laws_attract_only_and_energy_rises_to_zero(coll, name, t):
    """Away from the wall: p <= 0 (the wall alone repels), -w <= Phi <= 0 rising with the gap."""
    law = law_of(name, 0.3, 1.0)
    g = np.sort(np.array(t))
    p, phi = law.pressure(g), law.energy(g)
    ok = (np.all(p <= 0) and np.all(phi <= 0) and np.all(phi >= -0.3 * (1 + 1e-12))
          and np.all(np.diff(phi) >= -1e-15))
    assert coll.all(ok)


@pytest.mark.parametrize("element", [False, True])
@prop
@given(seed=st.integers(0, 2**31), nx=st.integers(3, 12), ny=st.integers(max(3, SIZE), 23),
       periodic=st.booleans())
def test_traction_is_rank_count_independent(coll, element, seed, nx, ny, periodic):
    """The adhesive traction of a random gap field (element-integrated: with halo rows from the
    neighbouring ranks) is bit-identical on COMM_WORLD and on COMM_SELF."""
    law = law_of("lj", 0.2, 1.0)
    gap = np.random.default_rng(seed).uniform(-0.3, 4.0, (nx, ny))
    world_grid = SurfaceGrid(nx, ny, 0.7, periodic=periodic)
    world_rows = AdhesiveTraction(law, world_grid, element).pressure(
        np.ascontiguousarray(gap[:, world_grid.ys:world_grid.ye].T))
    self_grid = SurfaceGrid(nx, ny, 0.7, periodic=periodic, comm=PETSc.COMM_SELF)
    self_rows = AdhesiveTraction(law, self_grid, element).pressure(np.ascontiguousarray(gap.T))
    err = np.abs(world_rows - self_rows[world_grid.ys:world_grid.ye]).max()
    assert coll.max(err) == 0.0


# -- elastic operators -------------------------------------------------------------------------------
def operator(periodic, nx, ny, dx, dy, e_star, comm=None):
    grid = SurfaceGrid(nx, ny, dx, dy, periodic=periodic, comm=comm)
    cls = PeriodicHalfSpace if periodic else IsolatedHalfSpace
    return grid, cls(grid, e_star, planner="estimate")


def apply(grid, op, field):
    """K field for a global (nx, ny) field; the gathered (nx, ny) result on every rank."""
    rows = np.ascontiguousarray(field[:, grid.ys:grid.ye].T)
    out = op.apply(rows, np.empty_like(rows))
    return np.concatenate(grid.mpi_comm.allgather(out), axis=0).T


# the slab FFT gives each rank at least one of the nx // 2 + 1 Fourier columns
grids = dict(nx=st.integers(max(3, 2 * SIZE), 17), ny=st.integers(max(3, SIZE), 19), dx=log_float(-9, -3),
             aspect=st.floats(0.3, 3.0), e_star=log_float(3, 12), seed=st.integers(0, 2**31),
             periodic=st.booleans())


@prop
@given(**grids)
def test_operator_symmetric_positive_and_scaled(coll, nx, ny, dx, aspect, e_star, seed, periodic):
    """<K x, y> = <x, K y>; <x, K x> > 0 (periodic: zero-mean x); E* K is independent of E*;
    K is linear."""
    grid, op = operator(periodic, nx, ny, dx, aspect * dx, e_star)
    rng = np.random.default_rng(seed)
    x, y = rng.standard_normal((2, nx, ny))
    if periodic:
        x -= x.mean()
        y -= y.mean()
    kx, ky = apply(grid, op, x), apply(grid, op, y)
    exx, eyy = np.vdot(x, kx), np.vdot(y, ky)
    _, op1 = operator(periodic, nx, ny, dx, aspect * dx, 1.0)
    kxy = apply(grid, op, 2.0 * x - 3.0 * y)
    errs = [abs(np.vdot(kx, y) - np.vdot(x, ky)) / np.sqrt(exx * eyy),
            np.abs(apply(grid, op1, x) / e_star - kx).max() / np.abs(kx).max(),
            np.abs(kxy - (2.0 * kx - 3.0 * ky)).max() / np.abs(kxy).max()]
    assert coll.max(errs) <= 1e-12
    assert coll.all(exx > 0 and eyy > 0)


@prop
@given(**grids)
def test_operator_positivity_and_geometric_symmetry(coll, nx, ny, dx, aspect, e_star, seed, periodic):
    """Isolated: a positive pressure pushes every node down (K p > 0), and a mirrored pressure
    gives the mirrored displacement.  Periodic: a shifted pressure gives the shifted displacement."""
    grid, op = operator(periodic, nx, ny, dx, aspect * dx, e_star)
    rng = np.random.default_rng(seed)
    p = rng.uniform(0.0, 1.0, (nx, ny))
    v = apply(grid, op, p)
    if periodic:
        sx, sy = rng.integers(0, nx), rng.integers(0, ny)
        moved = apply(grid, op, np.roll(p, (sx, sy), axis=(0, 1)))
        err = np.abs(moved - np.roll(v, (sx, sy), axis=(0, 1))).max() / np.abs(v).max()
        ok = True
    else:
        err = np.abs(apply(grid, op, p[::-1, ::-1]) - v[::-1, ::-1]).max() / np.abs(v).max()
        ok = bool(np.all(v > 0))
    assert coll.max(err) <= 1e-12 and coll.all(ok)


@prop
@given(**grids)
def test_isolated_point_load_displacement_falls_with_distance(coll, nx, ny, dx, aspect, e_star, seed, periodic):
    """One loaded element of an isolated half-space: the displacement falls monotonically along
    each axis away from it (Love's solution; ``periodic`` and ``seed`` pick the loaded node)."""
    grid, op = operator(False, nx, ny, dx, aspect * dx, e_star)
    rng = np.random.default_rng(seed)
    i, j = rng.integers(0, nx), rng.integers(0, ny)
    p = np.zeros((nx, ny))
    p[i, j] = 1.0
    v = apply(grid, op, p)
    ok = (np.all(np.diff(v[i:, j]) < 0) and np.all(np.diff(v[:i + 1, j]) > 0)
          and np.all(np.diff(v[i, j:]) < 0) and np.all(np.diff(v[i, :j + 1]) > 0))
    assert coll.all(ok)


@prop
@given(**grids)
def test_operator_rank_count_independent(coll, nx, ny, dx, aspect, e_star, seed, periodic):
    """K p and K^-1 v on COMM_WORLD (any split of the rows) equal COMM_SELF's to 1e-12."""
    p = np.random.default_rng(seed).standard_normal((nx, ny))
    res = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        grid, op = operator(periodic, nx, ny, dx, aspect * dx, e_star, comm=comm)
        v = apply(grid, op, p)
        rows = np.ascontiguousarray(v[:, grid.ys:grid.ye].T)
        inv = op.apply_inverse(rows, np.empty_like(rows))
        res.append((v, np.concatenate(grid.mpi_comm.allgather(inv), axis=0).T))
    (vw, iw), (vs, i_s) = res
    errs = [np.abs(vw - vs).max() / np.abs(vs).max(), np.abs(iw - i_s).max() / np.abs(i_s).max()]
    assert coll.max(errs) <= 1e-12


# -- the VI's inactive set -------------------------------------------------------------------------
@prop
@given(n=st.integers(1, 60), seed=st.integers(0, 2 ** 16), tail=st.booleans())
def test_inactive_set_copies_are_numpy_indexing(coll, n, seed, tail):
    """The reduced-Vec copies of any sorted set of positions (with or without a trailing run of
    consecutive ones, as a hard wall's adhesive block) equal numpy's indexed assignment and take."""
    from contactpetsc.solvers.reduced import InactiveSet
    rng = np.random.default_rng(seed)
    mask = rng.random(n) < rng.random()
    if tail:
        mask[n // 2:] = True
    idx = np.flatnonzero(mask)
    offset = 3
    iset = PETSc.IS().createGeneral((idx + offset).astype(PETSc.IntType), comm=PETSc.COMM_SELF)
    inactive = InactiveSet(iset, offset, n)
    x = PETSc.Vec().createSeq(idx.size, comm=PETSc.COMM_SELF)
    x.setArray(rng.standard_normal(idx.size))
    out, truth = np.full(n, np.nan), np.full(n, np.nan)
    truth[idx] = x.getArray()
    inactive.to_full(x, out)
    full = rng.standard_normal(n)
    y = x.duplicate()
    inactive.from_full(full, y)
    ok = (np.array_equal(out, truth, equal_nan=True) and np.array_equal(y.getArray(), full[idx])
          and inactive.everything == (idx.size == n))
    for obj in (iset, x, y):
        obj.destroy()
    assert coll.all(ok)
