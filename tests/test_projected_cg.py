"""Load control's Newton step (``projected_cg.py``) and the joint Newton iteration in (p, delta).

Truths: the KKT conditions of the saddle-point system K_II y - mu 1 = b, sum(y) = c (the
residual constant on I, the sum exact); the load-controlled state re-solved under displacement
control at its approach (the other code path: plain CG, delta given) gives the same pressure
and carries the load.  Serially and under ``mpirun -n 2/3``.
"""
import numpy as np
from petsc4py import PETSc

from contactpetsc.geometry import surfaces
from contactpetsc.grid import SurfaceGrid
from contactpetsc.solvers import ContactProblem, SpectralPC
from contactpetsc.solvers.projected_cg import ProjectedCG


def rough(n=32):
    g = SurfaceGrid(n, n, 1.0 / n, row_alignment=2)
    h = surfaces.self_affine(g, hurst=0.8, seed=5, rms_slope=0.1, rolloff_wavelength=0.25,
                             short_cutoff_wavelength=4.0 / n)
    return g, h


def test_projected_cg_solves_the_saddle_point_system(coll):
    g, h = rough()
    prob = ContactProblem(g, h, 1.0, prefix="pcg_kkt_")
    st = prob.solve(mean_pressure=0.01)
    J = prob.J
    inactive = g.rows(st.pressure, readonly=True) > 0          # a contact set
    idx = (np.flatnonzero(inactive) + g.nx * g.ys).astype(PETSc.IntType)
    iset = PETSc.IS().createGeneral(idx, comm=g.comm)
    A = J.createSubMatrix(iset, iset)
    ksp = PETSc.KSP().create(comm=g.comm)
    ksp.setOperators(A, A)
    ksp.getPC().setType("python")
    ksp.getPC().setPythonContext(SpectralPC())
    c = 0.37
    ksp.setType("python")
    ksp.setPythonContext(ProjectedCG(lambda: (c, 0.0)))
    ksp.setTolerances(rtol=1e-11, max_it=500)
    b, y = A.createVecs()
    b.setArray(np.sin(7.0 * idx) + 0.5)                        # any right-hand side
    ksp.solve(b, y)
    assert coll.all(ksp.getConvergedReason() > 0)
    r = A.createVecs()[0]
    A.mult(y, r)
    r.axpy(-1.0, b)                                           # K_II y - b = mu 1
    spread = (r.max()[1] - r.min()[1]) / b.norm(PETSc.NormType.INFINITY)
    assert coll.max(spread) <= 1e-9, spread
    assert coll.max(abs(y.sum() - c) / abs(c)) <= 1e-12
    assert coll.max(ksp.getIterationNumber()) < 100
    for obj in (b, y, r, A, iset, ksp):
        obj.destroy()


def test_load_control_state_is_the_displacement_controlled_state(coll):
    g, h = rough(64)
    target = 0.004
    st = ContactProblem(g, h, 1.0, prefix="pcg_load_", tol=1e-11).solve(mean_pressure=target)
    assert coll.all(st.converged)
    assert coll.max(abs(st.mean_pressure - target) / target) <= 1e-10
    ref = ContactProblem(g, h, 1.0, prefix="pcg_disp_", tol=1e-11).solve(approach=st.approach)
    d = st.pressure.copy()
    d.axpy(-1.0, ref.pressure)
    pmax = ref.pressure.max()[1]
    assert coll.max(d.norm(PETSc.NormType.INFINITY) / pmax) <= 1e-8
    assert coll.max(abs(ref.mean_pressure - target) / target) <= 1e-8
    assert 0.02 < coll.max(st.contact_fraction) < 0.5


def test_outer_iteration_takes_over_where_the_joint_iteration_fails(coll, monkeypatch):
    """A failed joint iteration (simulated) hands over to the outer iteration on delta, which
    reaches the same state from the same start."""
    g, h = rough(64)
    target = 0.004
    ref = ContactProblem(g, h, 1.0, prefix="pcg_ref_", tol=1e-11).solve(mean_pressure=target)

    def fails(self, target):
        self._pressure.scale(3.0)         # leaves a spoiled start behind, as a failed solve may
        return False, "DIVERGED_LINE_SEARCH"

    monkeypatch.setattr(ContactProblem, "_solve_load_joint", fails)
    st = ContactProblem(g, h, 1.0, prefix="pcg_fallback_", tol=1e-11).solve(mean_pressure=target)
    assert coll.all(st.converged) and "joint" in st.reason
    d = st.pressure.copy()
    d.axpy(-1.0, ref.pressure)
    assert coll.max(d.norm(PETSc.NormType.INFINITY) / ref.pressure.max()[1]) <= 1e-8
