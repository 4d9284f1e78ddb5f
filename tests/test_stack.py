"""The stack checks speak before a solve: a petsc4py of another PETSc, complex or single-precision
scalars, MPI libraries that disagree on the job, and a serial h5py under mpirun are refused with
the fix named; ``contactpetsc info`` and ``--version`` print the stack and the citation."""
import os
import subprocess
import sys

import numpy as np
import pytest

from contactpetsc import stack
from contactpetsc.app import runner, scenes
from contactpetsc.stack import StackError


def test_a_petsc4py_of_another_petsc_is_refused_naming_both_and_the_fix():
    with pytest.raises(StackError, match=r"petsc4py 3\.24\.0 is running against the PETSc library 3\.18\.5.*"
                                         r"petsc4py==3\.18\.\*.*PETSC_DIR"):
        stack.check_petsc("3.24.0", (3, 18, 5))
    stack.check_petsc("3.18.1", (3, 18, 5))            # micro versions may differ
    stack.check_petsc("3.21.0rc1", (3, 21, 0))


@pytest.mark.parametrize("scalar, real, name", [(np.complex128, np.float64, "complex128"),
                                                (np.float32, np.float32, "float32")])
def test_scalars_other_than_real_double_are_refused(scalar, real, name):
    with pytest.raises(StackError, match=f"{name} scalars.*--with-scalar-type=real --with-precision=double"):
        stack.check_petsc("3.18.5", (3, 18, 5), scalar=scalar, real=real)


def test_the_running_stack_passes_its_own_checks():
    from mpi4py import MPI
    from petsc4py import PETSc
    stack.check_petsc()
    stack.check_mpi(PETSc.COMM_WORLD.getSize(), MPI.COMM_WORLD.Get_size(), stack.launcher_size())


def test_mpi_libraries_that_disagree_on_the_job_are_refused():
    with pytest.raises(StackError, match="PETSc sees 2 MPI rank.*mpi4py sees 1.*rebuild mpi4py"):
        stack.check_mpi(2, 1, 2)
    with pytest.raises(StackError, match="launcher started 4 processes but each sees a job of 1 rank"):
        stack.check_mpi(1, 1, 4)
    stack.check_mpi(1, 1, None)
    stack.check_mpi(3, 3, 3)


def test_the_launcher_size_is_read_from_the_launchers_environment():
    assert stack.launcher_size({"OMPI_COMM_WORLD_SIZE": "3"}) == 3
    assert stack.launcher_size({"PMI_SIZE": "8"}) == 8
    assert stack.launcher_size({"SLURM_NTASKS": "16"}) is None   # the allocation, not this job
    assert stack.launcher_size({}) is None


def test_a_serial_h5py_under_mpirun_is_refused_with_the_fix():
    with pytest.raises(StackError, match=r"from 2 ranks.*serial.*python3-h5py-mpi.*HDF5_MPI=ON.*"
                                         r"output\.fields = false"):
        stack.check_parallel_output(2, True, has_mpi=False)
    stack.check_parallel_output(1, True, has_mpi=False)       # one rank writes serially
    stack.check_parallel_output(2, False, has_mpi=False)      # no field files
    stack.check_parallel_output(2, True, has_mpi=True)


def test_a_serial_h5py_is_refused_before_the_first_solve(coll, shared_tmp, monkeypatch):
    """Under mpirun a run that writes fields stops before anything is solved or written; on one
    rank the same scene runs."""
    monkeypatch.setattr(stack, "h5py_has_mpi", lambda: False)
    scene = scenes.validate({**scenes.DEFAULT_SCENE, "geometry": {**scenes.DEFAULT_SCENE["geometry"], "nx": 32,
                                                                  "dx": 2e-7}})
    out = os.path.join(shared_tmp, "run")
    if coll.size > 1:
        coll.raises(StackError, "serial", runner.run, scene, output=out)
        assert coll.all(not os.path.exists(os.path.join(out, "curve.csv")))
        coll.raises(StackError, "serial", runner.run, scene, output=out, dry_run=True)
    else:
        states = runner.run(scene, output=out)
        assert len(states) == len(scene["protocol"]["values"]) and all(st.converged for st in states)


@pytest.mark.serial
def test_info_and_version_print_the_stack_and_the_citation():
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_COMM_WORLD", "PMI", "PMIX"))}
    info = subprocess.run([sys.executable, "-m", "contactpetsc", "info"], capture_output=True, text=True,
                          env=env, timeout=120)
    assert info.returncode == 0, info.stderr
    lines = dict(line.split(": ", 1) for line in info.stdout.splitlines())
    from petsc4py import PETSc
    assert lines["PETSc"] == "%d.%d.%d" % PETSc.Sys.getVersion()
    assert int(lines["PETSc index bits"]) == 8 * PETSc.IntType(0).itemsize
    assert lines["MPI ranks"] == "1"
    assert lines["FFTW"].startswith("fftw-3")
    for key in ("petsc4py", "mpi4py", "MPI", "h5py", "HDF5", "parallel HDF5", "PETSC_DIR"):
        assert lines[key]
    assert "doi:10.1016/j.ijsolstr.2014.03.033" in lines["cite"]
    version = subprocess.run([sys.executable, "-m", "contactpetsc", "--version"], capture_output=True, text=True,
                             env=env, timeout=120)
    assert version.returncode == 0 and "Medina" in version.stdout and "PETSc index bits" in version.stdout
