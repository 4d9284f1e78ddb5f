"""Solvers: the SNES VI contact problems, their preconditioners and histories."""
from .history import SolveHistory, HistoryRecord
from .problem import ContactProblem, ContactState, ContactSolveError
from .preconditioners import SpectralPC
from .mlmi import MLMIPC
from .adhesive_jacobian import AdhesivePC
from .adhesive_mlmi import AdhesiveMLMIPC

__all__ = ["ContactProblem", "ContactState", "ContactSolveError", "SolveHistory", "HistoryRecord",
           "SpectralPC", "MLMIPC", "AdhesivePC", "AdhesiveMLMIPC"]
