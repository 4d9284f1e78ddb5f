"""PETSc log events of the package (listed by ``-log_view``; docs/performance.md)."""
from __future__ import annotations

from petsc4py import PETSc

_events: dict[str, PETSc.Log.Event] = {}


def log_event(name: str) -> PETSc.Log.Event:
    """A PETSc log event, created on first use (so -log_view lists it)."""
    ev = _events.get(name)
    if ev is None:
        ev = _events[name] = PETSc.Log.Event(name)
    return ev
