"""Questionable input to the problem constructors and solves is refused with the field's name
and the accepted range: tolerances above 1e-2 (1e300 would mark the zero guess converged),
loads in the subnormal range, heights laid out on another grid."""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem, AdhesiveSolveError
from contactpetsc.solvers.problem import ContactProblem
from contactpetsc.geometry.surfaces import sphere

LJ = make_law("lj", work_of_adhesion=0.1, z0=1.0)


@pytest.mark.parametrize("tol", [1e300, 0.02, 0.0, -1e-8, float("nan"), float("inf")])
def test_tolerance_outside_its_range_is_refused(coll, tol):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    coll.raises(ValueError, ["tol", "(0, 0.01]"], ContactProblem, grid, h, 1.0, tol=tol)
    coll.raises(ValueError, ["load_tol", "(0, 0.01]"], ContactProblem, grid, h, 1.0, load_tol=tol)
    coll.raises(ValueError, ["tol", "(0, 0.01]"], AdhesiveProblem, grid, h, 1.0, LJ, tol=tol)


@pytest.mark.parametrize("kind", ["contact", "adhesion"])
def test_tolerance_option_outside_its_range_is_refused(coll, kind):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    prefix = f"huge_tol_{kind}_"
    opts = PETSc.Options()
    opts.setValue(prefix + "tol", "1e300")
    try:
        if kind == "contact":
            problem = ContactProblem(grid, h, 1.0, prefix=prefix)
        else:
            problem = AdhesiveProblem(grid, h, 1.0, LJ, prefix=prefix)
        coll.raises(ValueError, [f"-{prefix}tol", "1e+300", "(0, 0.01]"], problem.solve, approach=0.5)
    finally:
        opts.delValue(prefix + "tol")


def test_negative_coarse_step_levels_are_refused(coll):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    problem = AdhesiveProblem(grid, sphere(grid, 100.0), 1.0, LJ, prefix="neg_levels_",
                              petsc_options={"fmg_step_levels": -1})
    coll.raises(ValueError, ["-neg_levels_fmg_step_levels", ">= 0", "-1"], problem.solve, approach=0.5)


@pytest.mark.parametrize("progress", [0.0, 1.5])
def test_stall_progress_outside_its_range_is_refused(coll, progress):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    problem = AdhesiveProblem(grid, sphere(grid, 100.0), 1.0, LJ, prefix="stall_progress_",
                              petsc_options={"stall_progress": progress})
    coll.raises(ValueError, ["-stall_progress_stall_progress", "(0, 1]"], problem.solve, approach=0.5)


def test_a_hard_wall_cell_pressed_past_its_mean_height_has_no_state(coll):
    """On a periodic cell K has no mean mode, so the mean gap is mean(h) - delta whatever the
    pressures: past mean(h) a hard wall cannot keep g >= 0, and the solve says so by name (the
    mean gap) without iterating, and raises unless told not to."""
    grid = SurfaceGrid(16, 16, 1.0, periodic=True)
    problem = AdhesiveProblem(grid, grid.create_vec(0.25), 1.0, make_law("hardwall-lj", work_of_adhesion=0.01, z0=1.0),
                              prefix="no_equilibrium_")
    st = problem.solve(approach=1.25, raise_on_failure=False)
    assert coll.all(not st.converged and "NO_EQUILIBRIUM" in st.reason and "-1.0000e+00 m" in st.reason)
    assert coll.all(st.newton_iterations == 0)
    coll.raises(AdhesiveSolveError, ["NO_EQUILIBRIUM", "mean gap"], problem.solve, approach=1.5)


def test_subnormal_load_is_refused(coll):
    grid = SurfaceGrid(16, 16, 1e-9, periodic=False)
    h = sphere(grid, 100e-9)
    problem = ContactProblem(grid, h, 1e10)
    coll.raises(ValueError, ["mean_pressure = 1e-310 Pa", "accepted range", "E*"], problem.solve,
                mean_pressure=1e-310)
    coll.raises(ValueError, ["force = 1e-300 N", "accepted range"], problem.solve, force=1e-300)
    # a small load that is still well above the limit converges, to a small relative load error
    st = problem.solve(mean_pressure=1e-6 * 1e10)
    assert st.converged and st.load_error <= 1e-6


def test_heights_of_a_transposed_grid_are_refused(coll):
    wide, tall = SurfaceGrid(16, 12, 1.0, periodic=False), SurfaceGrid(12, 16, 1.0, periodic=False)
    h = sphere(wide, 100.0)
    for make in (lambda: ContactProblem(tall, h, 1.0), lambda: AdhesiveProblem(tall, h, 1.0, LJ)):
        coll.raises(ValueError, ["heights", "16 x 12", "12 x 16"], make)
    # the same shape on another grid object is fine
    same = SurfaceGrid(16, 12, 1.0, periodic=False)
    assert ContactProblem(same, h, 1.0).solve(approach=0.5).converged


def test_heights_without_a_grid_of_the_wrong_size_are_refused(coll):
    grid = SurfaceGrid(16, 12, 1.0, periodic=False)
    v = PETSc.Vec().createMPI(16 * 13, comm=grid.comm)
    v.set(0.0)
    coll.raises(ValueError, ["heights", "208 values", "16 x 12"], ContactProblem, grid, v, 1.0)
    coll.raises(ValueError, ["heights", "PETSc.Vec"], ContactProblem, grid, np.zeros((12, 16)), 1.0)
