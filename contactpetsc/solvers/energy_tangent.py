"""The tangent of a full-LJ state from the energy's Hessian: the ``TangentPredictor``'s solve
where the energy descent applies (docs/formulation.md, "Energy descent").

With G(u, delta) = K^-1 u - P0 a(g) the energy's gradient (``descent.py``), the branch's
tangent t = du/d delta solves H t = -dG/d delta = P0 Phi''(g), H the descent's Hessian; then
dp/d delta = K^-1 t + mean(Phi''(g) (1 - P0 t)), and the force's derivative is the area
times its mean.  CG with the descent's preconditioner (options ``<problem prefix>tangent_``,
code default rtol 1e-3).
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .descent import EnergyDescent
from .descent_contexts import Compliance, Hessian


def tangent(descent: EnergyDescent) -> tuple[np.ndarray, float] | None:
    """(dp/d delta rows [Pa/m], dF/d delta [N/m]) at the present state of ``descent``'s problem
    (full LJ curve).  None where CG does not converge (it may not on an unstable state's
    indefinite H; where it converges its solution is the tangent whatever H's inertia).
    Collective."""
    p = descent.p
    if p.hard_wall or not p.grid.periodic:
        raise ValueError("energy_tangent: the full LJ curve on a periodic grid only (a hard wall's tangent, "
                         "and an isolated window's, is the Jacobian's)")
    descent.at_state()
    H = descent.shell((descent.grid.n_local, descent.n), Hessian(descent))
    b, t = H.createVecs()
    ksp = PETSc.KSP().create(comm=descent.grid.comm)
    try:
        rhs = b.getArray().reshape(descent.shape)
        # the scaled Hessian K_ii H acts on t = du/d delta, dimensionless as v = u / z0 is
        rhs[...] = descent.curvature - descent._sum(float(descent.curvature.sum())) / descent.n
        rhs *= descent.kappa
        ksp.setOptionsPrefix(p.prefix + "tangent_")
        ksp.setType("cg")
        ksp.setTolerances(rtol=1e-3, max_it=1000)
        ksp.getPC().setType("python")
        ksp.getPC().setPythonContext(Compliance(descent))
        ksp.setOperators(H, H)
        ksp.setFromOptions()
        ksp.solve(b, t)
        if ksp.getConvergedReason() <= 0:
            return None
        tu = t.getArray(readonly=True).reshape(descent.shape)
        dp = p.op.convolve(descent._k_inv, tu, np.empty(descent.shape))
        mean_t = descent._sum(float(tu.sum())) / descent.n
        mean_dp = descent._sum(float(np.dot(descent.curvature.ravel(), 1.0 - (tu.ravel() - mean_t)))) / descent.n
        dp += mean_dp
        area = descent.grid.lengths[0] * descent.grid.lengths[1]
        return dp, mean_dp * area
    finally:
        for obj in (ksp, H, b, t):
            obj.destroy()
        if descent.cycle is not None:
            descent.cycle.release()
