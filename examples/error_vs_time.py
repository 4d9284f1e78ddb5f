"""Error against run time for one rough-surface solve, per preconditioner.

    python examples/error_vs_time.py [n]          (writes error_vs_time.png and .csv files)
    mpirun -n 2 python examples/error_vs_time.py 256

The benchmark surface of the performance notes: periodic, self-affine
(H = 0.8, rms slope 0.1, roll-off at L/4, cut-off at 4 grid spacings), mean
pressure 0.005 E*.  Each solve's history records, per Newton iteration, the
wall time, the FFT pairs and the complementarity error relative to the rms
height; the plot shows error against time for each preconditioner.
"""
import sys

import petsc4py

petsc4py.init(sys.argv)

from petsc4py import PETSc  # noqa: E402

from contactpetsc import surfaces  # noqa: E402
from contactpetsc.grid import SurfaceGrid  # noqa: E402
from contactpetsc.solvers import ContactProblem  # noqa: E402

n = int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 256
E_STAR, L = 1.0, 1.0
grid = SurfaceGrid(n, n, dx=L / n, periodic=True, row_alignment=64)
h = surfaces.self_affine(grid, hurst=0.8, rms_slope=0.1, seed=1,
                         rolloff_wavelength=L / 4, short_cutoff_wavelength=4 * L / n)
curves = {}
for pc in ("spectral", "mlmi"):
    prefix = f"{pc}_"
    PETSc.Options(prefix).setValue("preconditioner", pc)
    PETSc.Options(prefix).setValue("tol", 1e-8)
    problem = ContactProblem(grid, h, E_STAR, prefix=prefix)
    state = problem.solve(mean_pressure=0.005 * E_STAR)
    hist = problem.history
    curves[pc] = (hist.column("wall_time"), hist.column("complementarity_error"))
    PETSc.Sys.Print(f"{pc:9s}: {state.wall_time:6.2f} s, {state.newton_iterations} Newton, "
                    f"{state.linear_iterations} Krylov, {state.fft_pairs:.0f} FFT pairs, "
                    f"error {state.complementarity_error:.1e}")
    if grid.mpi_comm.Get_rank() == 0:
        hist.write_csv(f"error_vs_time_{pc}.csv")

if grid.mpi_comm.Get_rank() == 0:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 3.5))
    for pc, (t, e) in curves.items():
        ax.semilogy(t, e, marker=".", label=pc)
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("complementarity error / rms height")
    ax.set_title(f"rough surface {n}x{n}, mean pressure 0.005 E*")
    ax.legend()
    fig.tight_layout()
    fig.savefig("error_vs_time.png", dpi=120)
