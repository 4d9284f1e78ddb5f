"""Destroy Python-context PETSc objects before the interpreter shuts down.

petsc4py 3.18 defers the destruction of parallel objects to PetscFinalize
(PETSc's "garbage"), which runs after Python has torn down its thread state;
a Mat or PC whose context is a Python object then crashes the process on
exit.  Objects registered here are destroyed by a Python ``atexit`` hook,
which runs first.  Every rank registers the same objects, so the collective
destroys match.
"""
from __future__ import annotations

import atexit
import weakref

_live: dict[int, weakref.ref] = {}


def destroy_at_exit(obj):
    """Register a PETSc object (Mat, PC, KSP, SNES, ...) for destruction at exit; returns it."""
    key = id(obj)
    _live[key] = weakref.ref(obj, lambda _ref, key=key: _live.pop(key, None))
    return obj


@atexit.register
def _destroy_live_objects():
    for ref in list(_live.values()):
        obj = ref()
        if obj is None:
            continue
        try:
            obj.destroy()
        except Exception:  # noqa: BLE001 - shutting down, nothing to report to
            pass
    try:
        from petsc4py import PETSc
        PETSc.garbage_cleanup()
    except Exception:  # noqa: BLE001
        pass
