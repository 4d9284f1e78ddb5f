"""The tangent predictor of ``AdhesiveProblem``: a strategy that steps a displacement-controlled
path along its branch (docs/formulation.md, "Adhesive contact: unknowns and Newton").

At a converged state the tangent t = dx/d delta solves J_II t = -dF/d delta on the inactive
set I (contact nodes keep zero gap: dq from it, da from the law), one Krylov solve (options
under ``<prefix>tangent_``; code default rtol 1e-2).  With the full LJ curve on a periodic grid
(nodal rule) it is CG on the energy's Hessian instead (``energy_tangent.py``, rtol 1e-3;
``-<prefix>tangent_hessian false`` keeps the Jacobian's): fewer FFT pairs than the Jacobian's
solve at 1e-2, and a stiffness to about 1e-3 where that one's was off by up to 15 %
(docs/performance.md, "The tangent").  It gives

* the Euler predictor of the next step, x + t (delta - delta_prev) (``-<prefix>predictor``);
* the tangent stiffness dF/d delta [N/m] = sum(t) dA of every displacement-controlled state
  (``-<prefix>stiffness``; sweeps test jumps with it, load control steps with it).  Off: NaN,
  and the tangent is solved only where the next step's predictor needs it.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from . import energy_tangent
from .descent import EnergyDescent
from .descent_options import descent_applies
from .options import code_default
from .pc_registry import ADHESIVE_PRECONDITIONERS


class TangentPredictor:
    """The tangent of ``problem`` (an ``AdhesiveProblem``) at its last converged state, solved
    when first needed; reads its options when made (inside the problem's ``inserted_options``)."""

    def __init__(self, problem):
        self.problem = problem
        opts = PETSc.Options(problem.prefix)
        self.predicts = opts.getBool("predictor", code_default("adhesion", "predictor"))
        self.stiffness_each_state = opts.getBool("stiffness", code_default("adhesion", "stiffness"))
        self.by_hessian = opts.getBool("tangent_hessian", code_default("adhesion", "tangent_hessian"))
        #: whether converged states get a tangent at all (the nested iteration's coarse levels: no)
        self.wanted = True
        #: (approach [m], dx/d delta (None under the descent strategy), dF/d delta [N/m]) at the
        #: last converged state
        self.value = None
        self._due = None     # approach of the present state when its tangent is not solved yet
        self._present = False   # ``present`` solved the present unknowns' tangent, for their state
        self._kept = False      # ``due`` kept that tangent for ``stiffness``

    def drop(self) -> None:
        """Forget the tangent (the state changed)."""
        if self.value is not None and self.value[1] is not None:
            self.value[1].destroy()
        self.value = self._due = None
        self._present = self._kept = False

    def due(self) -> None:
        """The present converged state's tangent is wanted, solved when first needed (kept where
        ``present`` solved it for this state)."""
        if self._present:
            self._present, self._kept = False, True
            return
        self.drop()
        if self.wanted:
            self._due = self.problem._approach

    def present(self) -> float:
        """dF/d delta [N/m] of the present converged unknowns, their tangent solved now and kept
        for the state made next (its ``due``); NaN where no tangent is wanted or it failed.  The
        caller drops it (``drop``) if it changes the unknowns before."""
        self.due()
        self.ensure()
        self._present = self.value is not None
        return self.value[2] if self._present else float("nan")

    def ensure(self) -> None:
        """Solve the present state's tangent if it is due."""
        if self._due is None:
            return
        pb = self.problem
        approach, self._due = self._due, None
        here, pb._approach = pb._approach, approach   # the state's own approach
        tv, stiffness = self.solve()
        pb._approach = here
        if pb.strategy == "descent":
            # each state is descended from the last: no step is predicted, the stiffness is all
            tv.destroy()
            tv = None
        self.value = (approach, tv, stiffness)

    @property
    def stiffness_due(self) -> bool:
        """Whether ``stiffness()`` solves the present state's tangent (not where it gives NaN: the
        stiffness off, or a coarse level that wants no tangent)."""
        return (self._due is not None or self._kept) and self.stiffness_each_state

    def stiffness(self) -> float:
        """dF/d delta [N/m] of the present state where it is wanted for every state, else NaN."""
        if not self.stiffness_due:
            return float("nan")
        self.ensure()
        self._kept = False
        return self.value[2]

    def predict(self, approach: float) -> None:
        """Step the problem's unknowns (still the previous state) to ``approach`` [m] along the
        tangent: x + dx/d delta (delta - delta_prev); q >= 0 kept."""
        if not self.predicts:
            return
        self.ensure()
        if self.value is None or self.value[1] is None:
            return
        pb = self.problem
        pb._x.axpy(float(approach) - self.value[0], self.value[1])
        if pb.hard_wall:
            q = pb.blocks(pb._x)[0]
            np.maximum(q, 0.0, out=q)

    def copy(self):
        """The tangent as a tuple with its own Vec (a snapshot's), or None."""
        self.ensure()
        if self.value is None:
            return None
        approach, tv, stiffness = self.value
        return approach, None if tv is None else tv.copy(), stiffness

    def restore(self, value) -> None:
        """Make ``value`` (from ``copy``) the tangent; it is copied."""
        self.drop()
        self.value = None if value is None else (value[0], None if value[1] is None else value[1].copy(), value[2])

    def solve(self) -> tuple[PETSc.Vec, float]:
        """(dx/d delta, dF/d delta [N/m]) at the problem's present unknowns."""
        pb = self.problem
        grid = pb.grid
        if self.by_hessian and not pb.hard_wall and pb.grid.periodic and descent_applies(pb):
            # the full LJ curve: CG on the energy's Hessian, preconditioned as the descent's
            # steps; a stable state's Hessian is positive definite, an unstable one's falls
            # back on the Jacobian's Krylov solve below
            found = energy_tangent.tangent(EnergyDescent(pb))
            if found is not None:
                tv = pb.create_unknown()
                pb.blocks(tv)[0] = found[0]
                return tv, found[1]
        pb._jacobian(None, pb._x, None, None)
        iset = pb._inactive_set()
        J = pb._J
        A = J.createSubMatrix(iset, iset)
        ctx = A.getPythonContext()
        rhs = np.zeros(ctx.shape)
        ones = np.ones((grid.ny_local, grid.nx))
        if pb.hard_wall:
            rhs[0] = 1.0
        pb.traction.apply_derivative(ones, rhs[-1])
        rhs[-1] *= -pb.kappa
        if pb._gap_rows is not None:
            rhs[-1][pb._gap_rows] = 1.0   # d(g - G(a))/d delta = -1
        b, t = A.createVecs()
        ctx.from_full(rhs, b)
        del rhs, ones       # three grid arrays that the Krylov solve's peak need not hold
        ksp = PETSc.KSP().create(comm=grid.comm)
        ksp.setOptionsPrefix(pb.prefix + "tangent_")
        # BiCGStab for every law (a hard wall's Newton steps take GMRES): it keeps a fixed
        # handful of vectors where GMRES's basis grew with the tangent's iterations into a
        # path's peak memory, and on the rough benchmark's hard-wall path its stiffness is the
        # nearer to a tight solve's at every state (docs/performance.md, "Memory of an adhesive path")
        ksp.setType("bcgs")
        # a predictor and a stiffness for jump detection and load updates: 1e-2 is plenty
        # (a jump is a force change larger than the predicted change itself; the predictor's
        # error is the branch's curvature times the step squared; docs/performance.md)
        ksp.setTolerances(rtol=1e-2, max_it=1000)
        if pb.preconditioner == "none":
            ksp.getPC().setType("none")
        else:
            ksp.getPC().setType("python")
            ksp.getPC().setPythonType(ADHESIVE_PRECONDITIONERS[pb.preconditioner])
        ksp.setOperators(A, A)
        ksp.setFromOptions()
        ksp.solve(b, t)
        ok = ksp.getConvergedReason() > 0
        for obj in (ksp, b):
            obj.destroy()       # the Krylov basis before the result's Vec: their memory does not add up
        tv = pb.create_unknown()      # zero off the inactive set
        ctx.to_full(t, pb.blocks(tv))
        for obj in (t, A, iset):
            obj.destroy()
        area = grid.lengths[0] * grid.lengths[1]
        total = float(pb.blocks(tv, readonly=True).sum())
        stiffness = grid.mpi_comm.allreduce(total) / (grid.nx * grid.ny) * area if ok else float("nan")
        return tv, stiffness
