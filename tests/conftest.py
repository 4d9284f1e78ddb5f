"""pytest set-up for contactpetsc's tests, serially and under ``mpirun -n N``.

Every rank runs every test.  Assertions must therefore be collective: compute
the error on each rank, reduce it over COMM_WORLD (``Collective.max``,
``Collective.all``) and assert the reduced value on every rank.  Tests that only
make sense on one rank, or whose MPI behaviour other tests check under mpirun, are marked
``@pytest.mark.serial`` and skipped under MPI; on more than two ranks the ``heavy`` tests and
the modules of ``TWO_RANK_MODULES`` (scenes, paths, studies) are skipped too: that pass is for
uneven grid splits.
A test that fails on some ranks only (a non-collective assertion or exception)
leaves the others in a collective: the failed rank then aborts the job after
``CONTACTPETSC_LONE_FAILURE_WAIT`` seconds (default 120) with its failure printed,
instead of a silent hang to the stage's time limit.
"""
import shutil
import os
import sys
import tempfile
import time
from pathlib import Path

import petsc4py

# the test session is an entry point: initialise PETSc before anything imports it
petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

WORLD = PETSc.COMM_WORLD.tompi4py()
#: the test harness's own synchronisation: a communicator of its own, so that its barrier can
#: never be matched with a collective that a test left unfinished on another rank
STEP = WORLD.Dup()

if WORLD.Get_size() > 1:
    # pytest prunes old numbered temp dirs under one root per user: give each rank its own
    _root = os.path.join(tempfile.gettempdir(), f"contactpetsc-pytest-rank{WORLD.Get_rank()}")
    os.makedirs(_root, exist_ok=True)
    os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", _root)


@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    _session_config.append(config)
    config.addinivalue_line(
        "markers", "serial: only meaningful on one MPI rank, or its MPI behaviour is checked by other tests under "
        "mpirun (its comment names them) (skipped when COMM_WORLD has > 1 rank)")
    config.addinivalue_line(
        "markers", "heavy: long adhesive paths and study runs, checked on 1 and 2 ranks (skipped on more, to keep the "
        "suite short; the 3-rank pass is for uneven splits, covered by the lighter tests)")
    config.addinivalue_line(
        "markers", "mpirun: launches mpirun jobs as subprocesses (run_scripts/test.sh runs these alone: their "
        "ranks need every core; sharing the cores with another session made them 5-10x slower)")
    if WORLD.Get_rank() != 0:
        # ranks != 0 run the same tests and reach the same collective verdicts: keep them quiet
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            config.pluginmanager.unregister(reporter, "terminalreporter")


#: run_scripts/test.sh's 1-rank pass as two sessions side by side, one core each:
#: ``CONTACTPETSC_TEST_GROUP=b`` keeps the tests of these modules (about half of that pass's
#: time; whole modules, so that a fixture shared by a module's tests is computed in one session),
#: ``a`` deselects them (and keeps everything else the markers select)
GROUP_B_MODULES = {
    "test_studies", "test_stability_auto", "test_adhesive_paths", "test_adhesive_sphere",
    "test_pull_off_and_jumps", "test_unit_scales", "test_plots_results", "test_robustness",
    "test_axisymmetric_reference", "test_restart", "test_descent",
}
GROUP = os.environ.get("CONTACTPETSC_TEST_GROUP", "")


def _in_group_b(item) -> bool:
    return item.path.stem in GROUP_B_MODULES


@pytest.hookimpl(trylast=True)   # after -m and -k have deselected theirs
def pytest_collection_modifyitems(config, items):
    if GROUP:
        if GROUP not in ("a", "b"):
            raise pytest.UsageError(f"CONTACTPETSC_TEST_GROUP={GROUP!r}: expected a or b")
        keep = [t for t in items if _in_group_b(t) == (GROUP == "b")]
        config.hook.pytest_deselected(items=[t for t in items if _in_group_b(t) != (GROUP == "b")])
        items[:] = keep
    if WORLD.Get_size() > 1:
        skip = pytest.mark.skip(reason="serial test, COMM_WORLD has several ranks")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)
    if WORLD.Get_size() > 2:
        skip = pytest.mark.skip(reason="heavy test: run on 1 and 2 ranks")
        skip_module = pytest.mark.skip(reason="scene, path and study tests run on 1 and 2 ranks; the pass on "
                                       "more ranks is for uneven grid splits (TWO_RANK_MODULES)")
        for item in items:
            if "heavy" in item.keywords:
                item.add_marker(skip)
            elif item.path.stem in TWO_RANK_MODULES:
                item.add_marker(skip_module)


#: modules checked on 1 and 2 ranks only: scenes, command lines, plots, restarts, load paths and
#: studies, whose parallel code (the grid split, the FFT, the solvers, parallel I/O) is that of the
#: grid, operator, solver and output tests, which the pass on 3 ranks (every grid split unevenly)
#: runs (a restart from the step files on an uneven split: test_field_output's
#: test_restart_resumes_from_the_last_step_file)
TWO_RANK_MODULES = {
    "test_adhesive_paths", "test_adhesive_sphere", "test_api_page", "test_axisymmetric_reference",
    "test_cli_options", "test_examples", "test_faults", "test_grid_biases", "test_interactions",
    "test_law_registry", "test_material_scenes", "test_output_directory", "test_plot_scales",
    "test_plots_results", "test_pull_off_and_jumps", "test_restart", "test_robustness", "test_run_lock",
    "test_scenes", "test_solver_input", "test_solver_options", "test_stability_auto", "test_studies",
    "test_under_resolved_jump_in", "test_unit_scales",
}


