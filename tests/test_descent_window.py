"""The energy descent on an isolated window (``solvers/descent_space.py``): the displacement on
the padded grid, the law on the window.

Independent truths: the window operator K_w (Love's coefficients, linear convolution) against
the padded grid's circulant, the equilibrium Newton reaches on the window's own unknowns from
the same start, the Lanczos stability check, the descent property (a state reached across a
jump has less energy than its start at the new approach), and COMM_WORLD against COMM_SELF.
Units: z0 = 1, E* = 1, dx = 1.
"""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from adhesive_setup import energy_moved, sphere_problem
from contactpetsc.grid import SurfaceGrid
from contactpetsc.operators.elastic import IsolatedHalfSpace
from contactpetsc.operators.love import love_displacement
from contactpetsc.solvers.descent import EnergyDescent
from contactpetsc.solvers.descent_space import PaddedWindow


class _Problem:
    """What ``PaddedWindow`` reads of a problem."""

    def __init__(self, grid, op):
        self.grid, self.op = grid, op


def test_the_padded_displacement_is_the_windows_with_no_pressure_outside(coll):
    """u = C E p on the padded grid is, on the window, Love's displacement of p (the dense sum
    of the rectangles' influence coefficients), and C^-1 u is p there and zero outside (the
    equilibrium the padded energy's minimum is, module doc); on a window whose rows leave one
    of three ranks none."""
    grid = SurfaceGrid(12, 20, 0.7, 0.9, periodic=False, comm=PETSc.COMM_WORLD)
    e_star = 2.5
    op = IsolatedHalfSpace(grid, e_star)
    space = PaddedWindow(_Problem(grid, op))
    p_all = np.random.default_rng(3).standard_normal((grid.ny, grid.nx))
    p = p_all[grid.ys:grid.ye]
    u = np.empty((space.grid.ny_local, space.grid.nx))
    space.displacement(p, u)
    back = np.empty_like(p)
    space.to_problem(np.ascontiguousarray(u[space.window]), back)
    y, x = (c.ravel() for c in np.meshgrid(np.arange(grid.ny) * grid.dy, np.arange(grid.nx) * grid.dx,
                                           indexing="ij"))
    mine = slice(grid.ys * grid.nx, grid.ye * grid.nx)
    coeff = love_displacement(x[mine, None] - x[None, :], y[mine, None] - y[None, :], 0.5 * grid.dx, 0.5 * grid.dy,
                              e_star)
    love = (coeff @ p_all.ravel()).reshape(p.shape)
    assert coll.max(np.abs(back - love)) < 1e-12 * coll.max(np.abs(love))
    pressure = space.convolve(op.inverse_pairs, u, np.empty_like(u))
    space.to_problem(np.ascontiguousarray(pressure[space.window]), back)
    assert coll.max(np.abs(back - p)) < 1e-10
    assert coll.max(space.outside_gap(pressure)) < 1e-10 * coll.max(np.abs(love))
    pressure[space.window] = 0.0
    assert coll.max(np.abs(pressure)) < 1e-10
    if grid.mpi_comm.Get_size() == 3:
        held = space.window[0].stop - space.window[0].start
        assert grid.mpi_comm.allreduce(held == 0, op=MPI.LOR)     # a rank without window rows


