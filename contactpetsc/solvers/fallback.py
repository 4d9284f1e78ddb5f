"""The fallback chain of ``AdhesiveProblem``: a strategy for where Newton fails or ends on an
unstable state (the branch has ended: a jump), docs/formulation.md, "Adhesive contact:
unknowns and Newton".

From the last converged state (or a stalled Newton's best iterate) the methods of the chain
follow a relaxation path in turn until one reaches a stable state, each polished by Newton:

* ``descent``: the energy descent (``descent.py``), first where it applies: it reaches the
  minimum next to the last state without pseudo-time;
* ``relaxation``: the paper's relaxation (``relaxation.py``, hard-wall laws);
* ``ptc``: pseudo-transient continuation, a VI Newton SNES on the problem's unknowns whose
  Jacobian carries a shift that follows the residual (switched evolution relaxation).

Options: ``-<prefix>fallback`` (the chain), ``-<prefix>fallback_tol`` and
``_fallback_max_cycles`` (the relaxation), ``-<prefix>ptc_shift`` and ``_ptc_max_it``, and the
PTC SNES's own options under ``<prefix>ptc_``.
"""
from __future__ import annotations

from petsc4py import PETSc

from .descent import EnergyDescent
from .descent_options import descent_applies, require_descent
from .newton import VINewton
from .options import code_default
from .relaxation import RelaxationSolver

#: the methods of -<prefix>fallback
FALLBACKS = ("descent", "relaxation", "ptc")

#: line search of the pseudo-transient continuation SNES: full (shifted) steps, the residual
#: norm need not fall monotonically along the relaxation path
PTC_LINESEARCH = "basic"


class FallbackChain:
    """The fallback methods of ``problem`` (an ``AdhesiveProblem``); reads and checks its
    options when made (before any PETSc object of the problem exists), makes the PTC SNES
    with ``build``."""

    def __init__(self, problem):
        self.problem = problem
        prefix = problem.prefix
        opts = PETSc.Options(prefix)
        # hard-wall laws: the paper's relaxation first, then PTC -- each reaches states where
        # the other stops at its cap (a strongly adhesive sphere loaded from rest, a jump-off)
        chain = ("descent," if descent_applies(problem) else "") + ("relaxation,ptc" if problem.hard_wall else "ptc")
        chain = opts.getString("fallback", chain).lower()
        self.methods = [m.strip() for m in chain.split(",") if m.strip()]
        if not self.methods or any(m not in FALLBACKS for m in self.methods):
            raise ValueError(f"-{prefix}fallback must be {', '.join(FALLBACKS)} or a comma-separated "
                             f"chain of them, got {chain!r}")
        if "descent" in self.methods:
            require_descent(problem, f"-{prefix}fallback {chain}")
        if "relaxation" in self.methods and not problem.hard_wall:
            raise ValueError(f"-{prefix}fallback relaxation needs a hard-wall law (the paper's relaxation "
                             f"stores contact pressures apart), got {problem.law.name!r}")
        self.tol = opts.getReal("fallback_tol", code_default("adhesion", "fallback_tol"))
        self.max_cycles = opts.getInt("fallback_max_cycles", code_default("adhesion", "fallback_max_cycles"))
        self.ptc_shift = opts.getReal("ptc_shift", code_default("adhesion", "ptc_shift"))
        # bounded: where PTC has not settled in a few hundred steps it wanders
        # (under-resolved strong adhesion; docs/robustness.md)
        self.ptc_max_it = opts.getInt("ptc_max_it", code_default("adhesion", "ptc_max_it"))
        self.ptc = None

    def build(self) -> None:
        """The PTC SNES (options under ``<prefix>ptc_``), once the problem's unknowns exist."""
        if self.ptc is None:
            # pseudo-transient continuation takes inexact steps: a step of a path need not be
            # solved exactly (docs/formulation.md, "Adhesive contact: unknowns and Newton")
            self.ptc = VINewton(self.problem, self.problem.prefix + "ptc_", PTC_LINESEARCH, self.ptc_max_it, 30)

    def takes_over_stalls(self) -> bool:
        """Whether a method of the chain goes on from a stalled Newton (its stall watch)."""
        return bool({"ptc", "descent"} & set(self.methods))

    def follow(self, approach, x_start, check, newton, linear, solver, reason, skip=()):
        """The methods in turn from the last converged state ``x_start`` (or a stalled Newton's
        best iterate), but those in ``skip``, until one reaches a state that is stable (or not
        checked, ``check`` false); returns (converged, reason, newton, linear, margin, solver).
        ``reason``: why Newton's state is not taken (kept where no method is left)."""
        pb = self.problem
        stalled = pb.newton.stalled
        ok, margin = False, float("nan")
        reason += " (no fallback method left)"
        for method in (m for m in self.methods if m not in skip):
            # a stalled Newton was near a state but for a few nodes: PTC from its best iterate
            (pb.newton.x_best if stalled and method == "ptc" else x_start).copy(pb._x)
            if method == "descent":
                ok, reason, n2, l2 = EnergyDescent(pb).descend(approach, pb._x)
                # its TAO's contexts hold its arrays (a window's padded grid's): freed before the polish
                PETSc.garbage_cleanup(pb.grid.comm)
            elif method == "relaxation":
                relax = RelaxationSolver(pb, tol=self.tol, max_cycles=self.max_cycles)
                ok, reason, n2, l2 = relax.relax(approach, polished=True)
            else:
                pb.shift, pb._ptc_prev = self.ptc_shift, 0.0
                ok, reason, n2, l2 = self.ptc.run()
                pb.shift = 0.0
            polish = ok and method != "ptc"
            if not ok and method == "descent":
                # the descent writes its last state, which no SNES measured (PTC's iterates
                # are measured by its SNES; a failed relaxation leaves the start in place)
                pb.offer_iterate(f"descent iteration {n2}")
                # and is polished as a converged one is: next to a fold its line search stalls
                # in round-off (the energy's change below its last digits) with its iterate at
                # the state, where Newton converges in a step or two and the methods after it
                # would start again from the last state (the branch check does the same)
                polish = not pb.out_of_time()
            if polish:
                # the polish: VI Newton at the approach itself (a hard wall's descent ends
                # within offset_tol z0 of it; the relaxation stops at fallback_tol)
                failed = not ok
                ok, why, n3, l3 = pb.newton.run()
                reason = f"{reason}; Newton from its iterate: {why}" if failed and not ok else why
                n2, l2 = n2 + n3, l2 + l3
            solver += "+" + method
            newton, linear = newton + n2, linear + l2
            margin = pb.stability_check.margin() if (ok and check) else float("nan")
            if (ok and not margin <= 0) or pb.out_of_time():
                break
        return ok, reason, newton, linear, margin, solver

    def destroy(self) -> None:
        """Destroy the PTC SNES (its callbacks hold the problem)."""
        if self.ptc is not None:
            self.ptc.destroy()
        self.ptc = None