class Collective:
    """Reductions over COMM_WORLD so that every rank asserts the same thing."""

    def __init__(self, comm):
        self.comm = comm
        self.size, self.rank = comm.Get_size(), comm.Get_rank()

    def max(self, value) -> float:
        """Largest ``value`` over all ranks (NaN counts as +inf, so it fails any bound)."""
        value = float(np.max(value))
        if not np.isfinite(value):
            value = np.inf
        return self.comm.allreduce(value, op=MPI.MAX)

    def all(self, flag) -> bool:
        return bool(self.comm.allreduce(bool(flag), op=MPI.LAND))

    def raises(self, exc_type, match, func, *args, **kwargs) -> list:
        """Call ``func`` on every rank; the messages of the ``exc_type`` raised on each rank.

        Asserts (collectively) that every rank raised ``exc_type`` whose message
        contains every string in ``match``.
        """
        match = [match] if isinstance(match, str) else list(match)
        try:
            func(*args, **kwargs)
        except exc_type as exc:
            msg = str(exc)
        except Exception as exc:  # noqa: BLE001 - reported below, collectively
            msg = f"<wrong exception {type(exc).__name__}: {exc}>"
        else:
            msg = "<no exception>"
        ok = (not msg.startswith("<")) and all(m.lower() in msg.lower() for m in match)
        messages = self.comm.allgather(msg)
        assert self.all(ok), f"expected {exc_type.__name__} matching {match} on every rank, got {messages}"
        return messages


#: how long a rank on which a test failed waits for the others at the next synchronisation
#: point before it aborts the job (seconds): a failure on some ranks only leaves the others
#: in a collective the failed rank never joins, and without this the job hangs to its timeout
LONE_FAILURE_WAIT = float(os.environ.get("CONTACTPETSC_LONE_FAILURE_WAIT", "120"))
_failed_here = []      # (test id, report) of tests that failed on this rank, not yet in step
_session_config = []


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    report = (yield).get_result()
    if report.failed and WORLD.Get_size() > 1:
        _failed_here.append((item.nodeid, report.longreprtext))


def step_together():
    """Barrier on COMM_WORLD; after a failure on this rank, one that gives up after
    LONE_FAILURE_WAIT and aborts the job with the failure printed (ranks other than 0 print
    nothing else, so a failure on them alone would otherwise be silent as well as a hang)."""
    if not _failed_here:
        STEP.Barrier()
        return
    request, start = STEP.Ibarrier(), time.monotonic()
    while not request.Test():
        if time.monotonic() - start > LONE_FAILURE_WAIT:
            nodeid, text = _failed_here[-1]
            capture = _session_config[0].pluginmanager.getplugin("capturemanager")
            if capture is not None:         # pytest captures stderr inside fixtures, at fd level
                capture.suspend_global_capture(in_=True)
            sys.stderr.write((f"\nrank {WORLD.Get_rank()} of {WORLD.Get_size()}: {nodeid} failed here, and the "
                             f"other ranks did not follow within {LONE_FAILURE_WAIT:g} s (they wait in a "
                             f"collective the test left on this rank): aborting the job.\n{text}\n"))
            sys.stderr.flush()
            time.sleep(1.0)         # let the launcher forward it before the abort kills the job
            WORLD.Abort(1)
        time.sleep(0.01)
    _failed_here.clear()


@pytest.fixture(scope="session")
def coll() -> Collective:
    return Collective(WORLD)


@pytest.fixture
def shared_tmp():
    """A temporary directory shared by all ranks (made by rank 0, removed after the test)."""
    path = tempfile.mkdtemp(prefix="contactpetsc-test-") if WORLD.Get_rank() == 0 else None
    path = WORLD.bcast(path, root=0)
    yield Path(path)
    step_together()
    if WORLD.Get_rank() == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(autouse=True)
def _keep_ranks_in_step():
    """Start every test on all ranks together: a rank that skipped ahead cannot mix collectives."""
    step_together()
    yield



@pytest.fixture(scope="session")
def adhesive_sweep():
    """The adhesive sphere example's short sweep (scene_files.sweep_every_4th: a jump-on, the most
    tensile state, a jump-off, the pull-off refined) run once on COMM_WORLD, uninterrupted: its
    directory, shared by the ranks and by the tests that read a finished adhesive run's files
    (test_field_output, test_recorder)."""
    import warnings
    from contactpetsc.app import runner
    from contactpetsc.physics.resolution import UnderResolvedWarning
    from scene_files import sweep_every_4th
    root = WORLD.bcast(tempfile.mkdtemp(prefix="contactpetsc-sweep-") if WORLD.Get_rank() == 0 else None)
    out = Path(root) / "sweep"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)    # 2 z0 spacing: the files, not the physics
        runner.run(sweep_every_4th(out), comm=PETSc.COMM_WORLD)
    yield out
    step_together()
    if WORLD.Get_rank() == 0:
        shutil.rmtree(root, ignore_errors=True)


@pytest.fixture(scope="session")
def example_sphere_path():
    """(problem, path): adhesive_setup's example sphere loaded along EXAMPLE_LOADING and unloaded
    back (a jump-on, a jump-off), solved once on COMM_WORLD for the tests that read it
    (test_adhesive_paths, test_axisymmetric_reference)."""
    from contactpetsc.paths import sweep
    from adhesive_setup import EXAMPLE_LOADING, example_sphere
    pb = example_sphere()
    return pb, sweep(pb, np.concatenate([EXAMPLE_LOADING, EXAMPLE_LOADING[-2::-1]]))
