"""An error on one rank ends the whole MPI job, loudly and without deadlock."""
import os
import shutil
import subprocess
import sys
import textwrap

import pytest
from scene_files import adhesive_sphere_scene, rough_scene

SCRIPT = textwrap.dedent("""
    import sys, petsc4py; petsc4py.init(sys.argv)
    from petsc4py import PETSc
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.geometry import surfaces
    from contactpetsc.solvers import ContactProblem, preconditioners

    def inner(self, f, out):   # a fault on rank 1 only, in the middle of a Krylov solve
        if PETSc.COMM_WORLD.getRank() == 1:
            raise RuntimeError("injected fault on rank 1")
        out[...] = f
        return out

    preconditioners.SpectralPC.inner = inner
    g = SurfaceGrid(32, 32, 1e-6, periodic=False)
    ContactProblem(g, surfaces.sphere(g, 1e-4), 1e9).solve(approach=1e-9)
    print("NOT REACHED")
""")


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_fault_on_one_rank_aborts_the_job(tmp_path):
    script = tmp_path / "fault.py"
    script.write_text(SCRIPT)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    proc = subprocess.run(["mpirun", "-n", "2", sys.executable, str(script)], env=env,
                          capture_output=True, text=True, timeout=120)
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "NOT REACHED" not in out
    assert "[rank 1]" in out and "injected fault on rank 1" in out


# -- the command line: faults, bad input, unused options, a killed sweep ------------------------------
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1")
CLI = [sys.executable, "-m", "contactpetsc"]

CLI_FAULT = textwrap.dedent("""
    import sys
    from mpi4py import MPI
    from contactpetsc.app import builder, cli

    build = builder.build_heights
    def build_heights(scene, grid, *rest):   # a fault on rank 1 only, while the others go on to solve
        if MPI.COMM_WORLD.Get_rank() == 1:
            raise OSError("injected fault on rank 1")
        return build(scene, grid, *rest)

    builder.build_heights = build_heights
    sys.exit(cli.main(sys.argv[1:]))
""")


def mpirun(n, args, timeout=120):
    return subprocess.run(["mpirun", "-n", str(n)] + args, env=ENV, capture_output=True, text=True,
                          timeout=timeout)


needs_mpirun = pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@needs_mpirun
def test_cli_fault_on_one_rank_aborts_the_job(tmp_path):
    """The command line's own path: rank 1 fails while rank 0 enters the solve; no hang."""
    script = tmp_path / "cli_fault.py"
    script.write_text(CLI_FAULT)
    scene = rough_scene(tmp_path / "s.toml", tmp_path / "out")
    proc = mpirun(2, [sys.executable, str(script), "run", scene])
    out = proc.stdout + proc.stderr
    assert proc.returncode != 0
    assert "contactpetsc [rank 1]: error: injected fault on rank 1" in out


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@needs_mpirun
def test_cli_more_ranks_than_grid_rows(tmp_path):
    """ny = 2 on 3 ranks: the job ends with the message naming the rows and the ranks."""
    scene = rough_scene(tmp_path / "s.toml", tmp_path / "out", nx=8, ny=2)
    proc = mpirun(3, CLI + ["run", scene])
    assert proc.returncode != 0
    assert "3 MPI ranks but only ny = 2 grid rows" in proc.stderr


