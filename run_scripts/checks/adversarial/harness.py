"""Processes, scenes, output readers and verdicts shared by every case of the sweep."""
from __future__ import annotations

import csv
import dataclasses
import json
import math
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np


REPO = Path(__file__).resolve().parents[3]


PYTHON = sys.executable


MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1", "OMP_NUM_THREADS": "1"}


TIMEOUT = 60.0          # s per process; set by --timeout


Z0 = 0.3e-9             # m, the equilibrium separation of most cases (and their grid spacing)


OK, WRONG, LOST, CRASH, HANG, UNCLEAR, LOUD, SLOW = ("OK", "SILENT-WRONG", "LOST-WORK", "CRASH", "HANG",
                                                    "UNCLEAR", "FAILED-LOUD", "SLOW")


@dataclasses.dataclass
class Case:
    name: str
    issue_class: str              # "1".."13", "msg" or a limit's name: the class of defect the case probes
    description: str
    expected: str
    run: Callable[[Path], tuple[str, str]]   # work dir -> (classification, detail)
    ranks: int = 1


# --------------------------------------------------------------------------------------------
# scenes and processes
def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v == math.inf else "-inf" if v == -math.inf
                                            else repr(v))
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, str):
        return json.dumps(v)
    return str(v)


def write_scene(path: Path, scene: dict) -> Path:
    """A scene dict {key: value, table: {key: value}} as a TOML file."""
    lines = [f"{k} = {toml_value(v)}" for k, v in scene.items() if not isinstance(v, dict)]
    for table, body in scene.items():
        if isinstance(body, dict):
            lines += ["", f"[{table}]"] + [f"{k} = {toml_value(v)}" for k, v in body.items()]
    path.write_text("\n".join(lines) + "\n")
    return path


def merged(base: dict, **tables) -> dict:
    """A copy of ``base`` with the given tables' keys replaced (None deletes a key)."""
    out = json.loads(json.dumps(base))
    for table, body in tables.items():
        if not isinstance(body, dict):
            out[table] = body
            continue
        out.setdefault(table, {})
        for k, v in body.items():
            if v is None:
                out[table].pop(k, None)
            else:
                out[table][k] = v
    return out


def z0s(*multiples) -> list[float]:
    return [m * Z0 for m in multiples]


def adhesive_sphere(w=0.05, law="lj", nx=32, e_star=1e10, values=None, out="out", **interaction):
    """A 30 nm sphere on a 32^2 window, dx = z0 = 0.3 nm (the weak-adhesion geometry)."""
    it = {"law": law, "work_of_adhesion": w}
    if law in ("lj", "hardwall-lj"):
        it["z0"] = Z0
    it.update(interaction)
    return {"name": "sweep-sphere",
            "geometry": {"kind": "sphere", "radius": 30e-9, "nx": nx, "dx": Z0},
            "material": {"e_star": e_star}, "interaction": it,
            "protocol": {"control": "approach",
                         "values": values or z0s(-3, -2, -1, -0.5, 0, 0.3, 0, -1, -3)},
            "output": {"directory": out}}


JUMP_VALUES = z0s(-3, -2.5, -2, -1.5, -1, -0.5, 0, 0.5, 1, 0.5, 0, -0.5, -1, -1.5, -2, -2.5, -3,
                  -3.5, -4)


def jump_sphere(out="out", **kw):
    """mu ~ 1: a jump-on while loading, a jump-off while unloading, in about a second."""
    return adhesive_sphere(w=0.3, values=JUMP_VALUES, out=out, **kw)


def hertz_scene(nx=64, dx=2e-9, radius=1e-6, values=(1e-9, 2e-9, 3e-9), out="out"):
    """docs/scenes.md's minimal scene (its window is too small: 58 % covered)."""
    return {"name": "sweep-hertz",
            "geometry": {"kind": "sphere", "radius": radius, "nx": nx, "dx": dx},
            "material": {"e_star": 1e9},
            "protocol": {"control": "approach", "values": list(values)},
            "output": {"directory": out}}


