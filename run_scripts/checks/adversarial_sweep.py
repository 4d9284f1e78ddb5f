"""Adversarial sweep: bad scenes, bad files, kills, full disks, concurrent runs, extreme physics
and API misuse, each case run through the product's front doors (``contactpetsc run``,
``contactpetsc plot``, the Python API) in a process of its own under a wall-time bound.

Every case has an expected outcome of its own, computed here without the package: the law
summed over a rigid sphere's gap (F = sum p(h - delta) dx dy, the laws of docs/formulation.md
written out below), the flat periodic cell (F = A p(-delta), pull-off -A times the law's peak),
Hertz (F = 4/3 E* R^1/2 delta^3/2) on a big window, a sphere kept 10 z0 away (no jumps, no
pull-off), an uninterrupted run (kill and restart), a second process (two runs into one
directory), the signature of PETSc's random vector (a failed step's pressure uniform in [0, 1)),
strict JSON, and the axis round trip of a step file fed back as ``kind = "file"``.

Outcomes:
  OK            the right answer within the stated tolerance, or a loud refusal (exit 1 or 2 and
                a message naming the offending key or file)
  SILENT-WRONG  exit 0 (or "converged") with a wrong or mixed answer, or bad input accepted
  LOST-WORK     finished results missing after a kill and --restart
  CRASH         a signal, a traceback instead of a message, an exit code outside {0, 1, 2, 3}
  HANG          the wall-time bound was reached
  UNCLEAR       refused, but the message names no key or file (or names internals)
  FAILED-LOUD   valid input that should give an answer ended with a non-zero exit instead
  SLOW          the per-step cost grows along a run (bookkeeping)

    python run_scripts/checks/adversarial_sweep.py --list
    python run_scripts/checks/adversarial_sweep.py --only flat --timeout 60 --markdown sweep.md
    python run_scripts/checks/adversarial_sweep.py --jobs 2 --markdown sweep.md    # all, ~6 min on 2 cores

One JSON line per case on stdout, then the counts; the exit status is 0 only when every case
is OK.  Cases under mpirun (2 ranks) run one at a time.
"""
from __future__ import annotations

import argparse
import concurrent.futures
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

REPO = Path(__file__).resolve().parents[2]
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
    issue_class: str              # "1".."13" or "msg" (issue 19's numbering)
    description: str
    expected: str
    run: Callable[[Path], tuple[str, str]]   # work dir -> (classification, detail)
    ranks: int = 1


# --------------------------------------------------------------------------------------------
# interaction laws, written out from docs/formulation.md (pressure [Pa], compressive positive)
def law_pressure(law: str, g, w: float, z0: float = Z0, rho: float | None = None,
                 sigma0: float | None = None):
    """p(g) [Pa] of a law at gap g [m] (hard-wall laws: the adhesive part for g >= 0)."""
    g = np.asarray(g, dtype=float)
    if law in ("lj", "hardwall-lj"):
        t = z0 / (g + z0)
        return 8 * w / (3 * z0) * (t ** 9 - t ** 3)
    if law == "exponential":
        return -(w / rho) * np.exp(-g / rho)
    if law == "dugdale":
        return np.where(g < w / sigma0, -sigma0, 0.0)
    return np.zeros_like(g)


def law_peak(law: str, w: float, z0: float = Z0, rho=None, sigma0=None) -> float:
    """The law's largest tension [Pa] (> 0)."""
    return {"lj": 16 * w / (9 * math.sqrt(3) * z0), "hardwall-lj": 16 * w / (9 * math.sqrt(3) * z0),
            "exponential": w / rho if rho else 0.0, "dugdale": sigma0 or 0.0}[law]


