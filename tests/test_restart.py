"""Restarts: a killed or stopped run, continued with --restart, reports what an uninterrupted
run reports (curve, jumps, pull-off, forces per atom); a restart of another problem, or from
damaged files, is refused naming what differs or the file.

The kill tests launch the command line (serially and under ``mpirun -n 2``) and kill the
whole job with SIGKILL once some steps are on disk: they are marked serial (a rank of an MPI
job cannot launch mpirun).  The in-process tests run on any number of ranks.
"""
import csv
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import h5py
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import runner, scenes
from contactpetsc.app.rundir import RunDirectoryError
from test_field_output import expected_steps

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "scenes")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1")
CLI = [sys.executable, "-m", "contactpetsc"]
needs_mpirun = pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")


def command(ranks, args):
    return (["mpirun", "-n", str(ranks)] if ranks > 1 else []) + CLI + list(args)


def cli(ranks, args, code=0):
    proc = subprocess.run(command(ranks, args), env=ENV, capture_output=True, text=True, timeout=600)
    assert proc.returncode == code, proc.stdout + proc.stderr
    return proc


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def finished_rows(path) -> int:
    """Complete lines of a CSV file being written, header excluded."""
    try:
        with open(path) as f:
            return max(f.read().count("\n") - 1, 0)
    except FileNotFoundError:
        return 0


def kill_after(ranks, args, curve, n, log=None):
    """Launch a run and SIGKILL the whole job (every rank, mpirun) once ``n`` steps are in
    ``curve``; returns the steps left on disk.  With ``log`` (a path) its standard output is
    kept there (unbuffered: what it printed before the kill)."""
    with open(log or os.devnull, "w") as out:
        proc = subprocess.Popen(command(ranks, args), env=dict(ENV, PYTHONUNBUFFERED="1") if log else ENV, stdout=out,
                                stderr=subprocess.DEVNULL)
        return _kill_when(proc, curve, n)