def flat_cell(w=0.1, law="lj", e_star=None, values=None, nx=32, out="out", **interaction):
    """A flat periodic cell (rms height 0); stiff enough (w / E* z0 = 1e-3) that the uniform
    state is stable wherever the law's slope is."""
    it = {"law": law, "work_of_adhesion": w, **interaction}
    if law in ("lj", "hardwall-lj"):
        it.setdefault("z0", Z0)
    return {"name": "sweep-flat",
            "geometry": {"kind": "self-affine", "nx": nx, "dx": Z0, "rms_height": 0.0,
                         "periodic": True},
            "material": {"e_star": e_star or w / (Z0 * 1e-3)}, "interaction": it,
            "protocol": {"control": "approach",
                         "values": values or z0s(-2, -1, -0.5, -0.25, 0, -0.1, -0.15, -0.19, -0.23,
                                                 -0.3, -0.5, -1)},
            "output": {"directory": out}}


def rough_cell(out="out", nx=32, **protocol):
    return {"name": "sweep-rough",
            "geometry": {"kind": "self-affine", "nx": nx, "dx": 1e-8, "rms_slope": 0.1, "seed": 3},
            "material": {"e_star": 5e10},
            "protocol": {"control": "mean_pressure", "values": [1e7, 5e7, 2e8], **protocol},
            "output": {"directory": out}}


@dataclasses.dataclass
class Result:
    rc: int | None
    out: str
    err: str
    seconds: float
    timed_out: bool = False

    @property
    def text(self) -> str:
        return self.out + "\n" + self.err


def env(**extra) -> dict:
    e = dict(os.environ, **MPI_ENV, **extra)
    e["PYTHONPATH"] = str(REPO) + os.pathsep + e.get("PYTHONPATH", "")
    return e


