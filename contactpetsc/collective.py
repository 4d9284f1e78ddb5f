"""Collective error handling: a failure on one rank is loud on every rank, never a hang.

``collective_call`` raises one rank's error on every rank (file I/O, input checks);
``petsc_error_message`` names a PETSc error by its meaning.  Errors inside PETSc callbacks
must not deadlock an MPI job either (docs/robustness.md, "Faults").

A Python exception raised in a Mat, PC or SNES callback on one rank only
leaves the other ranks waiting in the next collective (an all-reduce inside
the Krylov method) forever.  Callbacks therefore run under
``collective_guard``: on one rank the exception propagates as usual (petsc4py
re-raises it from the solve); on several ranks the failing rank prints its
traceback, tagged with its rank, and aborts the whole job with
``MPI_Abort`` — loud, immediate, no hang.  "Several ranks" means the
communicator of the callback's PETSc object (its first argument after self).
"""
from __future__ import annotations

import functools
import sys
import traceback

import numpy as np
from mpi4py import MPI


def collective_call(comm, exc_type, message: str, fn, *args, **kwargs):
    """fn(*args, **kwargs) on every rank of ``comm``; if it raised on any rank, raise
    ``exc_type(message.format(error=...))`` on every rank (the first failing rank's error).

    For work that can fail on some ranks only (reading a file, a user's
    function): the others must not walk on into the next collective.
    """
    err, result = None, None
    try:
        result = fn(*args, **kwargs)
    except Exception as exc:  # noqa: BLE001 - re-raised collectively below
        err = message.format(error=exc)
    errors = [e for e in comm.allgather(err) if e]
    if errors:
        raise exc_type(errors[0])
    return result


def collective_guard(method):
    """Decorate a PETSc callback method (see the module docstring)."""

    @functools.wraps(method)
    def wrapper(*args, **kwargs):
        try:
            return method(*args, **kwargs)
        except Exception:
            # the communicator of the callback's PETSc object (Mat, PC, SNES): a
            # problem on COMM_SELF inside a parallel job just raises
            try:
                comm = args[1].getComm().tompi4py()
            except Exception:  # noqa: BLE001 - not a PETSc object: assume the world
                comm = MPI.COMM_WORLD
            if comm.Get_size() == 1:
                raise
            rank = comm.Get_rank()
            sys.stderr.write(f"contactpetsc [rank {rank}]: error in {method.__qualname__}, "
                             f"aborting all ranks:\n{traceback.format_exc()}")
            sys.stderr.flush()
            comm.Abort(1)
    return wrapper


#: PETSc error codes (petscerror.h) in a user's terms
PETSC_ERRORS = {55: "out of memory", 56: "an operation this PETSc build does not support",
                57: "a signal (e.g. a floating-point exception)", 58: "a floating-point exception",
                60: "sizes that do not match", 62: "an argument out of range", 63: "an argument out of range",
                65: "a file that cannot be opened", 66: "a file read failure", 67: "a file write failure",
                73: "an object in the wrong state", 76: "an error in a library PETSc calls",
                98: "a failed MPI call"}


def petsc_error_message(exc) -> str:
    """What a ``PETSc.Error`` means, in words (its code, the raw "error code N", named)."""
    code = getattr(exc, "ierr", None)
    what = PETSC_ERRORS.get(code)
    if what is None and isinstance(code, int) and code > 0:
        what = "an internal PETSc failure, most often memory or an index beyond the PETSc build's range"
    return f"PETSc stopped with {what or 'an error'} (PETSc error code {code})"


def max_error(comm, local):
    """The largest over the ranks of ``local``, an error measure or an array of them (reduced
    element by element), a NaN counted as infinite.  A MAX reduction (MPI's, or mpi4py's over
    Python floats) can drop a NaN, and a state with a NaN on one rank would then measure
    finite -- even converged -- on the others."""
    if np.ndim(local):
        errs = np.where(np.isnan(local), np.inf, local).astype(float)
        comm.Allreduce(MPI.IN_PLACE, errs, op=MPI.MAX)
        return errs
    local = float(local)
    return comm.allreduce(float("inf") if local != local else local, op=MPI.MAX)
