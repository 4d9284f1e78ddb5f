"""Physics: interaction laws between the surfaces (and, later, geometry)."""
from .interactions import (InteractionLaw, NoAdhesion, HardWallLennardJones, LennardJones,
                           Exponential, Dugdale, make_law, tabor_parameter, lj_from_atomistic)

__all__ = ["InteractionLaw", "NoAdhesion", "HardWallLennardJones", "LennardJones",
           "Exponential", "Dugdale", "make_law", "tabor_parameter", "lj_from_atomistic"]
