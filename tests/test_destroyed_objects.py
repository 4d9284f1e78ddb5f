"""A PETSc user who destroys the grid's DMDA or the heights Vec before the last solve gets a
Python error naming the object (``SurfaceGrid.check_vec``, checked at every problem's entry
points), not PETSc's segmentation fault (error 59) or a reshape error; on every rank.

Run in subprocesses: a segmentation fault must fail the test, not kill pytest."""
import os
import shutil
import subprocess
import sys
import textwrap

import pytest

SCRIPT = textwrap.dedent("""
    import sys, petsc4py; petsc4py.init(sys.argv[:1])
    from petsc4py import PETSc
    from contactpetsc.grid import GridError, SurfaceGrid
    from contactpetsc.geometry.surfaces import sphere
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers import ContactProblem
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    from contactpetsc.solvers.relaxation import RelaxationSolver

    def case(kind, obj, when):
        g = SurfaceGrid(16, 16, 0.5, periodic=False)
        h = sphere(g, 50.0)
        def make():
            if kind == "contact":
                return ContactProblem(g, h, 1.0)
            return AdhesiveProblem(g, h, 1.0, make_law("hardwall-lj", work_of_adhesion=0.05, z0=1.0))
        pb = make() if when == "after" else None
        (g.da if obj == "da" else h).destroy()
        pb = pb or make()
        (RelaxationSolver(pb) if kind == "relaxation" else pb).solve(approach=0.5)

    cases = [c.split(":") for c in sys.argv[1:]]
    for c in cases[:-1]:
        try:
            case(*c)
            said = "solved"
        except GridError as exc:
            said = str(exc)
        for line in PETSc.COMM_WORLD.tompi4py().gather(said) or []:     # every rank's verdict
            print(":".join(c), line)
    case(*cases[-1])        # uncaught: the exit code of a Python error
""")
CASES = ["contact:da:before", "contact:heights:before", "contact:heights:after", "adhesive:da:after",
         "adhesive:heights:after", "relaxation:heights:after", "contact:da:after"]
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1")


def check(out, ranks):
    text = out.stdout + out.stderr
    assert out.returncode == 1, f"exit code {out.returncode} (negative: a signal; 59: PETSc's SEGV)\n{text}"
    lines = [line for line in out.stdout.splitlines() if line.split(" ")[0] in CASES]
    for c in CASES[:-1]:
        said = [line for line in lines if line.startswith(c + " ")]
        assert len(said) == ranks, f"{c}: {len(said)} verdicts on {ranks} ranks\n{text}"
        what = "the grid's DMDA was destroyed (grid.da.destroy())" if ":da:" in c else "heights was destroyed"
        assert all(what in line for line in said), f"{c}: {said}"
    assert "GridError: the grid's DMDA was destroyed" in out.stderr


@pytest.mark.serial
def test_destroyed_dmda_or_heights_is_a_python_error_naming_it(tmp_path):
    script = tmp_path / "destroyed.py"
    script.write_text(SCRIPT)
    check(subprocess.run([sys.executable, str(script)] + CASES, env=dict(ENV, PYTHONPATH=os.getcwd()),
                         capture_output=True, text=True, timeout=120), 1)


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@pytest.mark.skipif(shutil.which("mpirun") is None, reason="needs mpirun")
def test_destroyed_dmda_or_heights_is_refused_on_every_rank(tmp_path):
    script = tmp_path / "destroyed.py"
    script.write_text(SCRIPT)
    check(subprocess.run(["mpirun", "-n", "2", sys.executable, str(script)] + CASES,
                         env=dict(ENV, PYTHONPATH=os.getcwd()), capture_output=True, text=True, timeout=120), 2)