def _kill_when(proc, curve, n):
    t0 = time.time()
    # the time limit only guards against a hung run: on an oversubscribed machine reaching
    # step n has taken over 300 s
    while finished_rows(curve) < n and time.time() - t0 < 1800 and proc.poll() is None:
        time.sleep(0.005)
    for pid in [proc.pid] + descendants(proc.pid):   # mpirun and every rank at once, as a scheduler
        try:
            os.kill(pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    proc.wait()
    return finished_rows(curve)


def descendants(pid) -> list:
    """Process ids below ``pid`` (from /proc: mpirun's ranks)."""
    children = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                with open(f"/proc/{entry}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
            except (OSError, ValueError, IndexError):
                continue
            children.setdefault(ppid, []).append(int(entry))
    out, todo = [], [pid]
    while todo:
        for child in children.get(todo.pop(), []):
            out.append(child)
            todo.append(child)
    return out


def summary(out):
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


def same_jumps(a, b):
    assert [r["kind"] for r in a] == [r["kind"] for r in b]
    for x, y in zip(a, b):
        for c in ("approach_before_m", "approach_after_m", "force_before_N", "force_after_N"):
            assert float(x[c]) == pytest.approx(float(y[c]), rel=1e-6), c


@pytest.mark.serial
@pytest.mark.heavy
@pytest.mark.mpirun   # launches mpirun jobs
@needs_mpirun
@pytest.mark.parametrize("ranks", [2])   # serial kills and restarts: test_faults, test_stability_auto
def test_killed_adhesive_sweep_restarts_to_the_uninterrupted_results(tmp_path, ranks):
    """The adhesive sphere (a jump-on while loading, the most tensile state at step 22, a
    jump-off at step 26), killed after the jump-on, restarted, and the restarted run killed
    again after the most tensile state: each --restart takes over the killed run's lock and
    resumes after its last step, and the path ends with the uninterrupted run's curve,
    jumps.csv and refined pull-off force (so the first restart's steps, the jump-on kept
    across both restarts and the most tensile state written by the restarted run are those
    of the uninterrupted run)."""
    scene = os.path.join(SCENES, "adhesive_sphere.toml")
    full = tmp_path / "full"
    cli(ranks, ["run", scene, "--output", str(full)])
    ref, ref_jumps, ref_summary = rows(full / "curve.csv"), rows(full / "jumps.csv"), summary(full)
    assert [j["kind"] for j in ref_jumps] == ["jump-on", "jump-off"] and ref_summary["pull_off_refined"]
    cut = tmp_path / "cut"
    run = ["run", scene, "--output", str(cut)]
    kept = kill_after(ranks, run, cut / "curve.csv", 8)
    assert 8 <= kept < len(ref), "the run was not killed mid-path"
    for n in (24, None):    # the restart killed after the most tensile state, then one to the end
        if n is not None:
            log = tmp_path / f"restart{kept}.log"
            done = kill_after(ranks, run + ["--restart"], cut / "curve.csv", n, log=log)
            assert n <= done < len(ref), "the restarted run was not killed mid-path"
            out = log.read_text()
        else:
            out = cli(ranks, run + ["--restart"]).stdout
        assert f"restart: {kept} of {len(ref)} steps already done" in out
        assert "took over the lock" in out
        if n is not None:
            kept = done
    resumed = rows(cut / "curve.csv")
    assert [r["step"] for r in resumed] == [r["step"] for r in ref]
    for a, b in zip(resumed, ref):
        assert float(a["force_N"]) == pytest.approx(float(b["force_N"]), rel=1e-5, abs=1e-12)
    same_jumps(rows(cut / "jumps.csv"), ref_jumps)
    s = summary(cut)
    same_jumps(s["jumps"], ref_jumps)
    assert s["steps"] == len(ref) and s["converged"] and s["pull_off_refined"]
    assert s["pull_off_force_N"] == pytest.approx(ref_summary["pull_off_force_N"], rel=1e-6)


def tip_scene(path, out, output=()):
    scene = scenes.load(os.path.join(SCENES, "atomic_tip.toml"))
    g = scene["geometry"]
    lines = ["[geometry]", 'kind = "tip"', f'tip = "{g["tip"]}"', f"radius = {g['radius']!r}",
             f"atom_spacing = {g['atom_spacing']!r}", "nx = 64", f"dx = {g['dx']!r}",
             "[material]", f"e_star = {scene['material']['e_star']!r}",
             "[interaction]", 'law = "lj"', f"work_of_adhesion = {scene['interaction']['work_of_adhesion']!r}",
             f"z0 = {scene['interaction']['z0']!r}",
             "[protocol]", f"values = {scene['protocol']['values']!r}",
             "[output]", f'directory = "{out}"', "atom_forces = true", *output]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.mark.serial
@needs_mpirun
@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=pytest.mark.mpirun)])
def test_killed_tip_run_keeps_the_forces_per_atom(tmp_path, ranks):
    """An atomic tip with atom_forces, and field files of every 4th step (float32, a selection,
    lengths in nm), killed mid-path and restarted: atom_forces.csv has every step's forces
    (those before the kill too), equal to the uninterrupted run's, the pull-off force is the
    uninterrupted run's, and the step files and the temporal collection are those of the
    documented rule (the path resumed from the last step file)."""
    output = ('fields = ["gap", "contact"]', 'field_precision = "float32"', "field_every = 4",
              'length_unit = "nm"')
    full = tmp_path / "full"
    cli(ranks, ["run", tip_scene(tmp_path / "full.toml", full, output)])
    cut = tmp_path / "cut"
    scene = tip_scene(tmp_path / "cut.toml", cut, output)
    kept = kill_after(ranks, ["run", scene], cut / "curve.csv", 5)
    assert 5 <= kept < 17
    cli(ranks, ["run", scene, "--restart"])
    a, b = rows(cut / "atom_forces.csv"), rows(full / "atom_forces.csv")
    assert [(r["step"], r["atom"]) for r in a] == [(r["step"], r["atom"]) for r in b]
    for x, y in zip(a, b):
        assert float(x["force_N"]) == pytest.approx(float(y["force_N"]), rel=1e-5, abs=1e-15)
    # per step the forces on the atoms add up to the step's force
    for r in rows(cut / "curve.csv"):
        total = sum(float(x["force_N"]) for x in a if x["step"] == r["step"])
        assert total == pytest.approx(float(r["force_N"]), rel=1e-9)
    assert summary(cut)["pull_off_force_N"] == pytest.approx(summary(full)["pull_off_force_N"], rel=1e-6)
    for out in (full, cut):   # the documented steps (round-off may order two equal forces apart)
        want = expected_steps(out, 4, True)
        assert written_steps(out) == [f"step_{k:04d}.{ext}" for k in want for ext in ("h5", "xdmf")]
        assert len(want) < 17 and (out / "fields.xdmf").read_text().count("<Time ") == len(want)


