"""The reference paper's relaxation (Fig. 2b) in both of its forms: eq. 7 (hard wall) and eq. 8
(the full Lennard-Jones curve).

Independent truths: agreement with a different solver (SNES VI Newton) on the same state; the
closed form of a flat punch on a periodic cell (K has no mean mode, so the gap is -delta
everywhere and the pressure is the law's, p_LJ(z0 - delta)).  Units: z0 = 1, E* = 1.
"""
import numpy as np
import pytest

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.relaxation import RelaxationSolver

from adhesive_setup import sphere_problem

TOL = 1e-6


@pytest.mark.parametrize("law", ["hardwall-lj", "lj"])
def test_relaxation_equals_newton_on_a_sphere(coll, law):
    """Tabor parameter 1, 64^2, delta = z0: the relaxation at E_Total <= 1e-6 z0 gives Newton's
    state (1e-10 z0); its history carries both of the paper's measures per cycle."""
    newton = sphere_problem(1.0, law=law, n=64, dx=2.0, tol=1e-10, stability_check=False)
    relaxed = sphere_problem(1.0, law=law, n=64, dx=2.0, prefix="relaxed_", stability_check=False)
    sn = newton.solve(approach=1.0)
    sr = RelaxationSolver(relaxed, tol=TOL, contact_tol=TOL).solve(approach=1.0)
    assert sn.converged and sr.converged and sr.solver == "relaxation-mlmi"
    assert 0.2 < sr.contact_fraction < 0.8   # a contact edge inside the window
    g = newton.grid
    dg = g.rows(sn.gap, readonly=True) - g.rows(sr.gap, readonly=True)
    assert coll.max(np.abs(dg)) < 50 * TOL
    assert np.sqrt(g.mpi_comm.allreduce(float(np.sum(dg ** 2))) / (g.nx * g.ny)) < 10 * TOL
    assert abs(sn.force - sr.force) < 1e-5 * abs(sn.force)
    rows = [r for r in relaxed.history.records if r.solver == "relaxation-mlmi"]
    e = np.array([r.total_error for r in rows])
    rms = np.array([r.rms_contact_residual for r in rows])
    assert len(rows) > 3 and np.all(np.isfinite(e)) and np.all(np.isfinite(rms))
    assert e[-1] <= TOL < 100 * TOL < e[0] and rms[-1] <= TOL
    header = relaxed.history.csv_text().splitlines()[0].split(",")
    assert {"total_error", "rms_contact_residual"} <= set(header)


# one rank: on more, eq. 8's relaxation is test_relaxation_equals_newton_on_a_sphere[lj]'s
@pytest.mark.serial
def test_eq8_relaxation_of_a_flat_punch_gives_the_lj_pressure(coll):
    """Periodic flat surface: g = -delta at every node, so the pressure must be p_LJ(z0 - delta),
    reached from the previous state on both branches (adhesive, repulsive) and back."""
    grid = SurfaceGrid(8, 8, 1.0, periodic=True)
    h = grid.create_vec(0.0)
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    relax = RelaxationSolver(AdhesiveProblem(grid, h, 1.0, law, prefix="flat_", stability_check=False),
                             tol=1e-10, contact_tol=1e-10)
    for delta in (-0.3, 0.05, 0.3, -1.0):
        st = relax.solve(approach=delta)
        p = grid.rows(st.pressure, readonly=True)
        exact = float(law.pressure(-delta))
        assert coll.max(np.abs(p - exact)) < 1e-7 * abs(exact)


def test_eq8_relaxation_needs_the_nodal_rule(coll):
    pb = sphere_problem(1.0, law="lj", n=16, element_integration=True)
    coll.raises(ValueError, ["nodal rule", "element_integration"], RelaxationSolver, pb)
