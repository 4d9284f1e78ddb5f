"""Shared pieces of the reference paper's studies: command line, outputs, sphere grids, plots.

Every study is ``run(size, outdir) -> dict`` (collective: call it on every
rank) plus a command line ``python examples/studies/<study>.py [--size
small|default] [--out DIR] [PETSc options]``.  Data go to CSV and JSON files
and figures to PNG files in the output directory; rank 0 writes them.
"""
from __future__ import annotations

import argparse
import csv
import json
import os
import sys
from pathlib import Path

import numpy as np


def parse(description: str, default_out: str, sizes=("small", "default"), extra=None):
    """(args, PETSc options) of a study's command line; initialises petsc4py with the rest.
    ``extra(parser)`` adds a study's own arguments."""
    ap = argparse.ArgumentParser(description=description)
    if extra is not None:
        extra(ap)
    ap.add_argument("--size", choices=sizes, default="default",
                    help="small: seconds, for tests; default: the study itself (minutes); "
                         "others: see the study's docstring")
    ap.add_argument("--out", default=default_out, help="output directory (default %(default)s)")
    args, rest = ap.parse_known_args()
    import petsc4py
    petsc4py.init([sys.argv[0]] + rest)
    return args


def world():
    from petsc4py import PETSc
    return PETSc.COMM_WORLD.tompi4py()


def is_root() -> bool:
    return world().Get_rank() == 0


def say(*msg) -> None:
    if is_root():
        print(*msg, flush=True)


def prepare(outdir) -> Path:
    out = Path(outdir)
    if is_root():
        out.mkdir(parents=True, exist_ok=True)
    world().Barrier()
    return out


def write_csv(path, rows: list[dict]) -> None:
    """Rows (dicts with the same keys) to CSV, on rank 0."""
    if not is_root() or not rows:
        return
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def write_json(path, data) -> None:
    if is_root():
        with open(path, "w") as f:
            json.dump(data, f, indent=2, default=float)


def path_rows(path, **extra) -> list[dict]:
    """The converged points of a ``paths.Path`` as CSV rows (SI units)."""
    return [dict(extra, step=p.step, branch=p.branch, approach=p.approach, central_gap=p.central_gap,
                 force=p.force, adhesive_force=p.adhesive_force, contact_fraction=p.contact_fraction,
                 stable=p.stable)
            for p in path.points if p.converged]


def jump_rows(path, **extra) -> list[dict]:
    """The located jumps of a ``paths.Path`` as CSV rows (SI units)."""
    return [dict(extra, kind=j.kind, approach_before=j.approach_before, approach_after=j.approach_after,
                 force_before=j.force_before, force_after=j.force_after) for j in path.jumps]


def jkr_contact_radius(radius, work, e_star, load=0.0) -> float:
    """JKR contact radius [m]: a^3 = 3R/(4E*) (W + 3 pi w R + sqrt(6 pi w R W + (3 pi w R)^2))."""
    k = 3 * np.pi * work * radius
    return (3 * radius / (4 * e_star) * (load + k + np.sqrt(max(6 * np.pi * work * radius * load + k * k, 0.0)))) ** (1 / 3)


def sphere_grid(radius, work, e_star, z0, n, load=0.0, span=3.2, comm=None):
    """An isolated n x n window about a sphere's apex: ``span`` times the larger of the JKR
    and Hertz contact radii at ``load`` (the adhesive zone and the LJ tail fit), returned
    with the resolution measure p_peak dx / (E* z0) (elastic displacement of one element
    under the peak LJ attraction, in z0: below ~1 resolves the adhesive zone)."""
    from contactpetsc.grid import SurfaceGrid
    a = max(jkr_contact_radius(radius, work, e_star, load),
            (3 * max(load, 0.0) * radius / (4 * e_star)) ** (1 / 3))
    dx = span * a / n
    p_peak = 16 * work / (9 * np.sqrt(3) * z0)
    return SurfaceGrid(n, n, dx, periodic=False, comm=comm, row_alignment=8), p_peak * dx / (e_star * z0)


# -- plots (rank 0) ------------------------------------------------------------------------------
def plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot


