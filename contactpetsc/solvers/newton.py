"""VI Newton on ``AdhesiveProblem``'s unknowns: the strategy that reaches a state from a nearby
start (docs/formulation.md, "Adhesive contact: unknowns and Newton").

A ``vinewtonrsls`` SNES on the problem's residual, Jacobian, bounds and convergence test (its
error measures, relative to the law's own scales), with

* the line search and Krylov method of the law (``newton_linesearch``, ``newton_ksp_type``),
  the problem's preconditioner, an inexact Krylov tolerance (``-<prefix>newton_ksp_rtol``)
  and the step limit of the full LJ curve;
* the stall watch (``-<prefix>stall_steps``, ``_stall_progress``): Newton without an error
  below ``stall_progress`` of its smallest so far for this many steps has stalled -- full
  steps can cycle for good where a few nodes of one edge sit at their own fold -- and
  stops, its best iterate kept for a fallback to go on from.

The same class makes the SNES of pseudo-transient continuation (``fallback.py``, options
under ``<prefix>ptc_``), whose Jacobian carries the problem's shift.
"""
from __future__ import annotations

from petsc4py import PETSc

from ..collective import collective_guard
from ..physics.resolution import steepest_slope
from .base import reason_name
from .options import LINESEARCH_MAX_STEP, code_default
from .pc_registry import ADHESIVE_PRECONDITIONERS


def newton_linesearch(hard_wall: bool) -> str:
    """The line search of the Newton steps (code default of ``-<prefix>snes_linesearch_type``).

    Backtracking for hard-wall laws (contact-set changes need damping); full steps for the
    full LJ curve, whose residual norm is dominated by the stiff repulsive rows and stalls
    bt (docs/performance.md, "Adhesive rough contact").
    """
    return "bt" if hard_wall else "basic"


def newton_ksp_type(hard_wall: bool, descends: bool = False) -> str:
    """The Krylov method of the Newton and PTC steps (code default of ``-<prefix>ksp_type``).

    Full LJ curve: BiCGStab, which keeps no Krylov basis (GMRES's Gram-Schmidt on the
    whole grid costs as much as the FFTs; docs/performance.md, "Adhesive rough contact").
    Hard-wall laws: GMRES, where Newton finds the state (fewer FFT pairs; the PTC fallback too);
    BiCGStab where it polishes the energy descent's (``descends``: the problem's strategy is the
    descent), whose few Newton steps need no fewer pairs with GMRES, and whose basis was a
    scene's peak of memory (docs/performance.md, "Memory of an adhesive path").  Under central-gap
    control nothing descends, yet the strategy's Newton keeps BiCGStab.
    """
    return "gmres" if hard_wall and not descends else "bcgs"


