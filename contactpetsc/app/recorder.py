"""The step recorder: everything a run writes, written as soon as it is known.

Per finished step, in this order (rank 0 for the text files, every rank for
the field file): ``step_NNNN.h5`` (renamed into place when complete; the steps
``writes_fields`` picks) and ``fields.xdmf``, the step's rows of
``atom_forces.csv`` and ``jumps.csv``, its row of ``curve.csv`` -- the
step's commit point --, its iterations in
``history.csv``, then ``summary.json``.  The CSV files are appended (whole
lines, flushed and synced), so the cost of a step does not grow with the
path.  ``resume`` reads back what an interrupted run left: the rows of
``curve.csv`` (a partial last row is dropped and that step solved again; a
damaged earlier row is refused, naming the file and the row), the step files
of those steps (each checked: intact, the grid's shape, ``axes = "y,x"``), and the
rows of ``jumps.csv`` and ``atom_forces.csv`` of those steps.  The path resumes
from the last step with a field file: the rows after it (steps that
``output.field_every`` left without a file) are dropped and solved again.
"""
from __future__ import annotations

import csv
import io
import json
import math
import os

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_call
from .output import (COLLECTION, check_step_file, read_written_step, scene_field_types, write_collection,
                     write_state, write_text_atomic)
from .plots import is_number

CURVE_COLUMNS = ["step", "branch", "approach_m", "force_N", "mean_pressure_Pa", "contact_fraction",
                 "adhesive_force_N", "adhesive_load_ratio", "adhesive_area_ratio", "alpha_star", "W_star",
                 "central_gap_m", "stable", "complementarity_error", "adhesive_error", "total_error",
                 "load_error", "converged", "reason", "solver", "newton_iterations",
                 "krylov_iterations", "fft_pairs", "wall_time_s", "window_reach", "pressure_error",
                 "interference_error", "plastic_fraction", "plastic_volume_m3", "max_plastic_displacement_m",
                 "mean_gap_m", "mean_gap_error_m", "stability_checked", "energy_J", "stability_margin",
                 "stability_settled"]
JUMP_COLUMNS = ["step", "kind", "approach_before_m", "approach_after_m", "force_before_N", "force_after_N"]
ATOM_COLUMNS = ["step", "approach_m", "atom", "x_m", "y_m", "radius_m", "force_N"]
NAN = float("nan")


