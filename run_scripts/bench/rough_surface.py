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


#: the rough adhesive case: the full LJ curve with w = ADHESIVE_W E* dx and z0 = ADHESIVE_Z0 dx
ADHESIVE_W, ADHESIVE_Z0 = 0.05, 1.0


def adhesive_law(grid, w_rel=ADHESIVE_W, z0_rel=ADHESIVE_Z0, name="lj"):
    """The law ``name`` of the rough adhesive case on ``grid`` (E* = 1): work of adhesion
    w_rel * dx [J/m^2], range z0_rel * dx [m] (z0; the exponential law's rho)."""
    from contactpetsc.physics.interactions import make_law
    length = {"rho" if name == "exponential" else "z0": z0_rel * grid.dx}
    return make_law(name, work_of_adhesion=w_rel * grid.dx, **length)


def calibrate(grid, h, law, areas, steps=40, max_n=128):
    """Approaches giving the target contact fractions (p > 0, i.e. z < z0) of the adhesive
    contact on its loading path: a sweep with our solver (untimed) in ``steps`` equal steps
    across the height range, stopped past the largest target, then linear interpolation.
    Above ``max_n`` nodes per side the sweep runs on the heights averaged to that grid (same
    w and z0): the areas are then approximate -- each case reports the area it reached --
    and the calibration no longer costs more than the benchmark (at 1024^2 it had taken
    over an hour on the full grid)."""
    import warnings

    import numpy as np

    from contactpetsc.physics.resolution import UnderResolvedWarning
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    from contactpetsc.solvers.transfer import can_halve, halved, restrict
    while grid.nx > max_n and can_halve(grid):
        coarse = halved(grid)
        hc = coarse.create_vec()
        coarse.rows(hc)[...] = restrict(grid.rows(h, readonly=True))
        grid, h = coarse, hc
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)   # coarser than the case by design
        # one preconditioner, one strategy (its descent fallback's too) and one tangent (the
        # Newton steps' predictor) whatever the defaults: the approaches stay those of earlier tables
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix="cal_", tol=1e-6, stability_check=False,
                             preconditioner="spectral",
                             petsc_options={"strategy": "newton", "descent_pc_contact_factor": 0,
                                            "descent_tao_bnk_ksp_max_it": 10000, "tangent_hessian": False,
                                            "descent_tao_bnk_psfac": 0.4, "descent_floor_factor": 0,
                                            "descent_tao_bnk_ksp_cg_dtype": "unpreconditioned"})
    lo, hi = float(h.min()[1]) - law.length_scale(), float(h.max()[1])
    deltas, fractions = [], []
    for d in np.linspace(lo, hi, steps):
        st = pb.solve(approach=d, raise_on_failure=False)
        if st.converged:
            deltas.append(d)
            fractions.append(st.contact_fraction)
        if fractions and fractions[-1] > 1.2 * max(areas):
            break
    if len(fractions) < 2:
        return None     # no loading path to interpolate on: the case is reported as failed
    return [float(np.interp(a, fractions, deltas)) for a in areas]


def path_approaches(lo, hi, states):
    """About half the states from lo up to hi (both included), the rest back down towards lo
    (hi not repeated)."""
    import numpy as np

    up = max(2, states - states // 2)
    down = states - up
    return list(np.linspace(lo, hi, up)) + list(np.linspace(hi, lo, down + 1)[1:])


def load_unload_path(grid, h, law, states):
    """Approaches [m] of the benchmark's load-unload path: ``states`` from 1 % contact up to 10 %
    and back (``path_approaches``), the ends from ``calibrate``."""
    ends = calibrate(grid, h, law, [0.01, 0.10])
    return path_approaches(ends[0], ends[1], states)


def non_adhesive_unit(grid, h):
    """(FFT pairs, CPU s) of the non-adhesive solve of the heights at the benchmark's mean
    pressure 0.005 E* (E* = 1) to 1e-8: the unit of the adhesive benchmarks' ratios."""
    import time

    from contactpetsc.solvers.problem import ContactProblem
    t0 = time.process_time()
    st = ContactProblem(grid, h, 1.0, prefix="unit_", tol=1e-8).solve(mean_pressure=0.005)
    return st.fft_pairs, time.process_time() - t0