def pressure_map(ax, grid, pressure, title="", scale=1.0, unit="Pa", extent_unit=1e-9):
    """A pressure map (gathered (nx, ny) array) on a diverging scale centred at zero:
    red compressive, blue adhesive."""
    from matplotlib.colors import TwoSlopeNorm
    p = pressure / scale
    lo, hi = min(p.min(), -1e-12), max(p.max(), 1e-12)
    lx, ly = grid.lengths
    im = ax.imshow(p.T, origin="lower", cmap="RdBu_r", norm=TwoSlopeNorm(0.0, lo, hi),
                   extent=(0, lx / extent_unit, 0, ly / extent_unit))
    ax.set_title(title, fontsize=9)
    ax.figure.colorbar(im, ax=ax, shrink=0.8, label=unit)
    return im


def load_approach(ax, path, x_scale, y_scale, label, color, unstable_hollow=True):
    """Loading (filled, ->) and unloading (hollow, <-) markers of a ``paths.Path``; unstable
    prescribed-gap states (central gap, then edge gap: one S-curve) hollow squares."""
    pts = [p for p in path.points if p.converged]
    for branch, marker, face in (("loading", "o", color), ("unloading", "v", "none"),
                                 ("central-gap", "s", None)):
        sel = [p for p in pts if p.branch == branch or (branch == "central-gap" and p.branch == "edge-gap")]
        if not sel:
            continue
        x = np.array([p.approach for p in sel]) / x_scale
        y = np.array([p.force for p in sel]) / y_scale
        if branch == "central-gap":
            stable = np.array([p.stable is not False for p in sel])
            ax.plot(x, y, "-", color=color, lw=0.8)
            ax.plot(x[stable], y[stable], "s", mfc=color, mec=color, ms=3, label=f"{label}, prescribed gap (stable)")
            if unstable_hollow and (~stable).any():
                ax.plot(x[~stable], y[~stable], "s", mfc="none", mec=color, ms=3,
                        label=f"{label}, prescribed gap (unstable)")
            continue
        ax.plot(x, y, "-" + marker, color=color, mfc=face, ms=4, lw=0.8,
                label=f"{label}, {branch} ({'->' if branch == 'loading' else '<-'})")


def dress(ax, xlabel, ylabel, title="", zero_line=False, legend_size=None) -> None:
    """Axis labels, title, a grey zero-force line and a legend."""
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    if title:
        ax.set_title(title)
    if zero_line:
        ax.axhline(0, color="0.7", lw=0.5)
    if legend_size:
        ax.legend(fontsize=legend_size)


def savefig(fig, path) -> None:
    if is_root():
        fig.tight_layout()
        fig.savefig(path, dpi=110)
    plt().close(fig)


def here() -> str:
    return os.path.dirname(os.path.abspath(__file__))


class _LoadReached(Exception):
    pass


def load_until(problem, start, step, load, refine, on_state=None, max_steps=400):
    """Loading path: one displacement-controlled ``paths.sweep`` through start + k step
    (k = 0, 1, ...) [m], stopped at the first state whose net force reaches ``load`` [N].
    One sweep, not one per step, so that every step is checked for a jump (a sweep
    compares each state with the previous one of the same call).  ``on_state`` as for
    ``sweep``.  Raises RuntimeError if a state did not converge or the load was not met."""
    import numpy as np
    from contactpetsc.paths import Path, sweep

    def check(k, st, pt):
        if on_state is not None:
            on_state(k, st, pt)
        if st.force >= load:
            raise _LoadReached

    path = Path()
    try:
        sweep(problem, start + step * np.arange(max_steps), refine=refine, path=path, branch="loading",
              on_state=check)
    except _LoadReached:
        pass
    failed = [p.approach for p in path.points if not p.converged]
    if failed or path.points[-1].force < load:
        raise RuntimeError(f"loading failed at approaches {failed} m (last force {path.points[-1].force:.3e} N)")
    return path


