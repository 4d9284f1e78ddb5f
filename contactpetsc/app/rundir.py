"""The output directory of a run: one run per directory, locked while it runs, its scene stored.

``open_directory`` is called by every rank before any solve.  It makes the
directory, checks that every rank can write there and that the outputs fit,
takes the lock (``.contactpetsc.lock``: the host and process id of rank 0),
and then decides what to do with a directory that already holds a run's files
(``RUN_FILES``, ``step_NNNN.h5`` / ``.xdmf``):

- a new run refuses it, unless ``overwrite`` (``--overwrite``) removes those
  files (and nothing else);
- ``restart`` compares the scene stored there (``scene.json``; older runs: the
  ``scene`` attribute of their first step file) with the new one and refuses
  when the physics differ, naming the keys: the geometry, the material, the
  interaction, the control mode and the values of the steps already done, and for a
  height file the digest of its heights (a file rewritten since is refused, named).
  Output keys, the name, the solver's settings and the path's numerical
  settings (jump and pull-off refinement, sub-steps) may differ.

A lock left by a process that no longer runs on this host (a killed run) is
taken over with a note; a live one, or one of another host, is refused.
"""
from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import socket
from contextlib import contextmanager

from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_call
from .plots import PLOTS

LOCK = ".contactpetsc.lock"
SCENE = "scene.json"
RUN_FILES = ("curve.csv", "history.csv", "jumps.csv", "summary.json", "atom_forces.csv", SCENE,
             "fields.xdmf") + PLOTS
STEP_FILE = re.compile(r"step_\d{4,}\.(h5|xdmf)$")
#: scene keys that may differ on a restart (they change the outputs or the numerics, not the problem)
NOT_PHYSICS = ("name", "output.", "solver.", "protocol.refine_pull_off", "protocol.jump_refinement",
               "protocol.substeps", "protocol.values")
#: physics keys added since runs were first stored, with what a run stored without them did
ADDED_KEYS = {"protocol.agreement": 0.0, "protocol.agreement_levels": 2, "protocol.agreement_increment": 0.0}


class RunDirectoryError(RuntimeError):
    """A directory the run must not write into (locked, another run's files, another scene)."""


def run_files(out_dir: str) -> list[str]:
    """The names in ``out_dir`` that belong to a run (with their ``.tmp`` leftovers), sorted."""
    try:
        names = os.listdir(out_dir)
    except FileNotFoundError:
        return []
    return sorted(n for n in names
                  if n.removesuffix(".tmp") in RUN_FILES or STEP_FILE.match(n.removesuffix(".tmp")))


def open_directory(scene: dict, grid, out_dir: str, *, restart: bool, overwrite: bool) -> dict | None:
    """Make, probe, lock and check ``out_dir`` (collective; see the module docstring).

    Returns the stored scene of the run being restarted (None for a new run).
    Raises OSError (cannot write, no room) or RunDirectoryError on every rank.
    """
    comm = grid.mpi_comm
    rank = comm.Get_rank()
    what = f"output directory {out_dir!r} (output.directory or --output)"
    collective_call(comm, OSError, f"{what} cannot be created: {{error}}",
                    lambda: os.makedirs(out_dir, exist_ok=True) if rank == 0 else None)
    _probe(scene, grid, out_dir, what)
    note = collective_call(comm, RunDirectoryError, "{error}",
                           lambda: _lock(out_dir) if rank == 0 else None)
    try:
        stored = collective_call(comm, RunDirectoryError, "{error}",
                                 lambda: _check(scene, out_dir, restart, overwrite) if rank == 0 else None)
    except RunDirectoryError:
        release(comm, out_dir)
        raise
    for line in comm.bcast(note, root=0) or []:
        PETSc.Sys.Print(f"  note: {line}")
    return comm.bcast(stored, root=0)


def write_scene(comm, out_dir: str, scene: dict) -> None:
    """Store the scene (rank 0), for the next ``--restart`` to compare."""
    from .output import write_text_atomic
    if comm.Get_rank() == 0:
        write_text_atomic(os.path.join(out_dir, SCENE), json.dumps(scene, indent=1) + "\n")


