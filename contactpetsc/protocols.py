"""Protocols: run a validated scene's loading path and write its results.

A path is a list of approaches or loads solved in order, each warm-started
from the previous state.  Rank 0 prints progress and writes ``curve.csv``
(one row per step) and ``history.csv`` (one row per iteration: the error
against run time); all ranks write ``step_NNNN.h5`` fields with an XDMF
sidecar (``output.fields``, see ``output.py``).  A smooth sphere on an
isolated half-space without adhesion is also compared with Hertz at each
step.  With adhesion the path runs through ``paths.sweep`` (or
``paths.central_gap_path``): jumps are detected and written to
``jumps.csv``, the pull-off force to ``summary.json``, and spheres are
reported in Greenwood's alpha* and W* as well.
"""
from __future__ import annotations

import csv
import io
import os

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from . import surfaces
from .errors import collective_call
from .grid import SurfaceGrid
from .output import ADHESIVE_FIELDS, FIELDS, versions, write_state, write_text_atomic

CURVE_COLUMNS = ["step", "branch", "approach_m", "force_N", "mean_pressure_Pa", "contact_fraction",
                 "adhesive_force_N", "adhesive_load_ratio", "adhesive_area_ratio", "alpha_star", "W_star",
                 "central_gap_m", "stable", "complementarity_error", "adhesive_error", "total_error",
                 "load_error", "converged", "reason", "solver", "newton_iterations",
                 "krylov_iterations", "fft_pairs", "wall_time_s"]
NAN = float("nan")


def build_grid(scene: dict, comm=None) -> SurfaceGrid:
    g = scene["geometry"]
    return SurfaceGrid(g["nx"], g["ny"], g["dx"], g["dy"], periodic=g["periodic"], comm=comm,
                       row_alignment=16)


def build_tip(scene: dict, grid: SurfaceGrid):
    """(tip, heights, owner) of a ``kind = tip`` scene (``tips.py``)."""
    from . import tips
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
    g, n = scene["geometry"], grid.nx * grid.ny
    size = grid.mpi_comm.Get_size()
    fft_points = n * (4 if not grid.periodic else 1)
    # FFT buffers (~5 doubles per transform point) + solver vectors (~20 doubles per node)
    per_rank = (5 * fft_points + 20 * n) * 8 / size
    from .scenes import adhesive
    sol = scene["solver"]
    if adhesive(scene):
        it = scene["interaction"]
        law = f"law {it['law']}, w = {it['work_of_adhesion']:g} J/m^2" + (
            ", element-integrated" if it["element_integration"] else "")
        from .physics.interactions import LAWS
        from .solvers.adhesive import newton_ksp_type
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
    return [f"scene {scene['name']}: {g['kind']} surface, E* = {scene['material']['e_star']:g} Pa, {law}",
            f"  {grid}",
            f"  rows per rank {[b - a for a, b in grid.y_ranges]}",
            chain,
            f"  protocol: {scene['protocol']['control']} x {len(scene['protocol']['values'])} steps",
            f"  memory estimate: {per_rank / 2**20:.0f} MiB per rank",
            _outputs_line(scene, n, out_dir or scene["output"]["directory"])]


def _read_step(path: str, grid: SurfaceGrid, fields=("pressure",)) -> tuple[list, float]:
    """([Vec per field], approach) of a step file written by ``output.write_state``; every rank
    reads its rows."""
    import h5py

    def read():
        with h5py.File(path, "r") as f:
            for name in fields:
                if f[name].shape != (grid.ny, grid.nx):
                    raise ValueError(f"{name} has shape {f[name].shape}: it does not fit the scene's grid")
            return [np.asarray(f[name][grid.ys:grid.ye, :]) for name in fields], float(f.attrs["approach"])

    arrays, approach = collective_call(grid.mpi_comm, RuntimeError,
                                       f"cannot restart from {path}: {{error}}", read)
    vecs = []
    for rows in arrays:
        v = grid.create_vec()
        grid.rows(v)[...] = rows
        vecs.append(v)
    return vecs, approach