def reach_load(problem, load, approach, rel_tol=1e-3, max_updates=8):
    """Displacement-controlled solves whose approach is updated by the tangent stiffness
    until the net force is ``load`` [N] within ``rel_tol``: load control without the
    stability verdict of ``solve_force`` (a marginal check on a rough surface stops it).
    Starts at ``approach`` [m] from the problem's current state (a loading path that
    passed the load there)."""
    st, prev = None, None
    delta = approach
    for _ in range(max_updates):
        st = problem.solve(approach=delta)
        if abs(st.force - load) <= rel_tol * abs(load):
            break
        slope = st.stiffness
        if not (np.isfinite(slope) and slope > 0) and prev is not None:
            slope = (st.force - prev[1]) / (st.approach - prev[0])     # secant
        if not (np.isfinite(slope) and slope > 0):
            raise RuntimeError(f"reach_load: no positive stiffness at approach {st.approach:.4e} m")
        prev = (st.approach, st.force)
        delta = st.approach + (load - st.force) / slope
    return st


class StudyRecorder:
    """What a study's path writes besides its paths CSV, with the CLI's writers
    (docs/outputs.md): the solver's iterations in ``history_<name>.csv`` (history.csv's
    columns, each labelled with the state it solved), one row per state with its errors,
    FFT pairs and wall time in ``states_<name>.csv`` (curve.csv's meaning), and, with
    ``fields``, the state's pressure and gap in ``<name>/step_NNNN.h5`` (NNNN = the row's
    ``state``).  Rank 0 writes the text files; the field files are collective.  Use as a
    ``paths.sweep`` ``on_state`` callback, or ``record`` a state of one's own."""

    COLUMNS = ["state", "branch", "approach", "force", "adhesive_force", "contact_fraction", "converged",
               "reason", "solver", "newton_iterations", "complementarity_error", "adhesive_error", "total_error",
               "fft_pairs", "wall_time", "stable"]

    def __init__(self, out, name, grid, heights, problem, fields=False):
        self.out, self.name, self.grid, self.heights, self.problem = Path(out), name, grid, heights, problem
        self.fields = self.out / name if fields else None
        self.states = self.history_written = 0
        if self.fields is not None and is_root():
            self.fields.mkdir(parents=True, exist_ok=True)
        world().Barrier()
        for f in (self._history_path, self._states_path):
            if is_root() and f.exists():
                f.unlink()

    @property
    def _history_path(self):
        return self.out / f"history_{self.name}.csv"

    @property
    def _states_path(self):
        return self.out / f"states_{self.name}.csv"

    def __call__(self, k, st, pt):
        self.record(st, pt.branch)

    def record(self, st, branch) -> int:
        """Write state ``st`` (solved on ``branch``); returns its number."""
        from contactpetsc.app.output import write_state
        from contactpetsc.app.recorder import append_text, csv_lines
        self.states += 1
        if self.fields is not None:
            write_state(str(self.fields), self.states, self.grid, self.heights, st, {"study": self.name},
                        types={"pressure": "f8", "gap": "f8"})
        self._append_history(self.states)
        if is_root():
            row = dict(state=self.states, branch=branch, **{c: getattr(st, c) for c in self.COLUMNS[2:]})
            lines = ([self.COLUMNS] if not self._states_path.exists() else []) + [[row[c] for c in self.COLUMNS]]
            append_text(str(self._states_path), csv_lines(lines))
        return self.states

    def flush(self) -> None:
        """The iterations solved after the last recorded state (a failed step, a pull-off
        refinement) to the history, labelled NaN (as the CLI's history.csv)."""
        self._append_history(float("nan"))

    def _append_history(self, step) -> None:
        """The solver's iterations since the last call to the history (rank 0), labelled ``step``."""
        from contactpetsc.app.recorder import append_text
        from contactpetsc.solvers.history import SolveHistory
        new = self.problem.history.records[self.history_written:]
        if is_root() and new:
            append_text(str(self._history_path), SolveHistory(records=new).csv_text(
                header=not self._history_path.exists(), step=step))
        self.history_written = len(self.problem.history.records)


def read_state_fields(directory, state) -> dict:
    """{"pressure", "gap", "approach", "force"} of a ``StudyRecorder`` field file (arrays (nx, ny),
    as ``grid.gather`` gives them)."""
    import h5py
    with h5py.File(Path(directory) / f"step_{state:04d}.h5", "r") as f:
        return dict(pressure=f["pressure"][...].T, gap=f["gap"][...].T, approach=float(f.attrs["approach"]),
                    force=float(f.attrs["force"]))
