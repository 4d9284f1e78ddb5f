"""PETSc-native options of the problems: ``petsc_options`` reach the solver under the prefix and
nothing is left in the global options database after a build or a solve (the database itself is
the truth); the factory picks the stack by law and method; options the convergence test would
ignore are refused; snapshots free themselves."""
import pytest
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers.factory import describe_solver, make_problem
from contactpetsc.solvers.problem import ContactProblem
from contactpetsc.solvers.relaxation import RelaxationSolver
from contactpetsc.geometry.surfaces import sphere

LJ = make_law("lj", work_of_adhesion=0.05, z0=0.5)
HARD = make_law("hardwall-lj", work_of_adhesion=0.05, z0=0.5)


def _left(prefix):
    return sorted(k for k in PETSc.Options().getAll() if k.startswith(prefix))


def test_contact_options_applied_then_removed(coll):
    grid = SurfaceGrid(32, 32, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    prefix = "popt_contact_"
    with ContactProblem(grid, h, 1.0, prefix=prefix,
                        petsc_options={"tol": 1e-9, "ksp_type": "gmres", "-snes_max_it": 40}) as pb:
        st = pb.solve(approach=1.0)
        assert st.converged and st.complementarity_error <= 1e-9
        assert pb.tol == 1e-9
        assert pb.solver.getKSP().getType() == "gmres"
        assert pb.solver.getTolerances()[3] == 40
        assert pb.x.getSize() == grid.nx * grid.ny and pb.J.getSize()[0] == grid.nx * grid.ny
        assert _left(prefix) == []


def test_command_line_option_wins_and_stays(coll):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    prefix = "popt_cmd_"
    PETSc.Options().setValue(prefix + "ksp_type", "gmres")
    try:
        pb = ContactProblem(grid, h, 1.0, prefix=prefix, petsc_options={"ksp_type": "bcgs"})
        pb.solve(approach=0.5)
        assert pb.solver.getKSP().getType() == "gmres"
        assert _left(prefix) == [prefix + "ksp_type"]
        pb.destroy()
    finally:
        PETSc.Options().delValue(prefix + "ksp_type")


@pytest.mark.parametrize("law", [LJ, HARD], ids=["lj", "hardwall-lj"])
def test_adhesive_options_applied_then_removed(coll, law):
    grid = SurfaceGrid(32, 32, 0.25, periodic=False)
    h = sphere(grid, 20.0)
    prefix = f"popt_{law.name.replace('-', '_')}_"
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix, petsc_options={"tol": 1e-7, "stall_steps": 5})
    st = pb.solve(approach=0.2)
    assert st.converged and pb.tol == 1e-7 and pb.stall_steps == 5
    with pb.snapshot() as snap:
        assert snap.x.getSize() == pb.x.getSize() and snap.approach == pytest.approx(0.2)
    assert snap.x is None                         # freed by the context manager
    assert _left(prefix) == []
    pb.destroy()