def run(scene: dict, *, output: str | None = None, dry_run: bool = False, comm=None,
        restart: bool = False) -> list:
    """Run ``scene``; returns the list of ContactState of the steps solved (empty for a dry run).

    With ``restart``, steps already in ``curve.csv`` are kept and the path
    resumes from the last one's field file (``step_NNNN.h5``).
    """
    from .scenes import adhesive
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
    run_path = _run_adhesive if adhesive(scene) else _run_signorini
    states = run_path(scene, grid, h, output=output, restart=restart)
    if states and scene["output"]["atom_forces"]:
        _write_atom_forces(grid, tip, states, output or scene["output"]["directory"], restart)
    return states


def _write_atom_forces(grid: SurfaceGrid, tip_build, states: list, out_dir: str, restart: bool) -> None:
    """atom_forces.csv: per step, the force [N] on every atom whose footprint carries
    pressure (compressive positive), with the atom's position about the apex axis;
    ``tip_build`` is ``build_tip``'s (tip, heights, owner)."""
    from .metrics import atom_forces
    tip, _, owner = tip_build
    header = "approach_m,atom,x_m,y_m,radius_m,force_N\n"
    lines = []
    for st in states:
        f = atom_forces(grid, st.pressure, owner, len(tip.atoms))
        for k in np.flatnonzero(f):
            x, y = tip.atoms[k, :2]
            lines.append(f"{st.approach!r},{k},{x!r},{y!r},{float(np.hypot(x, y))!r},{f[k]!r}\n")
    path = os.path.join(out_dir, "atom_forces.csv")
    if grid.mpi_comm.Get_rank() == 0:
        old = open(path).read() if (restart and os.path.exists(path)) else header
        write_text_atomic(path, old + "".join(lines))
    grid.mpi_comm.Barrier()


def _run_signorini(scene: dict, grid: SurfaceGrid, h: PETSc.Vec, *, output: str | None,
                   restart: bool) -> list:
    """The non-adhesive branch of ``run``: displacement or load control with warm starts."""
    from .solvers import ContactProblem
    say = PETSc.Sys.Print
    opts = PETSc.Options("contact_")
    for key, value in scene["solver"]["options"].items():
        if not opts.hasName(key):  # the command line wins over the scene
            opts.setValue(key, str(value))
    g = scene["geometry"]
    e_star = scene["material"]["e_star"]
    hertz = g["kind"] == "sphere" and not g["periodic"] and scene["interaction"]["law"] == "none"
    problem = ContactProblem(grid, h, e_star, tol=scene["solver"]["tol"] or 1e-10,
                             preconditioner=scene["solver"]["preconditioner"],
                             length_scale=(max(scene["protocol"]["values"]) if hertz
                                           and scene["protocol"]["control"] == "approach" else None))
    control = scene["protocol"]["control"]
    values = scene["protocol"]["values"]
    out_dir = output or scene["output"]["directory"]
    rank0 = grid.mpi_comm.Get_rank() == 0
    header = f"  {'step':>4} {'approach [m]':>12} {'force [N]':>11} {'contact':>8} {'error':>9} {'Newton':>6} {'time [s]':>8}"
    if hertz:
        header += f" {'F/F_Hertz':>9} {'a/a_Hertz':>9}"
    say(header)
    states = []
    curve_path, history_path, rows, old_history = _open_outputs(scene, grid, out_dir, restart)
    done = len(rows)
    if done:
        (p,), approach = _read_step(os.path.join(out_dir, f"step_{done:04d}.h5"), grid)
        problem.warm_start(p, approach)
    if restart:
        say(f"  restart: {done} of {len(values)} steps already done")
    provenance = {"scene": scene, "versions": versions()} if scene["output"]["fields"] else None
    t_start = MPI.Wtime()
    for k, value in enumerate(values, 1):
        if k <= done:
            continue
        st = problem.solve(**{control: value}, raise_on_failure=False)
        states.append(st)
        line = (f"  {k:4d} {st.approach:12.4e} {st.force:11.4e} {st.contact_fraction:8.4f} "
                f"{st.complementarity_error:9.2e} {st.newton_iterations:6d} {st.wall_time:8.2f}")
        if hertz:
            R, delta = g["radius"], st.approach
            f_h = 4.0 / 3.0 * e_star * np.sqrt(R) * max(delta, 0.0) ** 1.5
            a_num = np.sqrt(st.contact_fraction * grid.lengths[0] * grid.lengths[1] / np.pi)
            a_h = np.sqrt(R * max(delta, 0.0))
            line += f" {st.force / f_h:9.5f} {a_num / a_h:9.4f}" if f_h > 0 else ""
        elapsed = MPI.Wtime() - t_start
        left = elapsed / (k - done) * (len(values) - k)
        say(line + f"  [step {k}/{len(values)}, {elapsed:.1f} s, ~{left:.1f} s left]"
            + ("" if st.converged else f"  NOT CONVERGED: {st.reason}"))
        rows.append([k, _branch(control, values, k - 1), st.approach, st.force, st.mean_pressure,
                     st.contact_fraction, 0.0, 0.0, 0.0, NAN, NAN, NAN, True, st.complementarity_error,
                     NAN, NAN, st.load_error, st.converged, st.reason, "snes-vi+" + problem.preconditioner,
                     st.newton_iterations, st.linear_iterations, st.fft_pairs, st.wall_time])
        if provenance is not None:
            write_state(out_dir, k, grid, h, st, provenance)
        if rank0:  # rewrite after every step: a finished step is never lost
            _write_csv(curve_path, CURVE_COLUMNS, rows)
            # an interrupted run's iterations stay in front, under one header
            write_text_atomic(history_path,
                              old_history + problem.history.csv_text(header=not old_history))
    _save_plots(scene, grid, out_dir, states)
    grid.mpi_comm.Barrier()  # the outputs are complete when run() returns, on every rank
    say(f"  wrote {out_dir}/curve.csv and {out_dir}/history.csv")
    return states


