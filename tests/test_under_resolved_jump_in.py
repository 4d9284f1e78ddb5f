"""The jump-in of the paper's Tabor-5 sphere on a grid too coarse for it (the study
run_scripts/checks/tabor5_steps.py at its failing size, reduced to 32^2): the failed step is loud
and the path goes on from the last converged state.

Independent truths: the snap criterion K_ii max|dp/dg| > 1 with K_ii of a uniformly loaded square
cell (Love: 4 ln(1 + sqrt 2) dx / (pi E*)) and the law's steepest slope, sampled here; the same
reason on every rank; an uninterrupted run (the next approach solved by a problem that never
failed).  Units: SI, the reference paper's R, E* and z0.
"""
import warnings

import numpy as np
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.physics.resolution import UnderResolvedWarning
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import sphere

R, E_STAR, Z0, MU = 100e-6, 50e9, 0.3e-9, 5.0            # m, Pa, m, Tabor parameter
W = (MU ** 3 * E_STAR ** 2 * Z0 ** 3 / R) ** 0.5          # J/m^2
N, DX = 32, 100e-9                                        # the under-resolved grid (m)


def problem(prefix):
    opts = PETSc.Options(prefix)
    opts.setValue("max_it", 20)        # Newton and PTC capped: the failure, not its cost, is tested
    opts.setValue("ptc_max_it", 20)
    grid = SurfaceGrid(N, N, DX, periodic=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)   # under-resolved on purpose
        return AdhesiveProblem(grid, sphere(grid, R), E_STAR, make_law("lj", work_of_adhesion=W, z0=Z0),
                               prefix=prefix, element_integration=True)


def clear(prefix):
    for key in ("max_it", "ptc_max_it"):
        PETSc.Options(prefix).delValue(key)


def test_failed_jump_in_is_loud_and_the_path_goes_on_from_the_last_converged_state(coll):
    law = make_law("lj", work_of_adhesion=W, z0=Z0)
    g = np.linspace(0.5 * Z0, 5 * Z0, 20001)
    slope = np.abs(np.gradient(law.pressure(g), g)).max()
    k_ii = 4 * np.log(1 + np.sqrt(2)) * DX / (np.pi * E_STAR)
    assert k_ii * slope > 1                                # every node can snap on its own
    try:
        pb, ref = problem("jumpin_"), problem("jumpref_")
        assert pb.solve(approach=-5 * Z0).converged        # separated: no jump yet
        failed = pb.solve(approach=-4 * Z0, raise_on_failure=False)
        after = pb.solve(approach=-4.5 * Z0, raise_on_failure=False)
        ref.solve(approach=-5 * Z0)
        uninterrupted = ref.solve(approach=-4.5 * Z0)
    finally:
        clear("jumpin_")
        clear("jumpref_")
    assert coll.all(not failed.converged)
    assert coll.all("under-resolved adhesion" in failed.reason), failed.reason
    reasons = PETSc.COMM_WORLD.tompi4py().allgather(failed.reason)
    assert len(set(reasons)) == 1
    assert coll.all(after.converged and uninterrupted.converged)
    grid = pb.grid
    dg = grid.rows(after.gap, readonly=True) - grid.rows(uninterrupted.gap, readonly=True)
    assert coll.max(np.abs(dg)) < 1e-6 * Z0
    assert abs(after.force / uninterrupted.force - 1) < 1e-6
