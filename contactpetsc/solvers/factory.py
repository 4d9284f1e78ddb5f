"""One door from (grid, h, E*, law) to a solver, for the runner and API users alike, and a
description of the solver stack it builds (``--dry-run``; docs/api.md, "Non-adhesive contact")."""
from __future__ import annotations

from petsc4py import PETSc

from ..operators.elastic import half_space
from ..operators.layer import Layer
from ..physics.interactions import relaxation_laws
from .adhesive import AdhesiveProblem
from .fallback import PTC_LINESEARCH
from .newton import newton_ksp_type, newton_linesearch
from .base import VI_SNES, VIProblem
from .options import code_default
from .pc_registry import ADHESIVE_PRECONDITIONERS, AUTO_MLMI_SNAP, PRECONDITIONERS, auto_adhesive_preconditioner
from .problem import NEWTON_KSP, NEWTON_LINESEARCH, ContactProblem
from .relaxation import RelaxationSolver

METHODS = ("newton", "relaxation")
#: keyword defaults of ``make_problem`` that go to the relaxation solver, not to its problem
RELAXATION_DEFAULTS = ("tol", "contact_tol", "max_cycles")


def _no_adhesion(law) -> bool:
    return law is None or not law.adhesive


def _check_method(law, method: str) -> None:
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if method == "relaxation" and (_no_adhesion(law) or law.name not in relaxation_laws()):
        name = "none" if law is None else law.name
        raise ValueError(f"method 'relaxation' needs an adhesive law with a hard wall or a repulsive branch "
                         f"({', '.join(relaxation_laws())}), got law {name!r}")


def make_problem(grid, heights, e_star: float, law=None, *, method: str = "newton", prefix: str | None = None,
                 petsc_options: dict | None = None, layer: Layer | None = None, **defaults):
    """``ContactProblem`` (``law`` None or ``none``), ``AdhesiveProblem`` (method ``newton``) or a
    ``RelaxationSolver`` on an ``AdhesiveProblem`` (method ``relaxation``; its ``tol``,
    ``contact_tol`` and ``max_cycles`` go to the relaxation).  ``prefix`` defaults to
    ``contact_`` / ``adhesion_``; ``layer`` (``operators.Layer``) makes the body a finite layer
    on a rigid base (periodic cells); ``defaults`` are the problems' keyword code defaults
    (``hardness`` without adhesion only)."""
    _check_method(law, method)
    prefix = prefix or ("contact_" if _no_adhesion(law) else "adhesion_")
    if defaults.get("hardness") is not None and not _no_adhesion(law):
        raise ValueError(f"hardness = {defaults['hardness']!r} Pa with adhesion (law {law.name!r}) is not "
                         f"supported: the hardness caps the pressure of the non-adhesive problem")
    if layer is not None:
        with _Options(prefix, petsc_options).inserted_options():   # -<prefix>fft_* reach the operator
            defaults["operator"] = half_space(grid, e_star, layer=layer, prefix=prefix)
    if _no_adhesion(law):
        return ContactProblem(grid, heights, e_star, prefix=prefix, petsc_options=petsc_options, **defaults)
    relax = {k: defaults.pop(k) for k in RELAXATION_DEFAULTS if method == "relaxation" and k in defaults}
    problem = AdhesiveProblem(grid, heights, e_star, law, prefix=prefix,
                              petsc_options=petsc_options, **defaults)
    return RelaxationSolver(problem, **relax) if method == "relaxation" else problem


def grid_snap_number(law, grid, e_star: float) -> float:
    """The snap number K_ii max da/dg of ``law`` on ``grid`` without building its operator: K_ii
    by Love's coefficient of a uniformly loaded dx x dy element (the isolated half-space's own;
    for a periodic cell or a layer an estimate, good to the images' share of order dx / L)."""
    from ..operators.love import love_displacement
    from ..physics.resolution import snap_number
    k_ii = float(love_displacement(0.0, 0.0, 0.5 * grid.dx, 0.5 * grid.dy, e_star))
    return snap_number(law, k_ii)


class _Options(VIProblem):
    """Only the options push and pop of ``VIProblem`` (no grid, no operator)."""

    def __init__(self, prefix, petsc_options):   # noqa: D107 - no VIProblem.__init__: nothing to solve
        self.prefix = prefix
        self.petsc_options = {str(k).lstrip("-"): v for k, v in dict(petsc_options or {}).items()}
        self._inserted, self._options_depth = None, 0