def test_snes_norm_tolerances_are_refused(coll):
    grid = SurfaceGrid(16, 16, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    pb = ContactProblem(grid, h, 1.0, prefix="popt_rtol_", petsc_options={"snes_rtol": 1e-3})
    coll.raises(ValueError, ["-popt_rtol_snes_rtol", "-popt_rtol_tol"], pb.solve, approach=0.5)
    assert _left("popt_rtol_") == []


def test_factory_picks_the_stack(coll):
    grid = SurfaceGrid(16, 16, 0.25, periodic=False)
    h = sphere(grid, 20.0)
    assert type(make_problem(grid, h, 1.0)) is ContactProblem
    assert type(make_problem(grid, h, 1.0, make_law("none"))) is ContactProblem
    ad = make_problem(grid, h, 1.0, LJ, prefix="popt_f_", tol=1e-6)
    assert type(ad) is AdhesiveProblem and ad.prefix == "popt_f_"
    relax = make_problem(grid, h, 1.0, HARD, method="relaxation", tol=1e-3)
    assert isinstance(relax, RelaxationSolver) and relax.tol == 1e-3 and relax.problem.prefix == "adhesion_"
    assert isinstance(make_problem(grid, h, 1.0, LJ, method="relaxation", prefix="popt_r_"), RelaxationSolver)
    with pytest.raises(ValueError, match="nodal rule"):
        make_problem(grid, h, 1.0, LJ, method="relaxation", prefix="popt_e_", element_integration=True)
    with pytest.raises(ValueError, match="method"):
        make_problem(grid, h, 1.0, LJ, method="guess")


def test_describe_solver_reports_types_and_prefixes(coll):
    lines = describe_solver(None, petsc_options={"ksp_type": "gmres"}, prefix="popt_d_")
    text = "\n".join(lines)
    assert "vinewtonrsls" in text and "-popt_d_" in text and "KSP gmres" in text
    assert "contactpetsc.solvers.SpectralPC" in text
    text = "\n".join(describe_solver(LJ))
    assert "KSP bcgs" in text and "line search basic" in text and "-adhesion_ptc_" in text
    assert "KSP gmres" in "\n".join(describe_solver(HARD))
    # auto (the adhesive default) names its pick on the finest grid from the snap number given
    stiff, soft = "\n".join(describe_solver(HARD, snap=0.1)), "\n".join(describe_solver(HARD, snap=0.5))
    assert "preconditioner auto" in stiff and "-> mlmi" in stiff and "AdhesiveMLMIPC" in stiff
    assert "-> spectral" in soft and "AdhesivePC" in soft and "-> mlmi" in "\n".join(describe_solver(LJ, snap=0.3))
    assert "-> spectral" in "\n".join(describe_solver(LJ, snap=0.1))
    assert _left("popt_d_") == [] and not any(k.startswith("adhesion_") for k in PETSc.Options().getAll())


def test_option_tables_in_the_docs_are_generated():
    """docs/formulation.md's option tables are the registry's (``solvers.options``)."""
    import os
    from contactpetsc.solvers.options import options_markdown
    with open(os.path.join(os.path.dirname(__file__), "..", "docs", "formulation.md")) as f:
        text = f.read()
    for table in ("contact", "adhesion"):
        assert options_markdown(table) in text, f"regenerate the {table} table from options_markdown()"


def test_help_lists_the_package_options(coll, capfd):
    grid = SurfaceGrid(16, 16, 0.25, periodic=False)
    h = sphere(grid, 20.0)
    opts = PETSc.Options()
    opts.setValue("help", None)
    try:
        ContactProblem(grid, h, 1.0, prefix="popt_help_c_").snes()
        AdhesiveProblem(grid, h, 1.0, LJ, prefix="popt_help_a_").snes()
    finally:
        opts.delValue("help")
    out = capfd.readouterr().out
    if coll.comm.Get_rank() == 0:
        for name in ("-popt_help_c_tol", "-popt_help_c_load_tol", "-popt_help_a_stall_steps",
                     "-popt_help_a_fallback", "-popt_help_a_time_budget"):
            assert name in out


@pytest.mark.parametrize("choice", ["spectral", "mlmi"])
def test_views_name_the_python_contexts(coll, shared_tmp, choice):
    """-snes_view of a solved problem shows the Mat and PC contexts (kernel, set, levels)."""
    grid = SurfaceGrid(32, 32, 1.0, periodic=False)
    h = sphere(grid, 100.0)
    pb = ContactProblem(grid, h, 1.0, prefix=f"popt_view_{choice}_", preconditioner=choice)
    pb.solve(approach=1.0)
    path = str(shared_tmp / f"view_{choice}.txt")
    viewer = PETSc.Viewer().createASCII(path, comm=grid.comm)
    pb.solver.view(viewer)
    pb.J.view(viewer)
    viewer.destroy()
    coll.comm.Barrier()
    with open(path) as f:
        text = f.read()
    assert "ContactJacobian" in text and "K_ii" in text and "inactive nodes" in text
    assert ("SpectralPC" in text) if choice == "spectral" else ("levels" in text and "MLMIPC" in text)
    pb.destroy()
    lj = AdhesiveProblem(SurfaceGrid(32, 32, 0.25, periodic=False), sphere(SurfaceGrid(32, 32, 0.25, periodic=False),
                                                                         20.0), 1.0, LJ, prefix=f"popt_view_lj_{choice}_",
                         preconditioner=choice)
    lj.solve(approach=0.2)
    path = str(shared_tmp / "view_lj.txt")
    viewer = PETSc.Viewer().createASCII(path, comm=lj.grid.comm)
    lj.solver.view(viewer)
    viewer.destroy()
    coll.comm.Barrier()
    with open(path) as f:
        text = f.read()
    assert ("AdhesivePC" in text) if choice == "spectral" else ("AdhesiveMLMIPC" in text and "levels" in text)
