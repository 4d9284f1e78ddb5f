"""Run cases: kill and restart against an uninterrupted run (classes 8, 9), the output
directory (10), a full disk (11), per-step bookkeeping (12), summary.json (13)."""
from __future__ import annotations

import csv
import json
import shutil
import time
from pathlib import Path

import numpy as np

from . import harness
from .harness import (
    Case, JUMP_VALUES, LOST, LOUD, OK, SLOW, UNCLEAR, WRONG, Z0, abnormal, adhesive_sphere, cli,
    column, finish, hertz_scene, judge_refusal, judge_success, jump_sphere, launch, merged, message,
    read_curve, read_field, run_py, run_scene, strict_json, write_scene, z0s)


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
from contactpetsc.app.cli import main
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
                  timeout=harness.TIMEOUT / 2)


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
    for name in ("stable", "stability_checked"):
        if name in a[0] and [r[name] for r in a] != [r.get(name) for r in b]:
            steps = [r["step"] for r, s in zip(a, b) if r[name] != s.get(name)]
            return WRONG, f"curve.csv's {name} differs from the uninterrupted run at steps {steps}"
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
        if pa is None and pb is not None:
            return WRONG, f"pull-off {pb:.4e} N after restart, none uninterrupted"
        if pa is not None and pb is None:
            return LOST, f"pull-off missing after restart (uninterrupted: {pa:.4e} N)"
        if pa is not None and abs(pa - pb) > 1e-3 * abs(pa):
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
                notes.append(f"mpirun did not end within {harness.TIMEOUT / 2:g} s of the kill")
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
        res = run_scene(d, scene, "-adhesion_time_budget", budget)
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
        procs = [launch(["-m", "contactpetsc", "run", str(f)], d, n) for f, n in zip(files, ranks)]
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
        # the product's own line (mpirun may add lines of its own when a rank ends early)
        said = [ln for ln in results[loser].err.splitlines() if ln.startswith("contactpetsc")]
        msg = said[-1][:220] if said else message(results[loser])
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
from contactpetsc.app.cli import main
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
        proc = launch(["-m", "contactpetsc", "run", str(write_scene(d / "scene.toml", scene))], d)
        t0, marks = time.time(), []
        curve = d / "out/curve.csv"
        while proc.poll() is None and time.time() - t0 < harness.TIMEOUT * 2:
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
