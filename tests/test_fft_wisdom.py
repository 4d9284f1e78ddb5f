"""FFTW plans repeat from run to run (contactpetsc/fft_wisdom.py): a measured plan is stored on
disk and the next process plans the same transform from the file without measuring; estimated
plans never take wisdom from memory."""
import os
import subprocess
import sys

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc import fft_wisdom
from contactpetsc.fft import SlabRFFT

CHILD = r"""
import sys
import pyfftw
from mpi4py import MPI
from contactpetsc import fft_wisdom
from contactpetsc.fft import SlabRFFT
if sys.argv[1] == "plan":
    SlabRFFT(MPI.COMM_SELF, 96, 80, [(0, 80)], planner="measure")
else:
    if sys.argv[1] == "load":
        fft_wisdom.load(MPI.COMM_SELF)
    a = pyfftw.empty_aligned((80, 96), "float64")
    s = pyfftw.empty_aligned((80, 49), "complex128")
    try:
        pyfftw.FFTW(a, s, axes=(0, 1), flags=("FFTW_MEASURE", "FFTW_WISDOM_ONLY"))
        print("wise")
    except RuntimeError:
        print("no wisdom")
"""


def child(tmp_path, mode):
    env = dict(os.environ, CONTACTPETSC_FFTW_WISDOM=str(tmp_path / "wisdom.dat"))
    out = subprocess.run([sys.executable, "-c", CHILD, mode], env=env, capture_output=True, text=True,
                         check=True, timeout=120)
    return out.stdout.strip()


@pytest.mark.serial
def test_a_measured_plan_is_read_back_by_the_next_process(tmp_path):
    # FFTW_WISDOM_ONLY plans only from wisdom: it fails in a process that has none
    assert child(tmp_path, "bare") == "no wisdom"
    child(tmp_path, "plan")
    assert (tmp_path / "wisdom.dat").exists()
    assert child(tmp_path, "bare") == "no wisdom"
    assert child(tmp_path, "load") == "wise"


@pytest.mark.serial
def test_off_switch_and_default_path(monkeypatch, tmp_path):
    monkeypatch.setenv(fft_wisdom.ENV, "off")
    assert fft_wisdom.wisdom_path() is None
    monkeypatch.delenv(fft_wisdom.ENV)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    path = fft_wisdom.wisdom_path()
    assert path.startswith(str(tmp_path / "contactpetsc" / "fftw-wisdom-")) and path.endswith(".dat")


def test_estimated_plans_ignore_measured_wisdom(coll):
    """An estimated transform gives the same bits before and after a measured plan of its size
    is made in the process (FFTW would otherwise take the measured plan's wisdom)."""
    comm = PETSc.COMM_WORLD.tompi4py()
    n = 256
    rows = [(r * n // comm.size, (r + 1) * n // comm.size) for r in range(comm.size)]
    ys, ye = rows[comm.rank]
    field = np.random.default_rng(3).standard_normal((n, n))[ys:ye]

    def estimated():
        fft = SlabRFFT(comm, n, n, rows, planner="estimate")
        return fft.forward(field).copy()

    before = estimated()
    SlabRFFT(comm, n, n, rows, planner="measure")
    assert coll.all(np.array_equal(estimated(), before))


@pytest.mark.serial
@pytest.mark.parametrize("kind", ["fifo", "directory"])
def test_a_wisdom_path_that_is_no_regular_file_is_left_alone_with_a_warning(tmp_path, kind):
    """A FIFO would block the read after the plan forever, a directory cannot be replaced (the
    temporary was left behind): both are warned about, named, and neither read nor written."""
    path = tmp_path / "wisdom.dat"
    os.mkfifo(path) if kind == "fifo" else path.mkdir()
    env = dict(os.environ, CONTACTPETSC_FFTW_WISDOM=str(path))
    out = subprocess.run([sys.executable, "-c", CHILD, "plan"], env=env, capture_output=True, text=True,
                         timeout=60)      # the former hang is a timeout here
    assert out.returncode == 0, out.stderr
    assert f"FFTW wisdom file {str(path)!r}" in out.stderr and f"is a {kind.replace('fifo', 'FIFO')}" in out.stderr
    assert sorted(os.listdir(tmp_path)) == ["wisdom.dat"]
    assert (path.is_fifo() if kind == "fifo" else os.listdir(path) == [])
