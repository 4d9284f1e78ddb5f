"""What a solve frees between states changes no state.

An adhesive problem frees after each Newton run its SNES's work vectors and Krylov basis, and
after each solve its preconditioners' levels, its products' scratch and its best iterates
(``AdhesiveProblem.release``, docs/performance.md, "Memory of an adhesive path").  The truth:
the same path solved by a problem that keeps them all lands in the same states (the same
verdicts, solvers and Newton steps, gaps within the solver's tolerance: a preconditioner made anew starts its power
iterations afresh, so the Krylov iterates differ at round-off) on 1, 2 or 3 ranks, for the full LJ curve (the descent strategy)
and a hard wall (its default, the descent strategy, and the predicted VI Newton step with the multilevel
preconditioner); and every FFT pair is counted in
some state's (the freed levels' too).  Units: z0 = rho = 1, E* = 1.
"""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.geometry.surfaces import self_affine
from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.newton import VINewton


@pytest.mark.parametrize("law_name, preconditioner, strategy",
                         [("lj", "auto", "descent"), ("exponential", "mlmi", "descent"), ("exponential", "mlmi", "newton")])
def test_freeing_between_states_changes_no_state(coll, monkeypatch, law_name, preconditioner, strategy):
    grid = SurfaceGrid(64, 64, 1.0, periodic=True, comm=PETSc.COMM_WORLD)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=11)
    law = make_law(law_name, work_of_adhesion=0.05, **({"z0": 1.0} if law_name == "lj" else {"rho": 1.0}))
    top = float(h.min()[1])
    # loading into contact and back: jumps both ways on the rough surface
    path = [top + d for d in (0.5, 1.0, 1.5, 1.0, 0.5)]

    def states(prefix):
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix, preconditioner=preconditioner,
                             petsc_options={"strategy": strategy})
        out, pairs = [], 0.0
        for d in path:
            st = pb.solve(approach=d, raise_on_failure=False)
            pairs += st.fft_pairs
            out.append((st.converged, st.stable, grid.rows(st.gap, readonly=True).copy(), st.solver,
                        st.newton_iterations))
        # every FFT pair is some state's: the freed levels' pairs stay counted
        assert abs(pairs - pb.fft_pairs()) <= 1e-9 * pb.fft_pairs()
        return pb, out

    freed, freeing = states(f"free_{law_name}_{strategy}_")
    # what the solve frees is gone between states ...
    assert freed._scratch is None and freed._x_solve_best is None
    assert freed._jac.pc_data.mlmi_levels is None and freed._jac.pc_data.full_pair is None
    # ... and a problem that keeps everything lands in the same states
    monkeypatch.setattr(AdhesiveProblem, "release", lambda self: None)
    monkeypatch.setattr(VINewton, "_reset", lambda self: None)
    kept, keeping = states(f"keep_{law_name}_{strategy}_")
    assert kept._scratch is not None
    for (c1, s1, g1, m1, n1), (c2, s2, g2, m2, n2) in zip(freeing, keeping):
        # the same strategies and the same Newton work: a freed set-up is made again whole
        assert coll.all(c1 and c2 and s1 == s2 and m1 == m2 and abs(n1 - n2) <= 1), (m1, n1, m2, n2)
        assert coll.max(np.abs(g1 - g2).max(initial=0.0)) <= freed.tol * freed.z0


@pytest.mark.parametrize("law_name", ["lj", "exponential"])
def test_a_solve_leaves_no_descent_alive_without_the_cyclic_collector(coll, monkeypatch, law_name):
    """Each state's descents (and their grid arrays) are freed by reference counting when the
    solve ends: a reference cycle through one (its gap floor, say, pointing back at it) would keep
    its arrays until Python's cyclic collector happened to run, which large arrays never trigger
    (a 512^2 path had grown by ten doubles per point a state)."""
    import gc
    import weakref

    from contactpetsc.solvers.descent import EnergyDescent

    made = []
    init = EnergyDescent.__init__

    def recording(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(weakref.ref(self))

    monkeypatch.setattr(EnergyDescent, "__init__", recording)
    grid = SurfaceGrid(32, 32, 1.0, periodic=True, comm=PETSc.COMM_WORLD)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=11)
    law = make_law(law_name, work_of_adhesion=0.05, **({"z0": 1.0} if law_name == "lj" else {"rho": 1.0}))
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"cycles_{law_name}_")
    top = float(h.min()[1])
    gc.collect()
    gc.disable()
    try:
        for d in (top + 0.5, top + 1.5, top + 1.0):
            st = pb.solve(approach=d, raise_on_failure=False)
            assert coll.all(st.converged), st.reason
            alive = sum(ref() is not None for ref in made)
            # the full LJ curve's floor and a hard wall's bounds both took part
            assert coll.all(made and alive == 0), f"{alive} of {len(made)} descents alive after a solve"
    finally:
        gc.enable()
