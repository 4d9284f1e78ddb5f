"""An error on one rank ends the whole MPI job, loudly and without deadlock."""
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import sys, petsc4py; petsc4py.init(sys.argv)
    from petsc4py import PETSc
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc import surfaces
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