def _describe_snes(opts: _Options, prefix: str, linesearch: str, ksp_type: str, pc_path: str | None) -> list[str]:
    snes = PETSc.SNES().create(comm=PETSc.COMM_SELF)
    try:
        snes.setOptionsPrefix(prefix)
        snes.setType(VI_SNES)
        opts.set_default("snes_linesearch_type", linesearch, prefix)
        ksp = snes.getKSP()
        ksp.setType(ksp_type)
        pc = ksp.getPC()
        if pc_path is None:
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType(pc_path)
        snes.setFromOptions()
        line = PETSc.Options(prefix).getString("snes_linesearch_type", linesearch)
        pc_type = pc.getType() + (f" ({pc.getPythonType()})" if pc.getType() == "python" else "")
        return [f"SNES {snes.getType()} (prefix -{prefix}, line search {line})",
                f"  KSP {ksp.getType()} (prefix -{ksp.getOptionsPrefix()})",
                f"  PC {pc_type} (prefix -{pc.getOptionsPrefix()})"]
    finally:
        snes.destroy()


def adhesive_strategy(prefix: str, petsc_options: dict | None, periodic: bool, element_integration: bool) -> str:
    """The strategy (newton or descent) an ``AdhesiveProblem`` under ``prefix`` with these options
    and the command line will take, without building it (``strategy_option``)."""
    from .descent_options import strategy_option
    with _Options(prefix, petsc_options).inserted_options():
        # the rule as the problem reads it: the option, else the scene's setting
        element_integration = PETSc.Options(prefix).getBool("element_integration", element_integration)
        return strategy_option(prefix, periodic and not element_integration)


def describe_solver(law=None, method: str = "newton", prefix: str | None = None,
                    petsc_options: dict | None = None, snap: float | None = None,
                    descends: bool = False) -> list[str]:
    """The SNES/KSP/PC types and options prefixes that ``make_problem`` would solve with, from
    the code defaults and the options (``petsc_options`` under the prefix, the command line);
    builds only those PETSc objects, no grid vectors.  ``snap``: the finest grid's snap number
    (``grid_snap_number``), for the preconditioner ``auto`` picks there; ``descends``: the
    adhesive problem's strategy is the energy descent (``adhesive_strategy``), which Newton
    polishes (``newton.newton_ksp_type``)."""
    _check_method(law, method)
    adhesive = not _no_adhesion(law)
    prefix = prefix or ("adhesion_" if adhesive else "contact_")
    opts = _Options(prefix, petsc_options)
    with opts.inserted_options():
        opts.check_snes_options(*([prefix, prefix + "ptc_"] if adhesive else [prefix]))
        db = PETSc.Options(prefix)
        if not adhesive:
            choice = db.getString("preconditioner", "spectral").lower()
            if choice not in PRECONDITIONERS:
                raise ValueError(f"-{prefix}preconditioner must be one of {sorted(PRECONDITIONERS)}, got {choice!r}")
            return (_describe_snes(opts, prefix, NEWTON_LINESEARCH, NEWTON_KSP, PRECONDITIONERS[choice])
                    + [f"  preconditioner {choice} (-{prefix}preconditioner)"])
        choice = db.getString("preconditioner", code_default("adhesion", "preconditioner")).lower()
        if choice != "auto" and choice not in ADHESIVE_PRECONDITIONERS:
            raise ValueError(f"-{prefix}preconditioner must be auto or one of "
                             f"{', '.join(ADHESIVE_PRECONDITIONERS)}, got {choice!r}")
        if method == "relaxation":
            return [f"relaxation-mlmi (the reference paper's MLMI relaxation; options prefix -{prefix}relax_)"]
        note = f"  preconditioner {choice} (-{prefix}preconditioner)"
        if choice == "auto":
            lo, hi = AUTO_MLMI_SNAP["hard wall" if law.hard_wall else "full LJ"]
            rule = f"from the snap number K_ii max da/dg: mlmi for {lo:g} to {hi:g}, spectral elsewhere; " + (
                "each coarser grid of the nested iteration (twice the snap number) chooses for itself"
                if law.hard_wall else "the coarser grids of the nested iteration take the finest grid's pick")
            if snap is None:
                note += f": {rule}"
            else:
                choice = auto_adhesive_preconditioner(snap, law.hard_wall)
                note += f" -> {choice} on the finest grid (snap number {snap:.3g}); {rule}"
        pc_path = ADHESIVE_PRECONDITIONERS.get(choice, ADHESIVE_PRECONDITIONERS["spectral"])
        lines = _describe_snes(opts, prefix, newton_linesearch(law.hard_wall),
                               newton_ksp_type(law.hard_wall, descends), pc_path)
        lines.append(note)
        lines += ["fallback " + line for line in _describe_snes(opts, prefix + "ptc_", PTC_LINESEARCH,
                                                                 newton_ksp_type(law.hard_wall), pc_path)]
        return lines
