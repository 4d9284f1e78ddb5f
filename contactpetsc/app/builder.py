"""The scene builder: one place that turns a validated scene into grid, heights, law and problem.

The scene is translated once: the law is built from the registry (``physics.interactions``)
with the parameters its class declares, the adhesive zone is checked against the grid once,
with the one criterion of ``physics.resolution`` (docs/robustness.md, "The resolution
criterion"), and the problem is built with the scene's PETSc options under its prefix.
A dry run builds the grid (a DMDA, no vectors) and the law only.
"""
from __future__ import annotations

import warnings

from petsc4py import PETSc

from ..collective import petsc_error_message
from ..grid import SurfaceGrid
from ..physics.interactions import LAWS, InteractionLaw, make_law
from ..physics.resolution import UnderResolvedWarning, check_resolution
from .scenes import adhesive, e_star, law_keys, layer

#: the options prefixes of the scene's problems (docs/formulation.md)
CONTACT_PREFIX, ADHESION_PREFIX = "contact_", "adhesion_"


def build_grid(scene: dict, comm=None) -> SurfaceGrid:
    """The scene's grid; a PETSc failure (memory) is told in the scene's keys."""
    g = scene["geometry"]
    try:
        grid = SurfaceGrid(g["nx"], g["ny"], g["dx"], g["dy"], periodic=g["periodic"], comm=comm)
        grid.require_slabs("a scene run (its outputs and measures)")
        return grid
    except PETSc.Error as exc:
        size = (comm or PETSc.COMM_WORLD).getSize()
        raise RuntimeError(f"cannot build the {g['nx']} x {g['ny']} grid (geometry.nx, geometry.ny) on {size} "
                           f"rank(s), about {memory_per_rank(scene, size) / 2**20:.0f} MiB per rank: "
                           f"{petsc_error_message(exc)}; use a smaller grid or more ranks") from None


#: a scene's run's resident doubles per grid node beside the process's own, (periodic cell,
#: isolated window), measured on one rank (``run_scripts/bench/bench_run_memory.py`` on the
#: example scenes, docs/performance.md, "Memory of an adhesive path"): without adhesion at
#: 1024^2; with a law without a hard wall (the full LJ curve) and with a hard wall at 512^2,
#: where a run's fixed parts weigh more per node than on larger grids; a periodic hard wall
#: under the energy descent (its default: Newton polishes with BiCGStab; under
#: ``-adhesion_strategy newton`` GMRES's basis holds about 12 more)
RUN_DOUBLES = {"contact": (36, 64), "adhesive": (48, 98), "hard wall": (66, 163)}
#: the process without a grid (Python, numpy, PETSc, MPI, FFTW) [bytes]
PROCESS_BYTES = 110 * 2**20


def memory_per_rank(scene: dict, size: int) -> float:
    """Bytes per rank a run needs, estimated from measured runs: the process's own
    (``PROCESS_BYTES``) and ``RUN_DOUBLES`` doubles per grid node of the rank's share."""
    g = scene["geometry"]
    if not adhesive(scene):
        kind = "contact"
    else:
        kind = "hard wall" if LAWS[scene["interaction"]["law"]].hard_wall else "adhesive"
    per_node = RUN_DOUBLES[kind][0 if g["periodic"] else 1]
    return PROCESS_BYTES + per_node * 8.0 * g["nx"] * g["ny"] / size


def build_tip(scene: dict, grid: SurfaceGrid):
    """(tip, heights, owner) of a ``kind = tip`` scene (``geometry.tips``)."""
    from ..geometry import tips
    g = scene["geometry"]
    tip = tips.make_tip(g["tip"], grid, g["radius"], g["atom_spacing"], atom_radius=g["atom_radius"],
                        seed=g["seed"])
    h, owner = tips.profile(grid, tip)
    return tip, h, owner


def build_heights(scene: dict, grid: SurfaceGrid, info: dict | None = None) -> PETSc.Vec:
    """The composite surface h [m] of the scene's geometry; ``info`` (a file's): gets
    ``filled_points``, the points not measured that ``geometry.fill`` filled."""
    from ..geometry import surfaces
    g = scene["geometry"]
    if g["kind"] == "tip":
        return build_tip(scene, grid)[1]
    if g["kind"] == "sphere":
        return surfaces.sphere(grid, g["radius"])
    if g["kind"] == "file":
        return surfaces.from_topography(grid, g["path"], g["dataset"], format=g["format"],
                                        height_unit=g["height_unit"], detrend=g["detrend"],
                                        heights_are=g["heights_are"], fill=g["fill"], info=info)
    return surfaces.self_affine(grid, hurst=g["hurst"], seed=g["seed"], rms_height=g["rms_height"],
                                rms_slope=g["rms_slope"], rolloff_wavelength=g["rolloff_wavelength"],
                                short_cutoff_wavelength=g["short_cutoff_wavelength"])


def build_law(scene: dict) -> InteractionLaw | None:
    """The scene's interaction law with the parameters its class declares; None without adhesion."""
    if not adhesive(scene):
        return None
    it = scene["interaction"]
    return make_law(it["law"], work_of_adhesion=it["work_of_adhesion"],
                    **{key: it[key] for key in law_keys(it["law"])})


def resolution_nodes(scene: dict, law: InteractionLaw | None) -> float | None:
    """Nodes per adhesive zone (``physics.resolution.check_resolution``: a sphere or tip with its
    radius, a self-affine surface with its rms slope); an ``UnderResolvedWarning`` below the
    criterion, the same on every rank.  None without adhesion."""
    if law is None:
        return None
    g = scene["geometry"]
    return check_resolution(law, e_star(scene), max(g["dx"], g["dy"]),
                            radius=g["radius"] if g["kind"] in ("sphere", "tip") else None,
                            rms_slope=g["rms_slope"] if g["kind"] == "self-affine" else None)


