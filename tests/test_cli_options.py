"""The command line's front door: every PETSc option passes through (option files included),
``python -m contactpetsc`` is the command, the console script names a real entry point,
``-help`` lists the package's own options before anything is solved, and
``import contactpetsc`` neither initialises PETSc nor pays for the solvers.

Independent truth: an option set only in a file takes effect (the SNES monitor prints its
residual norms, and does not without the file), a second process importing the package.
"""
import os
import subprocess
import sys
import textwrap
import tomllib

import pytest

ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1", OMP_NUM_THREADS="1")
CLI = [sys.executable, "-m", "contactpetsc"]
MONITOR = "SNES Function norm"


def hertz_scene(tmp_path):
    path = tmp_path / "hertz.toml"
    path.write_text(textwrap.dedent("""
        [geometry]
        kind = "sphere"
        radius = 1e-6
        nx = 16
        dx = 1e-8
        [material]
        e_star = 1e9
        [protocol]
        values = [1e-9]
        [output]
        fields = false
    """))
    return path


@pytest.mark.serial
@pytest.mark.parametrize("flag, text", [("-options_file", "-contact_snes_monitor\n"),
                                        ("-options_file_yaml", "contact_snes_monitor: \n")])
def test_petsc_option_files_pass_through_the_command_line(tmp_path, flag, text):
    scene = hertz_scene(tmp_path)
    options = tmp_path / "options"
    options.write_text(text)
    plain = subprocess.run(CLI + ["run", str(scene), "--output", str(tmp_path / "plain")],
                           env=ENV, capture_output=True, text=True, timeout=120)
    assert plain.returncode == 0, plain.stderr
    assert MONITOR not in plain.stdout
    run = subprocess.run(CLI + ["run", str(scene), "--output", str(tmp_path / "out"), flag, str(options)],
                         env=ENV, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert MONITOR in run.stdout and "unrecognized arguments" not in run.stderr
    assert "nobody used" not in run.stderr   # the file's option reached the solver


@pytest.mark.serial
def test_python_m_contactpetsc_is_the_command_and_the_console_script_names_it():
    run = subprocess.run(CLI + ["--version"], env=ENV, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "contactpetsc" in run.stdout, run.stderr
    with open(os.path.join(ROOT, "pyproject.toml"), "rb") as f:
        target = tomllib.load(f)["project"]["scripts"]["contactpetsc"]
    module, func = target.split(":")
    check = subprocess.run([sys.executable, "-c", f"import {module} as m; assert callable(m.{func})"],
                           env=ENV, capture_output=True, text=True, timeout=120)
    assert check.returncode == 0, (target, check.stderr)


@pytest.mark.serial
def test_the_package_import_is_cheap_and_its_public_names_resolve():
    code = textwrap.dedent("""
        import sys
        import contactpetsc
        assert "petsc4py" not in sys.modules and "contactpetsc.solvers" not in sys.modules
        for name in contactpetsc.__all__:
            assert getattr(contactpetsc, name) is not None, name
        print(len(contactpetsc.__all__))
    """)
    run = subprocess.run([sys.executable, "-c", code], env=ENV, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr


@pytest.mark.serial
@pytest.mark.parametrize("scene, option", [(None, "-contact_tol"),
                                           ("examples/scenes/adhesive_sphere.toml", "-adhesion_tol")])
def test_help_lists_the_package_options_of_the_scene_before_anything_is_solved(scene, option):
    # independent truth: the option table of solvers/options.py, whose names the problems read
    words = ["run"] + ([os.path.join(ROOT, scene)] if scene else []) + ["--dry-run", "-help"]
    run = subprocess.run(CLI + words, env=ENV, capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    table = "adhesion" if scene else "contact"
    assert f"contactpetsc {table} options" in run.stdout and f"  {option} <" in run.stdout, run.stdout[-2000:]


@pytest.mark.serial
@pytest.mark.parametrize("scene, option", [(None, "-contact_snes_type vinewtonssls"),
                                           ("examples/scenes/adhesive_sphere.toml", "-adhesion_ptc_snes_type newtonls")])
def test_unsupported_snes_types_are_refused_before_the_run_naming_the_option(tmp_path, scene, option):
    """The run stops before its first step (no curve.csv) with the option, the value and the
    accepted type (docs/robustness.md, "Bad input"); the other prefixes and types through the
    API: test_solver_options.py."""
    path = os.path.join(ROOT, scene) if scene else str(hertz_scene(tmp_path))
    run = subprocess.run(CLI + ["run", path, "--output", str(tmp_path / "out")] + option.split(),
                         env=ENV, capture_output=True, text=True, timeout=120)
    assert run.returncode != 0 and not (tmp_path / "out" / "curve.csv").exists()
    assert option in run.stderr and "accepted: vinewtonrsls" in run.stderr, run.stderr[-2000:]