def release(comm, out_dir: str) -> None:
    """Remove the lock if this process holds it (rank 0)."""
    if comm.Get_rank() != 0:
        return
    path = os.path.join(out_dir, LOCK)
    try:
        with open(path) as f:
            mine = json.load(f) == _owner()
    except (OSError, ValueError):
        return
    if mine:
        os.remove(path)


def differences(old: dict, new: dict, done: int) -> list[str]:
    """The physics keys in which scene ``new`` differs from ``old`` (see the module docstring);
    ``protocol.values`` is compared over the ``done`` steps already on disk."""
    from .scene_files import DIGEST
    a, b = _flat(json.loads(json.dumps(old))), _flat(json.loads(json.dumps(new)))
    a = {**ADDED_KEYS, **a}
    out = [f"{k}: {a.get(k)!r} on disk, {b.get(k)!r} now" for k in sorted(set(a) | set(b))
           if not k.startswith(NOT_PHYSICS) and a.get(k) != b.get(k) and k != f"geometry.{DIGEST}"]
    was, now = a.get(f"geometry.{DIGEST}"), b.get(f"geometry.{DIGEST}")
    if was != now:
        out.append(f"the heights in {b.get('geometry.path')!r} (geometry.path) are not those the steps on disk "
                   "were solved on: " + ("the run on disk recorded no digest of its heights" if was is None else
                                         f"the file was rewritten since (SHA-256 of its heights {was[:12]}... "
                                         f"on disk, {str(now)[:12]}... now)"))
    old_values = [float(v) for v in old.get("protocol", {}).get("values", [])[:done]]
    new_values = [float(v) for v in new["protocol"]["values"][:done]]
    if len(new_values) < done:
        out.append(f"protocol.values: {done} steps are done on disk, the scene now has {len(new_values)} values")
    else:
        k = next((k for k, (a, b) in enumerate(zip(old_values, new_values)) if a != b), None)
        if k is not None:
            out.append(f"protocol.values: step {k + 1} is {old_values[k]!r} on disk, {new_values[k]!r} now")
    return out


def _flat(d: dict, prefix: str = "") -> dict:
    out = {}
    for k, v in d.items():
        if isinstance(v, dict) and not (prefix == "solver." and k == "options"):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def _owner() -> dict:
    return {"host": socket.gethostname(), "pid": os.getpid()}


def _alive(pid: int) -> bool:
    """Whether process ``pid`` runs on this host (a zombie, killed but not yet reaped, does not)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return True


def _lock(out_dir: str) -> list[str]:
    """Take the lock (rank 0); returns notes (a stale lock taken over).

    The lock file appears complete (written under a name of this process, then hard-linked to
    ``LOCK``, which fails if it exists), so that a reader never takes a lock being written for
    an empty one.  A stale lock is removed only under an exclusive ``flock`` of the directory,
    after reading it again there: of several processes that found the same stale lock, the
    first removes it and takes the lock, the others then find that one's (live) lock and are
    refused naming it.  A lock that vanishes between the attempt and the read is attempted again.
    """
    path = os.path.join(out_dir, LOCK)
    notes = []
    for _ in range(10):
        if _create_lock(path):
            return notes
        holder = _holder(path)
        if holder is None:
            continue                          # released (or taken over) meanwhile: try again
        if not _stale(holder):
            here = holder.get("host") == socket.gethostname()
            raise RunDirectoryError(
                f"output directory {out_dir!r} is in use by another run (lock {path}: host "
                f"{holder.get('host', '?')}, process {holder.get('pid', '?')}); wait for it to end or choose "
                f"another --output" + ("" if here else "; if no run is left there, remove the lock file"))
        with _directory_locked(out_dir):
            if _holder(path) == holder:       # still that stale lock: nobody took it over before us
                os.remove(path)
                notes.append(f"took over the lock {path} of process {holder['pid']}, which no longer runs "
                             "(an interrupted run)")
                if _create_lock(path):
                    return notes
    raise RunDirectoryError(f"cannot lock {out_dir!r}: {path} keeps changing")


def _create_lock(path: str) -> bool:
    """Create the lock naming this process, complete; False if a lock exists."""
    tmp = f"{path}.{os.getpid()}.tmp"
    with open(tmp, "w") as f:
        json.dump(_owner(), f)
    try:
        os.link(tmp, path)
        return True
    except FileExistsError:
        return False
    except OSError as exc:                    # a file system without hard links: create in place
        if exc.errno not in (errno.EPERM, errno.EOPNOTSUPP, errno.ENOSYS):
            raise
        try:
            fd = os.open(path, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        with os.fdopen(fd, "w") as f:
            json.dump(_owner(), f)
        return True
    finally:
        os.remove(tmp)


def _holder(path: str) -> dict | None:
    """The lock's contents (``{}`` when unreadable), None when there is no lock."""
    try:
        with open(path) as f:
            holder = json.load(f)
    except FileNotFoundError:
        return None
    except (OSError, ValueError):
        return {}
    return holder if isinstance(holder, dict) else {}


