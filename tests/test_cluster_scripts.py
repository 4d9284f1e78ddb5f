"""The SLURM sweep job, run here with stand-ins for srun and squeue: it takes the Python of the
environment it starts in, prints the stack, passes PETSc options through, and a resubmission
continues the run in its output directory with --restart."""
import csv
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from scene_files import rough_scene

SWEEP = Path(__file__).resolve().parents[1] / "run_scripts" / "cluster" / "sweep.slurm"


def _stand_in(path: Path, body: str) -> None:
    path.write_text("#!/bin/bash\n" + body + "\n")
    path.chmod(path.stat().st_mode | stat.S_IEXEC)


@pytest.mark.serial
def test_the_sweep_job_prints_the_stack_passes_options_and_resumes_on_resubmission(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _stand_in(bin_dir / "srun", 'while [[ "$1" == --* ]]; do shift; done; exec "$@"')   # one task, here
    _stand_in(bin_dir / "squeue", 'echo "1:00:00"')                                     # an hour left
    # the environment's Python: the one running these tests, first on PATH as python3
    _stand_in(bin_dir / "python3", f'exec "{sys.executable}" "$@"')
    out = tmp_path / "run"
    scene = rough_scene(tmp_path / "scene.toml", out)
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_COMM_WORLD", "PMI", "PMIX"))}
    env.update(PATH=f"{bin_dir}:{env['PATH']}", SLURM_JOB_ID="42", SLURM_NTASKS="1", SCENE=scene, OUT=str(out),
               PYTHONPATH=str(Path(__file__).resolve().parents[1]))

    def submit():
        return subprocess.run(["bash", str(SWEEP), "-contact_snes_monitor"], env=env, capture_output=True,
                              text=True, timeout=300, cwd=tmp_path)

    first = submit()
    assert first.returncode == 0, first.stdout + first.stderr
    assert "PETSc index bits" in first.stdout and "parallel HDF5" in first.stdout   # the stack
    assert "SNES Function norm" in first.stdout                                   # the option reached PETSc
    assert "--restart" not in first.stdout.splitlines()[0]
    with open(out / "curve.csv") as f:
        rows = list(csv.DictReader(f))
    assert [int(r["step"]) for r in rows] == [1, 2]

    second = submit()                                        # the next allocation
    assert second.returncode == 0, second.stdout + second.stderr
    assert "--restart" in second.stdout
    assert "SNES Function norm" not in second.stdout         # nothing left to solve
    with open(out / "curve.csv") as f:
        assert list(csv.DictReader(f)) == rows


MODEL = Path(__file__).resolve().parents[1] / "run_scripts" / "cluster" / "model.slurm"


@pytest.mark.serial
def test_the_model_job_calibrates_measures_and_predicts(tmp_path):
    """The model job with a stand-in srun on one task: the calibration (FFT rate, copy rate, the
    apply beside its model), the benchmark solve, the model beside it, and the predictions."""
    import json
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    _stand_in(bin_dir / "srun", 'while [[ "$1" == --* ]]; do shift; done; exec "$@"')
    _stand_in(bin_dir / "python3", f'exec "{sys.executable}" "$@"')
    out = tmp_path / "model"
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_COMM_WORLD", "PMI", "PMIX"))}
    env.update(PATH=f"{bin_dir}:{env['PATH']}", SLURM_JOB_ID="7", SLURM_NTASKS="1", SIZES="64", CAL_N="64",
               PX="1", OUT=str(out), REPO=str(MODEL.parents[2]), PYTHONPATH=str(MODEL.parents[2]))
    run = subprocess.run(["bash", str(MODEL)], env=env, capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert run.returncode == 0, run.stdout + run.stderr
    cal = json.loads((out / "calibration.jsonl").read_text().splitlines()[0])
    assert cal["ranks"] == 1 and cal["k_fft"] > 0 and cal["b_core"] > 0
    assert cal["apply"]["1x1"]["measured"] > 0 and cal["apply"]["1x1"]["model"] > 0
    solve = json.loads((out / "solves.jsonl").read_text().splitlines()[0])
    assert solve["n"] == 64 and solve["converged"] and solve["px"] == 1
    assert "| 64 | 1 | 1 |" in (out / "check.md").read_text()
    predicted = (out / "predict.md").read_text()
    assert "| 8192 | 1024 |" in predicted and "| 16384 | 16 |" in predicted