def sphere_heights(nx: int, ny: int, dx: float, dy: float, radius: float) -> np.ndarray:
    """Paraboloid heights [m], indexed [j, i] (row = y), apex at node (nx//2, ny//2)."""
    x = (np.arange(nx) - nx // 2) * dx
    y = (np.arange(ny) - ny // 2) * dy
    return (x[None, :] ** 2 + y[:, None] ** 2) / (2 * radius)


def rigid_force(h: np.ndarray, delta: float, dx: float, dy: float, law: str, w: float,
                **kw) -> float:
    """F = sum p(h - delta) dx dy [N] of a rigid surface at approach delta [m]."""
    return float(np.sum(law_pressure(law, h - delta, w, **kw)) * dx * dy)


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
    """A 30 nm sphere on a 32^2 window, dx = z0 = 0.3 nm (issue 19's weak-adhesion geometry)."""
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
    return run_py(["-m", "contactpetsc.cli", *map(str, args)], cwd, ranks, **kw)


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
# class 1 and 3: the rigid sphere (negligible deformation) and the far sphere
def law_kwargs(scene: dict) -> dict:
    it = scene.get("interaction", {})
    return {k: it[k] for k in ("z0", "rho", "sigma0") if k in it}


def check_rigid_sphere(scene: dict, out: Path, tol: float, no_jumps=False) -> tuple[str, str]:
    """Forces and nodal pressures of every step against the law over the rigid sphere's gap."""
    g, it = scene["geometry"], scene["interaction"]
    law, w, kw = it["law"], it["work_of_adhesion"], law_kwargs(scene)
    h = sphere_heights(g["nx"], g["nx"], g["dx"], g["dx"], g["radius"])
    rows = read_curve(out)
    if len(rows) != len(scene["protocol"]["values"]):
        return LOST, f"{len(rows)} rows in curve.csv for {len(scene['protocol']['values'])} steps"
    truth = [rigid_force(h, float(r["approach_m"]), g["dx"], g["dx"], law, w, **kw) for r in rows]
    scale = max(abs(t) for t in truth)
    errors = {f"F step {r['step']}": abs(float(r["force_N"]) - t) / scale for r, t in zip(rows, truth)}
    peak = law_peak(law, w, **kw)
    for r in rows:
        # the law at the step's own gap (self-consistency), and that gap against the rigid
        # sphere's (negligible deformation): a steep repulsive law amplifies a 1e-4 z0 gap
        # change, so the nodal pressures are not compared with the rigid gap's directly
        path = out / f"step_{int(r['step']):04d}.h5"
        p, gap = read_field(path), read_field(path, "gap")
        errors[f"p(g) step {r['step']}"] = float(np.max(np.abs(p - law_pressure(law, gap, w, **kw)))) / peak
        rigid_gap = h - float(r["approach_m"])
        errors[f"gap/z0 step {r['step']}"] = float(np.max(np.abs(gap - rigid_gap))) / Z0
    verdict, detail = within(errors, tol,
                             "rigid-sphere F (rel. max|F|), nodal p - p(g) (rel. peak), gap (z0)")
    if no_jumps and verdict == OK:
        summary = strict_json(out / "summary.json")
        with open(out / "jumps.csv") as f:
            n_jumps = sum(1 for _ in f) - 1
        if n_jumps or summary.get("jumps"):
            return WRONG, f"{n_jumps} jump(s) in jumps.csv of a sphere never within 10 z0"
        if summary.get("pull_off_force_N") is not None:
            return WRONG, f"pull-off {summary['pull_off_force_N']:.3e} N reported for a far sphere"
        detail += "; no jumps, no pull-off"
    return verdict, detail


def rigid_sphere_case(name, w, e_star, law="lj", values=None, ranks=1, tol=1e-3, klass="1",
                      no_jumps=False, **interaction) -> Case:
    scene = adhesive_sphere(w=w, law=law, e_star=e_star, values=values, **interaction)
    ratio = w / (e_star * Z0)

    def run(d):
        res = run_scene(d, scene, ranks=ranks)
        return judge_success(res, lambda: check_rigid_sphere(scene, d / "out", tol, no_jumps))
    what = "far sphere (min gap 10 z0)" if no_jumps else "rigid sphere"
    return Case(name, klass, f"{law} sphere, w = {w:g} J/m^2, E* = {e_star:g} Pa (w/E*z0 = {ratio:.0e}), "
                f"{ranks} rank(s)",
                f"{what}: F = sum p(h-delta) dxdy, p = p(g) at every node, g = h - delta, "
                f"all within {tol:g}" +
                ("; no jumps, pull-off null" if no_jumps else ""), run, ranks)


FAR = z0s(-30, -25, -20, -15, -12, -10, -12, -15, -20, -25, -30)


def api_weak_adhesion_case(w, ranks) -> Case:
    code = f"""
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc import surfaces
        from contactpetsc.physics.interactions import make_law
        from contactpetsc.solvers.adhesive import AdhesiveProblem
        grid = SurfaceGrid(32, 32, {Z0!r}, periodic=False)
        problem = AdhesiveProblem(grid, surfaces.sphere(grid, 30e-9), 1e10,
                                  make_law("lj", work_of_adhesion={w!r}, z0={Z0!r}))
        out = []
        for m in (-3, -2, -1, -0.5, 0.0, -1, -3):
            st = problem.solve(approach=m * {Z0!r})
            out.append([st.approach, st.force, bool(st.converged)])
        report({{"states": out}})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code), ranks)

        def check():
            if rep is None:
                return WRONG, "no result printed"
            h = sphere_heights(32, 32, Z0, Z0, 30e-9)
            truth = [rigid_force(h, a, Z0, Z0, "lj", w) for a, _, _ in rep["states"]]
            scale = max(map(abs, truth))
            errors = {f"approach {a / Z0:+.1f} z0": abs(f - t) / scale
                      for (a, f, _), t in zip(rep["states"], truth)}
            if not all(c for *_, c in rep["states"]):
                return LOUD, "some states not converged"
            return within(errors, 1e-3, "API AdhesiveProblem.solve force vs rigid sphere")
        return judge_success(res, check)
    return Case(f"api-weak-adhesion-w{w:g}-np{ranks}", "1", f"AdhesiveProblem.solve, lj, w = {w:g}, "
                f"E* = 1e10, {ranks} rank(s)", "rigid-sphere force within 1e-3", run, ranks)


# --------------------------------------------------------------------------------------------
# class 2 and 3: the flat periodic cell
def flat_case(name, w=0.1, law="lj", values=None, e_star=None, refine=True, ranks=1, klass="2",
              check_forces=True, no_jumps=False, tol=1e-3, **interaction) -> Case:
    scene = flat_cell(w=w, law=law, values=values, e_star=e_star, **interaction)
    scene["protocol"]["refine_pull_off"] = refine
    kw = law_kwargs(scene)
    n = scene["geometry"]["nx"]
    area = (n * Z0) ** 2
    peak = law_peak(law, w, **kw)

    def check(out: Path):
        rows = read_curve(out)
        approaches = column(rows, "approach_m")
        truth = area * law_pressure(law, -approaches, w, **kw)
        errors = {}
        if check_forces:
            errors.update({f"F step {r['step']}": abs(float(r["force_N"]) - t) / (area * peak)
                           for r, t in zip(rows, truth)})
        summary = strict_json(out / "summary.json")
        unloading = [t for r, t in zip(rows, truth) if r["branch"] == "unloading"]
        expected = -area * peak if refine else min(unloading or truth)
        pull = summary.get("pull_off_force_N")
        if pull is None:
            return WRONG, f"no pull-off reported; expected {expected:.4e} N"
        errors["pull-off"] = abs(pull - expected) / (area * peak)
        verdict, detail = within(errors, tol, f"flat cell F = A p(-delta), pull-off {expected:.4e} N "
                                              f"(reported {pull:.4e})")
        if no_jumps and verdict == OK and summary.get("jumps"):
            return WRONG, f"{len(summary['jumps'])} jump(s) on a smooth flat-cell branch"
        return verdict, detail

    def run(d):
        res = run_scene(d, scene, ranks=ranks)
        return judge_success(res, lambda: check(d / "out"))
    return Case(name, klass, f"flat periodic cell 32^2, {law}, w = {w:g}, E* = "
                f"{scene['material']['e_star']:.2g}, refine_pull_off = {refine}, {ranks} rank(s)",
                ("pull-off -A x peak" if refine else "pull-off = most tensile sampled unloading state")
                + (", F = A p(-delta) each step" if check_forces else "")
                + (", no jumps" if no_jumps else ""), run, ranks)


# --------------------------------------------------------------------------------------------
# class 4: PETSc's random vector must never be written
def random_signature(p: np.ndarray) -> bool:
    """The output of VecSetRandom: every value in [0, 1), spread uniformly."""
    p = p[np.isfinite(p)]
    return (p.size > 16 and p.min() >= 0 and p.max() < 1 and p.std() > 0.2
            and abs(p.mean() - 0.5) < 0.06)


def random_vector_case(name, scene, args=(), ranks=1) -> Case:
    def run(d):
        res = run_scene(d, scene, *args, ranks=ranks)
        bad = abnormal(res)
        if bad:
            return bad
        out = d / "out"
        if not (out / "curve.csv").exists():
            return judge_refusal(res, ["tol"])
        rows = read_curve(out)
        for r in rows:
            f = out / f"step_{int(r['step']):04d}.h5"
            if f.exists() and random_signature(read_field(f)):
                return WRONG, (f"step {r['step']} ({r['reason']}, exit {res.rc}): pressure is "
                               "PETSc's random vector (uniform in [0, 1))")
        failed = [r for r in rows if r["converged"] != "True"]
        if res.rc == 0 and not failed:
            return OK, "every step converged; no random data"
        if failed and res.rc == 3:
            return OK, f"{len(failed)} step(s) marked not converged ({failed[0]['reason']}), no random data"
        return WRONG, f"exit {res.rc} but converged flags {[r['converged'] for r in rows]}"
    return Case(name, "4", f"Signorini SNES driven to a line-search/local-min failure "
                f"({' '.join(args) or 'solver.tol'}), {ranks} rank(s)",
                "no step file with p uniform in [0,1); failed steps flagged, exit 3", run, ranks)


def api_random_vector_case() -> Case:
    code = """
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc import surfaces
        from contactpetsc.solvers import ContactProblem
        grid = SurfaceGrid(32, 32, 2e-9, periodic=False)
        problem = ContactProblem(grid, surfaces.sphere(grid, 1e-6), 1e9, tol=1e-18)
        st = problem.solve(approach=1e-9, raise_on_failure=False)
        p = grid.gather(st.pressure)
        report({"converged": bool(st.converged), "reason": str(st.reason), "p": p.ravel().tolist()})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code))

        def check():
            if rep is None:
                return WRONG, "no result"
            if random_signature(np.array(rep["p"])):
                return WRONG, f"state.pressure is PETSc's random vector ({rep['reason']})"
            return OK, f"converged={rep['converged']} ({rep['reason']}), pressure not random"
        return judge_success(res, check)
    return Case("api-random-vector", "4", "ContactProblem(tol=1e-18).solve(raise_on_failure=False)",
                "state.pressure is the best iterate, not uniform [0,1) noise", run)


# --------------------------------------------------------------------------------------------
# class 5: questionable input
def same_forces(ref: Path, out: Path, tol: float) -> tuple[str, str]:
    """Forces of the steps ``out`` says converged against the reference run's; a run that
    stopped early is a loud failure if what it kept is right."""
    a, b = read_curve(ref), read_curve(out)
    b = [r for r in b if r["converged"] == "True"]
    if len(b) > len(a):
        return WRONG, f"{len(b)} steps against {len(a)} of the reference run"
    fa, fb = column(a[:len(b)], "force_N"), column(b, "force_N")
    scale = float(np.max(np.abs(column(a, "force_N")))) or 1.0
    errors = {f"step {i + 1}": abs(x - y) / scale for i, (x, y) in enumerate(zip(fa, fb))}
    verdict, detail = within(errors, tol, "converged steps' forces against a default run")
    if verdict == OK and len(b) < len(a):
        return LOUD, f"stopped: {len(b)} of {len(a)} steps converged ({detail})"
    return verdict, detail


def refuse_or_match_case(name, klass, description, scene, names, tol=1e-3, args=(),
                         edit=None) -> Case:
    """Questionable settings: refused naming one of ``names``, or the reference run's answer."""
    def run(d):
        ref = merged(scene, output={"directory": "ref"})
        res = run_scene(d, ref, name="ref.toml")
        if res.rc != 0:
            return LOUD, f"reference run failed: {message(res)}"
        bad_scene = edit(json.loads(json.dumps(scene))) if edit else scene
        res = run_scene(d, bad_scene, *args)
        return judge_refusal(res, names, accept=lambda: same_forces(d / "ref", d / "out", tol))
    return Case(name, klass, description, f"refused naming {names[0]!r}, or the default run's forces "
                f"within {tol:g}", run)


def load_case(name, scene) -> Case:
    """Subnormal or huge loads: refused naming protocol.values, or the load met."""
    def run(d):
        res = run_scene(d, scene)

        def accept():
            rows = read_curve(d / "out")
            control = scene["protocol"]["control"]
            col = "force_N" if control == "force" else "mean_pressure_Pa"
            errors = {f"step {r['step']}": abs(float(r[col]) - t) / abs(t)
                      for r, t in zip(rows, scene["protocol"]["values"])}
            if res.rc == 3:
                return OK, "not converged, exit 3 (a loud failure)"
            return within(errors, 1e-6, f"reported {col} against the prescribed load")
        return judge_refusal(res, ["values", "load", "pressure", "force"], accept=accept)
    vals = scene["protocol"]["values"]
    return Case(name, "5", f"{scene['protocol']['control']} = {vals}",
                "refused naming the load, or the load met to 1e-6 (or exit 3)", run)