def _open_outputs(scene: dict, grid: SurfaceGrid, out_dir: str, restart: bool):
    """(curve path, history path, rows already done, old history text); with ``restart`` the
    rows of an interrupted run, read on rank 0 and broadcast (every rank takes the same path).

    Before any solve: the directory must exist (made by rank 0), every rank must be able to
    create a file in it, and it must have room for the run's outputs; otherwise an OSError
    naming the directory on every rank.
    """
    comm = grid.mpi_comm
    rank = comm.Get_rank()
    curve_path, history_path = os.path.join(out_dir, "curve.csv"), os.path.join(out_dir, "history.csv")
    what = f"output directory {out_dir!r} (output.directory or --output)"
    collective_call(comm, OSError, f"{what} cannot be created: {{error}}",
                    lambda: os.makedirs(out_dir, exist_ok=True) if rank == 0 else None)

    def probe():
        path = os.path.join(out_dir, f".contactpetsc-write-test-{rank}-{os.getpid()}")
        try:
            with open(path, "wb") as f:
                f.write(b"x")
                f.flush()
                os.fsync(f.fileno())
        finally:
            if os.path.exists(path):
                os.remove(path)
        st = os.statvfs(out_dir)
        return st.f_bavail * st.f_frsize

    free = collective_call(comm, OSError, f"{what} is not writable: {{error}}", probe)
    fields = len(FIELDS) + (len(ADHESIVE_FIELDS) if scene["interaction"]["law"] != "none" else 0)
    steps = len(scene["protocol"]["values"])
    need = (steps * fields * 8 * grid.nx * grid.ny if scene["output"]["fields"] else 0) + 2**20 * (1 + steps)
    if comm.allreduce(free < need, op=MPI.LOR):
        raise OSError(f"{what} has {comm.allreduce(free, op=MPI.MIN) / 2**20:.1f} MiB free; the run writes "
                      f"about {need / 2**20:.1f} MiB ({steps} steps"
                      + (f" of {fields} fields of {grid.nx} x {grid.ny}" if scene["output"]["fields"] else "")
                      + "): free some space, choose another directory or set output.fields = false")
    rows, old_history = [], ""
    if restart:
        if not scene["output"]["fields"]:
            raise RuntimeError("restart needs the field files: set output.fields = true")

        def read():
            rows, old_history = [], ""
            if rank == 0 and os.path.exists(curve_path):
                with open(curve_path) as f:
                    rows = [r for r in csv.reader(f)][1:]
                if os.path.exists(history_path):
                    with open(history_path) as f:
                        old_history = f.read()
            return rows, old_history

        done = collective_call(comm, RuntimeError, f"cannot restart from {curve_path}: {{error}}", read)
        rows, old_history = comm.bcast(done, root=0)
    return curve_path, history_path, rows, old_history