def written_steps(out):
    return sorted(n for n in os.listdir(out) if n.startswith("step_"))


# -- in-process: what a restart refuses --------------------------------------------------------
def rough(out, **change):
    s = {"name": "restart-rough",
         "geometry": {"kind": "self-affine", "nx": 16, "dx": 1e-8, "rms_slope": 0.1, "seed": 3},
         "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": [5e6, 1e7]},
         "output": {"directory": str(out)}}
    for key, value in change.items():
        section, name = key.split("__")
        s.setdefault(section, {})[name] = value
    return scenes.validate(s)


@pytest.mark.parametrize("change, named", [
    ({"material__e_star": 2e9}, "material.e_star"),
    ({"geometry__seed": 4}, "geometry.seed"),
    ({"geometry__dx": 2e-8}, "geometry.dx"),
    ({"geometry__nx": 32}, "geometry.nx"),
    ({"protocol__control": "force"}, "protocol.control"),
    ({"protocol__values": [6e6, 1e7, 2e7]}, "protocol.values"),
])
def test_restart_of_another_problem_is_refused_naming_the_keys(coll, shared_tmp, change, named):
    out = shared_tmp / "run"
    runner.run(rough(out), comm=PETSc.COMM_WORLD)
    before = (out / "curve.csv").read_text() if coll.rank == 0 else None
    coll.raises(RunDirectoryError, ["cannot restart", "another problem", named], runner.run,
                rough(out, **change), comm=PETSc.COMM_WORLD, restart=True)
    if coll.rank == 0:
        assert (out / "curve.csv").read_text() == before          # nothing written
    # output keys, the name and the solver's settings may differ; more values continue the path
    more = rough(out, protocol__values=[5e6, 1e7, 2e7], output__plots=False, solver__tol=1e-9)
    more["name"] = "renamed"
    states = runner.run(more, comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 1 and coll.all(states[0].converged)


def test_damaged_files_are_refused_or_redone_naming_the_file(coll, shared_tmp):
    """A truncated earlier step file and a short row inside curve.csv are refused, naming the
    file (and the row); a partial last row (a kill while appending) is dropped and its step
    solved again, to the uninterrupted run's result."""
    world = PETSc.COMM_WORLD.tompi4py()
    ref = shared_tmp / "ref"
    full = runner.run(rough(ref, protocol__values=[5e6, 1e7, 2e7]), comm=PETSc.COMM_WORLD)
    out = shared_tmp / "run"
    runner.run(rough(out, protocol__values=[5e6, 1e7, 2e7]), comm=PETSc.COMM_WORLD)
    scene = rough(out, protocol__values=[5e6, 1e7, 2e7, 3e7])
    good = (out / "curve.csv").read_text() if coll.rank == 0 else None
    step1 = (out / "step_0001.h5").read_bytes() if coll.rank == 0 else None
    if coll.rank == 0:
        (out / "step_0001.h5").write_bytes(step1[: len(step1) // 2])
    world.Barrier()
    coll.raises(RunDirectoryError, ["cannot restart", "step_0001.h5"], runner.run, scene,
                comm=PETSc.COMM_WORLD, restart=True)
    if coll.rank == 0:
        (out / "step_0001.h5").write_bytes(step1)
        lines = good.splitlines(keepends=True)
        lines[2] = ",".join(lines[2].split(",")[:5]) + "\n"         # row 2 cut short
        (out / "curve.csv").write_text("".join(lines))
    world.Barrier()
    coll.raises(RunDirectoryError, ["curve.csv, row 2", "columns"], runner.run, scene,
                comm=PETSc.COMM_WORLD, restart=True)
    if coll.rank == 0:
        words = good.splitlines(keepends=True)[2].split(",")
        words[3] = "abc"                                              # row 2's force damaged
        lines[2] = ",".join(words)
        (out / "curve.csv").write_text("".join(lines))
    world.Barrier()
    coll.raises(RunDirectoryError, ["curve.csv, row 2", "damaged value"], runner.run, scene,
                comm=PETSc.COMM_WORLD, restart=True)
    if coll.rank == 0:
        (out / "curve.csv").write_text(good[: len(good) - 40])     # the last row half-written
    world.Barrier()
    states = runner.run(rough(out, protocol__values=[5e6, 1e7, 2e7]), comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 1                                          # step 3 solved again
    assert coll.max(abs(states[0].approach - full[2].approach) / abs(full[2].approach)) <= 1e-8
    with open(out / "curve.csv") as f:
        assert [r["step"] for r in csv.DictReader(f)] == ["1", "2", "3"]


def test_step_files_carry_the_axis_order_and_restart_checks_it(coll, shared_tmp):
    out = shared_tmp / "run"
    runner.run(rough(out), comm=PETSc.COMM_WORLD)
    world = PETSc.COMM_WORLD.tompi4py()
    if coll.rank == 0:
        with h5py.File(out / "step_0002.h5", "r+") as f:
            assert f.attrs["axes"] == "y,x" and all(f[name].attrs["axes"] == "y,x" for name in f)
            assert f["pressure"].shape == (16, 16)
            f.attrs["axes"] = "x,y"
    world.Barrier()
    coll.raises(RunDirectoryError, ["step_0002.h5", "axes 'x,y'"], runner.run,
                rough(out, protocol__values=[5e6, 1e7, 2e7]), comm=PETSc.COMM_WORLD, restart=True)


def test_restart_after_the_height_file_was_rewritten_is_refused_naming_it(coll, shared_tmp):
    """Steps 1-2 solved on one map; the file rewritten with other heights: --restart refuses,
    naming the file, and keeps the steps on disk; the same heights rewritten (another file's
    bytes, the same numbers) restart."""
    path, out = shared_tmp / "scan.npy", shared_tmp / "scan-run"
    x, y = np.meshgrid(np.arange(16), np.arange(16), indexing="ij")
    bump = 1e-9 * np.exp(-((x - 7) ** 2 + (y - 9) ** 2) / 8.0)

    def write(z):
        if coll.rank == 0:
            np.save(path, z)
        coll.comm.Barrier()

    def scene(values):
        return scenes.validate({"geometry": {"kind": "file", "path": str(path), "dx": 1e-9},
                                "material": {"e_star": 1e9},
                                "protocol": {"control": "approach", "values": values},
                                "output": {"directory": str(out)}})
    write(bump)
    runner.run(scene([1e-10, 2e-10]), comm=PETSc.COMM_WORLD)
    before = (out / "curve.csv").read_text() if coll.rank == 0 else None
    write(1.5 * bump)
    coll.raises(RunDirectoryError, ["cannot restart", "scan.npy", "geometry.path", "rewritten"],
                runner.run, scene([1e-10, 2e-10, 3e-10]), comm=PETSc.COMM_WORLD, restart=True)
    if coll.rank == 0:
        assert (out / "curve.csv").read_text() == before
    write(np.asfortranarray(bump))   # other bytes on disk, the same heights
    states = runner.run(scene([1e-10, 2e-10, 3e-10]), comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 1 and coll.all(states[0].converged)


# three relaxation sweeps: 1 and 2 ranks (on 3 ranks test_pull_off_and_jumps' relaxation sweep
# and the restarts of test_scenes and test_field_output split unevenly)
@pytest.mark.heavy
@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
@pytest.mark.filterwarnings("ignore::contactpetsc.topography.units.TopographyUnitWarning")
def test_a_restarted_relaxation_sweep_refines_the_uninterrupted_runs_pull_off(coll, shared_tmp):
    """solver.method = relaxation on the flat cell (test_pull_off_and_jumps), stopped after its most
    tensile step (3, written for the pull-off search although field_every = 4) and restarted: the
    pull-off refined by relaxation solves from that step's file is the uninterrupted run's."""
    from test_pull_off_and_jumps import flat_scene
    values = [-1.5, -0.6, -0.1, -0.6, -1.5]

    def scene(out, values):
        s = flat_scene(shared_tmp, 0.5, values)
        s["output"].update(fields=True, field_every=4, directory=str(out))
        return s

    full, cut = shared_tmp / "full", shared_tmp / "cut"
    runner.run(scene(full, values), comm=PETSc.COMM_WORLD)
    runner.run(scene(cut, values[:4]), comm=PETSc.COMM_WORLD)
    assert os.path.exists(cut / "step_0003.h5")
    states = runner.run(scene(cut, values), comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 1
    ref, got = summary(full), summary(cut)
    assert ref["pull_off_refined"] and got["pull_off_refined"]
    assert coll.max(abs(got["pull_off_force_N"] / ref["pull_off_force_N"] - 1)) <= 1e-12
