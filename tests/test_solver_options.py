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
    assert st.converged and pb.tol == 1e-7 and pb.newton.stall_steps == 5
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


@pytest.mark.parametrize("strategy", ["descent", "newton"])
def test_a_hard_walls_newton_krylov_method_is_the_one_its_plan_names(coll, strategy):
    """A hard wall's Newton steps take GMRES where they find the state and BiCGStab where they
    polish the energy descent's (its basis had been a scene's peak of memory): the problem
    builds what ``describe_solver`` (the plan) says, for either strategy."""
    grid = SurfaceGrid(32, 32, 1.0, periodic=True)
    h = sphere(grid, 100.0)
    prefix = f"popt_kt_{strategy}_"
    pb = AdhesiveProblem(grid, h, 1.0, HARD, prefix=prefix, petsc_options={"strategy": strategy})
    assert pb.descends == (strategy == "descent")
    built = pb.newton.snes.getKSP().getType()
    assert built == ("bcgs" if strategy == "descent" else "gmres")
    plan = describe_solver(HARD, descends=pb.descends)
    assert f"KSP {built}" in plan[1] and "fallback" not in plan[1]
    # the PTC fallback finds the state whoever polishes: GMRES either way
    assert pb.fallback.ptc.snes.getKSP().getType() == "gmres"
    assert any(line.startswith("fallback") and "KSP gmres" in line for line in plan)
    pb.destroy()


def test_the_plans_strategy_reads_the_element_integration_option(coll):
    """The strategy the plan reports is the problem's: element integration given as an option
    (not in the scene) leaves the descent out, as the problem reads it."""
    from contactpetsc.solvers.factory import adhesive_strategy
    assert adhesive_strategy("popt_ei_", {}, True, False) == "descent"
    assert adhesive_strategy("popt_ei_", {"element_integration": True}, True, False) == "newton"
    grid = SurfaceGrid(32, 32, 1.0, periodic=True)
    pb = AdhesiveProblem(grid, sphere(grid, 100.0), 1.0, HARD, prefix="popt_ei_",
                         petsc_options={"element_integration": True})
    assert not pb.descends
    pb.destroy()
    assert _left("popt_ei_") == []


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


def _rough_load(prefix, options, loads=(0.004,)):
    """(Newton steps, FFT pairs, warnings of the solver options) of load-controlled solves of a
    rough periodic 64^2 cell, with ``options`` under ``prefix``."""
    import warnings
    from contactpetsc.geometry.surfaces import self_affine
    from contactpetsc.solvers.contact_load import SolverOptionWarning
    grid = SurfaceGrid(64, 64, 1.0 / 64)
    h = self_affine(grid, hurst=0.8, seed=5, rms_slope=0.1, rolloff_wavelength=0.25, short_cutoff_wavelength=4 / 64)
    with warnings.catch_warnings(record=True) as caught, ContactProblem(grid, h, 1.0, prefix=prefix, tol=1e-9,
                                                                        petsc_options=options) as pb:
        warnings.simplefilter("always")
        states = [pb.solve(mean_pressure=p) for p in loads]
        newton, pairs = sum(s.newton_iterations for s in states), sum(s.fft_pairs for s in states)
    assert _left(prefix) == []
    return newton, pairs, [str(w.message) for w in caught if issubclass(w.category, SolverOptionWarning)]


def test_ksp_type_cg_is_the_default_load_control(coll):
    """-<prefix>ksp_type cg names the default's own method: the same Newton steps and FFT pairs
    (SNES VI resets its KSP from the database; it put plain CG in place of load control's
    projected CG, 18x the Newton steps at 128^2), and no warning."""
    default = _rough_load("popt_kdef_", {}, loads=(0.004, 0.006))
    cg = _rough_load("popt_kcg_", {"ksp_type": "cg"}, loads=(0.004, 0.006))
    assert coll.all(cg[:2] == default[:2]), (cg, default)
    assert coll.all(default[0] < 40 and not cg[2])


def test_another_ksp_type_under_load_control_warns_once_with_its_cost(coll):
    """minres cannot be the joint step's projected CG: the outer iteration runs it, at most
    7x the default's FFT pairs that the warning states (2.5x on 1 and 2 ranks, 6.3x on 3, whose
    uneven rows give other coarse levels), which rank 0 gives once, naming the
    option; -<prefix>load_joint true keeps the joint step (the default's counts)."""
    default = _rough_load("popt_kref_", {}, loads=(0.004, 0.006))
    newton, pairs, said = _rough_load("popt_kmin_", {"ksp_type": "minres"}, loads=(0.004, 0.006))
    assert coll.all(pairs <= 7 * default[1]), (pairs, default)
    rank0 = coll.comm.Get_rank() == 0
    assert coll.all(len(said) == (1 if rank0 else 0)), said
    assert coll.all(not rank0 or ("-popt_kmin_ksp_type minres" in said[0] and "7x the FFT pairs" in said[0]))
    kept = _rough_load("popt_kjoint_", {"ksp_type": "minres", "load_joint": True}, loads=(0.004, 0.006))
    assert coll.all(kept[:2] == default[:2] and not kept[2]), (kept, default)


@pytest.mark.parametrize("law, key, kind", [(None, "snes_type", "vinewtonssls"), (None, "snes_type", "newtonls"),
                                            (LJ, "snes_type", "newtonls"), (HARD, "ptc_snes_type", "vinewtonssls")],
                         ids=["contact-ssls", "contact-newtonls", "lj", "hardwall-ptc"])
def test_snes_types_other_than_vinewtonrsls_are_refused_before_anything_is_built(coll, law, key, kind):
    """The problems are variational inequalities on the reduced space (base.VI_SNES_WHY): another
    SNES type is refused with the option, its value and the accepted type, before the problem has
    a SNES, and by describe_solver (the CLI's --dry-run)."""
    grid = SurfaceGrid(16, 16, 0.25, periodic=False)
    h = sphere(grid, 20.0)
    prefix = f"popt_type_{key}_{kind}_"
    words = [f"-{prefix}{key} {kind}", "accepted: vinewtonrsls", "variational inequality"]
    pb = make_problem(grid, h, 1.0, law, prefix=prefix, petsc_options={key: kind})
    coll.raises(ValueError, words, pb.solve, approach=0.1)
    assert pb._snes is None and _left(prefix) == []
    coll.raises(ValueError, words, describe_solver, law, prefix=prefix, petsc_options={key: kind})
    assert _left(prefix) == []
