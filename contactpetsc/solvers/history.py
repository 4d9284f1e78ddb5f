"""Per-iteration solver history: the raw material of "error against run time"."""
from __future__ import annotations

import csv
import io
import time
from dataclasses import dataclass, field, asdict


@dataclass
class HistoryRecord:
    """One iteration of a solve.

    ``complementarity_error`` is max_i |min(K_ii p_i, g_i)| [m] relative to a
    length scale (the surface's rms height unless stated), ``load_error`` the
    relative mismatch of the net force (load control), NaN otherwise.
    """
    solve: int            #: index of the solve (step of a sweep, outer load iteration)
    iteration: int        #: Newton (or relaxation) iteration within the solve
    wall_time: float      #: seconds since the history was created
    fft_pairs: float      #: FFT pairs in fine-grid units, cumulative (coarse levels weighted by size)
    linear_iterations: int  #: Krylov iterations, cumulative
    complementarity_error: float
    load_error: float
    approach: float       #: rigid-body approach delta [m]
    mean_pressure: float  #: [Pa]
    contact_fraction: float
    solver: str = ""
    adhesive_error: float = float("nan")  #: max K_ii |a - a(g)| / z0 (adhesive solves)
    total_error: float = float("nan")     #: the reference paper's E_Total / z0 (relaxation solver)
    #: pressure error on the law's scale (adhesive solves, see ``AdhesiveProblem._measures``;
    #: the relaxation solver: rms(a(g) - a) / P, P the law's peak attraction)
    pressure_error: float = float("nan")
    #: complementarity error relative to min(length scale, interference) (contact solves)
    interference_error: float = float("nan")
    #: the paper's contact measure: rms of g - f(p) at the loaded or penetrating nodes / z0 (relaxation solver)
    rms_contact_residual: float = float("nan")


@dataclass
class SolveHistory:
    """Records of every iteration of every solve, with a common clock."""
    records: list = field(default_factory=list)
    t0: float = field(default_factory=time.perf_counter)

    def elapsed(self) -> float:
        return time.perf_counter() - self.t0

    def append(self, **kw) -> HistoryRecord:
        rec = HistoryRecord(wall_time=self.elapsed(), **kw)
        self.records.append(rec)
        return rec

    def __len__(self):
        return len(self.records)

    def __getitem__(self, i):
        return self.records[i]

    def column(self, name: str) -> list:
        return [getattr(r, name) for r in self.records]

    def csv_text(self, header: bool = True, step: float | None = None) -> str:
        """All records as CSV text, one row per iteration; with ``step`` a last column ``step``
        of that value (the run's step the iterations solved, docs/outputs.md)."""
        out = io.StringIO()
        names = list(HistoryRecord.__dataclass_fields__) + ([] if step is None else ["step"])
        w = csv.DictWriter(out, fieldnames=names)
        if header:
            w.writeheader()
        for r in self.records:
            w.writerow(asdict(r) if step is None else dict(asdict(r), step=step))
        return out.getvalue()

    def write_csv(self, path: str) -> None:
        """Write all records to ``path`` (call on one rank only)."""
        with open(path, "w", newline="") as f:
            f.write(self.csv_text())
