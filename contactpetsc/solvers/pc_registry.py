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
#: the snap numbers K_ii max da/dg where ``auto`` picks the multilevel cycle, for hard-wall laws
#: and for the full LJ curve (docs/performance.md, "Preconditioners for the adhesive Newton
#: system").  Hard wall: below the window the block preconditioner is nearly exact at one FFT
#: pair per application; above it the cycle failed on the nested iteration's coarse grids where
#: spectral converged.  Full LJ curve: its repulsive rows are in gap form, K-like, and below the
#: window the block preconditioner needs so few Krylov iterations that the cycle costs more time
#: (and on a sphere more FFT pairs); in it the cycle converged the rough cases spectral failed
#: (snap 0.28); at 0.7 (a flat periodic cell near the law's peak) it failed a path spectral follows
AUTO_MLMI_SNAP = {"hard wall": (0.01, 0.2), "full LJ": (0.2, 0.4)}


def auto_adhesive_preconditioner(snap_number: float, hard_wall: bool) -> str:
    """``auto``: the adhesive preconditioner of a grid with this snap number K_ii max da/dg."""
    lo, hi = AUTO_MLMI_SNAP["hard wall" if hard_wall else "full LJ"]
    return "mlmi" if lo <= snap_number <= hi else "spectral"


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
