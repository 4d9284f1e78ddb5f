"""The stability check left out where it cannot change an answer (``-adhesion_stability_check auto``).

Truths: the always-on check (every state checked) -- auto must find the same jumps (the same
bisected approaches) and the same pull-off, and every state it leaves out must be one the
always-on check found stable; a convex (non-adhesive) problem has a unique state and no fold,
so no check is run there.  The outputs say per state whether the check ran: ``stable`` is
True or False exactly where ``stability_checked`` is True.
"""
import csv
import os
import shutil
import subprocess
import sys
import tempfile

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, runner, scenes
from contactpetsc.fold_watch import FoldWatch
from contactpetsc.grid import SurfaceGrid
from contactpetsc.paths import sweep
from contactpetsc.pull_off import refine_pull_off
from adhesive_setup import sphere_problem

pytestmark = pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")


#: the sphere's grid per law: (nodes, spacing, preconditioner).  The hard-wall path runs on a
#: coarser grid of the same 48-z0 window with the preconditioner auto picks for it on 48 x 48
#: nodes (mlmi): the same solvers and fallbacks (Newton, then the relaxation and PTC) at about
#: half the time; auto's truth (the always-on check's jumps and pull-off) holds on any grid
GRIDS = {"lj": (48, 1.0, None), "hardwall-lj": (32, 1.5, "mlmi")}


def _path(mode, law, prefix):
    n, dx, pc = GRIDS[law]
    pb = sphere_problem(1.0, law=law, n=n, dx=dx, radius=50.0, prefix=prefix, stability_check=mode,
                        preconditioner=pc)
    step = 0.5
    approaches = np.concatenate([np.arange(-3.0, 1.01, step), np.arange(1.0 - step, -3.01, -step)])
    path = sweep(pb, approaches)
    return path, refine_pull_off(pb, path, xtol=0.01 * step)


# the hard-wall path is the dearest test of the suite: checked serially (the full LJ path
# checks that auto's decisions do not depend on the rank count)
@pytest.mark.parametrize("law", [pytest.param("lj", marks=pytest.mark.heavy),
                                 pytest.param("hardwall-lj", marks=pytest.mark.serial)])
def test_auto_finds_the_jumps_and_pull_off_of_the_always_on_check(coll, law):
    """Tabor 1 sphere, load and unload: jump-on, jump-off and pull-off identical with auto and
    with the check forced on; auto leaves the check out at some states, each of them one the
    always-on check found stable."""
    on, pull_on = _path(True, law, f"on_{law}_")
    auto, pull_auto = _path("auto", law, f"auto_{law}_")
    assert [j.kind for j in on.jumps] == ["jump-on", "jump-off"]
    assert [j.kind for j in auto.jumps] == [j.kind for j in on.jumps]
    for a, b in zip(auto.jumps, on.jumps):
        assert (a.approach_before, a.approach_after) == (b.approach_before, b.approach_after)
        assert coll.max(abs(a.force_before - b.force_before) + abs(a.force_after - b.force_after)) \
            <= 1e-8 * abs(b.force_after)
    assert np.isfinite(pull_on) and coll.max(abs(pull_auto / pull_on - 1)) <= 1e-8
    assert [p.approach for p in auto.points] == [p.approach for p in on.points]
    skipped = [k for k, p in enumerate(auto.points) if p.converged and p.stable is None]
    assert skipped, "auto checked every state"
    assert all(on.points[k].stable is True for k in skipped)
    assert all(a.stable == b.stable for a, b in zip(auto.points, on.points) if a.stable is not None)


