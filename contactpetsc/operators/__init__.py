"""Elastic half-space operators v = K p (reference paper, eq. 3), and the finite layer."""
from .love import love_displacement
from .layer import Layer, layer_factor
from .elastic import HalfSpaceOperator, PeriodicHalfSpace, PeriodicLayer, IsolatedHalfSpace, half_space

__all__ = ["love_displacement", "Layer", "layer_factor", "HalfSpaceOperator", "PeriodicHalfSpace",
           "PeriodicLayer", "IsolatedHalfSpace", "half_space"]
