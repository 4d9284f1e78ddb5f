"""Pull-off force and jumps of displacement-controlled paths against exact answers.

Flat periodic cell with the full LJ law: the state is uniform at every approach, so
F = A p_LJ(-delta) exactly -- a smooth branch without jumps -- and the uniform state is
stable wherever dp/dg <= 0 (at least down to the law's peak), so the most tensile stable
state of any path through the peak is -A * (peak attraction), whatever the sampling; on a
soft cell the states beyond the peak are unstable (sampled points there are marked so).
A sphere that never comes within 10 z0 of the surface sees a smooth, monotonic
attraction: no jumps, no pull-off (the most tensile state is the turning point).
"""
import numpy as np
import pytest

from contactpetsc.grid import SurfaceGrid
from contactpetsc.paths import sweep
from contactpetsc.pull_off import refine_pull_off
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import sphere


def flat_cell(n, w, prefix):
    grid = SurfaceGrid(n, n, 1.0, periodic=True)
    law = make_law("lj", work_of_adhesion=w, z0=1.0)
    return AdhesiveProblem(grid, grid.create_vec(0.0), 1.0, law, prefix=prefix), law


@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
# the soft cells' paths through unstable states: 1 and 2 ranks (heavy; on 3 ranks the stiff
# cells' paths and test_adhesive_paths' central-gap path through unstable states split unevenly)
@pytest.mark.parametrize("w, approaches", [
    # a coarse load-unload path whose samples straddle the unstable range beyond the peak
    pytest.param(0.5, [-2.05, -1.0, 0.05, 0.3, 0.05, -1.0, -2.05], marks=pytest.mark.heavy),
    pytest.param(0.5, [-1.5, -0.5, 0.5, -0.5, -1.5], marks=pytest.mark.heavy),
    # every state stable, samples off the peak
    (0.05, [-1.2, -0.9, -0.6, -0.3, 0.0, 0.3, 0.0, -0.3, -0.6, -0.9, -1.2]),
    # the peak between the path's reversal and the first unloading sample
    (0.05, [-2.0, -1.3, -0.6, 0.0, -0.37, -0.74, -1.11, -1.48]),
])
def test_flat_cell_pull_off_is_the_law_peak_and_its_branch_has_no_jumps(coll, w, approaches):
    n = 32
    problem, law = flat_cell(n, w, f"flat_{len(approaches)}_")
    path = sweep(problem, approaches)
    area = n * n
    for p in path.points:
        if p.converged:
            assert abs(p.force - area * law.pressure(-p.approach)) <= 1e-6 * area * law.peak_attraction
    assert not path.jumps, path.jumps
    pull = refine_pull_off(problem, path, xtol=1e-4)
    exact = -area * law.peak_attraction
    assert abs(pull / exact - 1) < 1e-6, (pull, exact)
    assert path.pull_off_force == pull


def test_far_sphere_has_no_jumps_and_no_pull_off(coll):
    z0 = 0.3e-9
    grid = SurfaceGrid(64, 64, z0, periodic=False)
    law = make_law("lj", work_of_adhesion=0.3, z0=z0)
    problem = AdhesiveProblem(grid, sphere(grid, 30e-9), 10e9, law, prefix="far_sphere_")
    # a coarse first step, then in and out again, never closer than 10 z0 (apex gap -delta)
    path = sweep(problem, np.array([-40.0, -11.0, -20.0, -10.0, -25.0, -40.0]) * z0)
    assert all(p.converged and p.stable for p in path.points)
    forces = [p.force for p in path.points]
    assert all(f < 0 for f in forces) and min(forces) == forces[3]   # most tensile: the closest
    assert not path.jumps, path.jumps
    assert np.isnan(path.pull_off_force)
    assert np.isnan(refine_pull_off(problem, path, xtol=0.01 * z0))


# one rank: on two, a path without jumps refined to its pull-off is the flat cells' here and the
# DMT sphere's of test_studies
@pytest.mark.serial
def test_sphere_pull_off_does_not_depend_on_the_sampling(coll):
    """mu = 0.5, full LJ (no jumps): the refined pull-off of a coarse path (steps of 0.5 z0,
    the minimum between samples) is the fine path's (steps of 0.1 z0), and lies between the
    JKR and DMT limits (Maugis-Dugdale: -2 < F / (pi R w) < -1.5)."""
    radius, mu = 100.0, 0.5
    w = np.sqrt(mu ** 3 / radius)     # E* = z0 = 1
    bars = []
    for step in (0.5, 0.1):
        grid = SurfaceGrid(64, 64, 1.0, periodic=False)
        problem = AdhesiveProblem(grid, sphere(grid, radius), 1.0, make_law("lj", work_of_adhesion=w, z0=1.0),
                                  prefix=f"sampling_{step:g}_")
        approaches = np.concatenate([np.arange(-2.5, 0.51, step), np.arange(0.5 - step, -2.51, -step)])
        path = sweep(problem, approaches)
        assert not path.jumps
        bars.append(refine_pull_off(problem, path, xtol=0.002) / (np.pi * radius * w))
    assert abs(bars[0] / bars[1] - 1) < 1e-4, bars
    assert -2.0 < bars[1] < -1.5


