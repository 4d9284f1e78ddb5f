"""Run a validated scene: one loop over the protocol's steps, one recorder of what they give.

A path is a list of approaches or loads solved in order, each warm-started
from the previous state.  ``run`` has the scene built (``builder``: grid, law,
the one resolution check, heights, problem), opens the output directory (``rundir``: locked, one run per directory, the scene stored
for a restart to compare), and then solves step after step with the scene's
stepper (``steppers``: Signorini contact, or adhesion with jumps and the
pull-off force), handing each state to the ``recorder.StepRecorder``, which
writes it at once (``docs/outputs.md``).  With ``restart`` the steps on disk
are kept and the path resumes after the last one.
"""
from __future__ import annotations

from petsc4py import PETSc

from . import builder, rundir
from ..collective import collective_call
from ..grid import SurfaceGrid
from ..stack import check_parallel_output, describe
from .recorder import CURVE_COLUMNS, NAN, StepRecorder, is_true

__all__ = ["run", "plan", "CURVE_COLUMNS"]


def plan(scene: dict, grid: SurfaceGrid, law=None, out_dir: str | None = None) -> list[str]:
    """What a run will do: grid, decomposition, solver chain, memory, outputs (dry run and log
    header); ``law`` the builder's (``builder.build_law``), None without adhesion."""
    from ..solvers.factory import describe_solver, grid_snap_number
    from .scenes import e_star
    from .steppers import resolve_sub_steps, scene_descends
    scene = resolve_sub_steps(scene, grid)
    g, sol = scene["geometry"], scene["solver"]
    if law is not None:
        law_text = f"law {law.name}, w = {law.work_of_adhesion:g} J/m^2" + (
            ", element-integrated" if scene["interaction"]["element_integration"] else "")
    else:
        law_text = "no adhesion (Signorini)"
    # the solver stack as built from the code defaults, the scene and the command line
    snap = None if law is None else grid_snap_number(law, grid, e_star(scene))
    descends = scene_descends(scene, grid)
    stack = describe_solver(law, sol["method"], builder.ADHESION_PREFIX if law is not None else builder.CONTACT_PREFIX,
                            petsc_options={**sol["options"], "preconditioner": builder.scene_preconditioner(scene)},
                            snap=snap, descends=descends)
    chain = "\n".join("  solver: " + line if k == 0 else "          " + line for k, line in enumerate(stack))
    per_rank = builder.memory_per_rank(scene, grid.mpi_comm.Get_size())
    return [f"scene {scene['name']}: {g['kind']} surface, {_body_text(scene)}, {law_text}",
            f"  {grid}", _heights_line(g),
            f"  rows per rank {[b - a for a, b in grid.y_ranges]}",
            chain,
            *builder.leave_out(scene),
            _protocol_line(scene, law, descends),
            f"  memory estimate: {per_rank / 2**20:.0f} MiB per rank" + _memory_note(grid, per_rank),
            _outputs_line(scene, grid.nx * grid.ny, out_dir or scene["output"]["directory"]),
            _stack_line(grid)]


def _protocol_line(scene: dict, law, descends: bool) -> str:
    """The steps, and under approach control with adhesion, those taken in sub-steps of at most
    ``protocol.max_step`` of the law's range and how they are checked (``scene`` resolved by
    ``steppers.resolve_sub_steps``; ``descends``: ``steppers.scene_descends``; ``paths.sweep``: the
    quasi-static path)."""
    proto = scene["protocol"]
    line = f"  protocol: {proto['control']} x {len(proto['values'])} steps"
    if law is None or law.work_of_adhesion == 0 or proto["control"] != "approach":
        return line
    if scene["solver"]["method"] == "relaxation":
        return line
    from ..path_steps import AGREEMENT_SPLIT
    from ..solvers.base import pieces
    max_step, agreement = proto["max_step"], proto["agreement"]
    values = proto["values"]
    counts = [pieces(b - a, max_step * law.length_scale()) for a, b in zip(values, values[1:])]
    long = [n for n in counts if n > 1]
    if long:
        line += (f"; {len(long)} longer than {max_step:g} of the law's range (protocol.max_step), "
                 f"taken in {sum(long)} equal sub-steps: the quasi-static path")
    if agreement and descends:
        foot = proto["agreement_increment"]
        start = (f"descended in increments of at most {foot:g} of the range (protocol.agreement_increment)"
                 if foot else "descended as the descent's options say")
        line += (f"; each step checked by the energy descent's increments to {agreement:g} of the law's "
                 f"range (protocol.agreement): {start}, then in {AGREEMENT_SPLIT}, ... "
                 f"{AGREEMENT_SPLIT ** proto['agreement_levels']} times as many until two agree")
        if not max_step:
            line += "; snaps within a step are in its state, located as jumps only with sub-steps (protocol.max_step)"
    elif agreement:
        line += (f"; each sub-step checked against its {AGREEMENT_SPLIT} equal pieces to {agreement:g} of the "
                 f"law's range (protocol.agreement), divided into them at most {proto['agreement_levels']} "
                 f"times where they part")
    return line