def launch(argv: list, cwd: Path, ranks: int = 1, extra_env=None) -> subprocess.Popen:
    cmd = ([*"mpirun -n".split(), str(ranks)] if ranks > 1 else []) + [PYTHON, *argv]
    return subprocess.Popen(cmd, cwd=cwd, env=env(**(extra_env or {})), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def finish(proc: subprocess.Popen, t0: float, timeout: float | None = None) -> Result:
    """Wait for a process started by ``launch``; on timeout kill its session (mpirun and ranks)."""
    try:
        out, err = proc.communicate(timeout=timeout or TIMEOUT)
        return Result(proc.returncode, out, err, time.time() - t0)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        return Result(None, out, err, time.time() - t0, timed_out=True)


def run_py(argv: list, cwd: Path, ranks=1, extra_env=None, timeout=None) -> Result:
    return finish(launch(argv, cwd, ranks, extra_env), time.time(), timeout)


def cli(cwd: Path, *args, ranks=1, **kw) -> Result:
    return run_py(["-m", "contactpetsc", *map(str, args)], cwd, ranks, **kw)


def run_scene(cwd: Path, scene: dict, *args, name="scene.toml", ranks=1, **kw) -> Result:
    return cli(cwd, "run", write_scene(cwd / name, scene), *args, ranks=ranks, **kw)


def api(cwd: Path, code: str, ranks=1, args=()) -> tuple[Result, dict | None]:
    """Run an API script; it reports with ``report(dict)`` (rank 0 prints one RESULT line)."""
    prelude = textwrap.dedent("""\
        import sys, json, petsc4py
        petsc4py.init(sys.argv)
        import numpy as np
        from petsc4py import PETSc
        def report(d):
            if PETSc.COMM_WORLD.getRank() == 0:
                print("RESULT " + json.dumps(d), flush=True)
        """)
    path = cwd / "case_api.py"
    path.write_text(prelude + code)
    res = run_py([str(path), *args], cwd, ranks)
    found = [ln[7:] for ln in res.out.splitlines() if ln.startswith("RESULT ")]
    return res, (json.loads(found[-1]) if found else None)


# --------------------------------------------------------------------------------------------
# reading outputs (strictly) and judging processes
def strict_json(path: Path):
    def refuse(token):
        raise ValueError(f"{path.name} contains {token}, not JSON")
    return json.loads(path.read_text(), parse_constant=refuse)


def read_curve(out: Path) -> list[dict]:
    with open(out / "curve.csv") as f:
        return list(csv.DictReader(f))


def column(rows: list[dict], name: str) -> np.ndarray:
    return np.array([float(r[name]) for r in rows])


def read_field(path: Path, name="pressure") -> np.ndarray:
    import h5py
    with h5py.File(path, "r") as f:
        return np.array(f[name])


def message(res: Result) -> str:
    lines = [ln for ln in res.err.splitlines() if "error" in ln.lower() or "refus" in ln.lower()]
    return (lines[-1] if lines else (res.err.strip().splitlines() or [""])[-1])[:220]


def abnormal(res: Result) -> tuple[str, str] | None:
    """HANG or CRASH, whatever the case expected."""
    if res.timed_out:
        return HANG, f"no exit within {TIMEOUT:g} s"
    if res.rc is None or res.rc < 0 or res.rc not in (0, 1, 2, 3):
        return CRASH, f"exit {res.rc}: {message(res)}"
    if "Traceback (most recent call last)" in res.err:
        last = res.err.strip().splitlines()[-1][:200]
        return CRASH, f"exit {res.rc} with a traceback: {last}"
    return None


def judge_refusal(res: Result, names: list[str], accept: Callable[[], tuple[str, str]] | None = None,
                  forbidden: tuple = ()) -> tuple[str, str]:
    """A case whose input must be refused (exit 1 or 2, a message naming one of ``names``), or,
    with ``accept``, may instead run and be judged by it."""
    bad = abnormal(res)
    if bad:
        return bad
    if res.rc in (0, 3):
        if accept is not None:
            return accept()
        return WRONG, f"accepted (exit {res.rc}), no refusal naming {names[0]!r}"
    msg = message(res)
    hit = [n for n in forbidden if n.lower() in res.err.lower()]
    if hit:
        return UNCLEAR, f"exit {res.rc}, message uses {hit[0]!r}: {msg}"
    if any(n.lower() in res.err.lower() for n in names):
        return OK, f"refused (exit {res.rc}): {msg}"
    return UNCLEAR, f"exit {res.rc}, no mention of {names[0]!r}: {msg}"


def judge_success(res: Result, check: Callable[[], tuple[str, str]], allow_rc=(0,)) -> tuple[str, str]:
    """A valid case: it must end with an exit in ``allow_rc`` and pass ``check``."""
    bad = abnormal(res)
    if bad:
        return bad
    if res.rc not in allow_rc:
        return LOUD, f"exit {res.rc}: {message(res)}"
    return check()


def within(errors: dict, tol: float, what: str) -> tuple[str, str]:
    worst = max(errors, key=lambda k: errors[k]) if errors else None
    if worst is None:
        return WRONG, f"no {what} to compare"
    ok = errors[worst] <= tol
    return (OK if ok else WRONG), f"{what}: largest error {errors[worst]:.2e} ({worst}) vs tol {tol:g}"


# --------------------------------------------------------------------------------------------
MPI_JOBS = threading.Lock()   # one mpirun at a time: two at once disturbed each other (ORTE errors)


def run_case(case: Case, keep: bool) -> dict:
    d = Path(tempfile.mkdtemp(prefix=f"sweep-{case.name}-"))
    t0 = time.time()
    try:
        if case.ranks > 1:
            with MPI_JOBS:
                outcome, detail = case.run(d)
        else:
            outcome, detail = case.run(d)
    except Exception as exc:  # noqa: BLE001 - a harness error is reported, not fatal
        outcome, detail = "HARNESS-ERROR", f"{type(exc).__name__}: {exc}"
    finally:
        if not keep:
            shutil.rmtree(d, ignore_errors=True)
    return {"case": case.name, "class": case.issue_class, "ranks": case.ranks,
            "description": case.description, "expected": case.expected, "outcome": outcome,
            "detail": detail, "seconds": round(time.time() - t0, 1), **({"dir": str(d)} if keep else {})}


def summary_line(results: list[dict]) -> str:
    counts: dict[str, int] = {}
    for r in results:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    failed = len(results) - counts.get(OK, 0)
    return (f"{counts.get(OK, 0)} passed, {failed} failed: " +
            ", ".join(f"{n} {k}" for k, n in sorted(counts.items()) if k != OK))


def markdown(results: list[dict]) -> str:
    """The table: case, class, what it does, expected, what happened, classification."""
    def cell(s):
        return str(s).replace("|", "\\|").replace("\n", " ")
    lines = [summary_line(results), "",
             "| case | class | probe | expected | outcome | classification |", "|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| `{r['case']}` | {r['class']} | {cell(r['description'])} | {cell(r['expected'])} | "
                     f"{cell(r['detail'])} | **{r['outcome']}** |")
    return "\n".join(lines) + "\n"
