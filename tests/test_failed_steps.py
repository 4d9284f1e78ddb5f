"""A failed solve returns a meaningful state: the iterate of smallest error, never what a
failed SNES left in its solution vector.

PETSc's VI Newton fills the solution with ``VecSetRandom`` after a failed line search:
values uniformly spread over [0, 1) at every node.  The truths here: the returned
pressure has none of that signature (pressures in Pa of a contact of a 1-10 GPa body
are zero outside the contact and far above 1 Pa inside), it is the state whose force,
displacement, gap and errors the state reports (recomputed from the pressure), and the
next solve starts from the last converged state.  The failure is forced with Newton
steps that go backwards (``snes_linesearch_damping -1``; the contact problem with PETSc's ``bt``,
whose failed line search is the one that leaves random values).  Where the fallback descent
runs out of iterations, its last state competes with Newton's iterates; a state with a NaN
anywhere is an infinite error on every rank, never a best iterate.
"""
import numpy as np
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.problem import ContactProblem
from contactpetsc.geometry.surfaces import self_affine, sphere


def backward_line_search(prefix, value="-1", kind=None):
    """Set (or with None clear) a line search that steps backwards under ``prefix``; ``kind``
    its type (default: the problem's)."""
    opts = PETSc.Options()
    for key, v in (("snes_linesearch_damping", value), ("snes_linesearch_type", kind if value else None)):
        if v is None:
            opts.delValue(prefix + key)
        else:
            opts.setValue(prefix + key, v)


def assert_not_random(coll, rows):
    """No trace of VecSetRandom: it leaves every node in [0, 1) with a nonzero value."""
    n = coll.comm.allreduce(rows.size)
    in_unit = coll.comm.allreduce(int(np.count_nonzero((rows > 0) & (rows < 1.0))))
    assert in_unit < 0.01 * n, f"{in_unit} of {n} nodes hold values in (0, 1) Pa"


def assert_consistent(coll, problem, st, heights):
    """The state's displacement, gap and force are those of its own pressure."""
    g = problem.grid
    p = g.rows(st.pressure, readonly=True)
    v = problem.op.apply(p.copy(), np.empty_like(p))
    scale = coll.max(np.abs(v))
    assert coll.max(np.abs(g.rows(st.displacement, readonly=True) - v)) <= 1e-12 * scale
    gap = g.rows(heights, readonly=True) + v - st.approach
    assert coll.max(np.abs(g.rows(st.gap, readonly=True) - gap)) <= 1e-12 * scale
    force = g.mpi_comm.allreduce(float(p.sum())) * g.dx * g.dy
    assert abs(st.force - force) <= 1e-12 * max(abs(force), 1e-300)


def test_failed_contact_solve_returns_its_best_iterate(coll):
    grid = SurfaceGrid(64, 64, 1e-9, periodic=False)
    h = sphere(grid, 100e-9)
    prefix = "failed_contact_"
    backward_line_search(prefix, kind="bt")   # PETSc's own: its failure leaves VecSetRandom's values
    try:
        problem = ContactProblem(grid, h, 1e9, prefix=prefix, fmg=False)
        st = problem.solve(approach=2e-9, raise_on_failure=False)
    finally:
        backward_line_search(prefix, None)
    assert not st.converged and st.reason.startswith(("DIVERGED_LINE_SEARCH", "DIVERGED_LOCAL_MIN")), st.reason
    assert "smallest complementarity error" in st.reason, st.reason
    p = grid.rows(st.pressure, readonly=True)
    assert coll.max(-p) <= 0.0                      # p >= 0: the bound of every VI iterate
    assert coll.max(p) > 0.0                        # an iterate, not the zero start
    assert_not_random(coll, p)
    assert_consistent(coll, problem, st, h)
    # its reported error is the error of the pressure returned, and below the start's
    comp = np.abs(np.minimum(problem.kappa * p, grid.rows(st.gap, readonly=True)))
    assert abs(coll.max(comp) / problem.length_scale - st.complementarity_error) <= 1e-9 * st.complementarity_error
    assert st.complementarity_error < problem.history[0].complementarity_error
    # the next start is still the last converged state (here: none, the zero pressure)
    assert coll.max(np.abs(grid.rows(problem._pressure, readonly=True))) == 0.0


def test_backtracking_failure_stops_with_its_best_iterate(coll):
    """The default line search (backtracking.py) given uphill Newton directions (one
    Richardson step scaled by -1) finds no decrease down to its smallest step: the solve stops
    with DIVERGED_LINE_SEARCH and returns its iterate of smallest error, a consistent state."""
    grid = SurfaceGrid(64, 64, 1e-9, periodic=False)
    h = sphere(grid, 100e-9)
    uphill = {"ksp_type": "richardson", "ksp_richardson_scale": "-1", "ksp_max_it": "1", "ksp_norm_type": "none"}
    problem = ContactProblem(grid, h, 1e9, prefix="failed_backtracking_", fmg=False, petsc_options=uphill)
    st = problem.solve(approach=2e-9, raise_on_failure=False)
    assert not st.converged and st.reason.startswith("DIVERGED_LINE_SEARCH"), st.reason
    assert "smallest complementarity error" in st.reason, st.reason
    p = grid.rows(st.pressure, readonly=True)
    assert coll.max(-p) <= 0.0
    assert_not_random(coll, p)
    assert_consistent(coll, problem, st, h)
    assert st.complementarity_error < problem.history[0].complementarity_error