#: which side of a generated surface touches first (docs/scenes.md, "Which side is pressed")
_GENERATED = {"sphere": "h = r^2 / 2R, the apex touches first",
              "tip": "the tip's atoms as a profile, the lowest atom touches first",
              "self-affine": "the random field is the gap h, its lowest point touches first"}


def _heights_line(g: dict) -> str:
    """Which side of the surface is pressed, and how the heights were made (plan and log)."""
    if g["kind"] != "file":
        return f"  heights: generated, {_GENERATED[g['kind']]}, min h = 0"
    side = ("the file's heights are the surface, peaks up: h = max(z) - z, the highest point touches first"
            if g["heights_are"] == "surface" else
            "the file's heights are a gap: h = z - min(z), the lowest point touches first")
    return (f"  heights: {g['path']} ({g['format']}, {g['nx']} x {g['ny']} nodes, in "
            f"{g['height_unit'] or 'the unit it states'}), fill {g['fill']}, detrend {g['detrend']}, {side} "
            f"(geometry.heights_are = {g['heights_are']}), "
            + ("periodic" if g["periodic"] else "an isolated window (zero-padded, not tapered)"))


def _memory_note(grid: SurfaceGrid, per_rank: float) -> str:
    """A warning for the plan when the estimate exceeds what a rank can allocate here (a dry run
    on a login node sizes a job for the cluster: it is a note, not a refusal)."""
    from ..grid import available_memory
    avail = available_memory(grid.mpi_comm)
    return "" if per_rank <= avail else f" (more than the {avail / 2**20:.0f} MiB a rank can allocate here)"


def _stack_line(grid: SurfaceGrid) -> str:
    """The stack a run uses, in its log (``contactpetsc info`` has the whole list)."""
    s = describe(grid.comm)
    return (f"  stack: PETSc {s['PETSc']} ({s['PETSc index bits']}-bit indices), petsc4py {s['petsc4py']}, "
            f"{s['MPI']}, parallel HDF5 {s['parallel HDF5'].split()[0]}")


def _body_text(scene: dict) -> str:
    """E*, and the layer and hardness where the scene has them, for the plan."""
    from .scenes import e_star
    m = scene["material"]
    text = f"E* = {e_star(scene):g} Pa"
    if m["layer_thickness"] is not None:
        text += f", {m['layer_interface']} layer t = {m['layer_thickness']:g} m"
    if m["hardness"] is not None:
        text += f", hardness H = {m['hardness']:g} Pa"
    return text