def json_safe(value):
    """``value`` with every non-finite float as None (JSON has no NaN)."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, (float, np.floating)):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.bool_):
        return bool(value)
    return value


def csv_lines(rows) -> str:
    out = io.StringIO()
    csv.writer(out).writerows(rows)
    return out.getvalue()


def append_text(path: str, text: str) -> None:
    """Append whole lines and sync them: a finished row is on disk when this returns."""
    with open(path, "a", newline="") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


class StepRecorder:
    """The files of one run (see the module docstring); collective where it writes fields.

    ``progress(state, row)`` gives a step's progress columns (the stepper's), printed
    before the elapsed time and time left; ``header`` heads them.  On a non-periodic
    window the zone carrying |p| > ``zone_threshold`` [Pa] is measured at every step
    (``metrics.window_reach``, column ``window_reach``) and a warning printed when it
    reaches the window's edge.  ``jumps``: the path locates jumps (``jumps.csv``);
    ``pull_off``: it refines its pull-off, so each new most tensile stable state writes its
    file (``writes_fields``; default: a sweep locating jumps that refines).
    """

    def __init__(self, scene: dict, grid, heights, out_dir: str, header: str, progress, *, tip=None,
                 zone_threshold: float = 0.0, jumps: bool = False, pull_off: bool | None = None):
        self.scene, self.grid, self.heights, self.out_dir = scene, grid, heights, out_dir
        self.progress, self.tip, self.zone_threshold = progress, tip, zone_threshold
        self.keeps_jumps = jumps
        self.rank0 = grid.mpi_comm.Get_rank() == 0
        self.total = len(scene["protocol"]["values"])
        self.rows, self.jumps, self.edge_steps = [], [], []
        self.summary = {}
        self.history_written = self.unconverged = 0
        self.provenance = None
        out = scene["output"]
        self.types = scene_field_types(scene)   #: {field: type code} of the step files; {}: none
        self.every, self.length_unit = out["field_every"], out["length_unit"]
        # a sweep that refines the pull-off restarts the refinement from its most tensile state's
        # file (``pull_off``: the stepper's ``refines``; by default a sweep locating jumps that does)
        self.pull_off_files = jumps and scene["protocol"]["refine_pull_off"] if pull_off is None else pull_off
        self.written = []   #: (step, approach, types) of the step files of the path, for fields.xdmf
        if self.types:
            from ..stack import CITATION, describe
            self.provenance = {"scene": scene, "versions": describe(grid.comm), "citation": CITATION}
        self.path = lambda name: os.path.join(out_dir, name)
        PETSc.Sys.Print(header)

    # -- restart -----------------------------------------------------------------------------
    def resume(self, fields: tuple, stored: dict | None) -> None:
        """Read back the steps on disk (rank 0, broadcast), refuse them when ``stored`` (the
        scene on disk) has other physics than this run's, and rewrite the text files to them."""
        from .rundir import RunDirectoryError, differences
        comm = self.grid.mpi_comm
        if not self.types:
            raise RuntimeError("restart needs the field files: set output.fields = true (or a list)")
        got = collective_call(comm, RunDirectoryError, f"cannot restart from {self.out_dir}: {{error}}",
                              lambda: self._read_back(fields) if self.rank0 else None)
        self.rows, self.jumps, atoms, steps, notes = comm.bcast(got, root=0)
        differ = differences(stored, self.scene, len(self.rows)) if stored is not None else []
        if differ:
            raise RunDirectoryError(f"cannot restart in {self.out_dir!r}: the run there solved another problem ("
                                    + "; ".join(differ) + "); choose another --output, or --overwrite it")

        def check_files():   # each intact; (step, approach, types) for fields.xdmf
            out = []
            for k in steps:
                check_step_file(self.path(f"step_{k:04d}.h5"), self.grid, fields)
                out.append((k,) + read_written_step(self.path(f"step_{k:04d}.h5")))
            return out

        self.written = comm.bcast(collective_call(comm, RunDirectoryError,
                                                  f"cannot restart from {self.out_dir}: {{error}}",
                                                  lambda: check_files() if self.rank0 else None), root=0)
        for line in notes:
            PETSc.Sys.Print(f"  note: {line}")

        def rewrite():   # the files as the steps kept (current columns; no partial rows)
            write_text_atomic(self.path("curve.csv"), csv_lines([CURVE_COLUMNS] + [
                [r[c] for c in CURVE_COLUMNS] for r in self.rows]))
            if self.keeps_jumps:
                write_text_atomic(self.path("jumps.csv"), csv_lines([JUMP_COLUMNS] + [
                    [j[c] for c in JUMP_COLUMNS] for j in self.jumps]))
            if atoms is not None:
                write_text_atomic(self.path("atom_forces.csv"), csv_lines([ATOM_COLUMNS] + atoms))
            _drop_partial_line(self.path("history.csv"))
            _add_step_column(self.path("history.csv"))
            _remove_steps_after(self.out_dir, len(self.rows))   # solved (and written) again
            write_collection(self.out_dir, self.grid, self.written, self.length_unit)

        collective_call(comm, OSError, f"cannot rewrite the files of {self.out_dir}: {{error}}",
                        lambda: rewrite() if self.rank0 else None)
        PETSc.Sys.Print(f"  restart: {len(self.rows)} of {self.total} steps already done")

    def _read_back(self, fields):
        notes = []
        rows = _read_rows(self.path("curve.csv"), ("step", "approach_m", "force_N", "converged"), notes,
                          numeric=("step", "approach_m", "force_N"))
        for k, r in enumerate(rows, 1):
            if r["step"] != str(k):
                raise ValueError(f"{self.path('curve.csv')}, row {k}: step {r['step']!r}, expected {k}")
        # the steps with a field file; the path resumes after the last one
        steps = [k for k in range(1, len(rows) + 1) if os.path.exists(self.path(f"step_{k:04d}.h5"))]
        done = steps[-1] if steps else 0
        if done < len(rows):
            notes.append(f"steps {done + 1}-{len(rows)} of curve.csv have no field file to resume from "
                         f"(output.field_every): they are solved again")
            rows = rows[:done]
        # rows of the steps on disk (files of an older version have no step column: all kept)
        jumps = [dict(j, step=j.get("step", "nan"))
                 for j in _read_rows(self.path("jumps.csv"), JUMP_COLUMNS[1:], notes, JUMP_COLUMNS[2:])
                 if float(j.get("step", 0)) <= done]
        atoms = None
        if os.path.exists(self.path("atom_forces.csv")):
            atoms = [[a.get(c, "nan") for c in ATOM_COLUMNS]
                     for a in _read_rows(self.path("atom_forces.csv"), ATOM_COLUMNS[1:], notes,
                                              ATOM_COLUMNS[1:])
                     if float(a.get("step", 0)) <= done]
        for r in rows:
            for c in CURVE_COLUMNS:
                r.setdefault(c, "nan")   # a column an older version did not write
        return rows, jumps, atoms, steps, notes

    def written_steps(self) -> list:
        """The steps of the path that have a field file."""
        return [k for k, _, _ in self.written]

    def read_step(self, step: int, fields: tuple) -> tuple[list, float]:
        """([Vec per field], approach) of step ``step``'s file; every rank reads its rows."""
        import h5py
        grid, path = self.grid, self.path(f"step_{step:04d}.h5")

        def read():
            check_step_file(path, grid, fields)
            with h5py.File(path, "r") as f:
                return ([np.asarray(f[name][grid.ys:grid.ye, :], dtype=float) for name in fields],
                        float(f.attrs["approach"]))

        arrays, approach = collective_call(grid.mpi_comm, RuntimeError, f"cannot restart from {path}: {{error}}",
                                           read)
        vecs = []
        for rows in arrays:
            v = grid.create_vec()
            grid.rows(v)[...] = rows
            vecs.append(v)
        return vecs, approach

    def path_state(self, step: int) -> dict:
        """The ``path_state`` stored with step ``step`` (``record``), {} in files of older versions."""
        import h5py
        path = self.path(f"step_{step:04d}.h5")

        def read():
            with h5py.File(path, "r") as f:
                return json.loads(f.attrs.get("path_state", "{}"))

        got = collective_call(self.grid.mpi_comm, RuntimeError, f"cannot restart from {path}: {{error}}",
                              lambda: read() if self.rank0 else None)
        return self.grid.mpi_comm.bcast(got, root=0)

    # -- a step ------------------------------------------------------------------------------
    def start(self) -> None:
        """Headers of new files; the clock of the progress line starts here."""
        if self.rank0:
            for name, columns in (("curve.csv", CURVE_COLUMNS), ("jumps.csv", JUMP_COLUMNS)):
                if not os.path.exists(self.path(name)) and (name != "jumps.csv" or self.keeps_jumps):
                    write_text_atomic(self.path(name), csv_lines([columns]))
            if self.tip is not None and not os.path.exists(self.path("atom_forces.csv")):
                write_text_atomic(self.path("atom_forces.csv"), csv_lines([ATOM_COLUMNS]))
        self.first = len(self.rows)
        self.unconverged = sum(not is_true(r["converged"]) for r in self.rows)
        self.t_start = MPI.Wtime()

    def record(self, st, row: dict, problem, new_jumps=(), results: dict | None = None,
               path_state: dict | None = None) -> None:
        """Write step ``row['step']`` (state ``st``; ``row`` keyed by CURVE_COLUMNS; the jumps found
        reaching it; the path's ``results`` so far, for summary.json; ``path_state``: what the
        path's next step decides by, stored in the step file for a restart, ``path_state``) and print it."""
        step = row["step"]
        share = 0.0
        if not self.grid.periodic:
            from ..metrics import window_reach
            row["window_reach"], share = window_reach(self.grid, st.pressure, self.zone_threshold)
        if self.types and self.writes_fields(row, new_jumps):
            attrs = self.provenance if path_state is None else dict(self.provenance, path_state=path_state)
            write_state(self.out_dir, step, self.grid, self.heights, st, attrs, types=self.types,
                        length_unit=self.length_unit)
            self.written.append((step, st.approach, self.types))
            collective_call(self.grid.mpi_comm, OSError, f"cannot write {self.path(COLLECTION)}: {{error}}",
                            lambda: write_collection(self.out_dir, self.grid, self.written, self.length_unit)
                            if self.rank0 else None)
        atoms = self._atom_rows(step, st) if self.tip is not None else []
        jumps = [dict(zip(JUMP_COLUMNS, [step, j.kind, j.approach_before, j.approach_after, j.force_before,
                                         j.force_after])) for j in new_jumps]
        self.jumps += jumps
        self.rows.append(row)
        self.unconverged += not is_true(row["converged"])

        def append():
            if atoms:
                append_text(self.path("atom_forces.csv"), csv_lines(atoms))
            if jumps:
                append_text(self.path("jumps.csv"), csv_lines([[j[c] for c in JUMP_COLUMNS] for j in jumps]))
            append_text(self.path("curve.csv"), csv_lines([[row[c] for c in CURVE_COLUMNS]]))
            self._append_history(problem, step)

        # rank 0 writes; a failure (a full disk) is raised on every rank
        collective_call(self.grid.mpi_comm, OSError, f"cannot write step {step} to {self.out_dir}: {{error}}",
                        lambda: append() if self.rank0 else None)
        self._print(st, row)
        for j in new_jumps:
            PETSc.Sys.Print(f"  {j.kind} between approaches {j.approach_before:.4e} and {j.approach_after:.4e} m: "
                            f"force {j.force_before:.4e} -> {j.force_after:.4e} N")
        if row.get("window_reach", NAN) >= 1.0:
            if not self.edge_steps:
                PETSc.Sys.Print(
                    f"  warning: step {step}: the pressure-carrying zone reaches the window's edge (reach "
                    f"{row['window_reach']:.2f} of the half-width, {share:.1%} of the edge nodes): the "
                    "isolated contact is cut there and its forces are off; enlarge the window (nx dx, ny dy)")
            self.edge_steps.append(step)
        self.write_summary(**(results or {}))

    def writes_fields(self, row: dict, new_jumps=()) -> bool:
        """Whether step ``row['step']`` writes its field file: every ``output.field_every``-th step,
        the protocol's last step, the first step on a new branch (a jump reached it), an
        unconverged step, and, on a sweep that refines the pull-off, each new most tensile stable
        state (a restart starts the refinement from its file)."""
        step = row["step"]
        if step % self.every == 0 or step == self.total or new_jumps or not is_true(row["converged"]):
            return True
        if not self.pull_off_files or row["stable"] in (False, "False"):
            return False
        earlier = [float(r["force_N"]) for r in self.rows
                   if is_true(r["converged"]) and r["stable"] not in (False, "False")]
        return not earlier or row["force_N"] < min(earlier)

    def _print(self, st, row) -> None:
        k = row["step"]
        elapsed = MPI.Wtime() - self.t_start
        left = elapsed / (k - self.first) * (self.total - k)
        PETSc.Sys.Print(self.progress(st, row) + f"  [step {k}/{self.total}, {elapsed:.1f} s, ~{left:.1f} s left]"
                        + ("" if st.converged else f"  NOT CONVERGED: {st.reason}"))

    def failed(self, step: int, st) -> None:
        """A step that ends the run: reported, not written (the steps on disk stay a path)."""
        done = step - 1
        self.summary["stopped_at"] = {"step": step, "approach_m": st.approach, "reason": st.reason}
        written = f"steps 1-{done} of {self.total} are written" if done > 1 else (
            f"step 1 of {self.total} is written" if done == 1 else "no step is written")
        PETSc.Sys.Print(f"  step {step} (approach {st.approach:.4e} m) NOT CONVERGED: {st.reason}\n"
                        f"  the run stopped there: {written}; fix the cause and continue with --restart")
        self.write_summary()

    def flush_history(self, problem) -> None:
        """The iterations solved after the last step's row (a failed step, the pull-off
        refinement) appended to history.csv (rank 0)."""
        collective_call(self.grid.mpi_comm, OSError, f"cannot write {self.path('history.csv')}: {{error}}",
                        lambda: self._append_history(problem) if self.rank0 else None)

    def _append_history(self, problem, step: float = NAN) -> None:
        """The iterations since the last call, labelled ``step`` (nan: after the path's last step)."""
        from ..solvers.history import SolveHistory
        new = problem.history.records[self.history_written:]
        self.history_written += len(new)
        path = self.path("history.csv")
        append_text(path, SolveHistory(records=new).csv_text(header=not os.path.exists(path), step=step))

    def _atom_rows(self, step: int, st) -> list:
        from ..metrics import atom_forces
        tip, _, owner = self.tip
        f = atom_forces(self.grid, st.pressure, owner, len(tip.atoms))
        rows = []
        for k in np.flatnonzero(f):
            x, y = tip.atoms[k, :2]
            rows.append([step, st.approach, k, float(x), float(y), float(np.hypot(x, y)), float(f[k])])
        return rows

    def write_summary(self, **results) -> None:
        """summary.json (rank 0): steps, converged, where the run stopped, the window's edge,
        the stepper's ``results`` (pull-off), and the jumps as in jumps.csv."""
        self.summary.update(results)
        s = {"steps": len(self.rows), "converged": self.unconverged == 0 and "stopped_at" not in self.summary}
        s.update(self.summary)
        s["window_edge_steps"] = self.edge_steps
        s["jumps"] = [{c: (j[c] if c == "kind" else _number(j[c], int if c == "step" else float))
                       for c in JUMP_COLUMNS} for j in self.jumps]
        text = json.dumps(json_safe(s), indent=1, allow_nan=False) + "\n"
        collective_call(self.grid.mpi_comm, OSError, f"cannot write {self.path('summary.json')}: {{error}}",
                        lambda: write_text_atomic(self.path("summary.json"), text) if self.rank0 else None)