def _stale(holder: dict) -> bool:
    """A lock of a process of this host that no longer runs."""
    return (holder.get("host") == socket.gethostname() and isinstance(holder.get("pid"), int)
            and not _alive(holder["pid"]))


@contextmanager
def _directory_locked(out_dir: str):
    """An exclusive ``flock`` of the directory itself (no file of its own to leave behind)."""
    fd = os.open(out_dir, os.O_RDONLY)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        os.close(fd)                          # releases the flock


def _stored_scene(out_dir: str) -> dict | None:
    path = os.path.join(out_dir, SCENE)
    if os.path.exists(path):
        try:
            with open(path) as f:
                return json.load(f)
        except (OSError, ValueError) as exc:
            raise RunDirectoryError(f"cannot restart: {path} is not readable ({exc})") from None
    first = os.path.join(out_dir, "step_0001.h5")
    if os.path.exists(first):
        import h5py
        try:
            with h5py.File(first, "r") as f:
                return json.loads(f.attrs["scene"])
        except (OSError, KeyError, ValueError):
            return None
    return None


def _check(scene: dict, out_dir: str, restart: bool, overwrite: bool) -> dict | None:
    """Rank 0: the directory's run files against the request (see the module docstring)."""
    found = run_files(out_dir)
    if restart:
        stored = _stored_scene(out_dir)
        if stored is None and any(STEP_FILE.match(n) or n == "curve.csv" for n in found):
            raise RunDirectoryError(f"cannot restart in {out_dir!r}: it holds a run without its scene "
                                    f"({SCENE} and step_0001.h5 missing or unreadable)")
        return stored
    if not found:
        return None
    if not overwrite:
        shown = ", ".join(found[:5]) + (f" and {len(found) - 5} more" if len(found) > 5 else "")
        raise RunDirectoryError(f"output directory {out_dir!r} holds another run ({shown}): continue it with "
                                "--restart, replace it with --overwrite, or choose another --output")
    for name in found:
        os.remove(os.path.join(out_dir, name))
    return None


def _probe(scene: dict, grid, out_dir: str, what: str) -> None:
    """Every rank can create a file in ``out_dir``, and it has room for the run's outputs."""
    from .output import expected_step_files, scene_field_types, step_file_bytes
    comm = grid.mpi_comm
    rank = comm.Get_rank()

    def probe():
        path = os.path.join(out_dir, f".contactpetsc-write-test-{rank}-{os.getpid()}")
        try:
            with open(path, "wb") as f:
                f.write(b"x")
                f.flush()
                os.fsync(f.fileno())
        finally:
            if os.path.exists(path):
                os.remove(path)
        st = os.statvfs(out_dir)
        return st.f_bavail * st.f_frsize

    free = collective_call(comm, OSError, f"{what} is not writable: {{error}}", probe)
    types = scene_field_types(scene)
    steps, files = len(scene["protocol"]["values"]), expected_step_files(scene)
    need = files * step_file_bytes(types, grid.nx * grid.ny) + 2**20 * (1 + steps)
    if comm.allreduce(free < need, op=MPI.LOR):
        raise OSError(f"{what} has {comm.allreduce(free, op=MPI.MIN) / 2**20:.1f} MiB free; the run writes "
                      f"about {need / 2**20:.1f} MiB ({steps} steps"
                      + (f", {files} step files of {len(types)} fields of {grid.nx} x {grid.ny}" if types else "")
                      + "): free some space, choose another directory or set output.fields = false")