def test_flat_cell_path_that_turns_before_the_peak_has_no_pull_off(coll):
    """Reversed at a gap of 0.4 z0, short of the peak at 3^(1/6) - 1 = 0.12 z0: the most
    tensile state is the reversal, where the force still falls with the approach."""
    problem, law = flat_cell(32, 0.05, "flat_turn_")
    path = sweep(problem, [-3.0, -2.0, -1.0, -0.6, -0.4, -0.6, -1.0, -2.0])
    assert all(p.converged and p.stable for p in path.points) and not path.jumps
    assert np.isnan(path.pull_off_force)
    assert np.isnan(refine_pull_off(problem, path, xtol=1e-4))


UNDER_RESOLVED = pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
#: the flat cell's scene in its units (E* = z0 = dx = 1): a map of metres, which is meant
METRE_MAP = pytest.mark.filterwarnings("ignore::contactpetsc.topography.units.TopographyUnitWarning")


def flat_scene(tmp, w, values, method="relaxation", n=16, **protocol):
    """The flat periodic cell of ``flat_cell`` as a scene (a file of zero heights), E* = z0 = 1."""
    from mpi4py import MPI
    from contactpetsc.app import scenes
    path = tmp / "flat.npy"
    if MPI.COMM_WORLD.Get_rank() == 0:
        np.save(path, np.zeros((n, n)))
    MPI.COMM_WORLD.Barrier()
    return scenes.validate(dict(
        name="flat-relaxation", geometry=dict(kind="file", path=str(path), dx=1.0, periodic=True),
        material=dict(e_star=1.0), interaction=dict(law="lj", work_of_adhesion=w, z0=1.0),
        protocol=dict(control="approach", values=list(values), **protocol), solver=dict(method=method),
        output=dict(fields=False)))


def sampled_pull_off(out):
    """The most tensile converged stable step of ``curve.csv`` [N]."""
    import csv
    with open(out / "curve.csv", newline="") as f:
        return min(float(r["force_N"]) for r in csv.DictReader(f) if r["converged"] == "True" and r["stable"] != "False")


@pytest.mark.parametrize("w", [0.05, 0.5])   # every state stable; unstable states beyond the peak
@UNDER_RESOLVED
@METRE_MAP
def test_a_relaxation_sweep_refines_the_flat_cell_pull_off_to_the_law_peak(coll, shared_tmp, w):
    """solver.method = relaxation on the flat cell, sampled every 0.5 z0 about the peak (at a gap
    of 0.2 z0): the sampled pull-off is over 10 % short of -A P; the one refined by relaxation
    solves (xtol = 1 % of the step) is within what a miss of xtol in approach gives at the peak
    plus the relaxation's pressure tolerance (1e-4 P), and summary.json says it is refined."""
    import json
    from contactpetsc.app import runner
    n, values = 16, [-1.5, -0.6, -0.1, -0.6, -1.5]
    law = make_law("lj", work_of_adhesion=w, z0=1.0)
    out = shared_tmp / "relax"
    runner.run(flat_scene(shared_tmp, w, values, n=n), output=str(out))
    summary = json.loads((out / "summary.json").read_text())
    exact = -n * n * law.peak_attraction
    gaps = np.linspace(0.0, 1.0, 100001)
    peak = gaps[np.argmin(law.pressure(gaps))]
    xtol = 0.01 * 0.5
    miss = max(float(law.pressure(np.array([peak - xtol, peak + xtol])).max()) / -law.peak_attraction + 1, 0.0)
    assert summary["pull_off_refined"] is True and "pull_off_not_refined" not in summary
    sampled, refined = sampled_pull_off(out) / exact - 1, summary["pull_off_force_N"] / exact - 1
    assert coll.max(sampled) < -0.1, sampled
    assert coll.max(abs(refined)) <= miss + 1e-4, (refined, miss)