@pytest.mark.parametrize("preconditioner", ["multigrid", "compliance"])
@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
def test_a_windows_descent_reaches_newtons_state_on_any_rank_count(coll, law_name, preconditioner):
    """From the converged state of the adhesive sphere (Tabor 1) on its loading path after its
    jump on, the descent alone (to 1e-9) reaches the state Newton reaches a step of z0 further,
    with the sphere pressed into contact (a hard wall's contact pressure and adhesive traction
    each), and the same on one rank as on all (on three, one holds no window rows); with the
    V-cycle on the padded grids (a window's default) and with the compliance."""
    key = law_name.replace("-", "") + preconditioner[0]
    pressures = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        kw = dict(law=law_name, n=40, dx=1.0, radius=100.0, comm=comm)
        newton = sphere_problem(1.0, prefix=f"wnewt{key}_", petsc_options={"strategy": "newton"}, **kw)
        for approach in np.arange(-2.0, -0.99, 0.25):
            newton.solve(approach=approach)
        start = newton._x.copy()
        reference = newton.solve(approach=0.0)
        pb = sphere_problem(1.0, prefix=f"wdesc{key}_", petsc_options={
            "descent_tol": 1e-9, "descent_preconditioner": preconditioner}, **kw)
        pb.prepare(-1.0)
        ok, reason, iterations, _ = EnergyDescent(pb).descend(0.0, start)
        assert ok and iterations > 0, reason
        grid = pb.grid
        p = pb.blocks(pb._x, readonly=True).sum(axis=0)
        assert reference.contact_fraction > 0.02
        scale = float(pb.law.peak_attraction)
        diff = coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / scale
        assert diff < 1e-6, diff
        for mine, newtons in zip(pb.blocks(pb._x, readonly=True), newton.blocks(newton._x, readonly=True)):
            assert coll.max(np.abs(mine - newtons)) < 1e-6 * scale
        pressures.append(grid.gather(reference.pressure))
        pressures.append(grid.gather(_as_vec(grid, p)))
    assert coll.max(np.abs(pressures[1] - pressures[3])) / 1.0 < 1e-8


def _as_vec(grid, rows):
    v = grid.create_vec()
    grid.rows(v)[...] = rows
    return v


def test_a_spheres_jump_on_is_a_descent_to_a_stable_state(coll):
    """The adhesive sphere (full LJ, Tabor 1) jumps on between approaches -1.75 and -1.5 z0; with
    Newton capped at 3 steps, too few for the jump, the fallback descends from the state out
    of contact to a converged, stable state of lower energy than that state has at the new
    approach, the same on one rank as on all."""
    gaps = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        pb = sphere_problem(1.0, law="lj", n=64, dx=1.0, radius=100.0, comm=comm, prefix="wjump_",
                            petsc_options={"max_it": 3, "descent_tol": 1e-9})
        before = pb.solve(approach=-1.75)
        after = pb.solve(approach=-1.5)
        assert "+descent" in after.solver and after.fallback, after.solver
        assert after.converged and after.stable
        assert after.force < 2.0 * before.force        # jumped on: the pull more than doubles
        assert after.energy < energy_moved(before, pb.law, pb.grid, 0.25)
        gaps.append(pb.grid.gather(after.gap))
    assert coll.max(np.abs(gaps[0] - gaps[1])) < 1e-7


def test_auto_takes_the_cycle_where_the_compliance_is_slow(coll):
    """``-<prefix>descent_preconditioner auto`` on a large contact resolved finely (the hard-wall
    sphere at Tabor 4, dx = z0 / 8, its contact 20 % of a 256^2 window), where CG with the
    compliance takes 9-16 iterations a Newton step and the V-cycle a few: the descent strategy's
    states are the compliance's (forces and gaps), for at most half its Krylov iterations."""
    states = {}
    for pc in ("compliance", "auto"):
        pb = sphere_problem(4.0, law="hardwall-lj", n=256, dx=0.125, radius=50.0, comm=PETSc.COMM_WORLD,
                            prefix=f"wauto{pc[0]}_", petsc_options={"strategy": "descent", "descent_preconditioner": pc})
        pb.solve(approach=-3.5)
        states[pc] = pb.solve(approach=-3.25)
    slow, fast = states["compliance"], states["auto"]
    assert slow.converged and fast.converged and slow.contact_fraction > 0.1
    assert abs(fast.force - slow.force) < 1e-6 * abs(slow.force)
    grid = pb.grid
    assert coll.max(np.abs(grid.rows(fast.gap, readonly=True) - grid.rows(slow.gap, readonly=True))) < 1e-7
    assert fast.linear_iterations <= 0.5 * slow.linear_iterations, (fast.linear_iterations, slow.linear_iterations)
