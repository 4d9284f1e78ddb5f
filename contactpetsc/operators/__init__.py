"""Elastic half-space operators v = K p (reference paper, eq. 3)."""
from .love import love_displacement
from .elastic import HalfSpaceOperator, PeriodicHalfSpace, IsolatedHalfSpace, half_space

__all__ = ["love_displacement", "HalfSpaceOperator", "PeriodicHalfSpace",
           "IsolatedHalfSpace", "half_space"]
