"""The branch check of ``AdhesiveProblem`` under the Newton strategy: a strategy that keeps a
displacement-controlled path on the branch a quasi-static path follows (``-<prefix>branch_check``;
docs/formulation.md, "Adhesive contact: unknowns and Newton").

A predicted Newton step converges to whichever equilibrium its start leads to.  Near the end of
a branch (a fold) that can be a stable state of another branch although the last state's branch
still goes on: the adhesive sphere's attached branch left a step before it ends on unloading.
A quasi-static path leaves a branch only where it ends, and the energy descent from the last
state follows it there (docs/performance.md, "The adhesive sphere's states").  On a smooth
branch the force over a step h is the trapezoid of the two states' tangent stiffnesses k0 and k1
to O(h^3); so where the force of Newton's converged, stable state misses it,

    |F1 - F0 - (k0 + k1) h / 2| > BRANCH_TOL max(|k0 h|, |k1 h|),

(a jump: its force change is of the order of the force itself, which neither end's stiffness
sees; a failed tangent too), the step is descended from the last state as the descent strategy
does (``descent_step.descend_step``) until its gaps come within ``SAME_STATE`` z0 of Newton's
state, or ``SAME_FRACTION`` of the jump (a jump the quasi-static path takes as well: Newton's
state is kept), or else to the tolerance (or until it fails): Newton polishes, the check
checks, and that state is taken (where Newton fails from it or it is unstable, Newton's state
is kept).  Only where the descent applies
(``descent_options.descent_applies``), not under the descent strategy, which always descends,
and not for a step law (``InteractionLaw.smooth`` false: Maugis-Dugdale's), whose branches are a
sawtooth at the grid's scale that the tangent does not see.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .descent_options import descent_applies
from .descent_step import descend_step
from .options import code_default

#: a descent whose gaps come this close to Newton's state is in its basin: within SAME_STATE z0,
#: or SAME_FRACTION of the jump (the gaps' largest change over Newton's step), since another
#: branch's state is a snap of z0 or more away somewhere, and the hop the check looks for
#: differs from Newton's state by about the jump itself (a pull-off's descent at Tabor 5 failed
#: short of 0.1 z0 of a jump of many z0)
SAME_STATE, SAME_FRACTION = 0.1, 0.1
#: the trapezoid's miss, relative to the larger tangent's force change, that makes a state suspect:
#: on the adhesive sphere's paths a smooth step misses by at most 0.15 of that change, the onset
#: of repulsive contact (a kink) by 0.5 and a jump by 0.75 or more; a rough surface's small snap
#: within a step (an asperity or two) by about 0.3, where the descent from the last state is no
#: nearer the quasi-static path than Newton's step (the path's sub-steps decide there:
#: ``paths.sweep``'s agreement)
BRANCH_TOL = 0.5
#: the force noise a converged state may carry, in units of the tolerance times the peak
#: attraction over the grid's area
FORCE_NOISE = 10.0


class BranchCheck:
    """The branch check of ``problem`` (an ``AdhesiveProblem``); reads ``-<prefix>branch_check``
    when made (inside the problem's ``inserted_options``)."""

    def __init__(self, problem):
        self.problem = problem
        on = PETSc.Options(problem.prefix).getBool("branch_check", code_default("adhesion", "branch_check"))
        self.applies = on and problem.strategy == "newton" and problem.law.smooth and descent_applies(problem)
        self._last = None   # (approach [m], net force [N], dF/d delta [N/m]) of the last state
        self.note = ""      # what the last ``follow`` did, for the state's reason

    def start(self, approach: float | None) -> None:
        """Before a solve at ``approach`` [m] (None: another control), while the unknowns are
        still the last converged state's: its force and tangent stiffness (solved here where it is
        due, as the predictor would: a restarted path's first step decides as the uninterrupted
        run's did)."""
        pb = self.problem
        self._last = None
        if not self.applies or approach is None or pb._start_approach is None:
            return
        pb.predictor.ensure()
        value = pb.predictor.value
        if value is None or value[0] != pb._start_approach or not np.isfinite(value[2]):
            return      # no tangent (a level that wants none), another state's, or a failed one
        self._last = (value[0], pb.net_force(), value[2])

    def missed(self, approach: float) -> str | None:
        """Why Newton's converged state at ``approach`` [m] may be on another branch, or None.
        Solves the state's tangent (``TangentPredictor.present``: the state keeps it)."""
        if self._last is None:
            return None
        pb = self.problem
        delta0, force0, k0 = self._last
        k1 = pb.predictor.present()
        step = approach - delta0
        miss = abs(pb.net_force() - force0 - 0.5 * (k0 + k1) * step)
        # at least what the solves' tolerance leaves in a net force (each node's pressure to tol
        # of the peak attraction): a tiny step's prediction is below that noise
        floor = FORCE_NOISE * pb.tol * pb.pressure_scale * pb.grid.lengths[0] * pb.grid.lengths[1]
        allowed = max(BRANCH_TOL * max(abs(k0 * step), abs(k1 * step)), floor)
        if miss <= allowed:    # False for a NaN k1
            return None
        self.note = (f" (branch check: the force misses the stiffnesses' trapezoid by {miss:.3e} N, a smooth "
                     f"branch's {allowed:.3e} N")
        return self.note

    def follow(self, approach: float, x_start: PETSc.Vec, check: bool):
        """The descent from the last state ``x_start`` to ``approach`` [m], stopped where its gaps
        come as near Newton's state as ``SAME_STATE`` and ``SAME_FRACTION`` say (a jump the
        quasi-static path takes too: Newton's state kept, with its tangent and margin); else to
        the tolerance or until it fails, then polished and checked (``check``).
        (taken, newton, linear, margin, increments): ``taken`` False where Newton's state is kept
        (the problem's unknowns, and the check's ``settled``, are then Newton's state's again,
        also where the descent raises)."""
        pb = self.problem
        newton_state = pb._x.copy()
        settled = pb.stability_check.settled
        taken = False
        try:
            newton_gap = pb._gap(pb.blocks(newton_state, readonly=True), np.empty(pb.grid.local_shape))
            # the gaps' largest change over Newton's step: a jump's size
            jump = np.abs(pb._gap(pb.blocks(x_start, readonly=True), np.empty_like(newton_gap)) - newton_gap)
            jump = pb.grid.mpi_comm.allreduce(float(jump.max(initial=0.0)), op=MPI.MAX)
            x_start.copy(pb._x)
            near = max(SAME_STATE * pb.z0, SAME_FRACTION * jump)
            descended, why, newton, linear, increments, reached = descend_step(pb, approach, pb._x,
                                                                               target=(newton_gap, near))
            del newton_gap
            PETSc.garbage_cleanup(pb.grid.comm)   # the descent's arrays, before the polish
            margin = float("nan")
            if reached:
                self.note += "; the descent from the last state reaches it: kept)"
            else:
                # also after a failed descent: next to a fold its line search stalls in round-off
                # (the energy's change below its last digits) while its iterate is near the
                # state, as the descent strategy's Newton polishes after it
                ok, _, n2, l2 = pb.newton.run()
                newton, linear = newton + n2, linear + l2
                margin = pb.stability_check.margin() if (ok and check) else float("nan")
                taken = ok and not margin <= 0
                ends = "ends elsewhere" if descended else f"stopped elsewhere ({why})"
                self.note += (f"; the descent from the last state {ends}: taken)" if taken else
                              f"; the descent from the last state {ends}, Newton from there "
                              f"{'found it unstable' if ok else 'failed'}: Newton's state kept)")
        finally:
            if taken:
                pb.predictor.drop()     # Newton's state's tangent
            else:
                newton_state.copy(pb._x)
                pb.stability_check.settled = settled
            newton_state.destroy()
        return taken, newton, linear, margin, increments
