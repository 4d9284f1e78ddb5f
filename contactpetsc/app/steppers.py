"""Steppers: how the runner's loop (``runner.run``) solves one step of a scene's path.

A stepper drives the problem the builder made (``builder.build_problem``), one prescribed value at
a time (``step``: the state and the jumps found on the way), fills the
columns of a step's row that are its own (``row``), prints its progress
columns, keeps with each step file what the path's next step decides by
(``path_state``), takes up a restarted path (``resume``) and gives the path's
results (``results``: the pull-off force, refined at the end by ``finish``).

``ContactSteps``: no adhesion, displacement or load control with warm
starts; a smooth sphere on an isolated half-space is compared with Hertz at
each step.  ``AdhesiveSteps``: adhesion, through ``paths.sweep`` (jumps
located, pull-off), ``paths.central_gap_path``, or the reference paper's
relaxation solver (pull-off refined by relaxation solves); spheres are
reported in Greenwood's alpha* and W*.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..solvers.stability import leaves_checks_out
from .output import RESTART_FIELDS

NAN = float("nan")
#: the defaults of ``protocol.max_step``, ``agreement`` and ``agreement_increment`` [the law's
#: range] (``sub_steps``)
MAX_STEP, AGREEMENT, AGREEMENT_INCREMENT = 0.1, 1e-3, 0.25


def sub_steps(proto: dict, descends: bool) -> tuple[float, float, float]:
    """(max_step, agreement, agreement_increment) of an adhesive sweep, in units of the law's
    range: the scene's, or by default the check of each step by the energy descent's increments
    where it is the strategy (``descends``), whole steps then, probed in increments of 0.25 (on
    the rough benchmark the states of the limit of small steps at 256^2 and 512^2, in fewer FFT
    pairs than fixed sub-steps that reach it: docs/performance.md, "Quasi-static limit of a
    load-unload path"), else sub-steps of 0.1 unchecked."""
    agreement = proto["agreement"]
    if agreement is None:
        agreement = AGREEMENT if descends else 0.0
    max_step = proto["max_step"]
    if max_step is None:
        max_step = 0.0 if descends and agreement > 0 else MAX_STEP
    foot = proto["agreement_increment"]
    if foot is None:
        foot = AGREEMENT_INCREMENT if descends and agreement > 0 else 0.0
    return max_step, agreement, foot


def resolve_sub_steps(scene: dict, grid) -> dict:
    """``scene`` with ``protocol.max_step`` and ``protocol.agreement`` given (``sub_steps``), for
    the strategy the run's problem will take (``factory.adhesive_strategy``: the scene's options
    and the command line): what the plan prints and ``scene.json`` keeps, so that a restart
    compares the sub-steps the steps on disk were taken in."""
    proto = scene["protocol"]
    if None not in (proto["max_step"], proto["agreement"], proto["agreement_increment"]):
        return scene
    max_step, agreement, foot = sub_steps(proto, sweep_descends(scene, grid))
    return {**scene, "protocol": {**proto, "max_step": max_step, "agreement": agreement,
                                  "agreement_increment": foot}}


def scene_descends(scene: dict, grid) -> bool:
    """Whether the scene's adhesive problem takes the energy descent as its strategy
    (``AdhesiveProblem.descends``), told without building it (``factory.adhesive_strategy``: the
    scene's options and the command line)."""
    from ..solvers.factory import adhesive_strategy
    from .builder import ADHESION_PREFIX, adhesive
    return bool(adhesive(scene) and scene["solver"]["method"] == "newton"
                and adhesive_strategy(ADHESION_PREFIX, scene["solver"]["options"], grid.periodic,
                                      scene["interaction"]["element_integration"]) == "descent")


def sweep_descends(scene: dict, grid) -> bool:
    """Whether the scene's run is an adhesive sweep (approach control) whose problem descends."""
    return scene["protocol"]["control"] == "approach" and scene_descends(scene, grid)


def mean_gap(grid, st, error_scale: float) -> dict:
    """``mean_gap_m``: the mean separation of the surfaces, the mean of max(g, 0) over the
    grid's nodes [m] (``metrics.mean_gap``: the nominal area; on an isolated window the
    window, not the contact); ``mean_gap_error_m``:
    ``error_scale`` [m], the state's largest nodal violation of its contact conditions in
    metres.  Read as the exact solution for a surface moved by at most that much at each node,
    the state's gaps are off by at most as much (the obstacle problem's comparison principle),
    and so is their mean (docs/outputs.md).  Collective."""
    from ..metrics import mean_gap as mean_separation
    return dict(mean_gap_m=mean_separation(grid, st.gap), mean_gap_error_m=error_scale)


class ContactSteps:
    """Signorini contact (no adhesion); a failed step is written and the path goes on."""
    stop_on_failure = False
    sweeping = False              #: no jumps, no pull-off
    refines = False
    zone_threshold = 0.0          #: the contact zone: p > 0
    fields = RESTART_FIELDS[False]

    def __init__(self, scene: dict, grid, problem, relax=None):
        g = scene["geometry"]
        self.grid, self.control, self.problem = grid, scene["protocol"]["control"], problem
        from .scenes import e_star
        self.e_star = e_star(scene)
        self.hertz = (g["kind"] == "sphere" and not g["periodic"] and scene["interaction"]["law"] == "none"
                      and scene["material"]["hardness"] is None)
        self.radius = g["radius"]
        self.plastic = scene["material"]["hardness"] is not None
        self.header = (f"  {'step':>4} {'approach [m]':>12} {'force [N]':>11} {'contact':>8} {'error':>9} "
                       f"{'Newton':>6} {'time [s]':>8}" + (f" {'F/F_Hertz':>9} {'a/a_Hertz':>9}" if self.hertz
                                                             else "") + (f" {'plastic':>8}" if self.plastic else ""))

    def resume(self, recorder) -> None:
        (p,), approach = recorder.read_step(len(recorder.rows), self.fields)
        self.problem.warm_start(p, approach)

    def step(self, value: float):
        return self.problem.solve(**{self.control: value}, raise_on_failure=False), []

    def row(self, st) -> dict:
        return dict(adhesive_force_N=0.0, adhesive_load_ratio=0.0, adhesive_area_ratio=0.0, stable=True,
                    stability_checked=False,
                    load_error=st.load_error, interference_error=st.interference_error,
                    solver="snes-vi+" + self.problem.preconditioner, plastic_fraction=st.plastic_fraction,
                    plastic_volume_m3=st.plastic_volume, max_plastic_displacement_m=st.max_plastic_displacement,
                    **mean_gap(self.grid, st, st.complementarity_error * self.problem.length_scale))

    def progress(self, st, row) -> str:
        line = (f"  {row['step']:4d} {st.approach:12.4e} {st.force:11.4e} {st.contact_fraction:8.4f} "
                f"{st.complementarity_error:9.2e} {st.newton_iterations:6d} {st.wall_time:8.2f}")
        if self.hertz:
            from ..physics.closed_forms import hertz_contact_radius, hertz_force
            f_h = float(hertz_force(self.e_star, self.radius, st.approach))
            a_num = np.sqrt(st.contact_fraction * self.grid.lengths[0] * self.grid.lengths[1] / np.pi)
            a_h = float(hertz_contact_radius(self.radius, st.approach))
            line += f" {st.force / f_h:9.5f} {a_num / a_h:9.4f}" if f_h > 0 else ""
        if self.plastic:
            line += f" {st.plastic_fraction:8.4f}"
        return line

    def results(self) -> dict:
        return {}

    def path_state(self) -> None:
        return None               # each step is solved on its own: nothing to carry

    def finish(self) -> dict:
        return {}


class AdhesiveSteps:
    """Adhesive contact: a failed step ends the run (the steps on disk stay a path to restart from)."""
    stop_on_failure = True
    fields = RESTART_FIELDS[True]

    def __init__(self, scene: dict, grid, problem, relax=None):
        from ..metrics import CUTOFF
        from ..paths import Path
        self.proto, g = scene["protocol"], scene["geometry"]
        self.problem, self.relax, self.law = problem, relax, problem.law
        law = self.law
        self.grid, self.z0, self.radius = grid, law.length_scale(), g["radius"]
        from .scenes import e_star
        self.kind, self.e_star = g["kind"], e_star(scene)
        self.sphere = g["kind"] in ("sphere", "tip") and not g["periodic"]   # Greenwood's scaling with R
        self.zone_threshold = CUTOFF * law.peak_attraction   # the paper's adhesive-zone cut-off
        # the relaxation solver relaxes wherever it goes: no jump location; its path's points
        # give the pull-off (the most tensile stable state), refined by relaxation solves
        self.path = Path()
        self.sweeping = self.relax is None and self.proto["control"] == "approach"
        self.pulls = self.proto["control"] == "approach"    #: a pull-off force
        self.refines = self.pulls and self.proto["refine_pull_off"]   #: refined at the end (``finish``)
        self.prev = None          #: (approach, force, dF/d delta) of the last state, for sweep
        #: the sweep's sub-steps and their check [m]
        self.max_step, self.agreement, self.foot = (z * self.z0 for z in sub_steps(
            self.proto, self.sweeping and problem.descends))
        self.header = (f"  {'step':>4} {'approach [m]':>12} {'force [N]':>11} {'contact':>8} {'adh. force':>11} "
                       f"{'error':>9} {'stable':>6} {'time [s]':>8}" + (f" {'alpha*':>8} {'W*':>9}"
                                                                       if self.sphere else ""))

    def resume(self, recorder) -> None:
        """The path on disk: its points and jumps (for the pull-off and the next jump), the most
        tensile stable state solved again from its file (for the pull-off refinement), then the
        last state as the warm start."""
        from ..paths import Jump
        rows = recorder.rows
        if self.path is not None:
            self.path.points = [_point(r) for r in rows]
            self.path.jumps = [Jump(kind=j["kind"], approach_before=float(j["approach_before_m"]),
                                    approach_after=float(j["approach_after_m"]),
                                    force_before=float(j["force_before_N"]),
                                    force_after=float(j["force_after_N"])) for j in recorder.jumps]
        last, saved = rows[-1], recorder.path_state(len(rows))
        # the coarse levels the uninterrupted run had dropped after a failed solve there, before
        # any solve here makes them
        self.problem.snes()
        self.problem.coarse_levels.restore(saved.get("coarse_levels", []))
        if self.refines:
            self._restore_best(recorder)
        (q, a), approach = recorder.read_step(len(rows), self.fields)
        self.problem.warm_start(q, a, approach)
        # whether the uninterrupted run's next loading step descended first (-loading_descent)
        self.problem.descending_loading = bool(saved.get("descending_loading", False))
        self.prev = (float(last["approach_m"]), float(last["force_N"]), NAN if saved.get("stiffness") is None
                     else float(saved["stiffness"]))
        if self.path is not None and saved.get("fold_watch") and leaves_checks_out(self.problem):
            # where the uninterrupted run would leave the check out (fold_watch.py)
            from ..fold_watch import FoldWatch
            self.path._watch = FoldWatch.restored(saved["fold_watch"])

    def path_state(self) -> dict | None:
        """What the next step of a sweep decides by and the step files keep for a restart: the
        last state's stiffness (jump test, fold watch), the fold watch's record and the coarse
        levels dropped so far."""
        if not self.sweeping or self.prev is None:
            return None
        watch = self.path._watch
        return {"stiffness": self.prev[2] if np.isfinite(self.prev[2]) else None,
                "fold_watch": None if watch is None else watch.state(),
                "coarse_levels": self.problem.coarse_levels.state(),
                "descending_loading": bool(self.problem.descending_loading)}

    def _restore_best(self, recorder) -> None:
        """The pull-off search's start (``paths.keep_for_search``) on a restarted path: the most
        tensile stable state on disk, solved again from its file by the run's solver (the
        relaxation's converged state passes its test unchanged: the uninterrupted run's)."""
        pts = self.path.points
        stable = [i for i, p in enumerate(pts) if p.converged and p.stable is not False]
        if not stable:
            return
        best = min(stable, key=lambda i: pts[i].force)
        if best + 1 not in recorder.written_steps():   # a run of other output settings
            PETSc.Sys.Print(f"  note: the most tensile state on disk (step {best + 1}) has no field file: the "
                            "pull-off refinement starts from the new steps only")
            return
        (q, a), approach = recorder.read_step(best + 1, self.fields)
        self.problem.warm_start(q, a, approach)
        if self.relax is not None:
            st = self.relax.solve(approach=approach, raise_on_failure=False)
        else:
            st = self.problem.solve(approach=approach, raise_on_failure=False, fallback=False)
        if st.converged and st.stable is not False:
            self.path._best = (best, self.problem.snapshot())
        else:
            PETSc.Sys.Print(f"  note: the most tensile state on disk (step {best + 1}) did not solve again "
                            f"({st.reason}): the pull-off refinement starts from the new steps only")

    def step(self, value: float):
        from ..paths import central_gap_path, sweep
        if self.relax is not None:
            from ..paths import keep_for_search, path_point
            st = self.relax.solve(approach=value, raise_on_failure=False)
            pts = self.path.points
            branch = "loading" if not pts or value >= pts[-1].approach else "unloading"
            pts.append(path_point(len(pts), branch, st))
            if self.pulls:
                # as a Newton sweep keeps it, one step at a time (a restart keeps the same)
                last = keep_for_search(self.path, self.problem, None)
                if last is not None:
                    last[1].destroy()
            return st, []
        got, n = [], len(self.path.jumps)

        def keep(k, st, pt):
            got.append(st)

        if self.proto["control"] == "central_gap":
            central_gap_path(self.problem, [value], path=self.path, on_state=keep, on_failure=keep)
        else:
            sweep(self.problem, [value], refine=self.proto["jump_refinement"], on_state=keep,
                  on_failure=keep, path=self.path, previous=self.prev, substeps=self.proto["substeps"],
                  max_step=self.max_step, agreement=self.agreement, levels=self.proto["agreement_levels"],
                  foot=self.foot)
        st = got[0]
        jumps = self.path.jumps[n:]
        if not st.converged:
            del self.path.jumps[n:]   # found again when the step is solved again
            return st, []
        self.prev = (st.approach, st.force, st.stiffness)
        return st, jumps

    def row(self, st) -> dict:
        from ..metrics import adhesion_ratios, greenwood
        load_ratio, area_ratio = adhesion_ratios(self.grid, st.pressure, self.law.peak_attraction)
        a_star, w_star = (greenwood(st.approach, st.force, self.radius, self.law.work_of_adhesion, self.z0)
                          if self.sphere else (NAN, NAN))
        return dict(adhesive_force_N=st.adhesive_force, adhesive_load_ratio=load_ratio,
                    adhesive_area_ratio=area_ratio, alpha_star=a_star, W_star=w_star,
                    central_gap_m=st.central_gap, stable=NAN if st.stable is None else st.stable,
                    stability_checked=st.stable is not None, stability_margin=st.stability_margin,
                    stability_settled=NAN if st.stability_converged is None else st.stability_converged,
                    adhesive_error=st.adhesive_error,
                    total_error=st.total_error, pressure_error=st.pressure_error, solver=st.solver,
                    energy_J=st.energy, **mean_gap(self.grid, st, self.z0 * np.nanmax([st.complementarity_error, st.adhesive_error,
                                                                   st.total_error])))

    def progress(self, st, row) -> str:
        err = max(st.complementarity_error, st.adhesive_error)
        return (f"  {row['step']:4d} {st.approach:12.4e} {st.force:11.4e} {st.contact_fraction:8.4f} "
                f"{st.adhesive_force:11.4e} {err:9.2e} {'-' if st.stable is None else str(st.stable):>6} "
                f"{st.wall_time:8.2f}"
                + (f" {row['alpha_star']:8.3f} {row['W_star']:9.4f}" if self.sphere else ""))

    def results(self, pull: float | None = None, refined: bool = False, why: str | None = None) -> dict:
        """The pull-off force of a sweep so far (the most tensile stable state on disk), or the
        refined one; ``why``: why a refinement asked for was not done."""
        if not self.pulls:
            return {}
        pull = self.path.pull_off_force if pull is None else pull
        out = {"pull_off_force_N": pull, "pull_off_refined": refined}
        if why:
            out["pull_off_not_refined"] = why
        if self.sphere:
            out["pull_off_W_star"] = pull / (2 * np.pi * self.radius * self.law.work_of_adhesion)
        out.update(self.pull_off_biases(pull))
        return out

    def pull_off_biases(self, pull: float) -> dict:
        """What the grid does to a smooth sphere's pull-off (summary.json, the log): the law's
        attraction outside the window (``closed_forms.window_tail_force``: the sphere's gap at the
        pull-off's approach with the half-space's far field F / (pi E* r); the pull-off is short of
        it) and, with a Lennard-Jones law on a grid too coarse for the adhesive zone, the sawtooth
        of the force along the path (``resolution.sawtooth_amplitude``; the pull-off is its deepest
        tooth).  Empty for other surfaces."""
        from ..paths import good_state
        from ..physics.closed_forms import sphere_window_edges, window_tail_force
        from ..physics.resolution import RESOLUTION_NODES, adhesive_zone_length, sawtooth_amplitude
        if not (self.kind == "sphere" and self.sphere and np.isfinite(pull) and pull < 0):
            return {}
        good = [p for p in self.path.points if good_state(p)]
        if not good:
            return {}
        at = min(good, key=lambda p: p.force).approach
        g = self.grid
        tail = window_tail_force(self.law, self.radius, at, sphere_window_edges(g.nx, g.ny, g.dx, g.dy),
                                 force=pull, e_star=self.e_star)
        out = {"window_tail_N": tail, "window_tail_fraction": tail / pull}
        zone = adhesive_zone_length(self.law, self.e_star, radius=self.radius)["zone"]
        nodes = zone / max(g.dx, g.dy)
        if nodes < RESOLUTION_NODES and self.law.name in ("lj", "hardwall-lj"):   # measured for LJ
            out["sawtooth_zone_nodes"] = nodes
            out["sawtooth_amplitude"] = sawtooth_amplitude(nodes)
            out["sawtooth_free_dx_m"] = zone / RESOLUTION_NODES
        return out

    def finish(self) -> dict:
        """The pull-off force refined (``protocol.refine_pull_off``; ``pull_off.refine_pull_off``):
        by Newton, or on a relaxation sweep by relaxation solves (``pull_off.RelaxedSearch``),
        to 1 % of the smallest step in approach.  A relaxation solve of the search that fails
        otherwise than by stalling beyond the end of the branch leaves the sampled pull-off (the
        most tensile stable step), with the reason."""
        from ..pull_off import RelaxedSearch, refine_pull_off
        if not self.pulls:
            return {}
        pull, refined, why, search = self.path.pull_off_force, False, None, None
        if self.refines and self.path._best is not None:
            values = self.proto["values"]
            step = min(np.abs(np.diff(values))) if len(values) > 1 else self.z0
            search = self.problem if self.relax is None else RelaxedSearch(self.relax)
            refine_pull_off(search, self.path, xtol=0.01 * step)
            failure = getattr(search, "failure", None)
            if failure is None:
                pull, refined = self.path.refined_pull_off, True
            else:
                self.path.refined_pull_off = None
                why = (f"a relaxation solve of the pull-off search (approach {failure[0]:.6e} m) did not converge: "
                       f"{failure[1]}; the pull-off is the most tensile stable step's")
        out = self.results(pull, refined, why)
        PETSc.Sys.Print(f"  pull-off force {pull:.6e} N"
                        + (f" (W* = {out['pull_off_W_star']:.4f})" if self.sphere else "")
                        + (" (refined by relaxation solves)" if refined and self.relax is not None else "")
                        + (f", not refined: {why}" if why else ""))
        if getattr(search, "stalled", 0) and not why:
            PETSc.Sys.Print(f"  pull-off search: {search.stalled} relaxation solve(s) stalled beyond the end of the "
                            "attached branch (counted off the branch, as a Newton solve that does not converge)")
        if "window_tail_N" in out:
            PETSc.Sys.Print(f"  the window leaves out the law's attraction beyond its edge: {out['window_tail_N']:.3e} N "
                            f"at the pull-off (sphere and far field, closed form), "
                            f"{100 * out['window_tail_fraction']:.2f} % of the pull-off (the pull-off is that much "
                            f"short; a wider window removes it; docs/validation.md)")
        if "sawtooth_amplitude" in out:
            lo, hi = out["sawtooth_amplitude"]
            PETSc.Sys.Print(f"  the adhesive zone spans {out['sawtooth_zone_nodes']:.2g} grid spacings: along the path "
                            f"the force is a sawtooth of about {100 * lo:+.2f} % to {100 * hi:+.2f} % about the "
                            f"smooth curve (the contact edge moves node by node), and the pull-off is its "
                            f"deepest tooth; dx <= {out['sawtooth_free_dx_m']:.3g} m removes it "
                            f"(docs/validation.md)")
        return out


def _point(row: dict):
    """A ``paths.PathPoint`` of a ``curve.csv`` row (a restarted path's earlier steps)."""
    from ..paths import PathPoint
    flag = {"True": True, "False": False}
    num = {c: float(row[c]) for c in ("approach_m", "central_gap_m", "force_N", "adhesive_force_N",
                                      "contact_fraction", "fft_pairs", "wall_time_s",
                                      "complementarity_error", "adhesive_error", "total_error")}
    return PathPoint(step=int(row["step"]) - 1, branch=row["branch"], approach=num["approach_m"],
                     central_gap=num["central_gap_m"], force=num["force_N"],
                     adhesive_force=num["adhesive_force_N"], contact_fraction=num["contact_fraction"],
                     stable=flag.get(row["stable"]), converged=row["converged"] == "True",
                     solver=row["solver"], fft_pairs=num["fft_pairs"], wall_time=num["wall_time_s"],
                     complementarity_error=num["complementarity_error"],
                     adhesive_error=num["adhesive_error"], total_error=num["total_error"],
                     reason=row["reason"])
