"""Physics: the interaction laws and their registry (``interactions``), their traction on the
grid (``traction``), closed forms of sphere contact (``closed_forms``) and the grid resolution
criterion (``resolution``); README.md, "Layout"."""
from .interactions import (InteractionLaw, NoAdhesion, HardWallLennardJones, LennardJones,
                           Exponential, Dugdale, Parameter, make_law, register_law, tabor_parameter,
                           lj_from_atomistic)

__all__ = ["InteractionLaw", "NoAdhesion", "HardWallLennardJones", "LennardJones",
           "Exponential", "Dugdale", "Parameter", "make_law", "register_law", "tabor_parameter",
           "lj_from_atomistic"]