def test_failed_adhesive_solve_returns_its_best_iterate(coll):
    z0 = 0.3e-9
    grid = SurfaceGrid(48, 48, z0, periodic=False)
    h = sphere(grid, 30e-9)
    prefix = "failed_adhesion_"
    law = make_law("lj", work_of_adhesion=0.3, z0=z0)
    problem = AdhesiveProblem(grid, h, 10e9, law, prefix=prefix)
    good = problem.solve(approach=-1.0 * z0)
    assert good.converged
    # the full LJ curve takes full Newton steps: a backward step fails by max_it
    backward_line_search(prefix)
    try:
        problem.snes().setFromOptions()
    finally:
        backward_line_search(prefix, None)
    st = problem.solve(approach=0.5 * z0, raise_on_failure=False, fallback=False)
    assert not st.converged and "DIVERGED" in st.reason, st.reason
    assert "iterate of smallest error" in st.reason, st.reason
    p = grid.rows(st.pressure, readonly=True)
    assert_not_random(coll, np.abs(p))
    assert_consistent(coll, problem, st, h)
    assert st.adhesive_error > problem.tol or st.pressure_error > problem.tol
    # the reported pressure is its own adhesive pressure (no wall: p = a)
    assert coll.max(np.abs(p - grid.rows(st.adhesive_pressure, readonly=True))) == 0.0
    # the next solve starts from the last converged state
    x = problem.snapshot().x
    start = x.getArray(readonly=True)
    assert coll.max(np.abs(start - grid.rows(good.pressure, readonly=True).ravel())) == 0.0
    x.destroy()


def test_failed_fallback_reports_its_last_state_where_it_is_the_best(coll):
    """Newton fails (steps backwards) and the energy descent, the fallback, runs out of
    iterations on its way down: the state reported is the descent's last state, whose error is
    below that of every Newton iterate before the descent -- not Newton's best, a worse iterate
    (Newton's polish of the failed descent, stepping backwards too, starts from that state and
    fails: its iterates are the descent's state and worse ones).  Truth: the errors of the
    Newton iterates in the history, and the reported state's own (recomputed) fields."""
    grid = SurfaceGrid(64, 64, 1.0, periodic=True, comm=coll.comm)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    prefix = "failed_fallback_"
    problem = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix,
                              petsc_options={"fallback": "descent", "descent_tao_max_it": 6, "strategy": "newton"})
    d0 = h.min()[1] + 0.5
    assert problem.solve(approach=d0).converged
    backward_line_search(prefix)
    try:
        problem.snes().setFromOptions()
    finally:
        backward_line_search(prefix, None)
    n0 = len(problem.history)
    st = problem.solve(approach=d0 + 0.5, raise_on_failure=False, check_stability=False)
    assert not st.converged and "descent DIVERGED_MAXITS" in st.reason, st.reason
    assert "iterate of smallest error" in st.reason and "at descent iteration" in st.reason, st.reason
    rows = list(problem.history)[n0:]
    first_descent = next(i for i, r in enumerate(rows) if r.solver.startswith("descent"))
    newton = [max(r.adhesive_error, r.pressure_error) for r in rows[:first_descent] if r.solver.startswith("newton")]
    assert newton
    assert "Newton from its iterate" in st.reason, st.reason
    assert max(st.adhesive_error, st.pressure_error) < min(newton)
    p = grid.rows(st.pressure, readonly=True)
    assert_consistent(coll, problem, st, h)
    assert coll.max(np.abs(p - grid.rows(st.adhesive_pressure, readonly=True))) == 0.0
    # a state with one NaN, on one rank, never replaces a measured iterate: it measures as an
    # infinite error on every rank (a NaN dropped by a MAX reduction or max() had measured 0)
    best = problem._solve_best
    if coll.comm.rank == coll.comm.size - 1:
        problem._x.getArray()[-1] = np.nan
    problem.offer_iterate("a state with a NaN")
    assert problem._solve_best == best


def test_a_nan_anywhere_is_an_infinite_error_on_every_rank(coll):
    """The contact solver's convergence measure of a state with one NaN, on one rank: infinite
    on every rank (a MAX reduction of Python floats keeps the first operand when the second is
    NaN, so the ranks holding finite values had measured a finite error)."""
    grid = SurfaceGrid(32, 32, 1e-9, periodic=False, comm=coll.comm)
    h = sphere(grid, 100e-9)
    problem = ContactProblem(grid, h, 1e9, prefix="nan_measure_", fmg=False)
    st = problem.solve(approach=2e-9)
    x, f = st.pressure.copy(), st.gap.copy()
    if coll.comm.rank == coll.comm.size - 1:
        x.getArray()[-1] = np.nan
    errors = problem._measures(x, f)[:2]
    assert not any(np.isfinite(errors)), errors
    x.destroy()
    f.destroy()
