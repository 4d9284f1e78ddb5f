"""contactpetsc from Python under mpirun: an adhesive sphere, loaded and unloaded, its pull-off force.

    mpirun -n 2 python examples/api_adhesive_mpirun.py [n] [PETSc options]   (n x n grid, default 96)
    mpirun -n 2 python examples/api_adhesive_mpirun.py -adhesion_snes_monitor

A tip of radius R = 30 nm (100 z0) on a half-space of E* = 10 GPa with the
full Lennard-Jones law (the reference paper's eq. 8), w = 0.3 J/m^2 and
z0 = 0.3 nm: Tabor parameter 1.  The heights are filled into a Vec of the
grid's DMDA as any PETSc code would (``da.getVecArray``); ``AdhesiveProblem``
(options prefix ``adhesion_``) is swept in displacement control with
``contactpetsc.paths.sweep``: loading to contact, then unloading, each state
warm-started from the last, jumps located by bisection.  The pull-off force
is refined by golden section and compared with the DMT and JKR limits and
Maugis-Dugdale.  Rank 0 writes the path to ``api_adhesive_mpirun.json``.
"""
import json
import sys

import petsc4py

petsc4py.init(sys.argv)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.paths import sweep  # noqa: E402
from contactpetsc.pull_off import refine_pull_off  # noqa: E402
from contactpetsc.physics.interactions import make_law, tabor_parameter  # noqa: E402
from contactpetsc.physics.closed_forms import maugis_pull_off  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

n = int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 96
R, E_STAR, W, Z0 = 30e-9, 10e9, 0.3, 0.3e-9      # m, Pa, J/m^2, m
say = PETSc.Sys.Print

# an isolated (non-periodic) window of 96 z0, wide enough for the LJ tail
grid = SurfaceGrid(n, n, dx=96 * Z0 / n, periodic=False)
heights = grid.create_vec()                       # a Vec of grid.da
(xs, xe), (ys, ye) = grid.da.getRanges()
with grid.da.getVecArray(heights) as h:           # h[i, j] on this rank's nodes
    x = (np.arange(xs, xe) - n // 2) * grid.dx
    y = (np.arange(ys, ye) - n // 2) * grid.dy
    h[:, :] = (x[:, None] ** 2 + y[None, :] ** 2) / (2 * R)   # the sphere's paraboloid

law = make_law("lj", work_of_adhesion=W, z0=Z0)
mu = tabor_parameter(R, W, E_STAR, Z0)
problem = AdhesiveProblem(grid, heights, E_STAR, law)      # options prefix adhesion_
say(f"{grid}; Tabor parameter {mu:.3f}; SNES {problem.snes().getType()} "
    f"(prefix {problem.snes().getOptionsPrefix()})")

# loading from -2.5 z0 to contact, then unloading to -2.5 z0, in steps of z0 / 4
approaches = Z0 * np.concatenate([np.arange(-2.5, 0.01, 0.25), np.arange(-0.25, -2.51, -0.25)])
path = sweep(problem, approaches)
say(f"{'step':>4} {'branch':>9} {'approach [m]':>12} {'force [N]':>11} {'stable':>6}")
for pt in path.points:
    say(f"{pt.step:4d} {pt.branch:>9} {pt.approach:12.4e} {pt.force:11.4e} {str(pt.stable):>6}")
for j in path.jumps:
    say(f"{j.kind} between {j.approach_before:.4e} and {j.approach_after:.4e} m: "
        f"force {j.force_before:.4e} -> {j.force_after:.4e} N")

pull_off = refine_pull_off(problem, path, xtol=0.01 * Z0)
bracket = (-2 * np.pi * R * W, -1.5 * np.pi * R * W)            # DMT, JKR
md = maugis_pull_off(R, W, 1.16 * mu)                            # Dugdale stress ~ the LJ peak
say(f"pull-off force {pull_off:.4e} N = {pull_off / (np.pi * R * W):.4f} pi R w: between DMT "
    f"{bracket[0]:.4e} and JKR {bracket[1]:.4e} N; Maugis-Dugdale (lambda = 1.16 mu) {md:.4e} N")
say(f"history: {len(problem.history)} iterations, "
    f"{sum(pt.fft_pairs for pt in path.points):.0f} FFT pairs, {problem.history.elapsed():.1f} s")

if grid.mpi_comm.Get_rank() == 0:
    with open("api_adhesive_mpirun.json", "w") as f:
        json.dump({"radius": R, "e_star": E_STAR, "work_of_adhesion": W, "z0": Z0, "tabor": mu,
                   "ranks": grid.mpi_comm.Get_size(), "pull_off_force": pull_off,
                   "points": [vars(pt) for pt in path.points],
                   "jumps": [vars(j) for j in path.jumps]}, f, indent=1)
