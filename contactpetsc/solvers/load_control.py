"""Load control as a driver over a problem's public ``solve(approach=...)``: Newton on the
approach for a net force, stepping with the state's stiffness (docs/formulation.md,
"Adhesive contact: unknowns and Newton")."""
from __future__ import annotations

import numpy as np

from .base import AdhesiveSolveError


def solve_force(problem, force: float, *, rel_tol: float = 1e-8, max_updates: int = 30,
                raise_on_failure: bool = True):
    """Load control where it is stable: Newton on the approach for a net force [N].

    ``problem``: an ``AdhesiveProblem`` (or any problem with this public interface).
    Each update solves in displacement control (tangent predictor) and steps
    delta by (F - W) / (dW/d delta).  Under load control a state is stable only
    where dW/d delta > 0; where the slope is not positive (beyond the pull-off
    force, or on the unstable branch) the solve stops with a reason saying so.
    """
    if not np.isfinite(force):
        raise ValueError(f"force must be finite, got {force!r}")
    problem.snes()
    delta = problem.approach
    if delta is None:
        delta = float(problem.heights.min()[1])
    scale = max(abs(force), 2.0 * np.pi * problem.law.work_of_adhesion * problem.z0 * 1e3)
    st = None
    predictor = problem.predictor
    eager, predictor.stiffness_each_state = predictor.stiffness_each_state, True   # the updates step with dW/d delta
    try:
        for _ in range(max_updates):
            st = problem.solve(approach=delta, raise_on_failure=False)
            if not st.converged:
                break
            miss = force - st.force
            if abs(miss) <= rel_tol * scale:
                return st
            if not (st.stiffness > 0 and st.stable):
                st.converged = False
                st.reason = (f"LOAD_CONTROL_UNSTABLE (dW/d delta = {st.stiffness:.3e} N/m at approach "
                             f"{st.approach:.4e} m, force {st.force:.4e} N): the target is beyond the end of "
                             f"a stable branch under load control; use displacement control")
                break
            delta = st.approach + miss / st.stiffness
        else:
            st.converged = False
            st.reason = f"DIVERGED_LOAD_ITERATION ({max_updates} approach updates)"
    finally:
        predictor.stiffness_each_state = eager
    if raise_on_failure:
        raise AdhesiveSolveError(f"load-controlled adhesive solve for {force:.4e} N failed: {st.reason}")
    return st