def _run_adhesive(scene: dict, grid: SurfaceGrid, h: PETSc.Vec, *, output: str | None,
                  restart: bool) -> list:
    """The adhesive branch of ``run``: sweeps with jumps and pull-off, or central-gap paths."""
    import json

    from .metrics import adhesion_ratios, greenwood
    from .paths import central_gap_path, refine_pull_off, sweep
    from .physics.interactions import make_law
    from .solvers.adhesive import AdhesiveProblem
    from .solvers.relaxation import RelaxationSolver
    say = PETSc.Sys.Print
    it, sol, proto, g = scene["interaction"], scene["solver"], scene["protocol"], scene["geometry"]
    opts = PETSc.Options("adhesion_")
    for key, value in sol["options"].items():
        if not opts.hasName(key):  # the command line wins over the scene
            opts.setValue(key, str(value))
    params = {"hardwall-lj": "z0", "lj": "z0", "exponential": "rho", "dugdale": "sigma0"}[it["law"]]
    law = make_law(it["law"], work_of_adhesion=it["work_of_adhesion"], **{params: it[params]})
    e_star = scene["material"]["e_star"]
    tol = sol["tol"] if sol["tol"] is not None else (1e-4 if sol["method"] == "relaxation" else None)
    problem = AdhesiveProblem(grid, h, e_star, law, element_integration=it["element_integration"],
                              tol=tol if sol["method"] == "newton" else None,
                              preconditioner=sol["preconditioner"])
    relax = RelaxationSolver(problem, tol=tol) if sol["method"] == "relaxation" else None
    sphere = g["kind"] in ("sphere", "tip") and not g["periodic"]   # Greenwood's scaling with R
    z0 = law.length_scale()
    out_dir = output or scene["output"]["directory"]
    rank0 = grid.mpi_comm.Get_rank() == 0
    values = [float(v) for v in proto["values"]]
    curve_path, history_path, rows, old_history = _open_outputs(scene, grid, out_dir, restart)
    done = len(rows)
    if done:
        (q, a), approach = _read_step(os.path.join(out_dir, f"step_{done:04d}.h5"), grid,
                                      ("contact_pressure", "adhesive_pressure"))
        problem.warm_start(q, a, approach)
    if restart:
        say(f"  restart: {done} of {len(values)} steps already done")
    provenance = {"scene": scene, "versions": versions()} if scene["output"]["fields"] else None
    say(f"  {'step':>4} {'approach [m]':>12} {'force [N]':>11} {'contact':>8} {'adh. force':>11} "
        f"{'error':>9} {'stable':>6} {'time [s]':>8}" + (f" {'alpha*':>8} {'W*':>9}" if sphere else ""))
    t_start = MPI.Wtime()
    states = []

    def record(k, st, pt):
        step = done + k + 1
        states.append(st)
        load_ratio, area_ratio = adhesion_ratios(grid, st.pressure, law.peak_attraction)
        a_star, w_star = (greenwood(st.approach, st.force, g["radius"], law.work_of_adhesion, z0)
                          if sphere else (NAN, NAN))
        err = max(st.complementarity_error, st.adhesive_error)
        elapsed = MPI.Wtime() - t_start
        left = elapsed / (k + 1) * (len(values) - done - k - 1)
        say(f"  {step:4d} {st.approach:12.4e} {st.force:11.4e} {st.contact_fraction:8.4f} "
            f"{st.adhesive_force:11.4e} {err:9.2e} {str(st.stable):>6} {st.wall_time:8.2f}"
            + (f" {a_star:8.3f} {w_star:9.4f}" if sphere else "")
            + f"  [step {step}/{len(values)}, {elapsed:.1f} s, ~{left:.1f} s left]"
            + ("" if st.converged else f"  NOT CONVERGED: {st.reason}"))
        rows.append([step, _branch(proto["control"], values, step - 1), st.approach, st.force,
                     st.mean_pressure, st.contact_fraction, st.adhesive_force, load_ratio, area_ratio,
                     a_star, w_star, st.central_gap, st.stable, st.complementarity_error,
                     st.adhesive_error, st.total_error, NAN, st.converged, st.reason, st.solver,
                     st.newton_iterations, st.linear_iterations, st.fft_pairs, st.wall_time])
        if provenance is not None:
            write_state(out_dir, step, grid, h, st, provenance)
        if rank0:
            _write_csv(curve_path, CURVE_COLUMNS, rows)
            write_text_atomic(history_path, old_history + problem.history.csv_text(header=not old_history))

    todo = values[done:]
    failed = []   # (step, state): a failed step ends the run, so that the written steps stay
    #               a contiguous path to restart from

    def stop(k, st, pt):
        failed.append((done + k + 1, st))

    if relax is not None:
        # the paper's solver, step by step (no jump location: it relaxes wherever it goes)
        for k, delta in enumerate(todo):
            st = relax.solve(approach=delta, raise_on_failure=False)
            if not st.converged:
                stop(k, st, None)
                break
            record(k, st, None)
        path = None
    elif proto["control"] == "central_gap":
        path = central_gap_path(problem, todo, on_state=record, stop_on_failure=True, on_failure=stop)
    else:
        last = rows[-1] if done else None   # a restart: jumps from the last written step on are found too
        previous = (float(last[CURVE_COLUMNS.index("approach_m")]), float(last[CURVE_COLUMNS.index("force_N")]),
                    NAN) if last else None
        path = sweep(problem, todo, refine=proto["jump_refinement"], on_state=record, stop_on_failure=True,
                     on_failure=stop, previous=previous, substeps=proto["substeps"])
    summary = {"steps": len(rows), "converged": not failed}
    if failed:
        step, st = failed[0]
        summary["stopped_at"] = {"step": step, "approach_m": st.approach, "reason": st.reason}
        say(f"  step {step} (approach {st.approach:.4e} m) NOT CONVERGED: {st.reason}\n"
            f"  the run stopped there: steps 1-{step - 1} of {len(values)} are written; "
            f"fix the cause and continue with --restart")
    if path is not None and proto["control"] == "approach":
        pull = path.pull_off_force
        if proto["refine_pull_off"] and path._best is not None:
            step = min(np.diff(values).__abs__()) if len(values) > 1 else z0
            pull = refine_pull_off(problem, path, xtol=0.01 * step)
        summary["pull_off_force_N"] = pull
        if sphere:
            summary["pull_off_W_star"] = pull / (2 * np.pi * g["radius"] * law.work_of_adhesion)
        summary["jumps"] = [vars(j) for j in path.jumps]
        say(f"  pull-off force {pull:.6e} N" + (f" (W* = {summary['pull_off_W_star']:.4f})" if sphere else ""))
        for j in path.jumps:
            say(f"  {j.kind} between approaches {j.approach_before:.4e} and {j.approach_after:.4e} m: "
                f"force {j.force_before:.4e} -> {j.force_after:.4e} N")
        if rank0:
            jumps_path = os.path.join(out_dir, "jumps.csv")
            # a restarted run keeps the jumps found before the interruption
            old_jumps = []
            if done and os.path.exists(jumps_path):
                with open(jumps_path) as f:
                    old_jumps = [r for r in csv.reader(f)][1:]
            _write_csv(jumps_path,
                       ["kind", "approach_before_m", "approach_after_m", "force_before_N", "force_after_N"],
                       old_jumps + [[j.kind, j.approach_before, j.approach_after, j.force_before, j.force_after]
                                    for j in path.jumps])
    if rank0:
        write_text_atomic(os.path.join(out_dir, "summary.json"), json.dumps(summary, indent=1, default=str))
    _save_plots(scene, grid, out_dir, states)
    grid.mpi_comm.Barrier()
    say(f"  wrote {out_dir}/curve.csv, history.csv, summary.json")
    # the failed step last: the caller (the command line's exit code) sees the failure
    return states + [failed[0][1]] if failed else states


def _outputs_line(scene: dict, n: int, out_dir: str) -> str:
    """The files a run writes (docs/outputs.md), for the plan."""
    from .scenes import adhesive
    out, steps = scene["output"], len(scene["protocol"]["values"])
    files = ["curve.csv", "history.csv"] + (["jumps.csv", "summary.json"] if adhesive(scene) else [])
    if out["fields"]:
        per_step = (len(FIELDS) + (len(ADHESIVE_FIELDS) if adhesive(scene) else 0)) * n * 8
        files.append(f"{steps} x step_NNNN.h5 + .xdmf ({per_step / 2**20:.1f} MiB each)")
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


def _write_csv(path: str, columns: list, rows: list) -> None:
    out = io.StringIO()
    w = csv.writer(out)
    w.writerow(columns)
    w.writerows(rows)
    write_text_atomic(path, out.getvalue())