@pytest.mark.serial   # rules on made-up records: no communicator
def test_fold_watch_rules():
    """The rules on made-up records: no trend without two checked states; a reversal, a new
    most tensile force, a missed tangent prediction, a harder Newton step and a falling
    margin each call for the check; a state on a smooth, stable stretch does not."""
    class St:
        def __init__(self, approach, margin, newton=3, force=-1.0):
            self.approach, self.stability_margin, self.newton_iterations, self.force = approach, margin, newton, force
            self.stable = None if np.isnan(margin) else bool(margin > 0)

    watch = FoldWatch()
    prev = (0.0, -1.0, 1.0)    # approach, force, stiffness
    assert "fewer than two" in watch.reason(prev, 0.1, 3, -0.9)
    watch.seen(St(0.0, 0.50), None, jumped=False)
    watch.seen(St(0.1, 0.51, force=-0.9), 0.0, jumped=False)
    prev = (0.1, -0.9, 1.0)
    assert watch.reason(prev, 0.2, 3, -0.8) is None                    # on the predicted branch
    assert "reverses" in watch.reason(prev, 0.0, 3, -1.0)
    assert "most tensile" in watch.reason(prev, 0.2, 3, -1.5)
    assert "tangent prediction" in watch.reason(prev, 0.2, 3, -0.5)
    assert "Newton" in watch.reason(prev, 0.2, 9, -0.8)
    assert "trend" in watch.reason(prev, 5.0, 3, -0.8 + 4.9)            # far along: the trend may reach 0
    watch.seen(St(0.2, 0.05, force=-0.8), 0.1, jumped=False)            # the margin falls fast
    assert "trend" in watch.reason((0.2, -0.8, 1.0), 0.3, 3, -0.7)
    watch.seen(St(0.3, 0.6, force=-0.7), 0.2, jumped=True)              # a new branch: no trend yet
    assert "fewer than two" in watch.reason((0.3, -0.7, 1.0), 0.4, 3, -0.6)
    assert "snap number" in FoldWatch(snap_number=1.5).reason(prev, 0.2, 3, -0.8)


SPHERE = dict(name="auto-sphere", geometry=dict(kind="sphere", radius=30e-9, nx=64, dx=0.3e-9),
              material=dict(e_star=10e9), interaction=dict(law="lj", work_of_adhesion=0.3, z0=0.3e-9),
              protocol=dict(control="approach", values=[v * 1e-9 for v in (-0.6, -0.45, -0.3, -0.15, 0.0, 0.15,
                                                                            0.3, 0.15, 0.0, -0.15, -0.3, -0.45)],
                            refine_pull_off=False),
              output=dict(field_precision="float64"))


def _rows(scene, out, restart=False):
    runner.run(scenes.validate(scene), output=str(out), overwrite=not restart, restart=restart)
    with open(os.path.join(out, "curve.csv")) as f:
        return list(csv.DictReader(f))


@pytest.fixture(scope="module")
def auto_run():
    """The SPHERE sweep under auto, uninterrupted: (its directory, its curve.csv rows); shared by
    the ranks and the tests of this module."""
    comm = PETSc.COMM_WORLD.tompi4py()
    out = comm.bcast(tempfile.mkdtemp(prefix="contactpetsc-auto-") if comm.rank == 0 else None)
    yield out, _rows(SPHERE, out)
    comm.Barrier()
    if comm.rank == 0:
        shutil.rmtree(out, ignore_errors=True)


# one rank: on two, auto's decisions against the always-on check are the full LJ path's of
# test_auto_finds_the_jumps_and_pull_off_of_the_always_on_check, and curve.csv's stable and
# stability_checked those of test_a_stopped_sweep_restarts_to_the_uninterrupted_run
@pytest.mark.serial
def test_curve_says_per_state_whether_the_check_ran(shared_tmp, auto_run):
    """curve.csv: stable is True/False exactly where stability_checked is True, nan elsewhere,
    and the margin has the verdict's sign there (nan elsewhere);
    the states auto leaves out are stable in the always-on run, and the checked ones agree
    with it; the jumps are the same.  A non-adhesive scene runs no check."""
    out = str(shared_tmp)
    auto = auto_run[1]
    forced = dict(SPHERE, solver=dict(options=dict(stability_check="true")))
    on = _rows(forced, os.path.join(out, "on"))
    assert all(r["stability_checked"] == "True" and r["stable"] in ("True", "False") for r in on)
    for r in on + auto:
        # the margin's sign is the verdict where the check ran; nothing where it did not
        if r["stability_checked"] == "True":
            assert (float(r["stability_margin"]) > 0.0) == (r["stable"] == "True")
            assert r["stability_settled"] in ("True", "False")
        else:
            assert r["stability_margin"] == "nan" and r["stability_settled"] == "nan"
    for a, b in zip(auto, on):
        assert a["stability_checked"] in ("True", "False")
        if a["stability_checked"] == "True":
            assert a["stable"] == b["stable"]
        else:
            assert a["stable"] == "nan" and b["stable"] == "True"
    assert any(r["stability_checked"] == "False" for r in auto)
    with open(os.path.join(auto_run[0], "jumps.csv")) as f, open(os.path.join(out, "on", "jumps.csv")) as g:
        ja, jb = list(csv.DictReader(f)), list(csv.DictReader(g))
    assert [(j["kind"], j["approach_before_m"]) for j in ja] == [(j["kind"], j["approach_before_m"]) for j in jb]
    hertz = dict(name="hertz", geometry=dict(kind="sphere", radius=1e-6, nx=32, dx=4e-9), material=dict(e_star=1e9),
                 protocol=dict(values=[0.5e-9, 1e-9]), output=dict(fields=False))
    rows = _rows(hertz, os.path.join(out, "hertz"))
    assert all(r["stability_checked"] == "False" and r["stable"] == "True" for r in rows)
    assert all(r["stability_margin"] == "nan" and r["stability_settled"] == "nan" for r in rows)


