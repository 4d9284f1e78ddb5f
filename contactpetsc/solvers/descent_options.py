"""The energy descent as a strategy of ``AdhesiveProblem``: where it applies, its options under
the problem's prefix (checked before anything is built) and TAO's code defaults; the descent
itself is ``descent.py`` (docs/formulation.md, "Energy descent")."""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
from petsc4py import PETSc

from .options import code_default

#: TAO's code defaults (set under the strategy's prefix unless the user gave them)
TAO_DEFAULTS = {
    "tao_type": "bnls",
    # BNK's default active-set estimate (a projected gradient step) collapsed its trust region
    # on every hard-wall state, measured in unit-scale problems (docs/journal/descent_probe.md)
    "tao_bnk_as_type": "none",
    # inexact Newton: a tenth of the gradient per step is cheapest (docs/journal/descent_probe.md)
    "tao_bnk_ksp_rtol": "0.1",
    # a truncated Newton step: across a large snap single CG solves ran to hundreds of
    # iterations for a direction the line search then cut (docs/performance.md)
    "tao_bnk_ksp_max_it": "50",
    # the Hessian's shift, put on where CG meets negative curvature (a snap), is taken off at
    # the next Newton step that succeeds: BNK's default only shrinks it, to min(0.4 shift,
    # 0.1 |gradient|) a step (its floor 1e-12), and what was left of it damped the Newton
    # steps after the snap (docs/performance.md)
    "tao_bnk_psfac": "0",
    "tao_max_it": "500",
}


#: the Krylov methods whose convergence test takes CG's natural norm |r|_P = sqrt(r . P r): the
#: descent's default there (``natural_norm``), where GMRES or MINRES, which refuse it, keep theirs
NATURAL_NORM_KSPS = ("stcg", "nash", "gltr", "cg")


def natural_norm(ksp: PETSc.KSP, prefix: str) -> None:
    """Set CG's natural norm on the descent's Krylov solver ``ksp`` (options prefix ``prefix``)
    unless the user chose a norm or a method that refuses it: no extra product per iteration,
    and on the rough benchmark's paths and steps the same states in fewer FFT pairs
    (docs/performance.md, "Where the descent's time goes")."""
    if ksp.getType() in NATURAL_NORM_KSPS and not PETSc.Options(prefix).hasName("tao_bnk_ksp_norm_type"):
        ksp.setNormType(PETSc.KSP.NormType.NATURAL)


#: -<prefix>descent_preconditioner: the compliance S K S, the V-cycle on the Hessian
#: (``descent_cycle.py``), or auto: on a window the compliance, the cycle where it cuts CG's
#: iterations by 2.5; on a cell the compliance
DESCENT_PRECONDITIONERS = ("auto", "compliance", "multigrid")


class DescentOptions(NamedTuple):
    pc_contact_factor: float   #: f of the preconditioner's scaling (descent.py's module doc)
    floor_factor: float        #: F of the full LJ curve's gap floor
    max_step: float            #: the largest increment of a step's approach [z0] (0: the whole step)
    step_tol: float            #: the error the increments but the last are descended to
    stall_its: int             #: iterations without an energy decrease above round-off (0: no stall test)
    preconditioner: str        #: compliance, multigrid or auto (``descent_cycle.py``)


def descent_options(prefix: str) -> DescentOptions:
    """The descent's options under the problem prefix ``prefix``, checked:
    ``-<prefix>descent_pc_contact_factor``, ``_floor_factor`` and ``_max_step`` finite and
    >= 0, ``_step_tol`` finite and > 0."""
    opts = PETSc.Options(prefix)
    values = {}
    for name, positive in (("pc_contact_factor", False), ("floor_factor", False), ("max_step", False),
                           ("step_tol", True)):
        key = "descent_" + name
        value = values[name] = opts.getReal(key, code_default("adhesion", key))
        if not (np.isfinite(value) and (value > 0 if positive else value >= 0)):
            raise ValueError(f"-{prefix}{key} must be finite and {'> 0' if positive else '>= 0'}, got {value}")
    values["stall_its"] = opts.getInt("descent_stall_its", code_default("adhesion", "descent_stall_its"))
    if values["stall_its"] < 0:
        raise ValueError(f"-{prefix}descent_stall_its must be >= 0, got {values['stall_its']}")
    pc = values["preconditioner"] = opts.getString("descent_preconditioner", "auto").lower()
    if pc not in DESCENT_PRECONDITIONERS:
        raise ValueError(f"-{prefix}descent_preconditioner must be {', '.join(DESCENT_PRECONDITIONERS)}, got {pc!r}")
    # BNK's embedded CG steps call the convergence test without its Python context (petsc4py
    # then fails inside TAOSolve with a TypeError): refused here, by name
    if opts.getInt("descent_tao_bnk_max_cg_its", 0) != 0:
        raise ValueError(f"-{prefix}descent_tao_bnk_max_cg_its must be 0 (BNK's CG steps are not supported "
                         f"by the descent's convergence test)")
    return DescentOptions(**values)


def descent_applies(problem) -> bool:
    """Whether ``EnergyDescent`` can drive ``problem``: the nodal rule (the law's energy at the
    nodes) on a periodic grid (K^-1 diagonal in Fourier space) or on an isolated window split
    along y (its padded grid's, ``descent_space.PaddedWindow``)."""
    grid = problem.grid
    return bool((grid.periodic or grid.px == 1) and not problem.element_integration)


def strategy_option(prefix: str, applies: bool) -> str:
    """``-<prefix>strategy`` (newton or descent), by default the descent where it ``applies``
    (``descent_applies``); read from the options as they stand (a problem's, inserted)."""
    strategy = PETSc.Options(prefix).getString("strategy", "descent" if applies else "newton").lower()
    if strategy not in ("newton", "descent"):
        raise ValueError(f"-{prefix}strategy must be newton or descent, got {strategy!r}")
    return strategy


def require_descent(problem, what: str) -> None:
    """Refuse ``what`` (an option naming the descent) where ``descent_applies`` is false."""
    if not descent_applies(problem):
        raise ValueError(f"{what} needs the energy descent, which needs the nodal rule "
                         f"(-{problem.prefix}element_integration false) on a periodic grid or on an isolated "
                         f"window split along y only (-grid_px 1)")
