"""What the step recorder writes: valid JSON whose jumps are jumps.csv's rows, a warning when
an isolated contact reaches the window's edge (against Hertz's contact radius), a clean end on
a failed field write (a file size limit, as a full disk), clear messages for damaged files and
PETSc failures, and a failure at the first step reported as such."""
import csv
import json
import os
import shutil
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, runner, scenes

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "scenes")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1")
CLI = [sys.executable, "-m", "contactpetsc"]


def strict_json(path):
    """JSON as the standard defines it: NaN and Infinity are refused."""
    def refuse(word):
        raise ValueError(f"{path}: {word} is not JSON")
    with open(path) as f:
        return json.loads(f.read(), parse_constant=refuse)


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def adhesive_sphere(out, n=64, values=None):
    scene = scenes.load(os.path.join(SCENES, "adhesive_sphere.toml"))
    g = scene["geometry"]
    g["dx"] = g["dy"] = g["dx"] * g["nx"] / n
    g["nx"] = g["ny"] = n
    scene["output"]["directory"] = str(out)
    if values is not None:
        scene["protocol"]["values"] = values
    return scene


@pytest.mark.heavy   # an adhesive path: 1 and 2 ranks (3 oversubscribed ranks spend minutes)
def test_summary_is_json_and_its_jumps_are_the_rows_of_jumps_csv(coll, shared_tmp, adhesive_sweep):
    """A finished adhesive sweep's summary.json (conftest's adhesive_sweep: a jump-on, a jump-off,
    the pull-off refined) is strict JSON and its jumps are jumps.csv's rows; a path whose first
    step fails has a null pull-off force."""
    out = adhesive_sweep
    s = strict_json(out / "summary.json")
    with open(out / "jumps.csv", newline="") as f:
        reader = csv.DictReader(f)
        jumps = list(reader)
    assert jumps and [list(j) for j in s["jumps"]] == [reader.fieldnames] * len(jumps)
    for a, b in zip(s["jumps"], jumps):
        assert a["kind"] == b["kind"] and a["step"] == int(b["step"])
        for c in ("approach_before_m", "approach_after_m", "force_before_N", "force_after_N"):
            assert a[c] == float(b[c])
    # a path whose first step fails has no pull-off force: null, not NaN
    opts = PETSc.Options()
    opts.setValue("adhesion_time_budget", "1e-9")
    try:
        states = runner.run(adhesive_sphere(shared_tmp / "stopped"), comm=PETSc.COMM_WORLD)
    finally:
        opts.delValue("adhesion_time_budget")
    assert len(states) == 1 and not coll.all(states[0].converged)
    s = strict_json(shared_tmp / "stopped" / "summary.json")
    assert s["pull_off_force_N"] is None and s["converged"] is False and s["steps"] == 0
    assert s["stopped_at"]["step"] == 1 and "WALL_TIME_BUDGET" in s["stopped_at"]["reason"]