def scene_preconditioner(scene: dict) -> str:
    """The scene's ``solver.preconditioner`` as its problem takes it: ``auto`` is the adhesive
    problem's own choice (per grid, from the snap number) and spectral without adhesion."""
    choice = scene["solver"]["preconditioner"]
    return "spectral" if choice == "auto" and not adhesive(scene) else choice


def build_problem(scene: dict, grid: SurfaceGrid, heights: PETSc.Vec, law: InteractionLaw | None):
    """(problem, relaxation solver or None) of the scene, by ``solvers.factory.make_problem``:
    ``ContactProblem`` without adhesion, ``AdhesiveProblem`` with it (and the paper's
    relaxation on it for ``solver.method = relaxation``); the scene's ``solver.options`` go
    to the problem's ``petsc_options``.  The resolution is checked by ``resolution_nodes``,
    not again here."""
    from ..solvers.factory import make_problem
    sol, modulus, body = scene["solver"], e_star(scene), layer(scene)
    options = dict(sol["options"])
    if law is None:
        g, control = scene["geometry"], scene["protocol"]["control"]
        # a Hertz sphere in displacement control: errors relative to the largest approach
        hertz = (g["kind"] == "sphere" and not g["periodic"] and scene["interaction"]["law"] == "none"
                 and control == "approach")
        problem = make_problem(grid, heights, modulus, prefix=CONTACT_PREFIX, petsc_options=options, layer=body,
                               hardness=scene["material"]["hardness"],
                               tol=sol["tol"] or 1e-10, preconditioner=scene_preconditioner(scene),
                               length_scale=max(scene["protocol"]["values"]) if hertz else None)
        return problem, None
    relax = sol["method"] == "relaxation"
    tol = sol["tol"] if sol["tol"] is not None else (1e-4 if relax else None)
    with warnings.catch_warnings():   # the scene's criterion was checked (resolution_nodes)
        warnings.simplefilter("ignore", UnderResolvedWarning)
        built = make_problem(grid, heights, modulus, law, method=sol["method"], prefix=ADHESION_PREFIX,
                             petsc_options=options, layer=body, tol=tol, preconditioner=sol["preconditioner"],
                             element_integration=scene["interaction"]["element_integration"],
                             stability_check="auto" if _sweeps(scene) else None)
    return (built.problem, built) if relax else (built, None)


def _sweeps(scene: dict) -> bool:
    """Whether the scene's path is an adhesive Newton sweep (``paths.sweep``: jumps, pull-off)."""
    return adhesive(scene) and scene["protocol"]["control"] == "approach" and scene["solver"]["method"] == "newton"


def leave_out(scene: dict) -> list[str]:
    """What the run leaves out of the stability check and the tangent, and why (lines of the plan:
    dry run and log).  Each runs only where it can change an answer: without adhesion the problem
    is convex (one state per load, no fold), so neither exists; an adhesive sweep checks states
    where a fold may be near (``-adhesion_stability_check auto``, ``fold_watch.py``) and needs every
    state's tangent (the predictor, the jump test and the pull-off search step with its
    stiffness); central-gap control reports every state's stability and steps without a tangent;
    the paper's relaxation labels every state and uses no tangent (its pull-off search predicts
    with the secant of the branch)."""
    from ..solvers.stability import stability_mode
    if not adhesive(scene):
        return ["  left out: the stability check and the tangent (no adhesion: a convex problem, one "
                "state per load and no folds; curve.csv stable = True, stability_checked = False)"]
    key = ADHESION_PREFIX + "stability_check"
    given = scene["solver"]["options"].get("stability_check", scene["solver"]["options"].get("-stability_check"))
    if PETSc.Options().hasName(key):
        given = PETSc.Options().getString(key, "")
    if given is not None:
        check, auto = stability_mode(given, f"-{key}")
        source = f" (-{key} {given})"
    else:
        check, auto, source = True, _sweeps(scene), ""
    if not check:
        what = (f"  stability check: left out at every state{source}: stable = nan, jumps found by the "
                "force alone, the pull-off among unchecked states")
    elif auto and _sweeps(scene):
        what = (f"  stability check: at the states where a fold may be near{source or ' (auto)'}: a branch's "
                "first two states, a reversal, a new most tensile state, a force off the tangent "
                "prediction, a harder Newton step, a margin trending to zero, snap number >= 1; always in "
                "jump bisection, and in the pull-off search beyond the stable points that bracket it; left out "
                "elsewhere (curve.csv stability_checked)")
    elif scene["protocol"]["control"] == "central_gap":
        what = f"  stability check: every state{source} (central-gap control reports each state's stability)"
    elif scene["solver"]["method"] == "relaxation":
        what = f"  stability check: every state{source} (the relaxation has no tangent to tell folds by)"
    else:
        what = f"  stability check: every state{source}"
    tangent = ("  tangent: every converged state (the predictor, the jump test and the pull-off search step "
               "with its stiffness)" if _sweeps(scene) else
               "  left out: the tangent (" + ("central-gap control steps without a predictor or jump test)"
                                             if scene["protocol"]["control"] == "central_gap" else
                                             "the relaxation uses none), and with it the jump location; the "
                                             "pull-off refinement continues from the most tensile stable step "
                                             "by relaxation solves, its jump test with the secant of the "
                                             "branch (summary.json pull_off_refined)"))
    return [what, tangent]
