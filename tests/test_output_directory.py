"""One run per output directory: a running run's directory is locked against a second process;
a directory holding another run is refused unless --restart or --overwrite says what to do,
and --overwrite removes that run's files only."""
import os
import subprocess
import sys
import time

import pytest
from scene_files import rough_scene
from petsc4py import PETSc

from contactpetsc.app import runner, scenes
from contactpetsc.app.rundir import LOCK, RunDirectoryError

ENV = dict(os.environ, OMP_NUM_THREADS="1")
CLI = [sys.executable, "-m", "contactpetsc"]


def scene_file(path, out, values, nx=32):
    return rough_scene(path, out, nx=nx, values=values)


def run(args):
    return subprocess.run(CLI + list(args), env=ENV, capture_output=True, text=True, timeout=600)


@pytest.mark.serial
def test_a_running_run_locks_its_directory_against_a_second_process(tmp_path):
    out = tmp_path / "out"
    long = scene_file(tmp_path / "long.toml", out, [2e6 + 1e3 * k for k in range(3000)], nx=128)
    first = subprocess.Popen(CLI + ["run", long], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
    try:
        t0 = time.time()
        while not (out / "curve.csv").exists() and time.time() - t0 < 120:
            time.sleep(0.01)
        assert (out / LOCK).exists()
        for flags in ([], ["--restart"], ["--overwrite"]):
            second = run(["run", long] + flags)
            assert second.returncode == 1, second.stdout + second.stderr
            assert "is in use by another run" in second.stderr and f"process {first.pid}" in second.stderr
            assert first.poll() is None          # the first run goes on
    finally:
        first.kill()
        first.wait()
    # the first run was killed: its stale lock is taken over, with a note
    third = run(["run", scene_file(tmp_path / "short.toml", out, [2e6, 3e6], nx=16), "--overwrite"])
    assert third.returncode == 0, third.stdout + third.stderr
    assert "took over the lock" in third.stdout and f"process {first.pid}" in third.stdout
    assert not (out / LOCK).exists()             # released at the end


@pytest.mark.serial
def test_another_runs_directory_is_refused_unless_overwrite(tmp_path):
    """A 3-step run, then a 2-step run of another scene into the same directory: refused
    without a flag (nothing touched); --overwrite leaves the new run's files only (no stale
    step_0003 of the old scene) and keeps files that are not a run's."""
    out = tmp_path / "out"
    cli_ok = run(["run", scene_file(tmp_path / "a.toml", out, [5e6, 1e7, 2e7]), "--plots"])
    assert cli_ok.returncode == 0, cli_ok.stderr
    (out / "notes.txt").write_text("mine")
    before = sorted(os.listdir(out))
    other = scene_file(tmp_path / "b.toml", out, [3e6, 6e6])
    refused = run(["run", other])
    assert refused.returncode == 1
    assert "holds another run" in refused.stderr
    assert "--restart" in refused.stderr and "--overwrite" in refused.stderr
    assert sorted(os.listdir(out)) == before
    both = run(["run", other, "--restart", "--overwrite"])
    assert both.returncode == 1 and "give one of them" in both.stderr
    done = run(["run", other, "--overwrite"])
    assert done.returncode == 0, done.stderr
    assert sorted(os.listdir(out)) == sorted(["curve.csv", "history.csv", "summary.json", "scene.json",
                                              "notes.txt", "fields.xdmf", "step_0001.h5", "step_0001.xdmf",
                                              "step_0002.h5", "step_0002.xdmf"])
    assert (out / "notes.txt").read_text() == "mine"


def test_a_second_run_into_a_run_directory_is_refused_on_every_rank(coll, shared_tmp):
    s = scenes.validate({"geometry": {"kind": "sphere", "radius": 1e-6, "nx": 16, "dx": 1e-8},
                         "material": {"e_star": 1e9}, "protocol": {"values": [1e-9, 2e-9]},
                         "output": {"directory": str(shared_tmp / "run")}})
    runner.run(s, comm=PETSc.COMM_WORLD)
    coll.raises(RunDirectoryError, ["holds another run", "curve.csv"], runner.run, s, comm=PETSc.COMM_WORLD)
    assert not (shared_tmp / "run" / LOCK).exists()
    states = runner.run(s, comm=PETSc.COMM_WORLD, overwrite=True)
    assert len(states) == 2 and coll.all(all(st.converged for st in states))
