"""Solvers: the SNES VI contact problem, its preconditioners and histories."""
from .history import SolveHistory, HistoryRecord
from .problem import ContactProblem, ContactState, ContactSolveError

__all__ = ["ContactProblem", "ContactState", "ContactSolveError", "SolveHistory", "HistoryRecord"]
