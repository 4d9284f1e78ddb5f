"""The package's own options, registered once: their code defaults (read by the problems), the
option tables of docs/formulation.md ("Options", "Adhesion options") and the ``-help`` text.

Keys are relative to the problem's prefix (``contact_`` / ``adhesion_`` by default); a key
with a leading dash in a row is shown in full (``-<prefix>key``) instead of as a ``_key`` suffix.
"""
from __future__ import annotations

from dataclasses import dataclass

from petsc4py import PETSc

#: the line search's largest step: PETSc 3.24 renamed snes_linesearch_maxstep (and warns about
#: the old name)
LINESEARCH_MAX_STEP = ("snes_linesearch_maxlambda" if PETSc.Sys.getVersion()[:2] >= (3, 24)
                       else "snes_linesearch_maxstep")


@dataclass(frozen=True)
class Option:
    names: tuple                 #: keys under the prefix, one row of the table
    default: tuple | str         #: typed code defaults, one per key, or a text for sub-objects
    meaning: str

    @property
    def keys(self) -> tuple:
        return tuple(n.lstrip("-") for n in self.names)


def _text(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float) and value != 0 and not (1e-2 <= abs(value) < 1e4):
        mantissa, exponent = f"{value:.0e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return str(value)


CONTACT = (
    Option(("snes_max_it", "-ksp_max_it"), (100, 500), "Newton steps per solve, Krylov steps per Newton step"),
    Option(("slope_ksp_*",), "cg, rtol 1e-2, max_it 500", "the KSP of the load-control slope solves K_II z = 1 (with a hardness)"),
    Option(("preconditioner",), ("spectral",), "`spectral`, `mlmi` or `none`"),
    Option(("tol",), (1e-10,), "complementarity error relative to the length scale"),
    Option(("load_tol",), (1e-10,), "relative load error (floored at what `tol` allows)"),
    Option(("newton_ksp_rtol",), (0.1,), "Krylov tolerance of the Newton steps (under load control: the largest)"),
    Option(("newton_ksp_forcing",), (True,),
           "under load control, the Krylov tolerance follows the Newton convergence (Eisenstat-Walker)"),
    Option(("load_joint",), (True,),
           "load control as one Newton iteration in (p, delta), its step CG on the load's plane; false (and the default "
           "with a `ksp_type` other than cg, with a warning): the outer iteration on delta (as with a hardness)"),
    Option(("load_max_it",), (50,), "approach updates under load control (the outer iteration)"),
    Option(("load_inner_tol", "load_inner_eta"), (1e-3, 0.1), "inexact intermediate solves (load control with a hardness)"),
    Option(("slope_warm_start",), (True,), "slope solves start from the previous z (with a hardness)"),
    Option(("fmg", "fmg_min_size", "fmg_tol"), (True, 32, 1e-4), "nested iteration on first solve"),
    Option(("fmg_prolong",), ("constant",), "coarse-to-fine pressure transfer: constant or bilinear"),
    Option(("mlmi_levels", "mlmi_min_size"), (8, 8), "multilevel hierarchy"),
    Option(("mlmi_cycle", "mlmi_pre", "mlmi_post", "mlmi_coarse_sweeps"), ("v", 1, 1, 4), "cycle"),
    Option(("mlmi_power_its", "mlmi_rho_bound"), (6, 1.6), "smoother damping bound"),
    Option(("fft_threads", "-fft_planner"), (1, "measure"),
           "FFTW threads per rank (or auto: the rank's cores), planner effort (a standalone operator "
           "reads `-elastic_fft_*`)"),
)

