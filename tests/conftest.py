"""pytest set-up for contactpetsc's tests, serially and under ``mpirun -n N``.

Every rank runs every test.  Assertions must therefore be collective: compute
the error on each rank, reduce it over COMM_WORLD (``Collective.max``,
``Collective.all``) and assert the reduced value on every rank.  Tests that only
make sense on one rank are marked ``@pytest.mark.serial`` and skipped under MPI.
"""
import shutil
import os
import sys
import tempfile
from pathlib import Path

import petsc4py

# the test session is an entry point: initialise PETSc before anything imports it
petsc4py.init(sys.argv[:1])

import numpy as np  # noqa: E402
import pytest  # noqa: E402
from mpi4py import MPI  # noqa: E402
from petsc4py import PETSc  # noqa: E402

WORLD = PETSc.COMM_WORLD.tompi4py()

if WORLD.Get_size() > 1:
    # pytest prunes old numbered temp dirs under one root per user: give each rank its own
    _root = os.path.join(tempfile.gettempdir(), f"contactpetsc-pytest-rank{WORLD.Get_rank()}")
    os.makedirs(_root, exist_ok=True)
    os.environ.setdefault("PYTEST_DEBUG_TEMPROOT", _root)


@pytest.hookimpl(trylast=True)
def pytest_configure(config):
    config.addinivalue_line(
        "markers", "serial: only meaningful on one MPI rank (skipped when COMM_WORLD has > 1 rank)")
    config.addinivalue_line(
        "markers", "heavy: long study runs, checked on 1 and 2 ranks (skipped on more, to keep the "
        "suite short; the 3-rank pass is for uneven splits, covered by the lighter tests)")
    if WORLD.Get_rank() != 0:
        # ranks != 0 run the same tests and reach the same collective verdicts: keep them quiet
        reporter = config.pluginmanager.get_plugin("terminalreporter")
        if reporter is not None:
            config.pluginmanager.unregister(reporter, "terminalreporter")


def pytest_collection_modifyitems(config, items):
    if WORLD.Get_size() > 1:
        skip = pytest.mark.skip(reason="serial test, COMM_WORLD has several ranks")
        for item in items:
            if "serial" in item.keywords:
                item.add_marker(skip)
    if WORLD.Get_size() > 2:
        skip = pytest.mark.skip(reason="heavy test: run on 1 and 2 ranks")
        for item in items:
            if "heavy" in item.keywords:
                item.add_marker(skip)


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


@pytest.fixture(scope="session")
def coll() -> Collective:
    return Collective(WORLD)


@pytest.fixture
def shared_tmp():
    """A temporary directory shared by all ranks (made by rank 0, removed after the test)."""
    path = tempfile.mkdtemp(prefix="contactpetsc-test-") if WORLD.Get_rank() == 0 else None
    path = WORLD.bcast(path, root=0)
    yield Path(path)
    WORLD.Barrier()
    if WORLD.Get_rank() == 0:
        shutil.rmtree(path, ignore_errors=True)


@pytest.fixture(autouse=True)
def _keep_ranks_in_step():
    """Start every test on all ranks together: a rank that skipped ahead cannot mix collectives."""
    WORLD.Barrier()
    yield