def run(scene: dict, *, output: str | None = None, dry_run: bool = False, comm=None,
        restart: bool = False, overwrite: bool = False) -> list:
    """Run ``scene``; returns the states of the steps solved (empty for a dry run), a step that
    ended the run last.  Only the last state keeps its fields (``pressure``, ``gap``, ...): each
    earlier state's are released before the next step is solved (``release_fields``), so that a
    path holds one state's fields, not every step's; the steps that write a step file
    (``output.fields``, ``output.field_every``) keep theirs on disk.

    ``restart``: keep the steps on disk (the same physics, ``rundir``) and resume after
    the last one.  ``overwrite``: remove another run's files from the directory first.
    """
    from ..path_steps import unsettled as check_unsettled
    from .steppers import AdhesiveSteps, ContactSteps, resolve_sub_steps
    grid = builder.build_grid(scene, comm)
    # the sweep's sub-steps as the run takes them: scene.json keeps them for a restart
    scene = resolve_sub_steps(scene, grid)
    law = builder.build_law(scene)
    builder.resolution_nodes(scene, law)   # the one resolution check, a dry run's too
    for line in plan(scene, grid, law, output):
        PETSc.Sys.Print(line)
    # a serial h5py under mpirun is refused now, not after the first solve (a dry run's check too)
    check_parallel_output(grid.mpi_comm.Get_size(), bool(scene["output"]["fields"]))
    if dry_run:
        return []
    if scene["output"]["plots"]:   # before the run, not after it
        from .plots import require
        collective_call(grid.mpi_comm, ImportError, "{error}", require)
    # a tip's profile and atom ownership are built once, for the solve and the forces per atom
    tip = builder.build_tip(scene, grid) if scene["geometry"]["kind"] == "tip" else None
    info = {}
    h = tip[1] if tip else builder.build_heights(scene, grid, info)
    if info.get("filled_points"):
        PETSc.Sys.Print(f"  heights: {info['filled_points']} points not measured, filled "
                        f"(geometry.fill = {scene['geometry']['fill']})")
    if scene["geometry"]["kind"] == "file":   # ties the steps to these heights (a restart compares it)
        from .scene_files import DIGEST
        scene = {**scene, "geometry": {**scene["geometry"], DIGEST: info["heights_sha256"]}}
    out_dir = output or scene["output"]["directory"]
    stored = rundir.open_directory(scene, grid, out_dir, restart=restart, overwrite=overwrite)
    try:
        problem, relax = builder.build_problem(scene, grid, h, law)
        stepper = (ContactSteps if law is None else AdhesiveSteps)(scene, grid, problem, relax)
        recorder = StepRecorder(scene, grid, h, out_dir, stepper.header, stepper.progress,
                                tip=tip if scene["output"]["atom_forces"] else None,
                                zone_threshold=stepper.zone_threshold,
                                jumps=stepper.sweeping, pull_off=stepper.refines)
        if restart:
            recorder.resume(stepper.fields, stored)
            if recorder.rows:
                stepper.resume(recorder)
        if scene["geometry"]["kind"] == "file":   # summary.json: the points the fill made up
            recorder.summary["filled_points"] = info.get("filled_points", 0)
        rundir.write_scene(grid.mpi_comm, out_dir, scene)
        states, plotted = _steps(scene, stepper, recorder)
        recorder.write_summary(**stepper.finish())
        recorder.flush_history(stepper.problem)
        unsettled = [r["step"] for r in recorder.rows if check_unsettled(str(r["solver"]))]
        if unsettled:
            PETSc.Sys.Print(f"  warning: in {len(unsettled)} step(s) ({', '.join(map(str, unsettled[:8]))}"
                            f"{', ...' if len(unsettled) > 8 else ''}) the check of the sub-steps did not settle "
                            "(curve.csv solver): the states may depend on the steps; shorter steps or more "
                            "protocol.agreement_levels")
        if recorder.edge_steps:
            PETSc.Sys.Print(f"  warning: in {len(recorder.edge_steps)} step(s) the pressure-carrying zone reached "
                            "the window's edge (curve.csv window_reach = 1): those forces are not the isolated "
                            "contact's")
        _save_plots(scene, grid, out_dir, plotted, h, recorder.rows)
        grid.mpi_comm.Barrier()   # the outputs are complete when run() returns, on every rank
        PETSc.Sys.Print(f"  wrote {out_dir}/curve.csv, history.csv, summary.json")
        return states
    finally:
        rundir.release(grid.mpi_comm, out_dir)


def _steps(scene: dict, stepper, recorder) -> tuple[list, tuple | None]:
    """The loop: each step solved by the stepper and written by the recorder, until the path's
    end or a failed step of a stepper that stops there.  Returns the states (each one's fields
    released before the next step is solved: the last keeps them) and, where ``output.plots``
    will draw a step of this run that has no step file with the pressure, that step's (step,
    pressure, gap): the step it would plot so far (``_plotted``)."""
    values = [float(v) for v in scene["protocol"]["values"]]
    control = scene["protocol"]["control"]
    recorder.start()
    states, plotted = [], None
    for step in range(len(recorder.rows) + 1, len(values) + 1):
        if states:
            states[-1].release_fields()
            # in parallel petsc4py frees a dropped Vec at the next cleanup (collective; the same
            # step on every rank): before this solve, not after it
            PETSc.garbage_cleanup(stepper.problem.grid.comm)
        st, jumps = stepper.step(values[step - 1])
        states.append(st)
        if not st.converged and stepper.stop_on_failure:
            recorder.failed(step, st)
            break
        row = dict.fromkeys(CURVE_COLUMNS, NAN)
        row.update(step=step, branch=_branch(control, values, step - 1), approach_m=st.approach,
                   force_N=st.force, mean_pressure_Pa=st.mean_pressure, contact_fraction=st.contact_fraction,
                   complementarity_error=st.complementarity_error, converged=st.converged, reason=st.reason,
                   newton_iterations=st.newton_iterations, krylov_iterations=st.linear_iterations,
                   fft_pairs=st.fft_pairs, wall_time_s=st.wall_time)
        row.update(stepper.row(st))
        recorder.record(st, row, stepper.problem, jumps, stepper.results(), stepper.path_state())
        if scene["output"]["plots"] and _plotted(scene, recorder.rows) == step:
            filed = bool(recorder.written) and recorder.written[-1][0] == step and _files_pressure(scene)
            plotted = None if filed else (step, st.pressure, st.gap)
    return states, plotted