@UNDER_RESOLVED
@METRE_MAP
def test_a_relaxation_sweep_whose_search_fails_keeps_the_sampled_pull_off(coll, shared_tmp, monkeypatch):
    """A relaxation solve of the pull-off search that does not converge (here: its cycle limit cut
    to 2) leaves the sampled pull-off (loading past the peak: the step at a gap of 0.1 z0), marked
    not refined with the reason (summary.json)."""
    import json
    from contactpetsc.app import runner
    from contactpetsc.app.steppers import AdhesiveSteps
    finish = AdhesiveSteps.finish

    def cut_short(self):
        self.relax.max_cycles = 2
        return finish(self)

    monkeypatch.setattr(AdhesiveSteps, "finish", cut_short)
    out = shared_tmp / "cut"
    runner.run(flat_scene(shared_tmp, 0.05, [-1.5, -1.0, -0.5, -0.1, 0.0]), output=str(out))
    summary = json.loads((out / "summary.json").read_text())
    assert summary["pull_off_refined"] is False
    assert "did not converge" in summary["pull_off_not_refined"] and "DIVERGED_MAX_CYCLES" in summary["pull_off_not_refined"]
    assert summary["pull_off_force_N"] == sampled_pull_off(out)


# one rank: on two, a relaxation sweep refining its pull-off is the flat cells' here
# (test_a_relaxation_sweep_refines_the_flat_cell_pull_off_to_the_law_peak)
@pytest.mark.serial
@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_a_relaxation_sweep_refines_its_pull_off_to_the_newton_sweeps(coll, shared_tmp):
    """solver.method = relaxation on a sphere (Tabor parameter 0.5, loaded to 0.3 nm and unloaded
    past its jump-off, steps of z0): the pull-off refined by relaxation solves is the Newton
    sweep's refined one within the relaxation's tolerance (1e-4 z0 in the gaps), where the
    sampled one is over 5 % short; the plan names the refinement."""
    import json
    from contactpetsc.app import builder, runner, scenes
    scene = dict(name="relax-pull-off", geometry=dict(kind="sphere", radius=30e-9, nx=16, dx=1.2e-9),
                 material=dict(e_star=30e9), interaction=dict(law="hardwall-lj", work_of_adhesion=0.3, z0=0.3e-9),
                 protocol=dict(control="approach", values=[v * 1e-9 for v in (-0.3, 0.0, 0.3, 0.0, -0.3, -0.6)]),
                 output=dict(fields=False))
    pulls = {}
    for method in ("newton", "relaxation"):
        out = shared_tmp / method
        runner.run(scenes.validate(dict(scene, solver=dict(method=method))), output=str(out))
        pulls[method] = json.loads((out / "summary.json").read_text())
    newton, relax = pulls["newton"]["pull_off_force_N"], pulls["relaxation"]["pull_off_force_N"]
    assert newton is not None and newton < 0
    assert pulls["relaxation"]["pull_off_refined"] is True
    assert coll.max(abs(relax / newton - 1)) <= 1e-3
    assert coll.max(sampled_pull_off(shared_tmp / "relaxation") / newton - 1) < -0.05
    plan = builder.leave_out(scenes.validate(dict(scene, solver=dict(method="relaxation"))))
    assert "pull-off refinement" in " ".join(plan)


def test_the_pull_off_search_holds_one_searched_state_at_a_time(coll, monkeypatch):
    """The search refines the flat cell's pull-off to the law's peak while holding, whatever its
    length, no searched state's fields through the next solve and at most three copies of the
    unknowns of its own (the path's end, the step's start, the most tensile state found): it had
    kept a copy of every state it continued through and each state's fields until the next
    solve returned (docs/performance.md, "Memory of an adhesive path")."""
    from contactpetsc.solvers import tangent
    n = 16
    problem, law = flat_cell(n, 0.05, "flat_search_mem_")
    path = sweep(problem, [-1.2, -0.6, 0.0, 0.3, 0.0, -0.6, -1.2])
    live, most = set(), [0]
    made, destroy = tangent.Snapshot.__init__, tangent.Snapshot.destroy

    def counted_init(self, *a):
        made(self, *a)
        live.add(id(self))
        most[0] = max(most[0], len(live))

    def counted_destroy(self):
        live.discard(id(self))
        destroy(self)

    monkeypatch.setattr(tangent.Snapshot, "__init__", counted_init)
    monkeypatch.setattr(tangent.Snapshot, "destroy", counted_destroy)
    solved, held = [], []
    solve = problem.solve

    def watched_solve(*a, **k):
        held.append(sum(st.gap is not None for st in solved))
        st = solve(*a, **k)
        solved.append(st)
        return st

    monkeypatch.setattr(problem, "solve", watched_solve)
    pull = refine_pull_off(problem, path, xtol=1e-5)
    assert abs(pull / (-n * n * law.peak_attraction) - 1) < 1e-6
    assert len(solved) > 8, len(solved)       # a search long enough to have held more
    assert max(held) == 0, held
    assert most[0] <= 3, most[0]
    assert not live
