"""The branch check of the Newton strategy (``solvers/branch_check.py``) on an isolated window.

Independent truth: the energy descent strategy's path (TAO's bound-constrained Newton line
search on the energy, each state descended from the last), which follows the branch a
quasi-static path follows: the Newton strategy with its branch check reaches its states, with
the same forces, across the jump on and where the predicted Newton step alone left the attached
branch of an adhesive sphere a step before that branch ends on unloading.  The same on one rank as on all.
Units: z0 = 1, E* = 1 (the adhesive sphere of docs/performance.md at Tabor 2, on a window of
64 z0).
"""
import numpy as np
import pytest
from petsc4py import PETSc

from adhesive_setup import sphere_problem

#: loading across the jump on (between -2.61 and -2.36), then unloading past the pull-off: the
#: attached branch ends between -3.36 and -3.61
PATH = -3.861 + 0.25 * np.array([4.0, 5.0, 6.0, 7.0, 6.0, 5.0, 4.0, 3.0, 2.0, 1.0])


def _forces(strategy, comm, tag):
    # the coarse levels predict each step (a window's default is the tangent): their prediction
    # lands Newton on the detached branch a step before the attached one ends
    pb = sphere_problem(2.0, law="lj", n=128, dx=0.5, radius=100.0, comm=comm,
                        prefix=f"branch_{strategy}_{tag}_",
                        petsc_options={"strategy": strategy, "fmg_step_levels": 2})
    states = [pb.solve(approach=float(d)) for d in PATH]
    return np.array([st.force for st in states]), [(st.solver, st.reason) for st in states]


@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_newton_with_the_branch_check_follows_the_descents_branch(coll):
    descent, _ = _forces("descent", PETSc.COMM_WORLD, "world")
    newton, solvers = _forces("newton", PETSc.COMM_WORLD, "world")
    scale = np.abs(descent).max()
    assert coll.max(np.abs(newton - descent)) < 1e-6 * scale
    # the attached branch goes on to -3.36 z0 and ends before -3.61 z0 (a pull-off jump)
    assert coll.all(descent[-2] < 5.0 * descent[-1] < 0.0)
    # the check took the descent's state where the Newton step's force missed the prediction
    # (the hop), and kept Newton's where the descent reached it (the jump on, which the
    # quasi-static path takes too)
    assert coll.all(any(s.endswith("branch-descent") for s, _ in solvers))
    assert coll.all(any("branch check" in r and r.endswith("kept)") for _, r in solvers))
    if coll.size > 1:
        alone, _ = _forces("newton", PETSc.COMM_SELF, f"self{coll.rank}")
        assert coll.max(np.abs(alone - newton)) < 1e-8 * scale
