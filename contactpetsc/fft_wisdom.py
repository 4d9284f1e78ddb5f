"""FFTW wisdom kept on disk, so that measured plans repeat from run to run.

FFTW_MEASURE times its candidate algorithms and keeps the fastest; on a busy machine the
winner changes between runs, and with it the round-off of every transform.  Contact paths
through folds (adhesion, snap-in) are sensitive to round-off: the same scene could land in
another of its many equilibria, at another cost, in the next run.  The first run on a machine
measures and stores its plans (FFTW wisdom); later runs import them and plan exactly the same
transforms without measuring.

The file is ``$CONTACTPETSC_FFTW_WISDOM`` when set (``off``: no file, plans measured anew in
every process), else ``~/.cache/contactpetsc/fftw-wisdom-<cpu>.dat``, one per CPU model (a
plan measured on one processor is only a guess on another).  On several ranks the wisdom of
rank 0 is read and broadcast before planning, and every rank's new wisdom is merged and
written by rank 0 after it, so that all ranks plan the same transforms of the same size.

FFTW_ESTIMATE plans (coarse grids, generated surfaces) would take any wisdom of their size in
memory; they are planned with none, so that they too are the same in every run.
"""
from __future__ import annotations

import os
import platform
import re
import stat
import warnings
from contextlib import contextmanager

import pyfftw
from mpi4py import MPI

ENV = "CONTACTPETSC_FFTW_WISDOM"

_known: tuple | None = None    # the wisdom this process last read or wrote
_warned: set = set()           # wisdom paths already warned about (no regular file)
#: the wisdom set aside while FFTW_ESTIMATE plans are made (None: it is in memory).  It is
#: restored only when a measured plan is next made: a file of many sizes costs 10-20 ms to
#: export or import, and a small adhesive problem plans a dozen coarse grids in a row
_set_aside: tuple | None = None


def cpu_model() -> str:
    """The processor's model name (/proc/cpuinfo), else the machine type."""
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.machine() or "unknown"


def wisdom_path() -> str | None:
    """Where this machine's FFTW wisdom is kept, or None when switched off."""
    path = os.environ.get(ENV)
    if path is not None:
        return None if path.strip().lower() in ("", "off", "none", "0") else os.path.expanduser(path)
    cpu = re.sub(r"[^A-Za-z0-9]+", "-", cpu_model()).strip("-") or "cpu"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "contactpetsc", f"fftw-wisdom-{cpu}.dat")


def _special(path: str, mode: int) -> bool:
    """Whether ``path`` is no regular file (a FIFO would block a read or a write forever, a
    directory cannot be replaced); warns once per path, naming it."""
    if stat.S_ISREG(mode):
        return False
    if path not in _warned:
        _warned.add(path)
        kind = "a FIFO" if stat.S_ISFIFO(mode) else "a directory" if stat.S_ISDIR(mode) else "no regular file"
        warnings.warn(f"FFTW wisdom file {path!r} ({ENV}) is {kind}: not read or written "
                      f"(plans are measured anew); point {ENV} at a regular file, or set it to 'off'", RuntimeWarning, stacklevel=4)
    return True


def _read(path: str) -> tuple | None:
    """The wisdom in ``path``, if it is a readable regular file (opened without blocking, so
    that a FIFO is seen for what it is before any read)."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError:
        return None
    try:
        if _special(path, os.fstat(fd).st_mode):
            return None
        with open(fd, "rb", closefd=False) as f:
            parts = f.read().split(b"\0\0\0")
    except OSError:
        return None
    finally:
        os.close(fd)
    return tuple(parts) if len(parts) == 3 else None


def _write(path: str, wisdom: tuple) -> None:
    """Atomically (a run that reads meanwhile sees the old file or the new one); only over a
    regular file or none, and never leaving the temporary behind."""
    try:
        if _special(path, os.stat(path).st_mode):
            return
    except OSError:
        pass                                  # no file yet
    tmp = f"{path}.{os.getpid()}.tmp"
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        with open(tmp, "wb") as f:
            f.write(b"\0\0\0".join(wisdom))
        os.replace(tmp, path)
    except OSError:
        try:                                  # a read-only home: plans are measured in every run
            os.remove(tmp)
        except OSError:
            pass


def load(comm: MPI.Comm) -> None:
    """Import the stored wisdom on every rank of ``comm`` (rank 0 reads); collective."""
    global _known
    path = wisdom_path()
    if path is None:
        return
    wisdom = _read(path) if comm.Get_rank() == 0 else None
    wisdom = comm.bcast(wisdom, root=0)
    if wisdom is not None and wisdom != _known:
        pyfftw.import_wisdom(wisdom)
        _known = pyfftw.export_wisdom()


def save(comm: MPI.Comm) -> None:
    """Merge every rank's wisdom with the file's and write it (rank 0); collective."""
    global _known
    path = wisdom_path()
    if path is None:
        return
    mine = pyfftw.export_wisdom()
    changed = comm.allreduce(mine != _known, op=MPI.LOR)
    if not changed:
        return
    every = comm.gather(mine, root=0)
    if comm.Get_rank() == 0:
        on_disk = _read(path)
        for wisdom in ([on_disk] if on_disk else []) + every:
            pyfftw.import_wisdom(wisdom)
        _write(path, pyfftw.export_wisdom())
    _known = pyfftw.export_wisdom()


@contextmanager
def planning(comm: MPI.Comm, planner: str):
    """Plans made inside repeat from run to run: measured ones from the stored wisdom (and new
    ones stored), estimated ones without any wisdom; collective on ``comm``."""
    global _set_aside
    if planner == "estimate":
        if _set_aside is None:
            _set_aside = pyfftw.export_wisdom()
            pyfftw.forget_wisdom()
        yield
        return
    if _set_aside is not None:
        pyfftw.import_wisdom(_set_aside)
        _set_aside = None
    load(comm)
    yield
    save(comm)