@pytest.mark.serial
def test_a_failure_at_the_first_step_says_no_step_is_written(tmp_path):
    scene = os.path.join(SCENES, "adhesive_sphere.toml")
    proc = subprocess.run(CLI + ["run", scene, "--output", str(tmp_path / "out"), "-adhesion_time_budget", "1e-9"],
                          env=ENV, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "no step is written" in proc.stdout and "1-0" not in proc.stdout


def hertz(out, nx, approach, radius=1e-6, dx=5e-9):
    return scenes.validate({"geometry": {"kind": "sphere", "radius": radius, "nx": nx, "dx": dx},
                            "material": {"e_star": 1e9}, "protocol": {"values": [approach]},
                            "output": {"directory": str(out), "fields": False}})


@pytest.mark.parametrize("ratio", [0.5, 1.3])
def test_window_edge_is_reported_against_hertz_contact_radius(coll, shared_tmp, capfd, ratio):
    """A Hertz sphere whose contact radius a = sqrt(R delta) is ``ratio`` times the window's
    half-width: at 0.5 the zone's reach (curve.csv window_reach) is a over the half-width and
    nothing is said; at 1.3 the zone is cut by the window: reach 1, a warning in the log and
    the step listed in summary.json."""
    nx, dx, radius = 64, 5e-9, 1e-6
    half = 0.5 * (nx - 1) * dx
    approach = (ratio * half) ** 2 / radius
    out = shared_tmp / "hertz"
    runner.run(hertz(out, nx, approach, radius, dx), comm=PETSc.COMM_WORLD)
    reach = float(read_rows(out / "curve.csv")[0]["window_reach"])
    s = strict_json(out / "summary.json")
    log = capfd.readouterr().out
    if ratio < 1:
        assert reach == pytest.approx(ratio, abs=2.5 * dx / half)
        assert s["window_edge_steps"] == [] and "window's edge" not in log
    else:
        assert reach == 1.0 and s["window_edge_steps"] == [1]
        if coll.rank == 0:
            assert "warning: step 1: the pressure-carrying zone reaches the window's edge" in log


def test_periodic_cells_have_no_window_reach(coll, shared_tmp):
    s = scenes.validate({"geometry": {"kind": "self-affine", "nx": 16, "dx": 1e-8, "rms_slope": 0.1},
                         "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": [5e6]},
                         "output": {"directory": str(shared_tmp / "p"), "fields": False}})
    runner.run(s, comm=PETSc.COMM_WORLD)
    assert np.isnan(float(read_rows(shared_tmp / "p" / "curve.csv")[0]["window_reach"]))


FILE_SIZE_LIMIT = textwrap.dedent("""
    import resource, signal, sys
    import petsc4py
    petsc4py.init(sys.argv)
    from petsc4py import PETSc
    import h5py
    # after MPI is up (it needs its own files): every file this process writes is capped, so the
    # step file's write fails inside HDF5 as on a full disk
    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
    from contactpetsc.app import cli
    sys.exit(cli.main(sys.argv[1:]))
""")