def _plan(scene):
    scene = scenes.validate(scene)
    grid = SurfaceGrid(scene["geometry"]["nx"], scene["geometry"]["ny"], scene["geometry"]["dx"], periodic=False)
    return "\n".join(runner.plan(scene, grid, builder.build_law(scene)))


def test_dry_run_says_what_is_left_out_and_why(coll):
    """The plan (what --dry-run prints) names, per scene, where the check and the tangent run
    and why the rest is left out."""
    sweep_plan = _plan(SPHERE)
    assert "stability check: at the states where a fold may be near (auto)" in sweep_plan
    assert "tangent: every converged state" in sweep_plan
    gap = dict(SPHERE, protocol=dict(control="central_gap", values=[3e-10, 2e-10]))
    text = _plan(gap)
    assert "stability check: every state (central-gap control" in text and "left out: the tangent" in text
    relax = dict(SPHERE, interaction=dict(law="hardwall-lj", work_of_adhesion=0.3, z0=0.3e-9),
                 solver=dict(method="relaxation"))
    text = _plan(relax)
    assert "stability check: every state (the relaxation" in text and "left out: the tangent (the relaxation" in text
    off = dict(SPHERE, solver=dict(options=dict(stability_check="false")))
    assert "stability check: left out at every state (-adhesion_stability_check false)" in _plan(off)
    hertz = dict(name="hertz", geometry=dict(kind="sphere", radius=1e-6, nx=32, dx=4e-9), material=dict(e_star=1e9),
                 protocol=dict(values=[1e-9]))
    assert "left out: the stability check and the tangent (no adhesion: a convex problem" in _plan(hertz)


@pytest.mark.serial
def test_cli_dry_run_names_a_forced_check():
    """`contactpetsc run --dry-run` with -adhesion_stability_check on the command line."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    scene = os.path.join(root, "examples", "scenes", "adhesive_sphere.toml")
    done = subprocess.run([sys.executable, "-m", "contactpetsc", "run", scene, "--dry-run",
                           "-adhesion_stability_check", "true"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert "stability check: every state (-adhesion_stability_check true)" in done.stdout
    bad = subprocess.run([sys.executable, "-m", "contactpetsc", "run", scene, "--dry-run",
                          "-adhesion_stability_check", "sometimes"], capture_output=True, text=True, timeout=120)
    assert bad.returncode != 0 and "accepted values are true, false, auto" in bad.stdout + bad.stderr


@pytest.mark.heavy   # an adhesive sweep: 1 and 2 ranks
def test_a_stopped_sweep_restarts_to_the_uninterrupted_run(coll, shared_tmp, auto_run):
    """The sweep stopped after 3, 6 and 9 of its 12 steps and restarted each time (a run of the
    first k values, then --restart with more): curve.csv has the uninterrupted run's Newton
    iterations, forces, ``stable`` and ``stability_checked`` at every step, and its jumps.  The
    fold watch's record and the last stiffness are kept with each step file; the nested
    iteration's coarse levels are put at the fine state before every step, so the first
    restarted step is predicted as in the uninterrupted run (the fold watch decides from Newton
    counts)."""
    scene, (full, ref) = SPHERE, auto_run
    out = shared_tmp / "stopped"
    values = scene["protocol"]["values"]
    for n, k in enumerate((3, 6, 9, len(values))):
        got = _rows(dict(scene, protocol=dict(scene["protocol"], values=values[:k])), str(out), n > 0)
    columns = ("newton_iterations", "stable", "stability_checked")
    assert [[r[c] for c in columns] for r in got] == [[r[c] for c in columns] for r in ref]
    assert coll.max([abs(float(a["force_N"]) / float(b["force_N"]) - 1) for a, b in zip(got, ref)]) <= 1e-12
    assert any(r["stability_checked"] == "False" for r in ref[3:])
    with open(os.path.join(full, "jumps.csv")) as f, open(out / "jumps.csv") as g:
        assert [j["approach_before_m"] for j in csv.DictReader(f)] == [j["approach_before_m"] for j in csv.DictReader(g)]
