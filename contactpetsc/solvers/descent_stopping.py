"""The energy descent's stopping test (``descent.EnergyDescent``, a mixin): TAO's convergence
test on the problem's own error measures at each iterate, the target a branch check looks for,
the full LJ curve's gap floor, the iteration cap and the time budget; each iterate goes to the
problem's history (docs/formulation.md, "Energy descent")."""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..collective import max_error
from ..physics.traction import node_blocks

#: TAO's converged reasons (petsc4py >= 3.20 also names them ConvergedReason)
TAO_REASON = getattr(PETSc.TAO, "ConvergedReason", None) or PETSc.TAO.Reason


#: the energy's decrease, relative to itself, below which a descent's progress is round-off: a
#: line search at a state whose energy no longer resolves its error takes zero steps
STALL_DECREASE = 1e-12


class StoppingTest:
    """When an ``EnergyDescent`` stops (its ``error`` and TAO's convergence test ``_converged``);
    uses the descent's fields, tolerance, target, floor, mean multiplier and ``stall_its``."""

    def error(self, g, k_inv_u, p0, a) -> float:
        """The problem's error measures (``AdhesiveProblem._measures``) on (g, p = K^-1 u + p0, a),
        their max; a block of nodes at a time (the measures' temporaries are a block's).  On a
        window, with the gap error [z0] that the pressure left outside it makes on its gaps
        (``PaddedWindow.outside_gap``, one FFT pair)."""
        p = self.p
        local = self.space.outside_gap(k_inv_u) / p.z0
        g, k_inv_u, a = g.reshape(-1), k_inv_u[self.win].reshape(-1), a.reshape(-1)
        for block in node_blocks(g.size):
            gb, ab = g[block], a[block]
            d = (k_inv_u[block] + p0) - ab
            if p.hard_wall:
                measures = (float(np.abs(np.minimum(p.kappa * d, gb)).max()) / p.z0,
                            float(np.abs(np.minimum(d / p.pressure_scale, gb / p.z0)).max()))
            else:
                measures = (p.kappa * float(np.abs(d).max()) / p.z0,
                            float((np.abs(d) / (p.pressure_scale + np.abs(ab))).max()))
            # a NaN is infinite (Python's max would keep whichever came first)
            local = max(local, *(np.inf if m != m else m for m in measures))
        return max_error(self.comm, local)

    def _converged(self, tao):
        g, a, mean_u, k_inv_u, p0 = self.fields(tao.getSolution())
        err = self.error(g, k_inv_u, p0, a)
        it = tao.getIterationNumber()
        p = self.p
        window = k_inv_u[self.win]
        contact = self._sum(float(np.count_nonzero(window > -p0))) / self.nodes
        p.history.append(
            solve=p.solve_count, iteration=it, fft_pairs=p.fft_pairs(), linear_iterations=self._lin0 + self.pc_applies,
            complementarity_error=err if p.hard_wall else float("nan"), load_error=float("nan"),
            approach=self.delta - mean_u, mean_pressure=self._sum(float(window.sum())) / self.nodes + p0,
            contact_fraction=contact, solver="descent", adhesive_error=float("nan") if p.hard_wall else err,
            pressure_error=err)
        self.last_error = err
        if tao.getConvergedReason() < 0:
            return       # TAO's own failure (line search, ...)
        if self._target is not None and max_error(self.comm, float(np.abs(g - self._target[0]).max(
                initial=0.0))) <= self._target[1]:
            self.reached = True
            tao.setConvergedReason(TAO_REASON.CONVERGED_USER)
            return
        if err <= (self.mean.target(mean_u, self.tol) if self.mean is not None else self.tol):
            tao.setConvergedReason(TAO_REASON.CONVERGED_USER)
        elif self.floor is not None and self.floor.active and self.floor.holds(tao, k_inv_u, p0, a):
            self.pinned = True
            tao.setConvergedReason(TAO_REASON.CONVERGED_USER)
        elif self._stalls(tao, it):
            # at the state to the energy's last digits (next to a fold the line search takes
            # zero steps to TAO's cap): Newton polishes it
            self.stalled = True
            tao.setConvergedReason(TAO_REASON.DIVERGED_USER)
        elif it >= tao.getMaximumIterations() or not np.isfinite(err):
            tao.setConvergedReason(TAO_REASON.DIVERGED_MAXITS)
        elif p.out_of_time():
            self.spent = True     # the reason names the budget (``EnergyDescent._descend``)
            tao.setConvergedReason(TAO_REASON.DIVERGED_MAXITS)
        else:
            tao.setConvergedReason(TAO_REASON.CONTINUE_ITERATING)

    def _stalls(self, tao, it: int) -> bool:
        """Whether the energy has fallen by at most ``STALL_DECREASE`` of itself in the last
        ``stall_its`` iterations of this TAO solve (a round's penalty changes the energy: each
        round starts its own record).  The energy is global: every rank decides alike."""
        if not self.stall_its:
            return False
        if it == 0:
            self._energies = []
        energies = self._energies
        energies.append(tao.getObjectiveValue())
        if len(energies) <= self.stall_its:
            return False
        del energies[:-self.stall_its - 1]
        return energies[0] - energies[-1] <= STALL_DECREASE * abs(energies[-1])
