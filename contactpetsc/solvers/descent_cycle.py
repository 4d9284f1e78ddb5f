"""The energy descent's multigrid preconditioner (``-<prefix>descent_preconditioner multigrid``):
the stability check's displacement V-cycle (``stability_pc.DisplacementCycle``) on the descent's
Hessian, in place of the compliance S K S (docs/formulation.md, "Energy descent").

The scaled Hessian is H = K_ii (K^-1 - A) on v = u / z0, A = -diag Phi''(g) the law's stiffness
[Pa/m]; the cycle approximates (K^-1 - A)^-1 on the MLMI grids (a periodic cell's, or an
isolated window's padded grids, ``stability_pc.padded_levels``), the nodes of TAO's active set
clamped (a hard wall's contact, the full LJ curve's floor), so T = cycle / K_ii.  On a cell K^-1
does not see the mean of v: the cycle runs on the zero-mean part and the mean goes as the
compliance's own preconditioner sends it (the hard wall's penalty, the full LJ curve's 1 / K_ii).
An application costs a few FFT pairs against the compliance's one, so it pays where it cuts
CG's iterations by more than that: on a large contact resolved finely (the sphere's windows at
high Tabor numbers), not on the rough benchmark at dx = z0, nor at a snap, where the Hessian is
indefinite.  ``auto`` (``choose``) takes the compliance, tries the cycle after two steps in a row
whose CG converged in ``TRY_ITS`` iterations or more, keeps it while its CG converges, in at most
a ``KEEP_RATIO``-th of that count in the mean, and otherwise goes back to the compliance for the
rest of the descent; across a step whose CG met negative curvature (a snap) it takes the
compliance, and may try the cycle again after it; a descent that ended with the cycle has the next one on the same problem
start with it.  On a periodic cell ``auto`` is the compliance: the cycle gained little on the
rough benchmark's paths, and its set-ups raised their resident size's high-water mark
(docs/performance.md, "The descent's V-cycle on a window").
"""
from __future__ import annotations

import weakref

import numpy as np
from petsc4py import PETSc

from .stability_pc import DisplacementCycle, cell_levels, padded_levels

#: ``auto``: the cycle is tried after two Newton steps whose CG converged in this many iterations
#: or more, and kept while its own CG converges, in at most a KEEP_RATIO-th of them in the mean
TRY_ITS, KEEP_RATIO = 10, 2.5
_KSP = PETSc.KSP.ConvergedReason
_CONVERGED = {int(_KSP.CONVERGED_RTOL), int(_KSP.CONVERGED_ATOL)}
_INDEFINITE = {int(_KSP.CONVERGED_CG_NEG_CURVE), int(_KSP.DIVERGED_INDEFINITE_MAT)}


class DescentCycle:
    """The cycle of an ``EnergyDescent`` ``descent``: its grids made at the first application
    and kept for the descent's life; the cycle itself made again for each Hessian (``stale``,
    set by the descent's ``set_curvature``) and each change of TAO's inactive set.  ``on``:
    whether the descent's Krylov solves take it (always under ``multigrid``; ``auto`` decides
    at each Hessian, ``choose``)."""

    def __init__(self, descent, auto: bool):
        # a proxy: the descent holds this object, and a reference cycle would keep a finished
        # descent's arrays alive until Python's collector ran (``descent_step``'s ``del``)
        self.d = weakref.proxy(descent)
        # ``auto``: the compliance's CG iterations the cycle is held to; it starts with the cycle
        # where the problem's last descent ended with it (``AdhesiveProblem.descent_cycle_won``)
        self.reference = descent.p.descent_cycle_won if auto else 0
        self.auto, self.on = auto, not auto or self.reference > 0
        self.lost = False             # ``auto``: the cycle has lost, the compliance to the end
        self._applies = 0             # the descent's preconditioner applications at the last choice
        self.taken = []               # ``auto``: the cycle's CG iterations at each of its steps
        self._slow = 0                # ``auto``: the last step's CG iterations if it was slow
        self.levels = None
        self.cycle = None
        self.stale = True
        self._t = None

    def choose(self, ksp: PETSc.KSP | None) -> None:
        """``auto``: from the last Newton step's Krylov solve ``ksp`` (its iterations and
        reason, read before the next solve), whether the next one takes the cycle."""
        if not self.auto or ksp is None or self.lost or self.d.pc_applies == self._applies:
            return        # (no Krylov solve since the last choice: BNK's Hessian again at a step)
        self._applies = self.d.pc_applies
        its, reason = ksp.getIterationNumber(), int(ksp.getConvergedReason())
        converged = reason in _CONVERGED
        if not self.on:
            # two slow steps in a row: one alone is often a snap's edge, where the cycle loses
            slow = converged and its >= TRY_ITS
            if slow and self._slow:
                self.on, self.reference, self.taken = True, min(its, self._slow), []
            self._slow = its if slow else 0
            return
        if reason in _INDEFINITE:
            # a snap: the compliance across it, the cycle to be tried again after it (no verdict
            # on the cycle, which meets the same negative curvature)
            self.on, self._slow = False, 0
            return
        self.taken.append(its)
        # held to the mean of its own counts: one harder step late in a descent is no verdict
        if not (converged and KEEP_RATIO * sum(self.taken) <= self.reference * len(self.taken)):
            # slower than it pays for: the compliance from here on
            self.on, self.lost = False, True
            self.d.p.descent_cycle_won = 0
            self._free()

    def _build(self, inactive) -> None:
        d = self.d
        if self.levels is None:
            self.levels = cell_levels(d.p) if d.space.projects_mean else padded_levels(d.p, d.space)
        clamped = np.zeros(d.shape, dtype=bool)
        if inactive is not None:
            clamped.reshape(-1)[...] = True
            clamped.reshape(-1)[inactive.idx] = False
        if self.cycle is not None:
            self.cycle.release()
        self.cycle = DisplacementCycle(self.levels, np.negative(d.curvature), clamped)
        self.stale = False

    def apply(self, inactive, x, y) -> None:
        """y = T x on TAO's inactive set ``inactive`` (``reduced.InactiveSet`` or None), x and y
        its Vecs.  Built anew where ``stale``: set on every rank alike, by each Hessian and each
        inactive set's sub-matrix (``descent_contexts.Hessian``), never by a rank's own test."""
        from .descent_contexts import embedded
        if self.stale:
            self._build(inactive)
        embedded(self.d, inactive, self.product, x, y)

    def product(self, x: np.ndarray, y: np.ndarray) -> None:
        """y = T x on full rows of v (``y`` may be ``x``)."""
        d = self.d
        if self._t is None:
            self._t = np.empty(d.shape)
        t = self._t
        if d.space.projects_mean:
            mean = d._sum(float(x.sum())) / d.n
            np.subtract(x, mean, out=t)
        else:
            np.copyto(t, x)
        out = self.cycle(t, t)
        if d.space.projects_mean:
            out -= d._sum(float(out.sum())) / d.n
            out += mean * d.mean_compliance
        np.multiply(out, 1.0 / d.kappa, out=y)

    def release(self) -> None:
        """Free the cycle and its grids; under ``auto`` the problem keeps whether it won."""
        if self.auto:
            self.d.p.descent_cycle_won = self.reference if self.on else 0
        self._free()

    def _free(self) -> None:
        if self.cycle is not None:
            self.cycle.release()
        self.levels = self.cycle = self._t = None
        self.stale = True