class VINewton:
    """A VI Newton SNES on ``problem``'s (an ``AdhesiveProblem``'s) shared unknowns, Jacobian and
    bounds, options under ``prefix``; made inside the problem's ``inserted_options`` after
    ``check_snes_options``.  ``polishes``: its runs polish the energy descent's states
    (``newton_ksp_type``)."""

    def __init__(self, problem, prefix: str, linesearch: str, max_it: int, ksp_max_it: int,
                 polishes: bool = False):
        self.problem = pb = problem
        self.prefix = prefix
        opts = PETSc.Options(pb.prefix)
        # 0.5 (an error that does not halve is no progress) where a hard-wall law's fallback
        # chain starts with the descent: a Newton creeping on damped steps hands over to it
        # sooner, for the same state; else 1 (any smaller error): the full LJ curve's slow
        # Newton runs converge where its descent is dear, and PTC after an early stall is
        # dearer than the slow Newton (docs/performance.md, "Energy descent as the fallback").
        # There, with a law that has a slope, in 4 steps instead of 8: across the sphere's jumps
        # Newton's eight futile steps had cost twice the descent's pairs.  A step law (Dugdale's)
        # keeps 8: its zone's edge has an equilibrium on either side of the step, and the descent
        # handed a slow Newton sooner settles on the other one (docs/performance.md, "The
        # adhesive sphere's states")
        descent_next = pb.fallback is not None and pb.fallback.methods[:1] == ["descent"]
        hands_over = pb.hard_wall and descent_next
        quick = hands_over and steepest_slope(pb.law) > 0.0
        self.stall_steps = opts.getInt("stall_steps", 4 if quick else 8)
        self.stall_progress = opts.getReal("stall_progress", 0.5 if hands_over else 1.0)
        if not 0.0 < self.stall_progress <= 1.0:
            raise ValueError(f"-{pb.prefix}stall_progress must be in (0, 1], got {self.stall_progress!r}")
        self.watch_stalls = False       # set per solve: only where a fallback goes on from a stall
        self.stalled = False
        self.best = (float("inf"), -1)  # (error [z0], step) of the watched run's best iterate
        self.progress = self.best       # (error [z0], step) of its last progress (``stall_progress``)
        self.x_best = None              # its best iterate (made when first watched: PTC never is)
        self.last_ksp_reason = 0        # the last solve's last Krylov reason (its KSP is reset)
        snes = self.snes = pb.make_vi_snes(prefix, None, max_it)     # bounds: per run
        snes.setConvergenceTest(self._converged)
        # an inexact step (Krylov limit reached) is still a step: let the line search judge it
        # (petsc4py >= 3.20 names it setMaxKSPFailures)
        (getattr(snes, "setMaxKSPFailures", None) or snes.setMaxLinearSolveFailures)(max_it)
        if pb.step_limit > 0:
            snes.setLineSearchPreCheck(pb._limit_step)
        pb.set_default("snes_linesearch_type", linesearch, prefix)
        # PETSc's default (1e8) is in the unknowns' units, Pa here: it cut every Newton step
        # of a stiff sphere (docs/formulation.md, "Adhesive contact: unknowns and Newton")
        pb.set_default(LINESEARCH_MAX_STEP, "1e300", prefix)
        ksp = snes.getKSP()
        ksp.setType(newton_ksp_type(pb.hard_wall, polishes))
        # with the full LJ curve an inexact step is cheaper than an exact one far from the
        # solution (docs/performance.md, "Adhesive rough contact")
        rtol = PETSc.Options(pb.prefix).getReal("newton_ksp_rtol", code_default("adhesion", "newton_ksp_rtol"))
        ksp.setTolerances(rtol=rtol, max_it=ksp_max_it)
        pc = ksp.getPC()
        if pb.preconditioner == "none":
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType(ADHESIVE_PRECONDITIONERS[pb.preconditioner])
        snes.setFromOptions()

    @collective_guard
    def _converged(self, snes, it, norms):
        """The problem's convergence test, then the stall watch (collective: the problem's
        verdict and errors are reduced over the ranks)."""
        pb = self.problem
        verdict = pb._converged(snes, it, norms)
        if verdict == PETSc.SNES.ConvergedReason.ITERATING and self.watch_stalls and self.stall_steps > 0:
            err = pb._last_error
            if it == 0 or err < self.best[0]:
                self.best = (err, it)
                if self.x_best is None:
                    self.x_best = pb.create_unknown()
                snes.getSolution().copy(self.x_best)
            if it == 0 or err < self.stall_progress * self.progress[0]:
                self.progress = (err, it)
            elif it - self.progress[1] >= self.stall_steps:
                self.stalled = True
                return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT   # named STALLED by run
        return verdict

    def run(self):
        """Solve from the problem's unknowns in place; (converged, reason, Newton steps,
        Krylov iterations)."""
        pb = self.problem
        pb._lin0 = pb.history[-1].linear_iterations if len(pb.history) else 0
        self.stalled = False
        # the residual Vec and the bounds live for the run (``AdhesiveProblem.vi_bounds``)
        f, bounds = pb.create_unknown(), pb.vi_bounds()
        pb.attach_vi_snes(self.snes, bounds, f)
        try:
            self.snes.solve(None, pb._x)
        finally:
            for vec in (f,) + (bounds or ()):
                vec.destroy()       # the SNES's references go with its reset below
        pb.record_solve()
        self.last_ksp_reason = self.snes.getKSP().getConvergedReason()
        code = self.snes.getConvergedReason()
        steps, linear = self.snes.getIterationNumber(), self.snes.getLinearSolveIterations()
        # the work vectors and the Krylov basis (GMRES: up to restart + 2 inactive-set vectors)
        # are not wanted again until the next run: the check and the tangent come first
        # (docs/performance.md, "Memory of an adhesive path")
        self._reset()
        name = pb.budget_reason if code < 0 and pb.out_of_time() else reason_name(code)
        if self.stalled:
            below = ("a smaller error" if self.stall_progress == 1.0
                     else f"an error below {self.stall_progress:g} of the smallest")
            name = (f"STALLED (no {below} in {self.stall_steps} Newton steps; smallest "
                    f"{self.best[0]:.3e} z0 at step {self.best[1]})")
        return code > 0, name, steps, linear

    def release(self) -> None:
        """Free what a run kept for the fallback after it: the best iterate."""
        if self.x_best is not None:
            self.x_best.destroy()
            self.x_best = None

    def _reset(self) -> None:
        """Free the SNES's work vectors after a run (``SNESReset``: its update, work and
        line-search vectors, the residual Vec, the VI's index arrays and bounds); its type,
        options and callbacks stay; the next run attaches the residual, Jacobian and bounds
        again.  Collective."""
        self.snes.reset()
        # and a fresh DM: the reset leaves the SNES's own (a DMShell) holding a Vec of the unknowns
        # that its VI made during the run (2 doubles per grid point with a hard wall); the next
        # run attaches the residual and Jacobian to the new one
        dm = PETSc.DMShell().create(comm=self.snes.getComm())
        dm.setGlobalVector(self.problem._x)     # its layout (a reference): getFunction() between runs works
        self.snes.setDM(dm)
        pc = self.snes.getKSP().getPC()
        if pc.getType() == "python":
            # a fresh context: the last one's references (levels, kernels, cycles) go with it
            pc.setPythonType(pc.getPythonType())

    def destroy(self) -> None:
        """Destroy the SNES (its callbacks hold the problem) and the best iterate."""
        self.snes.destroy()
        if self.x_best is not None:
            self.x_best.destroy()