ADHESION = (
    Option(("tol",), (1e-8,), "errors (z0) at convergence"),
    Option(("max_it",), (100,), "Newton steps per solve"),
    Option(("newton_ksp_rtol",), (1e-2,), "Krylov tolerance of the Newton steps"),
    Option(("ksp_max_it",), (30,), "Krylov iterations per Newton step"),
    Option(("repulsive_rows",), ("gap",), "gap-form rows g - G(a) where g < 0 (full LJ, nodal), or pressure"),
    Option(("step_limit",), "0.5 (full LJ), 0", "largest fall of a gap below min(g, 0) per Newton step (z0)"),
    Option(("fmg", "fmg_min_size", "fmg_tol"), (True, 32, 1e-3), "nested iteration on the first solve"),
    Option(("fmg_step_levels",), "0 (window, smooth law), 2", "coarse levels that predict a path's next step (FAS-corrected "
           "coarse steps; 0: the tangent predictor)"),
    Option(("fmg_ksp_max_it",), (100,), "Krylov iterations per Newton step on the coarse levels (at most "
           "-<prefix>ksp_max_it): a level only predicts"),
    Option(("preconditioner",), ("auto",), "auto (from the snap number K_ii max da/dg: mlmi for 0.01-0.2 "
           "with a hard wall, per grid, and 0.2-0.4 with the full LJ curve, else spectral), spectral (block: spectral on the contact-like rows), mlmi "
           "(multilevel cycle on the whole system) or none"),
    Option(("element_integration",), (False,), "the paper's element integration"),
    Option(("stability_check", "stability_steps"), (True, 150),
           "stability check (LOBPCG or Lanczos, at most this many steps): true, false or auto (left out of a sweep's states away from folds; "
           "the default of scenes' sweeps)"),
    Option(("stability_preconditioner",), ("auto",),
           "the LOBPCG check's preconditioner: compliance (K on W), mlmi (periodic grids: the adhesive "
           "multilevel cycle on the Hessian's pressure form), multigrid (a V-cycle on the Hessian; on a window "
           "on its padded grids) or auto (periodic: mlmi where the law's da/dg >= 0 off contact, the "
           "exponential law, else multigrid; a window: the compliance for its first iterations, then multigrid)"),
    Option(("predictor",), (True,), "tangent predictor under displacement control"),
    Option(("stiffness",), (True,),
           "every displacement-controlled state's tangent stiffness (false: NaN, the tangent only for the predictor)"),
    Option(("tangent_hessian",), (True,),
           "the tangent by CG on the energy's Hessian where the descent applies to the full LJ curve (false: "
           "the Jacobian's Krylov solve, as on hard walls)"),
    Option(("load_from_rest", "initial_step"), (False, 0.25),
           "first solve: load from separation in steps of at most this many z0"),
    Option(("strategy",), "descent (periodic grids with the nodal rule) or newton",
           "newton (from the predicted state) or descent (the energy descent from the last state, then Newton; "
           "the nodal rule on a periodic grid or an isolated window split along y)"),
    Option(("loading_descent",), "true (an isolated window with a hard-wall law that has a slope), false",
           "newton strategy where the descent applies: once Newton has failed on a step that raises the approach "
           "(the fallback's descent reached it), the steps that raise it further are descended from the last state "
           "first (then Newton polishes), until the approach falls again"),
    Option(("branch_check",), (True,),
           "newton strategy where the descent applies (smooth laws): a converged state whose force misses the "
           "trapezoid of its and the last state's tangent stiffnesses (a jump) is descended from the last state "
           "instead, and that state kept where it is stable"),
    Option(("fallback",), "descent first with the nodal rule (periodic grids, isolated windows split along y), "
           "then relaxation,ptc (hard wall) or ptc",
           "where Newton fails or ends unstable: these in turn"),
    Option(("descent_max_rounds",), (40,), "energy descent: a hard wall's mean-pressure rounds"),
    Option(("descent_stall_its",), (10,),
           "energy descent: stalled (Newton polishes its iterate) once its energy has not fallen by more than "
           "1e-12 of itself in this many iterations (0: never)"),
    Option(("descent_preconditioner",), "auto: compliance on a periodic cell; on an isolated window compliance, multigrid tried after "
           "two Newton steps whose CG took 10 iterations or more, kept while it takes at most 1 / 2.5 of them "
           "in the mean (left at a snap, tried again after it)",
           "energy descent: its Krylov solves' preconditioner, the compliance scaled on the repulsive nodes or "
           "the V-cycle on its Hessian (compliance, multigrid)"),
    Option(("descent_pc_contact_factor",), (10.0,),
           "energy descent: its compliance preconditioner's scaling on nodes in repulsive contact (0: none)"),
    Option(("descent_floor_factor",), (4.0,),
           "energy descent, full LJ curve: its gaps held above the one where the repulsion is this times "
           "the start's largest pressure (at least the peak attraction), lowered where a state needs it (0: none)"),
    Option(("descent_max_step", "descent_step_tol"), (0.0, 1e-2),
           "energy descent strategy: the step's approach followed in increments of at most this (z0; 0: the "
           "whole step at once), each but the last descended to this error only"),
    Option(("descent_tol", "descent_offset_tol"), "tol (full LJ) or tol / 2, tol / 10",
           "energy descent: error measure reached before Newton polishes, a hard wall's mean offset (z0)"),
    Option(("descent_tao_*",), "bnls, bnk_as_type none, bnk_ksp_rtol 0.1, bnk_ksp_norm_type natural (stcg, nash, gltr, cg), "
           "bnk_ksp_max_it 50, bnk_psfac 0, max_it 500",
           "the TAO of the energy descent (`-<prefix>descent_tao_monitor`)"),
    Option(("fallback_tol", "fallback_max_cycles"), (1e-3, 5000), "relaxation fallback"),
    Option(("ptc_shift", "ptc_max_it"), (1.0, 300), "pseudo-transient continuation: first shift, steps"),
    Option(("ptc_snes_*",), "vinewtonrsls, line search basic", "the SNES of pseudo-transient continuation"),
    Option(("stall_steps",), "4 (hard-wall laws with a slope whose fallback starts with the descent) or 8",
           "Newton without a smaller error in this many steps has stalled (`STALLED`): the fallback chain goes "
           "on (PTC from its best iterate) (0: never)"),
    Option(("stall_progress",), "0.5 (hard-wall laws whose fallback starts with the descent) or 1",
           "the stall watch counts an error as smaller only below this fraction of the smallest so far"),
    Option(("time_budget",), (0.0,),
           "wall time [s] for all of the problem's solves (0: none); then `WALL_TIME_BUDGET`"),
    Option(("relax_tol", "relax_contact_tol"), (1e-4, 1e-4), "the paper's solver (z0)"),
    Option(("relax_max_cycles", "relax_max_inner", "relax_omega_max"), (20000, 200, 1.0), "its limits"),
    Option(("tangent_ksp_*", "-stability_ksp_*"),
           "bcgs 1e-2; cg 1e-3 (full LJ, periodic, nodal rule); cg 1e-5 (Lanczos on a window: a tenth of its tolerance)",
           "the tangent (Jacobian, or the energy's Hessian; coarse levels of the nested iteration "
           "compute none) and stability solves"),
)

