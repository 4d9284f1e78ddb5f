"""A smooth sphere on an isolated elastic half-space, compared with Hertz.

    python examples/hertz_sphere.py [-contact_snes_monitor]
    mpirun -n 2 python examples/hertz_sphere.py

Load control: the total force F is prescribed; Hertz gives the approach
delta = (9 F^2 / (16 E*^2 R))^(1/3), the contact radius a = sqrt(R delta) and
the peak pressure p0 = 3F / (2 pi a^2).
"""
import sys

import petsc4py

petsc4py.init(sys.argv)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry import surfaces  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.solvers import ContactProblem  # noqa: E402

R, E_STAR, FORCE = 100e-6, 50e9, 5e-4          # m, Pa, N
delta_h = (9 * FORCE**2 / (16 * E_STAR**2 * R)) ** (1 / 3)
a_h = np.sqrt(R * delta_h)
p0_h = 3 * FORCE / (2 * np.pi * a_h**2)

n = 128
grid = SurfaceGrid(n, n, dx=a_h / 20, periodic=False, row_alignment=16)   # 20 elements per radius
problem = ContactProblem(grid, surfaces.sphere(grid, R), E_STAR, length_scale=delta_h)
state = problem.solve(force=FORCE)

a = np.sqrt(state.contact_fraction * grid.lengths[0] * grid.lengths[1] / np.pi)
PETSc.Sys.Print(f"approach      {state.approach:.4e} m   Hertz {delta_h:.4e} m   ratio {state.approach / delta_h:.5f}")
PETSc.Sys.Print(f"contact radius {a:.4e} m   Hertz {a_h:.4e} m   ratio {a / a_h:.5f}")
PETSc.Sys.Print(f"peak pressure {state.pressure.max()[1]:.4e} Pa  Hertz {p0_h:.4e} Pa  ratio {state.pressure.max()[1] / p0_h:.5f}")
PETSc.Sys.Print(f"{state.newton_iterations} Newton, {state.linear_iterations} CG, {state.fft_pairs:.0f} FFT pairs, "
                f"complementarity error {state.complementarity_error:.1e}")