def height_file_case(name, klass, make: Callable[[Path], str], nx=16, ny=16, accept=None,
                     dry_run=False, names=None, forbidden=(), periodic=True) -> Case:
    """A height file written by ``make(dir) -> file name`` fed to kind = "file"."""
    def run(d):
        fname = make(d)
        scene = {"name": "sweep-file",
                 "geometry": {"kind": "file", "path": fname, "nx": nx, "ny": ny, "dx": 1e-8,
                              "periodic": periodic},
                 "material": {"e_star": 1e9},
                 "protocol": {"control": "approach", "values": [1e-10]},
                 "output": {"directory": "out"}}
        res = run_scene(d, scene, *(["--dry-run"] if dry_run else []))
        return judge_refusal(res, names or [fname, "geometry.path", "heights"],
                             accept=(lambda: accept(d, res)) if accept else None, forbidden=forbidden)
    what = "--dry-run" if dry_run else "run"
    return Case(name, klass, f"{what} with a height file: {name}",
                f"refused naming the file{' (no ' + forbidden[0] + ')' if forbidden else ''}"
                + (", or read correctly" if accept else ""), run)


def npy(arr, fname="h.npy"):
    def make(d):
        np.save(d / fname, arr)
        return fname
    return make


def raw_file(data: bytes, fname):
    def make(d):
        (d / fname).write_bytes(data)
        return fname
    return make


def h5(arr, fname="h.h5", dataset="heights", **attrs):
    def make(d):
        import h5py
        with h5py.File(d / fname, "w") as f:
            f[dataset] = arr
            for k, v in attrs.items():
                f[dataset].attrs[k] = v
                f.attrs[k] = v
        return fname
    return make


def warn_ok(words):
    """Accept a run that warns with one of ``words`` in its log."""
    def accept(d, res):
        if any(w.lower() in res.text.lower() for w in words):
            return OK, "ran with a warning naming it"
        return WRONG, f"accepted without a word (no {words[0]!r} in the log)"
    return accept


# --------------------------------------------------------------------------------------------
# class 6: axes end to end
def tilted(nx, ny, dx=1e-8, dy=1e-8) -> np.ndarray:
    """An asymmetric surface [m], indexed [j, i] (row = y): any transposition shows."""
    x, y = np.arange(nx) * dx, np.arange(ny) * dy
    return 1e-3 * x[None, :] + 3e-3 * y[:, None] + 2e-10 * np.sin(x[None, :] / dx) ** 2


def round_trip_case(nx, ny, dy=1e-8, ranks=1) -> Case:
    """A self-affine run's step_0001.h5 fed back as kind = "file": the same heights and forces."""
    first = {"name": "sweep-axes",
             "geometry": {"kind": "self-affine", "nx": nx, "ny": ny, "dx": 1e-8, "dy": dy,
                          "rms_height": 1e-9, "seed": 7},
             "material": {"e_star": 1e9},
             "protocol": {"control": "mean_pressure", "values": [2e6]},
             "output": {"directory": "first"}}
    second = merged(first, geometry={"kind": "file", "path": "first/step_0001.h5",
                                     "dataset": "heights", "rms_height": None, "seed": None},
                    output={"directory": "out"})

    def run(d):
        res = run_scene(d, first, name="first.toml", ranks=ranks)
        if res.rc != 0:
            return LOUD, f"first run failed: {message(res)}"
        res = run_scene(d, second, ranks=ranks)

        def check():
            h1 = read_field(d / "first/step_0001.h5", "heights")
            h2 = read_field(d / "out/step_0001.h5", "heights")
            if h1.shape != h2.shape or not np.allclose(h1, h2, rtol=0, atol=1e-12 * np.abs(h1).max()):
                diff = np.abs(h1 - h2).max() if h1.shape == h2.shape else "shape"
                return WRONG, f"heights came back different (max diff {diff}): transposed"
            return same_forces(d / "first", d / "out", 1e-6)
        return judge_refusal(res, ["axes", "transpos", "shape"], accept=check)
    return Case(f"axes-round-trip-{nx}x{ny}{'-dxdy' if dy != 1e-8 else ''}-np{ranks}", "6",
                f"step file of a {nx}x{ny} run fed back as kind = file, {ranks} rank(s)",
                "the same heights (1e-12) and forces (1e-6), or refused naming the axes", run, ranks)


def axes_stamp_case() -> Case:
    def run(d):
        scene = rough_cell(nx=32)
        scene["geometry"]["ny"] = 16
        res = run_scene(d, scene)

        def check():
            import h5py
            with h5py.File(d / "out/step_0001.h5", "r") as f:
                stamps = [f.attrs.get("axes")] + [f[k].attrs.get("axes") for k in f.keys()]
            stamps = [s.decode() if isinstance(s, bytes) else s for s in stamps if s is not None]
            if stamps and all(s == "y,x" for s in stamps):
                return OK, f"axes = 'y,x' on the file/datasets ({len(stamps)})"
            return WRONG, f"step file not stamped with axes = 'y,x' (found {stamps})"
        return judge_success(res, check)
    return Case("axes-stamp", "6", "step file attributes after a 32x16 rough run",
                "attribute axes = 'y,x'", run)


def stamped_input_case(name, shape_order, stamp, nx=24, ny=16) -> Case:
    """A hand-written HDF5 heights file with an axes stamp: read the way it says."""
    yx = tilted(nx, ny)
    arr = yx if shape_order == "yx" else yx.T

    def accept(d, res):
        if res.rc != 0:
            return LOUD, f"exit {res.rc}: {message(res)}"
        got = read_field(d / "out/step_0001.h5", "heights")
        if got.shape == yx.shape and np.allclose(got, yx, atol=1e-15):
            return OK, "heights read in the stamped order"
        return WRONG, "heights read in the wrong order"
    make = h5(arr, **({"axes": stamp} if stamp else {}))
    return height_file_case(name, "6", make, nx=nx, ny=ny, accept=accept,
                            names=["axes", "shape", "h.h5"])


