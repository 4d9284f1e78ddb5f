"""Run a validated scene: one loop over the protocol's steps, one recorder of what they give.

A path is a list of approaches or loads solved in order, each warm-started
from the previous state.  ``run`` builds the grid and the heights, opens the
output directory (``rundir``: locked, one run per directory, the scene stored
for a restart to compare), and then solves step after step with the scene's
stepper (``steppers``: Signorini contact, or adhesion with jumps and the
pull-off force), handing each state to the ``recorder.StepRecorder``, which
writes it at once (``docs/outputs.md``).  With ``restart`` the steps on disk
are kept and the path resumes after the last one.
"""
from __future__ import annotations

from petsc4py import PETSc

from . import rundir
from ..geometry import surfaces
from ..collective import collective_call, petsc_error_message
from ..grid import SurfaceGrid
from .output import ADHESIVE_FIELDS, FIELDS
from .recorder import CURVE_COLUMNS, NAN, StepRecorder

__all__ = ["run", "plan", "build_grid", "build_heights", "build_tip", "CURVE_COLUMNS"]


def build_grid(scene: dict, comm=None) -> SurfaceGrid:
    g = scene["geometry"]
    try:
        return SurfaceGrid(g["nx"], g["ny"], g["dx"], g["dy"], periodic=g["periodic"], comm=comm,
                           row_alignment=16)
    except PETSc.Error as exc:
        size = (comm or PETSc.COMM_WORLD).getSize()
        raise RuntimeError(f"cannot build the {g['nx']} x {g['ny']} grid (geometry.nx, geometry.ny) on {size} "
                           f"rank(s), about {memory_per_rank(scene, size) / 2**20:.0f} MiB per rank: "
                           f"{petsc_error_message(exc)}; use a smaller grid or more ranks") from None


def memory_per_rank(scene: dict, size: int) -> float:
    """Bytes per rank a run needs, estimated: FFT buffers (~5 doubles per transform point, 4
    points per node on an isolated window) and solver vectors (~20 doubles per node)."""
    g = scene["geometry"]
    n = g["nx"] * g["ny"]
    fft_points = n * (1 if g["periodic"] else 4)
    return (5 * fft_points + 20 * n) * 8 / size


def build_tip(scene: dict, grid: SurfaceGrid):
    """(tip, heights, owner) of a ``kind = tip`` scene (``tips.py``)."""
    from ..geometry import tips
    g = scene["geometry"]
    tip = tips.make_tip(g["tip"], grid, g["radius"], g["atom_spacing"], atom_radius=g["atom_radius"],
                        seed=g["seed"])
    h, owner = tips.profile(grid, tip)
    return tip, h, owner


def build_heights(scene: dict, grid: SurfaceGrid) -> PETSc.Vec:
    g = scene["geometry"]
    if g["kind"] == "tip":
        return build_tip(scene, grid)[1]
    if g["kind"] == "sphere":
        return surfaces.sphere(grid, g["radius"])
    if g["kind"] == "file":
        return surfaces.from_file(grid, g["path"], g["dataset"])
    return surfaces.self_affine(grid, hurst=g["hurst"], seed=g["seed"], rms_height=g["rms_height"],
                                rms_slope=g["rms_slope"], rolloff_wavelength=g["rolloff_wavelength"],
                                short_cutoff_wavelength=g["short_cutoff_wavelength"])


def plan(scene: dict, grid: SurfaceGrid, out_dir: str | None = None) -> list[str]:
    """What a run will do: grid, decomposition, solver chain, memory, outputs (dry run and log
    header)."""
    from .scenes import adhesive
    g, sol = scene["geometry"], scene["solver"]
    if adhesive(scene):
        it = scene["interaction"]
        law = f"law {it['law']}, w = {it['work_of_adhesion']:g} J/m^2" + (
            ", element-integrated" if it["element_integration"] else "")
        from ..physics.interactions import LAWS
        from ..solvers.adhesive import newton_ksp_type
        ksp = newton_ksp_type(LAWS[it["law"]].hard_wall)
        chain = (f"  solver: SNES vinewtonrsls on (contact, adhesive) pressures (prefix adhesion_), "
                 f"KSP {ksp}, preconditioner {sol['preconditioner']}, Lanczos stability check"
                 if sol["method"] == "newton" else
                 "  solver: the reference paper's MLMI relaxation (prefix adhesion_relax_), E_Total tol "
                 f"{sol['tol'] or 1e-4:g} z0")
    else:
        law = "no adhesion (Signorini)"
        chain = (f"  solver: SNES vinewtonrsls (prefix contact_), KSP cg, preconditioner "
                 f"{sol['preconditioner']}, tol {sol['tol'] or 1e-10:g}")
    per_rank = memory_per_rank(scene, grid.mpi_comm.Get_size())
    return [f"scene {scene['name']}: {g['kind']} surface, E* = {scene['material']['e_star']:g} Pa, {law}",
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
    from .scenes import adhesive
    from .steppers import AdhesiveSteps, ContactSteps
    grid = build_grid(scene, comm)
    for line in plan(scene, grid, output):
        PETSc.Sys.Print(line)
    if dry_run:
        return []
    if scene["output"]["plots"]:   # before the run, not after it
        from .plots import require
        collective_call(grid.mpi_comm, ImportError, "{error}", require)
    # a tip's profile and atom ownership are built once, for the solve and the forces per atom
    tip = build_tip(scene, grid) if scene["geometry"]["kind"] == "tip" else None
    h = tip[1] if tip else build_heights(scene, grid)
    out_dir = output or scene["output"]["directory"]
    stored = rundir.open_directory(scene, grid, out_dir, restart=restart, overwrite=overwrite)
    try:
        stepper = (AdhesiveSteps if adhesive(scene) else ContactSteps)(scene, grid, h)
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
        _save_plots(scene, grid, out_dir, states)
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
    if out["fields"]:
        per_step = (len(FIELDS) + (len(ADHESIVE_FIELDS) if adhesive(scene) else 0)) * n * 8
        files.append(f"{steps} x step_NNNN.h5 + .xdmf ({per_step / 2**20:.1f} MiB each)")
    if out["atom_forces"] and scene["geometry"]["kind"] == "tip":
        files.append("atom_forces.csv")
    if out["plots"]:
        files.append("load_approach.png, pressure_map.png, error_vs_time.png")
    return f"  outputs in {out_dir}: " + ", ".join(files)


def _save_plots(scene: dict, grid: SurfaceGrid, out_dir: str, states: list) -> None:
    """``output.plots``: ``plots.plot_run`` on rank 0 from the files just written; collective (a
    plotting error is raised on every rank)."""
    if not scene["output"]["plots"]:
        return
    from .plots import plot_run
    pressure = None
    if not scene["output"]["fields"] and states:   # no field file: gather the last pressure
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


def _branch(control: str, values: list, i: int) -> str:
    """loading where the prescribed value rises (the first step too), unloading where it falls;
    central-gap paths are one branch, stable and unstable."""
    if control == "central_gap":
        return "central-gap"
    return "unloading" if i > 0 and values[i] < values[i - 1] else "loading"
