"""The one registry of the package's preconditioner names and their short public Python
paths (``-<prefix>pc_python_type``; docs/formulation.md, "Preconditioners")."""
from __future__ import annotations

import importlib

#: ``-<prefix>preconditioner`` choices of the contact problem -> ``pc_python_type`` (None: no PC)
PRECONDITIONERS = {
    "spectral": "contactpetsc.solvers.SpectralPC",
    "mlmi": "contactpetsc.solvers.MLMIPC",
    "none": None,
}
#: ``-<prefix>preconditioner`` choices of the adhesive problem -> ``pc_python_type`` of its
#: Newton, PTC and tangent solves: the block preconditioner (spectral on the contact-like rows,
#: Jacobi on the others) or the multilevel cycle on the whole reduced Jacobian
ADHESIVE_PRECONDITIONERS = {
    "spectral": "contactpetsc.solvers.AdhesivePC",
    "mlmi": "contactpetsc.solvers.AdhesiveMLMIPC",
    "none": None,
}
#: the snap numbers K_ii max da/dg from which ``auto`` picks the multilevel cycle for an
#: adhesive problem, and (hard-wall laws) up to which (docs/performance.md, "Preconditioners for
#: the adhesive Newton system"): below the window the block preconditioner is nearly exact at
#: one FFT pair per application; above it, with a hard wall, the cycle failed on the nested
#: iteration's coarse grids where spectral converged.  The full LJ curve has no upper end: its
#: stiffest measured cases (rough, snap 0.28 and 2x-8x that on the coarse grids) converged with
#: the cycle and failed or needed the fallback with spectral
AUTO_MLMI_SNAP = (0.01, 0.2)


def auto_adhesive_preconditioner(snap_number: float, hard_wall: bool) -> str:
    """``auto``: the adhesive preconditioner of a grid with this snap number K_ii max da/dg."""
    lo, hi = AUTO_MLMI_SNAP
    return "mlmi" if lo <= snap_number and (snap_number <= hi or not hard_wall) else "spectral"


def resolve(path: str):
    """The object a dotted ``pc_python_type`` path names (None when it names nothing)."""
    module, _, name = path.rpartition(".")
    try:
        return getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError, ValueError):
        return None


def preconditioner_name(python_type: str | None, pc_type: str) -> str:
    """The registry name of a PC in use (its Python type under any path), else its own type."""
    if python_type:
        cls = resolve(python_type)
        for name, path in PRECONDITIONERS.items():
            if path and (path == python_type or (cls is not None and resolve(path) is cls)):
                return name
        return python_type
    return pc_type
