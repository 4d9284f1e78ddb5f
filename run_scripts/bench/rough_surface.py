"""The rough benchmark surface at any grid size, from its one definition, the scene
examples/scenes/bench_rough.toml, built by the runner's own geometry code.

Every size is the same surface sampled finer: the cell, the roll-off and the seed stay, the cut-off
stays at the same number of grid spacings.
"""
from __future__ import annotations

import os
import tomllib

from contactpetsc.app import scenes
from contactpetsc.grid import SurfaceGrid
from contactpetsc.app.builder import build_heights

SCENE = os.path.join(os.path.dirname(os.path.abspath(__file__)), os.pardir, os.pardir,
                     "examples", "scenes", "bench_rough.toml")


def rough_scene(n: int) -> dict:
    """The validated benchmark scene on an n x n grid."""
    with open(SCENE, "rb") as f:
        raw = tomllib.load(f)
    g = raw["geometry"]
    length, cutoff_spacings = g["nx"] * g["dx"], g["short_cutoff_wavelength"] / g["dx"]
    g.update(nx=n, dx=length / n, short_cutoff_wavelength=cutoff_spacings * length / n)
    return scenes.validate(raw)


def rough_surface(n: int, row_alignment: int = 1, comm=None):
    """(grid, heights [m], scene) of the benchmark surface on an n x n periodic grid."""
    scene = rough_scene(n)
    g = scene["geometry"]
    grid = SurfaceGrid(n, n, g["dx"], periodic=True, row_alignment=row_alignment, comm=comm)
    return grid, build_heights(scene, grid), scene