@pytest.mark.serial
def test_cli_reports_unused_petsc_options(tmp_path):
    """A misspelt option is named at the end of the run; a used one is not; -options_left too."""
    scene = rough_scene(tmp_path / "s.toml", tmp_path / "out", nx=16, values=(5e6,))
    proc = subprocess.run(CLI + ["run", scene, "-contact_snes_monitr", "-contact_ksp_type", "cg"],
                          env=ENV, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert "PETSc options nobody used" in proc.stderr and "-contact_snes_monitr" in proc.stderr
    assert "ksp_type" not in proc.stderr
    proc = subprocess.run(CLI + ["run", scene, "--overwrite", "-contact_snes_monitr", "-options_left"],
                          env=ENV, capture_output=True, text=True, timeout=120)
    assert "Option left: name:-contact_snes_monitr" in proc.stdout


@pytest.mark.serial
def test_sweep_killed_mid_step_resumes_without_losing_steps(tmp_path):
    """SIGKILL once the first step is on disk (in the middle of a later one); every step in
    curve.csv has its field file, and --restart completes the sweep with the uninterrupted run's
    results."""
    import csv
    import signal
    import time

    values = [5e6 * k for k in range(1, 9)]
    full = rough_scene(tmp_path / "full.toml", tmp_path / "full", nx=128, values=values)
    subprocess.run(CLI + ["run", full], env=ENV, capture_output=True, timeout=300, check=True)
    out = tmp_path / "cut"
    cut = rough_scene(tmp_path / "cut.toml", out, nx=128, values=values)
    proc = subprocess.Popen(CLI + ["run", cut], env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    curve = out / "curve.csv"

    def rows(path):
        with open(path) as f:
            return list(csv.DictReader(f))

    t0 = time.time()
    while not (curve.exists() and len(rows(curve)) >= 1) and time.time() - t0 < 120:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    kept = rows(curve)
    assert 1 <= len(kept) < len(values), "the run was not killed mid-sweep"
    for r in kept:      # a step in the curve has its complete field file
        assert (out / f"step_{int(r['step']):04d}.h5").exists()
    proc = subprocess.run(CLI + ["run", cut, "--restart"], env=ENV, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    assert f"restart: {len(kept)} of {len(values)} steps already done" in proc.stdout
    resumed, ref = rows(curve), rows(tmp_path / "full" / "curve.csv")
    assert [r["step"] for r in resumed] == [str(k) for k in range(1, len(values) + 1)]
    for a, b in zip(resumed, ref):
        assert float(a["approach_m"]) == pytest.approx(float(b["approach_m"]), rel=1e-8)
        assert float(a["mean_pressure_Pa"]) == pytest.approx(float(b["mean_pressure_Pa"]), rel=1e-9)


@pytest.mark.serial
def test_time_budget_ends_a_sweep_loudly_and_restart_completes_it(tmp_path):
    """``-adhesion_time_budget`` ends an adhesive sweep at a step with WALL_TIME_BUDGET: exit
    code 3 and a message naming the step, its reason and --restart; the steps before it are
    written, and --restart completes the run with the uninterrupted run's forces and keeps
    the jumps found before the stop (jumps.csv) and the uninterrupted run's pull-off force
    (summary.json: the most tensile stable state of the whole path, not of the restarted part)."""
    import json
    import csv
    full, cut = tmp_path / "full", tmp_path / "cut"
    scene = adhesive_sphere_scene(tmp_path / "s.toml", tmp_path / "out")    # the example on a 10-step path

    def rows(path):
        with open(path) as f:
            return list(csv.DictReader(f))

    subprocess.run(CLI + ["run", scene, "--output", str(full)], env=ENV, capture_output=True, timeout=300,
                   check=True)
    proc = subprocess.run(CLI + ["run", scene, "--output", str(cut), "-adhesion_time_budget", "0.3"], env=ENV,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 3, proc.stdout + proc.stderr
    assert "NOT CONVERGED: WALL_TIME_BUDGET" in proc.stdout and "continue with --restart" in proc.stdout
    ref = rows(full / "curve.csv")
    kept = rows(cut / "curve.csv") if (cut / "curve.csv").exists() else []
    assert len(kept) < len(ref)
    proc = subprocess.run(CLI + ["run", scene, "--output", str(cut), "--restart"], env=ENV,
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    resumed = rows(cut / "curve.csv")
    assert [r["step"] for r in resumed] == [r["step"] for r in ref]
    for a, b in zip(resumed, ref):
        assert float(a["force_N"]) == pytest.approx(float(b["force_N"]), rel=1e-5, abs=1e-12)
    assert [r["kind"] for r in rows(cut / "jumps.csv")] == [r["kind"] for r in rows(full / "jumps.csv")]
    pull = [json.load(open(d / "summary.json"))["pull_off_force_N"] for d in (cut, full)]
    assert pull[0] == pytest.approx(pull[1], rel=1e-6)