@pytest.mark.serial
@pytest.mark.parametrize("ranks", [1, pytest.param(2, marks=pytest.mark.mpirun)])
def test_a_failed_step_file_write_ends_with_the_error_code_and_no_stray_file(tmp_path, ranks):
    """A step file larger than the process may write (RLIMIT_FSIZE, as a nearly full disk):
    exit 1 on every rank, naming the file and the room, nothing half-written -- also on two
    ranks, where a collective MPI-IO write that failed on one rank only would hang."""
    if ranks > 1 and shutil.which("mpirun") is None:
        pytest.skip("needs mpirun")
    script = tmp_path / "capped.py"
    script.write_text(FILE_SIZE_LIMIT)
    out = tmp_path / "out"
    scene = tmp_path / "s.toml"
    scene.write_text(textwrap.dedent(f"""
        [geometry]
        kind = "self-affine"
        nx = 64
        dx = 1e-8
        rms_slope = 0.1
        [material]
        e_star = 1e9
        [protocol]
        control = "mean_pressure"
        values = [5e6, 1e7]
        [output]
        directory = "{out}"
    """))
    launcher = ["mpirun", "-n", str(ranks)] if ranks > 1 else []
    proc = subprocess.run(launcher + [sys.executable, str(script), "run", str(scene)], env=ENV,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "cannot write" in proc.stderr and "step_0001.h5" in proc.stderr and "has room for" in proc.stderr
    assert not [n for n in os.listdir(out) if n.endswith(".tmp") or n.startswith("step_") or n.startswith(".")]


@pytest.mark.serial
def test_plot_of_a_damaged_curve_names_the_file_and_row(tmp_path):
    out = tmp_path / "out"
    runner.run(hertz(out, 16, 1e-9), comm=PETSc.COMM_SELF)
    lines = (out / "curve.csv").read_text().splitlines(keepends=True)
    (out / "curve.csv").write_text(lines[0] + lines[1] + "2,loading,2e-9\n")
    proc = subprocess.run(CLI + ["plot", str(out)], env=ENV, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1
    assert f"{out / 'curve.csv'}, row 2" in proc.stderr and "damaged" in proc.stderr
    assert "Traceback" not in proc.stderr
    (out / "curve.csv").write_text(lines[0] + lines[1].replace(lines[1].split(",")[3], "1.2e", 1))
    proc = subprocess.run(CLI + ["plot", str(out)], env=ENV, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 1 and "row 1: force_N = '1.2e' is not a number" in proc.stderr


@pytest.mark.serial
def test_plot_names_each_damaged_file_and_its_cause(tmp_path, capsys):
    """summary.json, scene.json, a step file and curve.csv damaged each in its own way: the
    message names the file and what is wrong with it, never a traceback; a run with no step
    (failed at its first) has nothing to plot and says so."""
    from mpi4py import MPI
    from contactpetsc.app import cli
    out = tmp_path / "out"
    scene = hertz(out, 16, 1e-9)
    scene["output"]["fields"] = True
    runner.run(scene, comm=PETSc.COMM_SELF)
    step = sorted(n for n in os.listdir(out) if n.startswith("step_") and n.endswith(".h5"))[-1]
    damage = {"summary.json": (b'{"pull_off', "not valid JSON"), "scene.json": (b"[1, 2]", "a JSON list"),
              step: (None, "truncated"), "curve.csv": (bytes(range(256)) * 4, "not a text file")}
    for name, (content, cause) in damage.items():
        case = tmp_path / name
        shutil.copytree(out, case)
        data = (case / name).read_bytes()
        (case / name).write_bytes(content if content is not None else data[:len(data) // 3])
        assert cli._plot(str(case), MPI.COMM_SELF) == 1
        err = capsys.readouterr().err
        assert f"cannot read {case / name}: " in err and cause in err and "Traceback" not in err
    none = tmp_path / "none"
    shutil.copytree(out, none)
    (none / "curve.csv").write_text((out / "curve.csv").read_text().splitlines(keepends=True)[0])
    assert cli._plot(str(none), MPI.COMM_SELF) == 1
    err = capsys.readouterr().err
    assert f"{none / 'curve.csv'} has no steps" in err and "nothing to plot" in err


def test_petsc_failure_building_the_grid_is_told_in_the_users_terms(coll, monkeypatch):
    def fails(*args, **kwargs):
        raise PETSc.Error(55)
    monkeypatch.setattr(builder, "SurfaceGrid", fails)
    coll.raises(RuntimeError, ["cannot build the 4096 x 4096 grid", "geometry.nx", "out of memory",
                               "PETSc error code 55", "MiB per rank"],
                builder.build_grid, hertz("unused", 4096, 1e-9))


@pytest.mark.serial
def test_cli_reports_a_petsc_error_by_its_meaning(tmp_path):
    script = tmp_path / "petsc_error.py"
    script.write_text(textwrap.dedent("""
        import sys, petsc4py
        petsc4py.init(sys.argv)
        from petsc4py import PETSc
        from contactpetsc.app import cli, steppers
        def solve(self, value):
            raise PETSc.Error(76)
        steppers.ContactSteps.step = solve
        sys.exit(cli.main(sys.argv[1:]))
    """))
    proc = subprocess.run([sys.executable, str(script), "run", "--output", str(tmp_path / "out")], env=ENV,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1
    assert "error: PETSc stopped with an error in a library PETSc calls (PETSc error code 76)" in proc.stderr
    assert not (tmp_path / "out" / ".contactpetsc.lock").exists()


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_a_failed_parallel_step_file_write_ends_every_rank(tmp_path):
    """Under mpirun -n 2 a write that fails on every rank (h5py raising, as on a full disk):
    exit 1, the message names the file, no temporary file is left."""
    script = tmp_path / "fails.py"
    script.write_text(textwrap.dedent("""
        import sys, petsc4py
        petsc4py.init(sys.argv)
        import h5py
        def fail(self, key, value):
            raise OSError(28, "No space left on device")
        h5py.Dataset.__setitem__ = fail
        from contactpetsc.app import cli
        sys.exit(cli.main(sys.argv[1:]))
    """))
    out = tmp_path / "out"
    proc = subprocess.run(["mpirun", "-n", "2", sys.executable, str(script), "run", "--output", str(out)],
                          env=ENV, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    assert "cannot write" in proc.stderr and "step_0001.h5" in proc.stderr and "No space left" in proc.stderr
    assert not [n for n in os.listdir(out) if n.endswith(".tmp") or n.startswith("step_")]