TABLES = {"contact": CONTACT, "adhesion": ADHESION}


def code_default(table: str, key: str):
    """The typed code default of ``-<prefix><key>`` in ``table`` (``contact`` or ``adhesion``)."""
    for option in TABLES[table]:
        if key in option.keys and not isinstance(option.default, str):
            return option.default[option.keys.index(key)]
    raise KeyError(f"no typed code default for {key!r} in the {table} options")


def _default_text(option: Option) -> str:
    if isinstance(option.default, str):
        return option.default
    return ", ".join(_text(v) for v in option.default)


def options_markdown(table: str) -> str:
    """The option table of docs/formulation.md for ``table``, default prefix ``<table>_``."""
    rows = ["| option | default | meaning |", "|---|---|---|"]
    for option in TABLES[table]:
        names = [f"`-{table}_{option.names[0]}`"]
        names += [f"`-{table}_{n[1:]}`" if n.startswith("-") else f"`_{n}`" for n in option.names[1:]]
        default = _default_text(option)
        if option.names == ("preconditioner",) and table == "contact":
            default = f"`{default}`"
        rows.append(f"| {', '.join(names)} | {default} | {option.meaning} |")
    return "\n".join(rows) + "\n"


_helped: set = set()


def print_help(table: str, prefix: str, comm=None) -> None:
    """With ``-help`` in the options, print this table's options under ``prefix`` once per
    prefix (petsc4py has no PetscOptionsBegin for Python code: PETSc's own ``-help`` lists
    only its objects' options)."""
    if not PETSc.Options().hasName("help") or (table, prefix) in _helped:
        return
    _helped.add((table, prefix))
    lines = [f"contactpetsc {table} options (docs/formulation.md):"]
    for option in TABLES[table]:
        names = ", ".join(f"-{prefix}{k}" for k in option.keys)
        lines.append(f"  {names} <{_default_text(option)}>: {option.meaning}")
    PETSc.Sys.Print("\n".join(lines), comm=comm)