def _plotted(scene: dict, rows: list) -> int:
    """The step ``output.plots`` draws among ``rows`` (``plots.plot_step``): the requested one,
    else the converged step of the largest approach so far, which is the whole run's when the
    run ends there."""
    requested = scene["output"]["plot_step"]
    if requested is not None:
        return requested
    from .plots import plot_step
    return plot_step([r["approach_m"] for r in rows], [is_true(r["converged"]) for r in rows])


def _outputs_line(scene: dict, n: int, out_dir: str) -> str:
    """The files a run writes (docs/outputs.md), for the plan."""
    from .scenes import adhesive
    out = scene["output"]
    files = ["curve.csv", "history.csv", "summary.json", "scene.json"] + (
        ["jumps.csv"] if adhesive(scene) else [])
    if out["fields"] is not False:
        from .output import expected_step_files, scene_field_types, step_file_bytes
        types = scene_field_types(scene)
        files.append(f"{expected_step_files(scene)} x step_NNNN.h5 + .xdmf ({', '.join(types)}; "
                     f"{step_file_bytes(types, n) / 2**20:.1f} MiB each), fields.xdmf")
    if out["atom_forces"] and scene["geometry"]["kind"] == "tip":
        files.append("atom_forces.csv")
    if out["plots"]:
        from .plots import planned
        files.append(", ".join(planned(scene)))
    return f"  outputs in {out_dir}: " + ", ".join(files)


def _save_plots(scene: dict, grid: SurfaceGrid, out_dir: str, plotted: tuple | None, heights, rows: list) -> None:
    """``output.plots``: ``plots.plot_run`` on rank 0 from the files just written, and where the
    plotted step has no step file with the pressure (``output.fields``, ``output.field_every``)
    from ``plotted``, its (step, pressure, gap) kept by ``_steps``, and the heights gathered to
    rank 0 (only then; a step of this run only); collective (a plotting error is raised on every
    rank)."""
    if not scene["output"]["plots"]:
        return
    from .plots import plot_step, plot_run
    fields = None
    if rows:
        step = collective_call(grid.mpi_comm, ValueError, "{error}", plot_step, [r["approach_m"] for r in rows],
                               [is_true(r["converged"]) for r in rows], scene["output"]["plot_step"])
        if plotted is not None and plotted[0] == step and not _wrote_pressure(scene, grid, out_dir, step):
            got = {name: grid.gather(vec, root=0) for name, vec in
                   (("pressure", plotted[1]), ("gap", plotted[2]), ("heights", heights))}
            if got["pressure"] is not None:
                fields = {name: a.T for name, a in got.items()}
                fields.update(step=step, dx=grid.dx, dy=grid.dy, hdx=grid.dx, hdy=grid.dy)
    rank0 = grid.mpi_comm.Get_rank() == 0
    written = collective_call(grid.mpi_comm, RuntimeError, "plots failed: {error}",
                              lambda: plot_run(out_dir, fields) if rank0 else [])
    if rank0:
        PETSc.Sys.Print("  plots: " + ", ".join(written), comm=PETSc.COMM_SELF)


def _files_pressure(scene: dict) -> bool:
    """Whether the scene's step files are the plots' (``output.fields`` true or naming the
    pressure; a contact run's files carry the pressure for a restart whatever the list, but
    not the gap and heights that the plots read beside it)."""
    fields = scene["output"]["fields"]
    return fields is True or (fields is not False and "pressure" in fields)


def _wrote_pressure(scene: dict, grid: SurfaceGrid, out_dir: str, step: int) -> bool:
    """Whether step ``step`` has a file with the pressure (read by ``plot_run``)."""
    import os
    if not _files_pressure(scene):
        return False
    path = os.path.join(out_dir, f"step_{step:04d}.h5")
    return grid.mpi_comm.bcast(os.path.exists(path) if grid.mpi_comm.Get_rank() == 0 else None, root=0)


def _branch(control: str, values: list, i: int) -> str:
    """loading where the prescribed value rises (the first step too), unloading where it falls;
    central-gap paths are one branch, stable and unstable."""
    if control == "central_gap":
        return "central-gap"
    return "unloading" if i > 0 and values[i] < values[i - 1] else "loading"