def _read_rows(path: str, required, notes: list, numeric=()) -> list[dict]:
    """The rows of a CSV file as dicts; a partial last line is dropped (noted), a short or
    damaged earlier row (a ``numeric`` column that is not a number) refused, naming the
    file and the row."""
    if not os.path.exists(path):
        return []
    with open(path, newline="") as f:
        text = f.read()
    lines = text.splitlines(keepends=True)
    if not lines:
        return []
    header = next(csv.reader([lines[0]]))
    missing = [c for c in required if c not in header]
    if missing:
        raise ValueError(f"{path}: no column {', '.join(missing)} in its header")
    rows = []
    for n, line in enumerate(lines[1:], 1):
        words = next(csv.reader([line]), [])
        bad = (len(words) != len(header) or not line.endswith("\n")
               or any(not is_number(words[header.index(c)]) for c in numeric))
        if bad and n == len(lines) - 1:
            notes.append(f"{path}: dropped its partial last row {n} (written when the run was interrupted); "
                         "that step is solved again")
            break
        if bad:
            raise ValueError(f"{path}, row {n}: {len(words)} of {len(header)} columns or a damaged value; "
                             "the file is damaged (fix or remove that row, or start again with --overwrite)")
        rows.append(dict(zip(header, words)))
    return rows