def api_from_step_file_case() -> Case:
    code = """
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc import surfaces, scenes, protocols
        scene = scenes.validate({"geometry": {"kind": "self-affine", "nx": 32, "ny": 16, "dx": 1e-8,
                                 "rms_height": 1e-9, "seed": 5}, "material": {"e_star": 1e9},
                                 "protocol": {"control": "mean_pressure", "values": [1e6]},
                                 "output": {"directory": "apiout"}})
        protocols.run(scene)
        grid = SurfaceGrid(32, 16, 1e-8, periodic=True)
        try:
            h = grid.gather(surfaces.from_file(grid, "apiout/step_0001.h5"))
            report({"read": True, "h_xy": h.tolist()})
        except Exception as exc:
            report({"read": False, "error": str(exc)})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code))

        def check():
            if rep is None:
                return WRONG, "no result"
            if not rep["read"]:
                ok = any(w in rep["error"].lower() for w in ("axes", "shape", "step_0001"))
                return (OK if ok else UNCLEAR), f"refused: {rep['error'][:150]}"
            stored = read_field(d / "apiout/step_0001.h5", "heights")     # (ny, nx)
            h_xy = np.array(rep["h_xy"])                                     # (nx, ny)
            if h_xy.shape == stored.T.shape and np.allclose(h_xy, stored.T):
                return OK, "surfaces.from_file read the step file's (y, x) heights correctly"
            return WRONG, "surfaces.from_file read a step file transposed or scrambled"
        return judge_success(res, check)
    return Case("api-from-file-step", "6", "surfaces.from_file on a 32x16 step file",
                "heights equal to the stored ones, or refused naming the axes", run)


# --------------------------------------------------------------------------------------------
# class 7: window edge
WINDOW_WORDS = ("window", "edge")


def hertz_force(e_star, radius, delta):
    return 4 / 3 * e_star * math.sqrt(radius) * delta ** 1.5


def window_case(name, scene, expect_warning: bool, hertz_tol=None) -> Case:
    def run(d):
        res = run_scene(d, scene)

        def check():
            warned = any(w in ln.lower() and "%" in ln or w in ln.lower() and "fraction" in ln.lower()
                         for ln in res.text.splitlines() for w in WINDOW_WORDS)
            if hertz_tol is not None:
                rows = read_curve(d / "out")
                g = scene["geometry"]
                errors = {f"step {r['step']}": abs(float(r["force_N"]) / hertz_force(
                    scene["material"]["e_star"], g["radius"], float(r["approach_m"])) - 1)
                    for r in rows}
                verdict, detail = within(errors, hertz_tol, "F / F_Hertz - 1")
                if verdict != OK:
                    return verdict, detail
            if expect_warning and not warned:
                return WRONG, "zone reaches the window edge: no warning with the fraction in the log"
            return OK, "window-edge warning with the fraction" if warned else "no warning needed"
        return judge_success(res, check, allow_rc=(0, 3))
    return Case(name, "7", scene["name"] + f": {scene['geometry']['nx']}^2, dx = "
                f"{scene['geometry']['dx']:g}", ("a window-edge warning with the fraction in the log"
                                                 if expect_warning else "")
                + (f"; F within {hertz_tol:g} of Hertz" if hertz_tol else ""), run)


# --------------------------------------------------------------------------------------------
# class 8 and 9: kill, restart, compare with an uninterrupted run
KILLER = '''\
"""contactpetsc run, killed from inside once curve.csv has SWEEP_KILL_ROWS rows."""
import os, signal, sys, threading, time
rank = int(os.environ.get("OMPI_COMM_WORLD_RANK", "0"))
piddir, curve = os.environ["SWEEP_PID_DIR"], os.environ["SWEEP_CURVE"]
rows, mode = int(os.environ["SWEEP_KILL_ROWS"]), os.environ["SWEEP_KILL_MODE"]
open(os.path.join(piddir, f"pid.{rank}"), "w").write(str(os.getpid()))


def count():
    try:
        with open(curve) as f:
            return sum(1 for _ in f) - 1
    except OSError:
        return 0


def watch():
    while count() < rows:      # the last row: the pull-off refinement runs after it
        time.sleep(0.0005)
    if mode == "all":
        for name in os.listdir(piddir):
            os.kill(int(open(os.path.join(piddir, name)).read()), signal.SIGKILL)
    os.kill(os.getpid(), signal.SIGTERM if mode == "term" else signal.SIGKILL)


if rank == int(os.environ.get("SWEEP_KILL_RANK", "0")):
    threading.Thread(target=watch, daemon=True).start()
sys.setswitchinterval(1e-4)
sys.argv[0] = "contactpetsc"
from contactpetsc.cli import main
sys.exit(main())
'''


def killed_run(d: Path, scene_file: Path, rows: int, mode="self", ranks=1, kill_rank=0, out="out"):
    """Run a scene and kill it (SIGKILL/SIGTERM) once curve.csv has ``rows`` rows."""
    (d / "killer.py").write_text(KILLER)
    piddir = d / f"pids{time.time_ns()}"
    piddir.mkdir()
    extra = {"SWEEP_PID_DIR": str(piddir), "SWEEP_CURVE": str(d / out / "curve.csv"),
             "SWEEP_KILL_ROWS": str(rows), "SWEEP_KILL_MODE": mode, "SWEEP_KILL_RANK": str(kill_rank)}
    return run_py([str(d / "killer.py"), "run", str(scene_file), *(["--restart"] if (d / out).exists()
                                                                    else [])], d, ranks, extra,
                  timeout=TIMEOUT / 2)


def read_jumps(out: Path) -> list[dict]:
    if not (out / "jumps.csv").exists():
        return []
    with open(out / "jumps.csv") as f:
        return list(csv.DictReader(f))


def compare_runs(ref: Path, out: Path, step: float) -> tuple[str, str]:
    """Everything an uninterrupted run wrote, against a killed and restarted one."""
    a, b = read_curve(ref), read_curve(out)
    if len(b) < len(a):
        return LOST, f"curve.csv has {len(b)} of {len(a)} rows"
    if len(b) > len(a):
        return WRONG, f"curve.csv has {len(b)} rows, {len(a)} expected"
    fa, fb = column(a, "force_N"), column(b, "force_N")
    scale = float(np.max(np.abs(fa)))
    worst = float(np.max(np.abs(fa - fb))) / scale
    if worst > 1e-4 or not np.allclose(column(a, "approach_m"), column(b, "approach_m")):
        return WRONG, f"curve.csv differs from the uninterrupted run (force error {worst:.1e})"
    ja, jb = read_jumps(ref), read_jumps(out)
    if [j["kind"] for j in jb] != [j["kind"] for j in ja]:
        cls = LOST if len(jb) < len(ja) else WRONG
        return cls, f"jumps {[j['kind'] for j in jb]} against {[j['kind'] for j in ja]}"
    for x, y in zip(ja, jb):
        if abs(float(x["approach_before_m"]) - float(y["approach_before_m"])) > step / 4:
            return WRONG, f"{x['kind']} at {y['approach_before_m']} against {x['approach_before_m']}"
    if (ref / "summary.json").exists():
        try:
            sa, sb = strict_json(ref / "summary.json"), strict_json(out / "summary.json")
        except (OSError, ValueError) as exc:
            return LOST, f"summary.json: {exc}"
        pa, pb = sa.get("pull_off_force_N"), sb.get("pull_off_force_N")
        if pb is None:
            return LOST, f"pull-off missing after restart (uninterrupted: {pa:.4e} N)"
        if abs(pa - pb) > 1e-3 * abs(pa):
            return WRONG, f"pull-off {pb:.4e} N against {pa:.4e} N uninterrupted"
        if len(sb.get("jumps", [])) != len(sa.get("jumps", [])):
            return LOST, f"summary.json lists {len(sb.get('jumps', []))} of {len(sa['jumps'])} jumps"
    if (ref / "atom_forces.csv").exists():
        def steps(p):
            with open(p / "atom_forces.csv") as f:
                return sorted({r["approach_m"] for r in csv.DictReader(f)})
        sa_, sb_ = steps(ref), steps(out) if (out / "atom_forces.csv").exists() else []
        if sb_ != sa_:
            return LOST, f"atom_forces.csv has {len(sb_)} of {len(sa_)} approaches"
    return OK, f"{len(b)} steps, {len(jb)} jumps, summary and forces as uninterrupted"


def kill_restart_case(name, scene, kills: list[tuple[int, str]], ranks=1, kill_rank=0,
                      restart_ranks=None, step=0.5 * Z0, klass="8") -> Case:
    def run(d):
        res = run_scene(d, merged(scene, output={"directory": "ref"}), name="ref.toml", ranks=ranks)
        if res.rc != 0:
            return LOUD, f"uninterrupted run failed: {message(res)}"
        scene_file = write_scene(d / "scene.toml", scene)
        notes = []
        for rows, mode in kills:
            res = killed_run(d, scene_file, rows, mode, ranks, kill_rank)
            if res.timed_out:
                # mpirun's business rather than the product's: noted, and the restart judged
                notes.append(f"mpirun did not end within {TIMEOUT / 2:g} s of the kill")
            if res.rc == 0:
                return OK, f"run finished before the kill at {rows} rows (inconclusive)"
            done = len(read_curve(d / "out")) if (d / "out/curve.csv").exists() else 0
            notes.append(f"killed at {done} rows")
            if done == len(scene["protocol"]["values"]) and (d / "out/summary.json").exists():
                notes.append("inconclusive: the path had finished before the kill")
        res = cli(d, "run", scene_file, "--restart", ranks=restart_ranks or ranks)
        verdict, detail = judge_success(res, lambda: compare_runs(d / "ref", d / "out", step))
        return verdict, "; ".join([detail] + notes)
    how = ", then ".join(f"{m} at {r} rows" for r, m in kills)
    return Case(name, klass, f"{scene['name']}: kill ({how}, rank {kill_rank} of {ranks}), --restart",
                "curve, jumps, pull-off, atom forces as the uninterrupted run", run, ranks)


def budget_restart_case(name, scene, budget) -> Case:
    def run(d):
        res = run_scene(d, merged(scene, output={"directory": "ref"}), name="ref.toml")
        if res.rc != 0:
            return LOUD, f"uninterrupted run failed: {message(res)}"
        res = run_scene(d, scene, f"-adhesion_time_budget", budget)
        if res.rc == 0:
            return OK, "finished within the budget (inconclusive)"
        res = cli(d, "run", d / "scene.toml", "--restart")
        return judge_success(res, lambda: compare_runs(d / "ref", d / "out", 0.5 * Z0))
    return Case(name, "8", f"graceful stop (-adhesion_time_budget {budget}) then --restart",
                "pull-off and jumps of the whole path, as uninterrupted", run)


def changed_physics_case(key: str, value, base=None, kill_rows=4, suffix="") -> Case:
    """A stopped run restarted with one physics key changed: refused, naming the key."""
    base = base or adhesive_sphere(values=JUMP_VALUES)
    table, k = key.split(".")

    def run(d):
        scene_file = write_scene(d / "scene.toml", base)
        if kill_rows:
            killed_run(d, scene_file, kill_rows)
        else:
            cli(d, "run", scene_file)
        changed = merged(base, **{table: {k: value}})
        res = run_scene(d, changed, "--restart", name="changed.toml")
        return judge_refusal(res, [k])
    return Case(f"restart-changed-{key}{suffix}", "9", f"--restart with {key} = {value!r} "
                f"({'after a kill' if kill_rows else 'after a finished run'})",
                f"exit 1 naming {k}", run)


def restart_allowed_case(name, change: dict, ranks=1) -> Case:
    """Restart with a non-physics change: allowed, and the same result as uninterrupted."""
    base = jump_sphere()

    def run(d):
        res = run_scene(d, merged(base, output={"directory": "ref"}), name="ref.toml")
        if res.rc != 0:
            return LOUD, f"uninterrupted run failed: {message(res)}"
        killed_run(d, write_scene(d / "scene.toml", base), 6)
        res = run_scene(d, merged(base, **change), "--restart", name="changed.toml", ranks=ranks)
        return judge_success(res, lambda: compare_runs(d / "ref", d / "out", 0.5 * Z0))
    return Case(name, "9", f"--restart with a non-physics change {change}, {ranks} rank(s)",
                "allowed; the uninterrupted run's result", run, ranks)


# --------------------------------------------------------------------------------------------
# class 10: the output directory
def step_consistency(out: Path, e_star: float) -> tuple[str, str]:
    """curve.csv and every step file from one run (the one with modulus ``e_star``)."""
    import h5py
    rows = read_curve(out)
    steps = sorted(out.glob("step_*.h5"))
    if len(steps) != len(rows):
        return WRONG, f"{len(steps)} step files beside {len(rows)} curve rows"
    for r, path in zip(rows, steps):
        with h5py.File(path, "r") as f:
            scene = json.loads(f.attrs["scene"])
            force = float(f.attrs["force"])
        if scene["material"]["e_star"] != e_star:
            return WRONG, f"{path.name} is from a run with E* = {scene['material']['e_star']:g}"
        if abs(force - float(r["force_N"])) > 1e-9 * abs(force) + 1e-30:
            return WRONG, f"{path.name} force {force:.6e} N beside curve.csv {r['force_N']}"
    return OK, f"{len(rows)} rows and step files of one run"


def concurrent_case(name, ranks=(1, 1), same=False) -> Case:
    def run(d):
        scenes = [jump_sphere(), jump_sphere(e_star=1e10 if same else 2e10)]
        files = [write_scene(d / f"s{i}.toml", s) for i, s in enumerate(scenes)]
        t0 = time.time()
        procs = [launch(["-m", "contactpetsc.cli", "run", str(f)], d, n) for f, n in zip(files, ranks)]
        results = [finish(p, t0) for p in procs]
        for r in results:
            bad = abnormal(r)
            if bad:
                return bad
        rcs = [r.rc for r in results]
        if rcs.count(0) == 2:
            verdict, detail = step_consistency(d / "out", scenes[0]["material"]["e_star"])
            if verdict == OK and not same:
                verdict, detail = step_consistency(d / "out", scenes[1]["material"]["e_star"])
            return WRONG, f"both runs exited 0 into one directory ({detail})"
        if sorted(rcs) != [0, 1]:
            return LOUD, f"exits {rcs}"
        loser, winner = (0, 1) if rcs[0] == 1 else (1, 0)
        msg = message(results[loser])
        words = ("lock", "in use", "another", "busy", "running", "concurrent")
        if not any(w in msg.lower() for w in words):
            return UNCLEAR, f"second run refused without naming the lock: {msg}"
        verdict, detail = step_consistency(d / "out", scenes[winner]["material"]["e_star"])
        return verdict, f"one refused ({msg[:80]}); {detail}"
    pair = "same scene" if same else "E* 1e10 vs 2e10"
    return Case(name, "10", f"two concurrent runs into one directory ({pair}, "
                f"ranks {ranks})", "one exits 0 with consistent files, the other exit 1 naming the lock",
                run, max(ranks))


def old_directory_case(name, flags=(), plant=None, expect="refuse") -> Case:
    """A new run into a directory already holding another run (more steps, plots)."""
    def run(d):
        old = merged(jump_sphere(e_star=2e10), output={"plots": True})
        res = run_scene(d, old, name="old.toml")
        if res.rc != 0:
            return LOUD, f"first run failed: {message(res)}"
        if plant:
            (d / "out" / plant).write_text("my notes\n")
        new = adhesive_sphere(values=z0s(-3, -2, -1))
        res = run_scene(d, new, *flags)

        def check():
            leftovers = [p.name for p in (d / "out").iterdir()
                         if p.name.endswith(".png") or (p.name.startswith("step_") and
                                                        int(p.name[5:9]) > 3)]
            if leftovers:
                return WRONG, (f"{len(leftovers)} files of the other run left beside the new one: "
                               f"{leftovers[:3]}")
            if plant and not (d / "out" / plant).exists():
                return WRONG, f"the user's {plant} was deleted"
            return step_consistency(d / "out", 1e10)
        if expect == "refuse":
            return judge_refusal(res, ["--restart", "--overwrite"], accept=check)
        return judge_success(res, check)
    return Case(name, "10", f"new scene into another run's directory {' '.join(flags)}"
                + (f" (with the user's {plant})" if plant else ""),
                "refused naming --restart/--overwrite" if expect == "refuse"
                else "exit 0, no file of the old run left", run)


def fresh_directory_case(name, prepare) -> Case:
    def run(d):
        prepare(d)
        res = run_scene(d, adhesive_sphere(values=z0s(-3, -2, -1)))
        return judge_success(res, lambda: step_consistency(d / "out", 1e10))
    return Case(name, "10", "run into an empty existing directory", "exit 0, like a new one", run)


def dry_run_untouched_case() -> Case:
    def run(d):
        run_scene(d, jump_sphere())
        before = {p.name: p.read_bytes() for p in (d / "out").iterdir()}
        res = run_scene(d, adhesive_sphere(values=z0s(-3, -2)), "--dry-run", name="other.toml")
        bad = abnormal(res)
        if bad:
            return bad
        after = {p.name: p.read_bytes() for p in (d / "out").iterdir()}
        return (OK, f"exit {res.rc}, directory untouched") if after == before else (
            WRONG, "--dry-run changed another run's directory")
    return Case("dry-run-leaves-directory", "10", "--dry-run of another scene into a finished run's "
                "directory", "no file changed", run)


# --------------------------------------------------------------------------------------------
# class 11: a full disk (RLIMIT_FSIZE: writes past the limit fail with EFBIG; Python ignores
# SIGXFSZ)
LIMITED = '''\
"""contactpetsc with a file size limit set after MPI is up (MPI's own files are not the run's)."""
import os, resource, sys
from mpi4py import MPI
n = int(os.environ["SWEEP_FSIZE"])
resource.setrlimit(resource.RLIMIT_FSIZE, (n, n))
sys.argv[0] = "contactpetsc"
from contactpetsc.cli import main
sys.exit(main())
'''


def disk_full_case(name, scene, limit_bytes, ranks=1) -> Case:
    def run(d):
        (d / "limited.py").write_text(LIMITED)
        res = run_py([str(d / "limited.py"), "run", str(write_scene(d / "scene.toml", scene))], d, ranks,
                     {"SWEEP_FSIZE": str(limit_bytes)})
        bad = abnormal(res)
        if bad:
            return bad
        stray = [p.name for p in (d / "out").glob("*") if "tmp" in p.name.lower()] \
            if (d / "out").exists() else []
        if res.rc == 0:
            return WRONG, f"exit 0 although a write failed (file limit {limit_bytes} B)"
        if stray:
            return WRONG, f"exit {res.rc}, stray files left: {stray[:3]}"
        if (d / "out/curve.csv").exists():
            try:
                rows = read_curve(d / "out")
                column(rows, "force_N")
            except (ValueError, KeyError, TypeError) as exc:
                return LOST, f"curve.csv left unreadable: {exc}"
        if res.rc != 1:
            return UNCLEAR, f"exit {res.rc} (documented: 1 on an error): {message(res)}"
        words = ("space", "too large", "write", "disk", "errno")
        if not any(w in res.err.lower() for w in words):
            return UNCLEAR, f"exit 1 without saying what failed: {message(res)}"
        return OK, f"exit 1, no stray files: {message(res)[:100]}"
    return Case(name, "11", f"file size limit {limit_bytes} B, {ranks} rank(s)",
                "exit 1 naming the failed write, no .tmp left, curve.csv readable", run, ranks)


# --------------------------------------------------------------------------------------------
# class 12: per-step bookkeeping must stay flat
def bookkeeping_case(steps=400) -> Case:
    values = [1e-9 * (1 + 0.5 * (k % 2)) for k in range(steps)]
    scene = merged(hertz_scene(nx=32, dx=8e-9, values=values), output={"fields": False})

    def run(d):
        proc = launch(["-m", "contactpetsc.cli", "run", str(write_scene(d / "scene.toml", scene))], d)
        t0, marks = time.time(), []
        curve = d / "out/curve.csv"
        while proc.poll() is None and time.time() - t0 < TIMEOUT * 2:
            try:
                marks.append((time.time(), curve.stat().st_size))
            except OSError:
                pass
            time.sleep(0.05)
        res = finish(proc, t0, timeout=1)
        bad = abnormal(res)
        if bad:
            return bad
        rows = read_curve(d / "out")
        per_row = curve.stat().st_size / max(len(rows), 1)
        pts = [(t, s / per_row) for t, s in marks]      # (time, rows written)

        def rate(lo, hi):
            sel = [(t, n) for t, n in pts if lo <= n <= hi]
            if len(sel) < 2 or sel[-1][1] == sel[0][1]:
                return float("nan")
            return (sel[-1][0] - sel[0][0]) / (sel[-1][1] - sel[0][1])
        early, late = rate(20, 120), rate(steps - 100, steps - 5)
        ratio = late / early
        detail = f"{early * 1e3:.1f} ms/step at 20-120, {late * 1e3:.1f} ms/step at the end (x{ratio:.2f})"
        return (OK if ratio < 1.6 else SLOW), detail
    return Case(f"bookkeeping-{steps}-steps", "12", f"{steps} cheap Signorini steps, no fields",
                "time per step at the end within 1.6x of steps 20-120", run)


# --------------------------------------------------------------------------------------------
# class 13: summary.json
def summary_case(name, scene, args=(), ranks=1, rc=(0,)) -> Case:
    def run(d):
        res = run_scene(d, scene, *args, ranks=ranks)

        def check():
            try:
                summary = strict_json(d / "out/summary.json")
            except ValueError as exc:
                return WRONG, str(exc)
            if summary.get("jumps") and not (d / "out/jumps.csv").exists():
                return WRONG, "summary.json lists jumps, no jumps.csv"
            columns = (next(csv.reader(open(d / "out/jumps.csv")))
                       if (d / "out/jumps.csv").exists() else [])
            for j in summary.get("jumps", []):
                if sorted(j) != sorted(columns):
                    return WRONG, f"jump keys {sorted(j)} against jumps.csv {columns}"
            return OK, f"strict JSON; {len(summary.get('jumps', []))} jumps with jumps.csv's keys"
        return judge_success(res, check, allow_rc=rc)
    return Case(name, "13", f"summary.json of {scene['name']} {' '.join(map(str, args))}, {ranks} rank(s)",
                "json.load without NaN; jump keys = jumps.csv columns", run, ranks)


# --------------------------------------------------------------------------------------------
# messages
def cli_refusal_case(name, klass, scene, names, args=(), forbidden=(), prepare=None,
                     accept=None) -> Case:
    def run(d):
        if prepare:
            prepare(d)
        res = run_scene(d, scene, *args) if isinstance(scene, dict) else cli(d, *scene)
        return judge_refusal(res, names, forbidden=forbidden,
                             accept=(lambda: accept(d, res)) if accept else None)
    words = " ".join(map(str, args)) if isinstance(scene, dict) else " ".join(map(str, scene))
    return Case(name, klass, f"{words}".strip() or name, f"refused naming {names[0]!r}"
                + (f", never {forbidden[0]!r}" if forbidden else ""), run)


def plot_case(name, curve_text: str | None, names=("curve.csv",)) -> Case:
    def run(d):
        (d / "out").mkdir()
        if curve_text is not None:
            (d / "out/curve.csv").write_text(curve_text)
        return judge_refusal(cli(d, "plot", "out"), list(names))
    return Case(name, "msg", f"contactpetsc plot on {name}", "exit 1 naming curve.csv, no traceback", run)


GOOD_CURVE_HEAD = "step,branch,approach_m,force_N,mean_pressure_Pa,contact_fraction\n"


def api_refusal_case(name, klass, code, names, ranks=1) -> Case:
    """API misuse (``code`` defines misuse() on API_GRID's 12 x 16 grid): the call must raise
    on every rank with a message naming one of ``names``."""
    wrapped = textwrap.dedent(API_GRID) + textwrap.dedent(code) + textwrap.dedent("""
        try:
            misuse()
            report({"raised": False})
        except Exception as exc:
            report({"raised": True, "type": type(exc).__name__, "error": str(exc)})
        """)

    def run(d):
        res, rep = api(d, wrapped, ranks)
        bad = abnormal(res)
        if bad:
            return bad
        if rep is None:
            return UNCLEAR, f"exit {res.rc}, no report: {message(res)}"
        if not rep["raised"]:
            return WRONG, "accepted without a word"
        text = rep["error"].lower()
        hit = any(n.lower() in text for n in names)
        return (OK if hit else UNCLEAR), f"{rep['type']}: {rep['error'][:150]}"
    return Case(name, klass, f"API: {name}", f"raises naming {names[0]!r}", run, ranks)


API_GRID = """
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc import surfaces
    from contactpetsc.solvers import ContactProblem
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    grid = SurfaceGrid(12, 16, 1e-8, periodic=True)
    """


# --------------------------------------------------------------------------------------------
# the cases
def all_cases() -> list[Case]:
    cases: list[Case] = []
    add = cases.append
    # 1: weak to strong adhesion against the rigid sphere (w / E* z0 <= 3e-4)
    for w, e in [(1e-12, 1e10), (1e-9, 1e10), (1e-8, 1e10), (1e-7, 1e10), (1e-6, 1e10),
                 (1e-3, 1e13), (1.0, 1e16), (1e3, 1e19)]:
        add(rigid_sphere_case(f"weak-lj-w{w:g}", w, e))
    add(rigid_sphere_case("weak-lj-w1e-9-np2", 1e-9, 1e10, ranks=2))
    add(rigid_sphere_case("weak-hardwall-w1e-8", 1e-8, 1e10, law="hardwall-lj",
                          values=z0s(-3, -2, -1, -0.5, -0.1, -0.5, -2)))
    add(rigid_sphere_case("weak-exponential-w1e-9", 1e-9, 1e10, law="exponential", rho=Z0,
                          values=z0s(-3, -2, -1, -0.5, -0.1, -0.5, -2)))
    add(rigid_sphere_case("weak-dugdale-w1e-9", 1e-9, 1e10, law="dugdale", sigma0=1e-9 / Z0,
                          values=z0s(-2.13, -1.07, -0.47, -0.21, -0.47, -1.07)))
    add(api_weak_adhesion_case(1e-10, 1))
    add(api_weak_adhesion_case(1e-8, 2))
    # 2: pull-off on the flat periodic cell
    add(flat_case("flat-lj-w0.1", 0.1))
    add(flat_case("flat-lj-w1e-6", 1e-6))
    add(flat_case("flat-lj-w10", 10.0))
    add(flat_case("flat-lj-coarse-steps", 0.1, values=z0s(-2, -1.3, -0.6, 0, -0.37, -0.74, -1.11, -1.48)))
    add(flat_case("flat-lj-loading-only", 0.1, values=z0s(-2, -1, -0.5, -0.3, -0.1, 0)))
    add(flat_case("flat-lj-soft", 0.1, e_star=1e10, check_forces=False))
    add(flat_case("flat-lj-no-refine", 0.1, refine=False))
    add(flat_case("flat-hardwall-lj", 0.1, law="hardwall-lj",
                  values=z0s(-2, -1, -0.5, -0.02, -0.1, -0.15, -0.19, -0.23, -0.3, -0.6)))
    add(flat_case("flat-exponential-no-refine", 0.1, law="exponential", rho=Z0, refine=False,
                  values=z0s(-2, -1, -0.3, -0.05, -0.3, -1, -2)))
    add(flat_case("flat-dugdale-no-refine", 0.1, law="dugdale", sigma0=0.1 / Z0, refine=False,
                  values=z0s(-2, -1.5, -0.7, -0.3, -0.7, -1.5)))
    add(flat_case("flat-lj-np2", 0.1, ranks=2))
    # 3: no jumps where the force is smooth
    add(rigid_sphere_case("far-sphere-lj-w0.05", 0.05, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-lj-w0.3", 0.3, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-hardwall", 0.3, 1e10, law="hardwall-lj", values=FAR, klass="3",
                          no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-fine-steps", 0.05, 1e10, klass="3", no_jumps=True, tol=1e-2,
                          values=z0s(*np.arange(-20, -9.9, 0.5), *np.arange(-10.5, -20.1, -0.5))))
    add(rigid_sphere_case("far-sphere-np2", 0.3, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2,
                          ranks=2))
    add(flat_case("flat-tail-smooth", 0.1, klass="3", no_jumps=True, tol=1e-2, refine=False,
                  values=z0s(-3, -2.5, -2, -1.5, -1, -0.6, -0.4, -0.6, -1, -1.5, -2, -3)))
    add(flat_case("flat-through-peak-smooth", 0.1, klass="3", no_jumps=True, tol=1e-2,
                  values=z0s(*np.arange(-1.5, 0.01, 0.1), *np.arange(-0.1, -1.51, -0.1))))
    # 4: the random vector
    hertz = hertz_scene(nx=32, dx=4e-9)
    add(random_vector_case("random-vector-option-tol", hertz, ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-scene-tol", merged(hertz, solver={"tol": 1e-18})))
    add(random_vector_case("random-vector-rough-load", rough_cell(), ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-force-control",
                           merged(hertz, protocol={"control": "force", "values": [1e-8, 3e-8]}),
                           ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-np2", hertz, ("-contact_tol", "1e-18"), ranks=2))
    add(api_random_vector_case())
    # 5: questionable input
    big = hertz_scene(nx=64, dx=4e-9, values=(1e-9, 2e-9))
    add(refuse_or_match_case("tol-1e300-signorini", "5", "solver.tol = 1e300 (Signorini)", big, ["tol"],
                             edit=lambda s: merged(s, solver={"tol": 1e300})))
    add(refuse_or_match_case("tol-1e300-adhesive", "5", "solver.tol = 1e300 (adhesive)", jump_sphere(),
                             ["tol"], edit=lambda s: merged(s, solver={"tol": 1e300})))
    add(refuse_or_match_case("tol-0.5-adhesive", "5", "solver.tol = 0.5 z0 (adhesive)", jump_sphere(),
                             ["tol"], tol=1e-2, edit=lambda s: merged(s, solver={"tol": 0.5})))
    add(refuse_or_match_case("option-tol-1e300", "5", "-contact_tol 1e300 on the command line", big,
                             ["tol"], args=("-contact_tol", "1e300")))
    add(refuse_or_match_case("option-adhesion-tol-1e10", "5", "-adhesion_tol 1e10 on the command line",
                             jump_sphere(), ["tol"], args=("-adhesion_tol", "1e10")))
    add(load_case("subnormal-mean-pressure", rough_cell(values=[1e-310])))
    add(load_case("subnormal-force", merged(big, protocol={"control": "force", "values": [5e-320]})))
    add(load_case("huge-mean-pressure-1e300", rough_cell(values=[1e300])))
    sq = np.full((16, 16), 1e-9)
    sq[3, 5] = 0.0
    add(height_file_case("heights-complex", "5", npy(sq.astype(complex) + 1e-10j),
                         names=["complex", "h.npy", "dtype"]))
    add(height_file_case("heights-bool", "5", npy(sq > 0), names=["bool", "h.npy", "dtype"]))
    add(height_file_case("heights-int", "5", npy((sq * 1e9).astype(np.int64)),
                         names=["int", "h.npy", "dtype"], accept=warn_ok(["int", "dtype"])))
    add(height_file_case("heights-nan", "5", npy(np.where(sq > 0, sq, np.nan)), names=["nan", "h.npy"]))
    add(height_file_case("heights-wrong-shape-16x12", "5", npy(np.zeros((16, 12))), nx=12, ny=16,
                         names=["shape", "h.npy"]))
    add(height_file_case("heights-truncated-npy", "5",
                         lambda d: (np.save(d / "t.npy", sq), (d / "t.npy").write_bytes(
                             (d / "t.npy").read_bytes()[:900]), "t.npy")[-1], names=["t.npy"]))
    add(api_refusal_case("api-vec-of-other-grid", "5", """
        def misuse():
            other = SurfaceGrid(16, 12, 1e-8, periodic=True)
            ContactProblem(grid, surfaces.sphere(other, 1e-6), 1e9).solve(approach=1e-9)
        """, ["grid", "shape", "size", "16"]))
    add(api_refusal_case("api-vec-of-other-grid-adhesive", "5", """
        def misuse():
            other = SurfaceGrid(16, 12, 1e-8, periodic=True)
            law = make_law("lj", work_of_adhesion=0.1, z0=3e-10)
            AdhesiveProblem(grid, surfaces.sphere(other, 1e-6), 1e10, law).solve(approach=0.0)
        """, ["grid", "shape", "size", "16"]))
    add(api_refusal_case("api-from-array-transposed", "5", """
        def misuse():
            surfaces.from_array(grid, np.zeros((16, 12)))
        """, ["shape", "(12, 16)", "nx"]))
    add(api_refusal_case("api-from-array-complex", "5", """
        def misuse():
            surfaces.from_array(grid, np.zeros((12, 16), complex))
        """, ["complex", "dtype"]))
    lawless = merged(big, interaction={"law": "none", "work_of_adhesion": 0.1})
    add(cli_refusal_case("w-with-law-none", "5", lawless, ["work_of_adhesion"],
                         accept=warn_ok(["work_of_adhesion"])))
    add(cli_refusal_case("sigma0-with-law-lj", "5", adhesive_sphere(sigma0=1e9), ["sigma0"],
                         accept=warn_ok(["sigma0"])))
    add(corrupted_restart_case("restart-truncated-last-step", "last-h5"))
    add(corrupted_restart_case("restart-truncated-earlier-step", "early-h5"))
    add(corrupted_restart_case("restart-short-curve-row", "short-row"))
    add(corrupted_restart_case("restart-garbage-curve-value", "garbage"))
    # 6: axes
    add(round_trip_case(32, 32))
    add(round_trip_case(32, 16))
    add(round_trip_case(16, 32, dy=2e-8))
    add(round_trip_case(32, 32, ranks=2))
    add(axes_stamp_case())
    add(stamped_input_case("heights-h5-stamped-yx", "yx", "y,x"))
    add(stamped_input_case("heights-h5-stamped-xy", "xy", "x,y"))
    add(api_from_step_file_case())
    # 7: the window edge
    add(window_case("docs-minimal-scene", hertz_scene(), expect_warning=True))
    add(window_case("hertz-big-window", merged(hertz_scene(dx=4e-9, values=(0.5e-9, 1e-9, 2e-9)),
                                               name="hertz-big-window"), False, hertz_tol=0.03))
    add(window_case("adhesive-zone-at-edge", adhesive_sphere(w=0.05), expect_warning=True))
    add(window_case("hertz-force-control-small-window",
                    merged(hertz_scene(), protocol={"control": "force", "values": [1e-7, 2e-7]}),
                    expect_warning=True))
    # 8: kill and restart
    add(kill_restart_case("kill-after-jump-on", jump_sphere(), [(5, "self")]))
    add(kill_restart_case("kill-while-unloading", jump_sphere(), [(12, "self")]))
    add(kill_restart_case("kill-after-jump-off", jump_sphere(), [(17, "self")]))
    add(kill_restart_case("kill-in-pull-off-refinement", jump_sphere(), [(19, "refine")]))
    add(kill_restart_case("kill-twice", jump_sphere(), [(4, "self"), (10, "self")]))
    add(kill_restart_case("sigterm-after-jump-on", jump_sphere(), [(6, "term")]))
    add(kill_restart_case("kill-np2-all-ranks", jump_sphere(), [(6, "all")], ranks=2))
    add(kill_restart_case("kill-np2-one-rank", jump_sphere(), [(6, "self")], ranks=2, kill_rank=1))
    add(kill_restart_case("kill-np1-restart-np2", jump_sphere(), [(6, "self")], restart_ranks=2))
    tip = {"name": "sweep-tip",
           "geometry": {"kind": "tip", "tip": "bent-commensurate", "radius": 30e-9,
                        "atom_spacing": 0.3367e-9, "nx": 48, "dx": 0.17e-9},
           "material": {"e_star": 100e9},
           "interaction": {"law": "lj", "work_of_adhesion": 0.1, "z0": 0.2147e-9},
           "protocol": {"control": "approach",
                        "values": [k * 1e-10 for k in (-6, -4, -2, 0, 2, 0, -2, -4, -6)]},
           "output": {"directory": "out", "atom_forces": True}}
    add(kill_restart_case("kill-tip-atom-forces", tip, [(4, "self")], step=2e-10))
    add(kill_restart_case("kill-signorini", merged(big, protocol={"values": [1e-9, 1.5e-9, 2e-9, 2.5e-9]}),
                          [(2, "self")]))
    add(budget_restart_case("budget-stop-restart", jump_sphere(), 0.3))
    add(Case("restart-finished-run", "8", "--restart of a finished run (nothing left to do)",
             "outputs unchanged: jumps and pull-off kept", _restart_finished))
    # 9: restart with other physics
    for key, value in [("material.e_star", 2e10), ("interaction.work_of_adhesion", 0.1),
                       ("interaction.z0", 0.25e-9), ("interaction.law", "hardwall-lj"),
                       ("geometry.dx", 0.25e-9), ("geometry.nx", 40),
                       ("protocol.values", z0s(-3, -2.2, -1.4, -0.6, 0.2, 1, 0.2, -0.6, -1.4, -3)),
                       ("protocol.control", "central_gap")]:
        add(changed_physics_case(key, value))
    add(changed_physics_case("geometry.seed", 4, base=rough_cell(), kill_rows=0))
    add(changed_physics_case("protocol.control", "force", base=merged(
        big, protocol={"control": "approach", "values": [1e-9, 2e-9]}), kill_rows=0, suffix="-signorini"))
    add(restart_allowed_case("restart-plots-toggled", {"output": {"plots": True}}))
    add(restart_allowed_case("restart-on-2-ranks", {}, ranks=2))
    # 10: the output directory
    add(concurrent_case("concurrent-two-scenes"))
    add(concurrent_case("concurrent-same-scene", same=True))
    add(concurrent_case("concurrent-np1-and-np2", ranks=(1, 2)))
    add(old_directory_case("new-run-into-old-directory"))
    add(old_directory_case("overwrite-old-directory", flags=("--overwrite",), expect="run"))
    add(old_directory_case("new-run-beside-user-file", plant="notes.txt"))
    add(fresh_directory_case("empty-existing-directory", lambda d: (d / "out").mkdir()))
    add(dry_run_untouched_case())
    # 11: full disk
    add(disk_full_case("disk-full-step-file", hertz_scene(nx=64, dx=4e-9), 20_000))
    add(disk_full_case("disk-full-history", merged(hertz_scene(nx=32, dx=8e-9, values=[1e-9 * (1 + k / 20)
                                                                                   for k in range(40)]),
                                                   output={"fields": False}), 6_000))
    add(disk_full_case("disk-full-adhesive", jump_sphere(), 50_000))
    add(disk_full_case("disk-full-np2", hertz_scene(nx=64, dx=4e-9), 20_000, ranks=2))
    # 12: bookkeeping
    add(bookkeeping_case())
    # 13: summary.json
    add(summary_case("summary-jump-keys", jump_sphere()))
    add(summary_case("summary-jump-keys-np2", jump_sphere(), ranks=2))
    add(summary_case("summary-stopped-at-step-1", jump_sphere(), ("-adhesion_time_budget", "1e-9"),
                     rc=(3,)))
    add(summary_case("summary-far-sphere", adhesive_sphere(values=FAR)))
    add(summary_case("summary-relaxation", merged(adhesive_sphere(law="hardwall-lj", values=z0s(
        -3, -2, -1, -0.5, -1, -2)), solver={"method": "relaxation"})))
    # messages
    flat_none = {"name": "flat-signorini",
                 "geometry": {"kind": "self-affine", "nx": 32, "dx": 1e-8, "rms_height": 0.0},
                 "material": {"e_star": 1e9}, "protocol": {"control": "approach", "values": [-1e-9]},
                 "output": {"directory": "out"}}
    add(cli_refusal_case("flat-signorini-separated", "msg", flat_none, ["rms_height", "flat"],
                         forbidden=("length_scale",), accept=_zero_force))
    add(cli_refusal_case("flat-signorini-load", "msg", merged(flat_none, protocol={
        "control": "mean_pressure", "values": [1e6]}), ["rms_height", "flat"],
        forbidden=("length_scale",), accept=_uniform_load))
    add(cli_refusal_case("dry-run-huge-grid", "msg", merged(big, geometry={"nx": 60000}),
                         ["nx", "64-bit", "index"], args=("--dry-run",), forbidden=("error code",)))
    add(height_file_case("empty-npy", "msg", npy(np.zeros(0)), forbidden=("pickle",)))
    add(height_file_case("zero-byte-npy", "msg", raw_file(b"", "h.npy"), forbidden=("pickle",)))
    add(height_file_case("h5-missing-dataset", "msg", h5(sq, dataset="z"), names=["heights", "h.h5"]))
    add(height_file_case("dry-run-missing-file", "msg", lambda d: "nowhere.npy", dry_run=True))
    add(height_file_case("dry-run-wrong-shape", "msg", npy(np.zeros((8, 8))), dry_run=True))
    add(plot_case("plot-short-row", GOOD_CURVE_HEAD + "1,loading,1e-9,2e-8,1e5,0.1\n2,loading,2e-9\n"))
    add(plot_case("plot-garbage-value", GOOD_CURVE_HEAD + "1,loading,1e-9,abc,1e5,0.1\n"))
    add(plot_case("plot-no-curve", None))
    rough = rough_cell()
    add(cli_refusal_case("hurst-1-dry-run", "msg", merged(rough, geometry={"hurst": 1.0}), ["hurst"],
                         args=("--dry-run",)))
    add(cli_refusal_case("hurst-1-run", "msg", merged(rough, geometry={"hurst": 1.0}), ["hurst"]))
    for key, table in [("dx", "geometry"), ("e_star", "material")]:
        add(cli_refusal_case(f"{key}-inf-range-text", "msg", merged(big, **{table: {key: math.inf}}),
                             [key], forbidden=("inf]",)))
    add(cli_refusal_case("steps-1-0-message", "msg", jump_sphere(), ["step"],
                         args=("-adhesion_time_budget", "1e-9"), forbidden=("1-0 of",),
                         accept=lambda d, res: (UNCLEAR, "says 'steps 1-0'") if "1-0 of" in res.text
                         else (OK, f"exit {res.rc}, no 'steps 1-0'")))
    add(cli_refusal_case("tol-nan", "msg", merged(big, solver={"tol": math.nan}), ["tol"]))
    add(cli_refusal_case("values-nan", "msg", merged(big, protocol={"values": [1e-9, math.nan]}),
                         ["values"]))
    add(cli_refusal_case("scene-missing", "msg", ["run", "no-such-scene.toml"], ["no-such-scene.toml"]))
    add(cli_refusal_case("scene-bad-toml", "msg", ["run", "bad.toml"], ["bad.toml", "line"],
                         prepare=lambda d: (d / "bad.toml").write_text("[geometry\nnx = 3\n")))
    add(api_refusal_case("api-negative-w", "msg", """
        def misuse():
            make_law("lj", work_of_adhesion=-1.0, z0=3e-10)
        """, ["work_of_adhesion"]))
    add(api_refusal_case("api-nan-approach-np2", "msg", """
        def misuse():
            ContactProblem(grid, surfaces.sphere(grid, 1e-6), 1e9).solve(approach=float("nan"))
        """, ["approach"], ranks=2))
    return cases


def _zero_force(d, res):
    if res.rc != 0:
        return LOUD, f"exit {res.rc}: {message(res)}"
    f = column(read_curve(d / "out"), "force_N")
    return (OK, "separated flat cell: F = 0") if np.all(f == 0) else (WRONG, f"F = {f} for a gap of 1 nm")


def _uniform_load(d, res):
    if res.rc != 0:
        return LOUD, f"exit {res.rc}: {message(res)}"
    p = read_field(d / "out/step_0001.h5")
    return (OK, "uniform pressure 1 MPa") if np.allclose(p, 1e6, rtol=1e-6) else (
        WRONG, f"pressure {p.min():.3g}..{p.max():.3g} Pa, expected 1e6 everywhere")


def _restart_finished(d: Path) -> tuple[str, str]:
    scene_file = write_scene(d / "scene.toml", jump_sphere())
    res = cli(d, "run", scene_file)
    if res.rc != 0:
        return LOUD, f"first run failed: {message(res)}"
    shutil.copytree(d / "out", d / "ref")
    res = cli(d, "run", scene_file, "--restart")
    return judge_success(res, lambda: compare_runs(d / "ref", d / "out", 0.5 * Z0))


def corrupted_restart_case(name, how) -> Case:
    """A killed run whose files were then damaged: --restart refuses naming the file, or
    repairs it and gives the uninterrupted result."""
    def run(d):
        res = run_scene(d, merged(jump_sphere(), output={"directory": "ref"}), name="ref.toml")
        if res.rc != 0:
            return LOUD, f"uninterrupted run failed: {message(res)}"
        scene_file = write_scene(d / "scene.toml", jump_sphere())
        killed_run(d, scene_file, 6)
        out = d / "out"
        rows = read_curve(out)
        n = len(rows)
        if how in ("last-h5", "early-h5"):
            target = out / f"step_{(n if how == 'last-h5' else 2):04d}.h5"
            target.write_bytes(target.read_bytes()[:2000])
            names = [target.name]
        else:
            lines = (out / "curve.csv").read_text().splitlines()
            lines[-1] = (",".join(lines[-1].split(",")[:5]) if how == "short-row"
                         else lines[-1].replace(lines[-1].split(",")[3], "abc", 1))
            (out / "curve.csv").write_text("\n".join(lines) + "\n")
            names = ["curve.csv"]
        res = cli(d, "run", scene_file, "--restart")

        def accept():
            for k in range(1, len(read_curve(d / "ref")) + 1):
                try:
                    read_field(out / f"step_{k:04d}.h5")
                except (OSError, KeyError) as exc:
                    return WRONG, f"exit {res.rc}, step_{k:04d}.h5 unreadable after the restart: {exc}"
            return compare_runs(d / "ref", out, 0.5 * Z0)
        return judge_refusal(res, names, accept=accept)
    return Case(name, "5", f"kill at 6 rows, damage ({how}), --restart",
                "refused naming the damaged file, or repaired to the uninterrupted result", run)


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
    """The table: case, issue class, what it does, expected, what happened, classification."""
    def cell(s):
        return str(s).replace("|", "\\|").replace("\n", " ")
    lines = [summary_line(results), "",
             "| case | class | probe | expected | outcome | classification |", "|---|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| `{r['case']}` | {r['class']} | {cell(r['description'])} | {cell(r['expected'])} | "
                     f"{cell(r['detail'])} | **{r['outcome']}** |")
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    global TIMEOUT
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--list", action="store_true", help="list the cases and exit")
    ap.add_argument("--only", default=None, help="run the cases whose name contains this")
    ap.add_argument("--timeout", type=float, default=TIMEOUT, help="wall-time bound per process [s]")
    ap.add_argument("--jobs", type=int, default=1, help="cases run at once")
    ap.add_argument("--markdown", default=None, help="write the table to this file")
    ap.add_argument("--keep", action="store_true", help="keep each case's directory")
    args = ap.parse_args(argv)
    TIMEOUT = args.timeout
    cases = [c for c in all_cases() if args.only is None or args.only in c.name]
    if args.list:
        for c in cases:
            print(f"{c.name:40s} class {c.issue_class:4s} np{c.ranks}  {c.description}")
        return 0
    results = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for r in pool.map(lambda c: run_case(c, args.keep), cases):
            print(json.dumps(r), flush=True)
            results.append(r)
    if args.markdown:
        Path(args.markdown).write_text(markdown(results))
    print(summary_line(results))
    return 0 if all(r["outcome"] == OK for r in results) else 1


if __name__ == "__main__":
    sys.exit(main())
