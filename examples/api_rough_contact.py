"""contactpetsc from Python: a rough surface given as a numpy array, pressed by a nominal load.

    python examples/api_rough_contact.py [n] [PETSc options]        (an n x n grid, default 256)
    mpirun -n 2 python examples/api_rough_contact.py 128 -rough_snes_monitor

The steps a PETSc user takes (docs/api.md): a ``SurfaceGrid`` (a DMDA split
along y), the heights as a Vec of its DMDA (here from a numpy array, as a
measured topography would come), a ``ContactProblem`` with its own options
prefix (``rough_``: every PETSc option of its SNES, KSP and PC works, e.g.
``-rough_snes_monitor -rough_ksp_type minres``), a solve, then the solution
Vecs, the SNES and the per-iteration history: the error against run time.
Rank 0 saves the global fields to ``api_rough_contact.npz`` and prints the
load balance and the Signorini conditions checked with numpy.
"""
import sys

import petsc4py

petsc4py.init(sys.argv)   # before anything imports PETSc, so that command-line options count

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.geometry import surfaces  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.solvers import ContactProblem  # noqa: E402

n = int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 256
E_STAR, L = 50e9, 2.56e-6            # Pa; m, a periodic 2.56 um cell
P_MEAN = 0.005 * E_STAR              # Pa, the nominal pressure
say = PETSc.Sys.Print

# 1. heights [m] as a numpy array (n, n) indexed [x, y], the same on every rank: self-affine,
#    Hurst exponent 0.8, roll-off at L/4, cut-off at 4 grid spacings, rms slope 0.1
rng = np.random.default_rng(1)
f = np.fft.fftfreq(n, L / n)
q = 2 * np.pi * np.hypot(f[:, None], f[None, :])
amplitude = np.where((q > 0) & (q <= np.pi * n / (2 * L)), np.maximum(q, 8 * np.pi / L) ** -1.8, 0.0)
h = np.fft.ifft2(amplitude * np.exp(2j * np.pi * rng.random((n, n)))).real
h *= 0.1 / np.sqrt(np.mean(sum(np.gradient(h, L / n, axis=k) ** 2 for k in (0, 1))))
h -= h.min()

# 2. the grid (grid.da is its DMDA) and the heights as a Vec of it: each rank keeps its rows
grid = SurfaceGrid(n, n, dx=L / n, periodic=True)
heights = surfaces.from_array(grid, h)

# 3. the problem, with options prefix rough_; tol is a code default that -rough_tol overrides
problem = ContactProblem(grid, heights, E_STAR, prefix="rough_", tol=1e-8)
snes = problem.snes()
say(f"{grid}\nSNES {snes.getType()}, KSP {snes.getKSP().getType()}, PC {snes.getKSP().getPC().getType()}"
    f" (options prefix {snes.getOptionsPrefix()})")

# 4. solve under load control (or approach=..., force=...)
state = problem.solve(mean_pressure=P_MEAN)
say(f"converged: {state.reason}, {state.newton_iterations} Newton, {state.linear_iterations} Krylov, "
    f"{state.fft_pairs:.0f} FFT pairs, {state.wall_time:.2f} s; contact fraction "
    f"{state.contact_fraction:.4f}, approach {state.approach:.4e} m")

# 5. the history: one record per iteration of every solve (the nested coarse grids, then the load
#    iterations on this grid), the error against run time; all of it: problem.history.write_csv(path)
records = problem.history.records
say(f"{'solve':>5} {'iter':>4} {'time [s]':>9} {'FFT pairs':>9} {'error':>9}   (every "
    f"{max(1, len(records) // 12)}th of {len(records)} records, and the last)")
for r in records[::max(1, len(records) // 12)] + records[-1:]:
    say(f"{r.solve:5d} {r.iteration:4d} {r.wall_time:9.3f} {r.fft_pairs:9.0f} {r.complementarity_error:9.2e}")

# 6. the solution Vecs (pressure, gap, displacement) live on grid.da: grid.rows(vec) is this
#    rank's (ny_local, nx) numpy view, grid.gather(vec, root=0) the global (nx, ny) array on rank 0
p, gap, v = (grid.gather(x, root=0) for x in (state.pressure, state.gap, state.displacement))
if grid.mpi_comm.Get_rank() == 0:
    np.savez("api_rough_contact.npz", heights=h, pressure=p, gap=gap, displacement=v, dx=L / n,
             e_star=E_STAR, mean_pressure=P_MEAN, approach=state.approach)
    say(f"load balance: mean pressure {p.mean():.6e} Pa for {P_MEAN:.6e} Pa "
        f"(relative error {abs(p.mean() / P_MEAN - 1):.1e})", comm=PETSc.COMM_SELF)
    say(f"Signorini: min p = {p.min():.1e} Pa, min gap = {gap.min():.1e} m, "
        f"max p * gap = {np.max(p * gap):.1e} N/m", comm=PETSc.COMM_SELF)
    say("wrote api_rough_contact.npz", comm=PETSc.COMM_SELF)