def _number(word, kind):
    """``kind(word)``, or None when ``word`` is not a finite number (a step an older version
    did not record)."""
    value = float(word)
    return kind(value) if math.isfinite(value) else None


def _add_step_column(path: str) -> None:
    """A history.csv of an older version, without the step column, given one (nan)."""
    if not os.path.exists(path):
        return
    with open(path, newline="") as f:
        lines = f.read().splitlines(keepends=True)
    if lines and "step" not in next(csv.reader([lines[0]])):
        write_text_atomic(path, "".join(line.rstrip("\r\n") + (",step" if k == 0 else ",nan") + "\r\n"
                                        for k, line in enumerate(lines)))


def is_true(flag) -> bool:
    """A ``converged`` flag, as solved (bool) or read back from curve.csv (text)."""
    return flag in (True, "True")


def _remove_steps_after(out_dir: str, done: int) -> None:
    """Remove the step files (and their leftovers) of steps after ``done``: those steps are
    solved again, and written again as the run's settings say."""
    from .rundir import STEP_FILE
    for name in os.listdir(out_dir):
        core = name.removesuffix(".tmp")
        if STEP_FILE.match(core) and int(core[5:].split(".")[0]) > done:
            os.remove(os.path.join(out_dir, name))


def _drop_partial_line(path: str) -> None:
    if not os.path.exists(path):
        return
    with open(path, "rb") as f:
        data = f.read()
    if data and not data.endswith(b"\n"):
        write_text_atomic(path, data[:data.rfind(b"\n") + 1].decode())
