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
from .recorder import CURVE_COLUMNS, NAN, StepRecorder

__all__ = ["run", "plan", "CURVE_COLUMNS"]


def plan(scene: dict, grid: SurfaceGrid, law=None, out_dir: str | None = None) -> list[str]:
    """What a run will do: grid, decomposition, solver chain, memory, outputs (dry run and log
    header); ``law`` the builder's (``builder.build_law``), None without adhesion."""
    from ..solvers.factory import describe_solver
    g, sol = scene["geometry"], scene["solver"]
    if law is not None:
        law_text = f"law {law.name}, w = {law.work_of_adhesion:g} J/m^2" + (
            ", element-integrated" if scene["interaction"]["element_integration"] else "")
    else:
        law_text = "no adhesion (Signorini)"
    # the solver stack as built from the code defaults, the scene and the command line
    stack = describe_solver(law, sol["method"], builder.ADHESION_PREFIX if law is not None else builder.CONTACT_PREFIX,
                            petsc_options={**sol["options"], "preconditioner": sol["preconditioner"]})
    chain = "\n".join("  solver: " + line if k == 0 else "          " + line for k, line in enumerate(stack))
    per_rank = builder.memory_per_rank(scene, grid.mpi_comm.Get_size())
    return [f"scene {scene['name']}: {g['kind']} surface, E* = {scene['material']['e_star']:g} Pa, {law_text}",
            f"  {grid}",
            f"  rows per rank {[b - a for a, b in grid.y_ranges]}",
            chain,
            f"  protocol: {scene['protocol']['control']} x {len(scene['protocol']['values'])} steps",
            f"  memory estimate: {per_rank / 2**20:.0f} MiB per rank",
            _outputs_line(scene, grid.nx * grid.ny, out_dir or scene["output"]["directory"])]


def run(scene: dict, *, output: str | None = None, dry_run: bool = False, comm=None,
        restart: bool = False, overwrite: bool = False) -> list:
    """Run ``scene``; returns the states of the steps solved (empty for a dry run), a step that
    ended the run last.

    ``restart``: keep the steps on disk (the same physics, ``rundir``) and resume after
    the last one.  ``overwrite``: remove another run's files from the directory first.
    """
    from .steppers import AdhesiveSteps, ContactSteps
    grid = builder.build_grid(scene, comm)
    law = builder.build_law(scene)
    builder.resolution_nodes(scene, law)   # the one resolution check, a dry run's too
    for line in plan(scene, grid, law, output):
        PETSc.Sys.Print(line)
    if dry_run:
        return []
    if scene["output"]["plots"]:   # before the run, not after it
        from .plots import require
        collective_call(grid.mpi_comm, ImportError, "{error}", require)
    # a tip's profile and atom ownership are built once, for the solve and the forces per atom
    tip = builder.build_tip(scene, grid) if scene["geometry"]["kind"] == "tip" else None
    h = tip[1] if tip else builder.build_heights(scene, grid)
    out_dir = output or scene["output"]["directory"]
    stored = rundir.open_directory(scene, grid, out_dir, restart=restart, overwrite=overwrite)
    try:
        problem, relax = builder.build_problem(scene, grid, h, law)
        stepper = (ContactSteps if law is None else AdhesiveSteps)(scene, grid, problem, relax)
        recorder = StepRecorder(scene, grid, h, out_dir, stepper.header, stepper.progress,
                                tip=tip if scene["output"]["atom_forces"] else None,
                                zone_threshold=stepper.zone_threshold,
                                jumps=stepper.sweeping)
        if restart:
            recorder.resume(stepper.fields, stored)
            if recorder.rows:
                stepper.resume(recorder)
        rundir.write_scene(grid.mpi_comm, out_dir, scene)
        states = _steps(scene, stepper, recorder)
        recorder.write_summary(**stepper.finish())
        recorder.flush_history(stepper.problem)
        if recorder.edge_steps:
            PETSc.Sys.Print(f"  warning: in {len(recorder.edge_steps)} step(s) the pressure-carrying zone reached "
                            "the window's edge (curve.csv window_reach = 1): those forces are not the isolated "
                            "contact's")
        _save_plots(scene, grid, out_dir, states, len(recorder.rows))
        grid.mpi_comm.Barrier()   # the outputs are complete when run() returns, on every rank
        PETSc.Sys.Print(f"  wrote {out_dir}/curve.csv, history.csv, summary.json")
        return states
    finally:
        rundir.release(grid.mpi_comm, out_dir)


def _steps(scene: dict, stepper, recorder) -> list:
    """The loop: each step solved by the stepper and written by the recorder, until the path's
    end or a failed step of a stepper that stops there."""
    values = [float(v) for v in scene["protocol"]["values"]]
    control = scene["protocol"]["control"]
    recorder.start()
    states = []
    for step in range(len(recorder.rows) + 1, len(values) + 1):
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
        recorder.record(st, row, stepper.problem, jumps, stepper.results())
    return states


def _outputs_line(scene: dict, n: int, out_dir: str) -> str:
    """The files a run writes (docs/outputs.md), for the plan."""
    from .scenes import adhesive
    out, steps = scene["output"], len(scene["protocol"]["values"])
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
        files.append("load_approach.png, pressure_map.png, error_vs_time.png")
    return f"  outputs in {out_dir}: " + ", ".join(files)


def _save_plots(scene: dict, grid: SurfaceGrid, out_dir: str, states: list, last_step: int) -> None:
    """``output.plots``: ``plots.plot_run`` on rank 0 from the files just written; collective (a
    plotting error is raised on every rank)."""
    if not scene["output"]["plots"]:
        return
    from .plots import plot_run
    pressure = None
    if states and not _wrote_pressure(scene, grid, out_dir, last_step):
        # no field file of the last step, or no pressure in it: gather the last pressure
        last = states[-1]
        field = grid.gather(last.pressure, root=0)
        if field is not None:
            pressure = (field.T, grid.dx, grid.dy,
                        f"last step: δ = {last.approach:.4g} m, F = {last.force:.4g} N")
    rank0 = grid.mpi_comm.Get_rank() == 0
    written = collective_call(grid.mpi_comm, RuntimeError, "plots failed: {error}",
                              lambda: plot_run(out_dir, pressure) if rank0 else [])
    if rank0:
        PETSc.Sys.Print("  plots: " + ", ".join(written), comm=PETSc.COMM_SELF)


def _wrote_pressure(scene: dict, grid: SurfaceGrid, out_dir: str, step: int) -> bool:
    """Whether step ``step`` (the last in curve.csv) has a file with the pressure (read by ``plot_run``)."""
    import os
    fields = scene["output"]["fields"]
    if fields is False or (fields is not True and "pressure" not in fields):
        return False
    path = os.path.join(out_dir, f"step_{step:04d}.h5")
    return grid.mpi_comm.bcast(os.path.exists(path) if grid.mpi_comm.Get_rank() == 0 else None, root=0)


def _branch(control: str, values: list, i: int) -> str:
    """loading where the prescribed value rises (the first step too), unloading where it falls;
    central-gap paths are one branch, stable and unstable."""
    if control == "central_gap":
        return "central-gap"
    return "unloading" if i > 0 and values[i] < values[i - 1] else "loading"
