"""Error against run time for one rough-surface solve, per preconditioner.

    python examples/error_vs_time.py [n]          (writes error_vs_time.png and .csv files)
    mpirun -n 2 python examples/error_vs_time.py 256

The benchmark surface of the performance notes: periodic, self-affine
(H = 0.8, rms slope 0.1, roll-off at L/4, cut-off at 4 grid spacings), mean
pressure 0.005 E*.  Each solve's history records, per Newton iteration, the
wall time, the FFT pairs and the complementarity error relative to the rms
height; the plot shows error against time for each preconditioner: the
coarse grids of the nested iteration shaded, then one line per fine-grid
solve of the load iteration (inexact intermediate solves, the last to the
tolerance).
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
    curves[pc] = hist
    PETSc.Sys.Print(f"{pc:9s}: {state.wall_time:6.2f} s, {state.newton_iterations} Newton, "
                    f"{state.linear_iterations} Krylov, {state.fft_pairs:.0f} FFT pairs, "
                    f"error {state.complementarity_error:.1e}")
    if grid.mpi_comm.Get_rank() == 0:
        hist.write_csv(f"error_vs_time_{pc}.csv")

if grid.mpi_comm.Get_rank() == 0:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(curves), figsize=(5 * len(curves), 3.6), sharey=True)
    for ax, (pc, hist) in zip(axes, curves.items()):
        # coarse grids of the nested iteration (solver tag "...@nxxny"): shaded
        coarse_end = max((r.wall_time for r in hist.records if "@" in r.solver), default=0.0)
        ax.axvspan(0, coarse_end, color="0.9", label="coarse grids")
        fine = [r for r in hist.records if "@" not in r.solver]
        for k, solve in enumerate(sorted({r.solve for r in fine})):
            recs = [r for r in fine if r.solve == solve]
            ax.semilogy([r.wall_time for r in recs],
                        [max(r.complementarity_error, 1e-16) for r in recs], marker=".",
                        color=f"C{k % 10}", label=f"fine solve {k + 1}" if k < 6 else None)
        ax.axhline(1e-8, color="k", lw=0.5, ls="--")
        ax.set_title(f"{pc}: {n}x{n}, mean pressure 0.005 E*")
        ax.set_xlabel("wall time [s]")
        ax.legend(fontsize=7)
    axes[0].set_ylabel("complementarity error / rms height")
    fig.tight_layout()
    fig.savefig("error_vs_time.png", dpi=120)
