"""Adhesive paths and stability: jumps, hysteresis, the S-curve, stiffness, load control.

Independent truths: the force slope (finite differences of the path), the loading and unloading
branches meeting, the stability margin's bound.  Units: z0 = 1, E* = 1 (Greenwood's).
"""
import json
import re

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.paths import central_gap_path, edge_gap_path, sweep
from contactpetsc.pull_off import refine_pull_off

from adhesive_setup import EXAMPLE_LOADING, EXAMPLE_RADIUS, example_sphere, work_for, sphere_problem


def test_stiffness_is_the_force_slope_and_can_be_left_out(coll):
    """The tangent stiffness is dW/d delta: central differences of the force over two further
    solves agree.  With -<prefix>stiffness false it is NaN, the tangent is solved only for
    the predictor, and the states are the same."""
    pb = sphere_problem(1.0, law="lj", n=64, dx=1.0, prefix="stiff_")
    h = 1e-3
    st = pb.solve(approach=0.5)
    lo, hi = pb.solve(approach=0.5 - h), pb.solve(approach=0.5 + h)
    # the tangent is solved to rtol 1e-2 (a predictor and a jump test need no more)
    assert coll.max(abs((hi.force - lo.force) / (2 * h) / st.stiffness - 1)) < 1e-2
    PETSc.Options().setValue("lazy_stiffness", False)
    try:
        lazy = sphere_problem(1.0, law="lj", n=64, dx=1.0, prefix="lazy_", element_integration=False)
        for d in (0.5, 0.5 - h, 0.5 + h):
            st2 = lazy.solve(approach=d)
            assert np.isnan(st2.stiffness)
        assert coll.max(abs(st2.force / hi.force - 1)) < 1e-8
    finally:
        PETSc.Options().delValue("lazy_stiffness")


@pytest.mark.heavy   # an adhesive path: 1 and 2 ranks (3 oversubscribed ranks spend minutes)
def test_loading_unloading_hysteresis_and_jumps(coll, example_sphere_path):
    """mu = 1, full LJ (conftest's example_sphere_path): jump-on while loading, jump-off while
    unloading at a smaller approach (hysteresis), pull-off between the JKR and DMT limits."""
    r = EXAMPLE_RADIUS
    pb, path = example_sphere_path
    w = work_for(1.0, r)
    kinds = [j.kind for j in path.jumps]
    assert kinds == ["jump-on", "jump-off"]
    on, off = path.jumps
    assert off.approach_before < on.approach_before
    assert on.force_after < on.force_before < 0      # snaps into tension
    assert off.force_after > off.force_before         # released
    bar = refine_pull_off(pb, path, xtol=0.01) / (np.pi * r * w)
    assert -2.0 < bar < -1.5
    # every point kept on the path is a stable, converged state
    assert all(p.converged and p.stable for p in path.points)


def test_central_gap_traces_the_unstable_branch(coll):
    """Greenwood's device: prescribing the central gap passes through states that are unstable
    under displacement control, where the approach turns back (the S-curve)."""
    pb = sphere_problem(1.0, law="lj", n=96, dx=1.0)
    path = central_gap_path(pb, np.arange(2.0, 0.19, -0.1))
    assert all(p.converged for p in path.points)
    stable = [p.stable for p in path.points]
    assert stable[0] and False in stable
    approach = path.column("approach")
    k = stable.index(False)
    # the approach has a maximum on the unstable stretch: the fold of the S-curve
    assert approach[k - 1] > approach[0] and np.max(approach) > approach[-1]


def test_a_prescribed_central_gap_is_reached_after_the_control_gap_is_read(coll):
    """A solve at a prescribed gap of the control node lands on that gap, also straight after
    ``control_gap`` read the present gap there (the step ``edge_gap_path`` takes at each node):
    the gap rows that read made under displacement control are not the prescribed gap's."""
    pb = sphere_problem(2.0, law="hardwall-lj", n=96, dx=0.5, radius=100.0, prefix="cg_read_")
    for delta in (-1.5, -1.0):
        st = pb.solve(approach=delta)
    j0, i0 = divmod(pb.centre_index, pb.grid.nx)
    pb.set_control_node((i0 + 24, j0))      # outside the contact (12 z0 out): its gap is free
    target = pb.control_gap() + 0.05
    st = pb.solve(central_gap=target)
    assert st.converged and abs(st.central_gap - target) <= 1e-6
    assert st.approach < delta - 0.01       # the sphere drawn back to open the gap


@pytest.mark.heavy   # an adhesive path: 1 and 2 ranks (3 oversubscribed ranks spend minutes)
def test_edge_gap_path_closes_the_s_curve_on_the_adhered_branch(coll):
    """Past the apex touching, prescribed gaps at nodes further out carry the S-curve
    through the rest of the unstable branch and its fold (the jump-off) onto the adhered
    branch: the last state equals the state that displacement-controlled unloading from
    compression reaches at the same approach (an independent path to it)."""
    pb = sphere_problem(2.0, law="lj", n=64, dx=1.5, element_integration=True, prefix="edge_")
    path = central_gap_path(pb, np.round(np.arange(2.0, 0.04, -0.1), 10))
    fold = [min(path.column("approach"))]

    def back_on_adhered_branch(pt):
        fold[0] = min(fold[0], pt.approach)
        return bool(pt.stable) and pt.approach > fold[0] + 1.0

    k0 = len(path.points)
    edge_gap_path(pb, 0.1, 0.05, stop=back_on_adhered_branch, path=path)
    edge = path.points[k0:]
    assert all(p.converged for p in edge) and edge[-1].stable
    stable = [p.stable for p in edge]
    assert stable[0] is False                      # it continues the unstable branch
    approach = np.array([p.approach for p in edge])
    k = int(np.argmin(approach))
    assert approach[k] < approach[0] - 0.1 and approach[k] < approach[-1] - 1.0   # the fold
    end = edge[-1]
    ref = sphere_problem(2.0, law="lj", n=64, dx=1.5, element_integration=True, prefix="edge_ref_")
    down = np.arange(2.0, end.approach, -0.5)
    unload = sweep(ref, np.concatenate([np.arange(-3.0, 2.01, 0.5), down, [end.approach]]), refine=0)
    assert coll.max(abs(unload.points[-1].force / end.force - 1)) < 1e-6


def test_truncated_stability_check_says_so(coll):
    """A Lanczos run cut short is reported as unsettled, and its margin is an upper bound:
    Ritz values only grow towards lambda_max(A S)."""
    pb = sphere_problem(1.0, law="lj", n=64, dx=1.0)
    pb.snes()
    pb.stability_check.steps = 3
    st = pb.solve(approach=0.5)
    assert st.converged and st.stability_converged is False
    pb.stability_check.steps = 60
    full = pb.stability_check.margin()
    assert pb.stability_check.settled is True
    assert full <= st.stability_margin + 1e-12


def test_load_control_where_stable(coll):
    """A prescribed tensile force on the stable branch is met; beyond the pull-off force
    load control reports why it cannot be met."""
    pb = sphere_problem(0.5, law="lj", n=64, dx=1.0, radius=100.0)
    w = work_for(0.5, 100.0)
    path = sweep(pb, np.arange(-2.0, 1.01, 0.25))
    target = -1.0 * np.pi * 100.0 * w           # tensile, above the pull-off force (~ -1.78)
    st = pb.solve_force(target)
    assert st.converged and st.stable and abs(st.force - target) < 1e-6 * abs(target)
    pull = path.pull_off_force
    beyond = pb.solve_force(1.5 * pull, raise_on_failure=False)
    assert not beyond.converged
    assert "LOAD_CONTROL_UNSTABLE" in beyond.reason


@pytest.mark.heavy   # an adhesive path: 1 and 2 ranks (3 oversubscribed ranks spend minutes)
def test_a_budget_spent_while_a_jump_is_located_keeps_neither_step_nor_jump(coll, monkeypatch,
                                                                            example_sphere_path):
    """The time budget runs out inside the jump's bisection: its solves were cut short, so the
    step is not kept (not converged, the budget's reason), no jump is recorded, and the
    problem is back at the last converged state -- the uninterrupted path's jump-on (that of
    ``example_sphere_path``, whose loading is this path) is found when the path goes on from
    there."""
    from contactpetsc import path_steps, paths
    approaches = EXAMPLE_LOADING
    reference = example_sphere_path[1]
    on = reference.jumps[0]
    assert on.kind == "jump-on" and on.approach_before < approaches[-1]     # the one jump of the loading
    pb = example_sphere()
    locate = path_steps._locate_jump
    spent = {"now": False}

    def locate_then_spent(*args, **kw):
        jump = locate(*args, **kw)
        spent["now"] = True
        return jump

    monkeypatch.setattr(path_steps, "_locate_jump", locate_then_spent)
    monkeypatch.setattr(pb, "out_of_time", lambda: spent["now"])
    path = sweep(pb, approaches, stop_on_failure=True)
    last = path.points[-1]
    assert not last.converged and "WALL_TIME_BUDGET" in last.reason and not path.jumps
    assert all(p.converged for p in path.points[:-1])
    assert pb.approach == path.points[-2].approach            # back at the last converged state
    monkeypatch.setattr(pb, "out_of_time", lambda: False)
    rest = sweep(pb, approaches[len(path.points) - 1:], path=paths.Path(),
                 previous=(path.points[-2].approach, path.points[-2].force, path.points[-2].stiffness))
    assert [j.kind for j in rest.jumps] == ["jump-on"]
    assert abs(rest.jumps[0].approach_before - on.approach_before) <= 1e-9


def _bench_rough(n):
    """The rough benchmark surface (examples/scenes/bench_rough.toml) on an n x n grid: the same
    cell and seed, the cut-off at the same 4 grid spacings; (grid, heights)."""
    import os
    import tomllib

    from contactpetsc.app import scenes
    from contactpetsc.app.builder import build_heights
    from contactpetsc.grid import SurfaceGrid
    path = os.path.join(os.path.dirname(__file__), "..", "examples", "scenes", "bench_rough.toml")
    with open(path, "rb") as f:
        raw = tomllib.load(f)
    g = raw["geometry"]
    g.update(nx=n, dx=g["nx"] * g["dx"] / n, short_cutoff_wavelength=4 * g["nx"] * g["dx"] / n)
    scene = scenes.validate(raw)
    grid = SurfaceGrid(n, n, scene["geometry"]["dx"], periodic=True)
    return grid, build_heights(scene, grid)


@pytest.mark.heavy   # two rough adhesive paths: 1 and 2 ranks
def test_a_rough_adhesive_path_is_the_limit_of_small_steps(coll):
    """The rough benchmark surface at 128^2, the full LJ curve (w = 0.05 E* dx, z0 = dx), loaded
    from 0.07 z0 below its lowest point to 0.73 z0 above it and back in steps of 0.2 / 0.16 z0
    with the defaults a scene gets: a quasi-static path does not depend on its step, so the
    sweep with its own steps and the sweep taking each in sub-steps of at most 0.05 z0
    (``max_step``) reach the same state at every approach.  (With the predicted Newton step,
    ``-strategy newton``, the two part at the first loading step: its steps land on
    neighbouring branches.)"""
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    grid, h = _bench_rough(128)
    z0 = grid.dx
    law = make_law("lj", work_of_adhesion=0.05 * grid.dx, z0=z0)
    hmin = h.min()[1]
    values = list(hmin + z0 * np.concatenate([np.linspace(-0.07, 0.73, 5), np.linspace(0.73, -0.07, 6)[1:]]))
    gaps = {}
    for max_step in (0.0, 0.05):
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"qs{int(max_step * 100)}_", stability_check=False)
        seen = []
        path = sweep(pb, values, max_step=max_step * z0, on_state=lambda k, st, pt: seen.append(grid.gather(st.gap)))
        assert all(p.converged for p in path.points)
        assert path.points[1].solver.endswith(" (4 sub-steps)") == (max_step > 0), path.points[1].solver
        gaps[max_step] = seen
    differ = [k for k, (a, b) in enumerate(zip(gaps[0.0], gaps[0.05])) if coll.max(np.abs(a - b)) > 1e-6 * z0]
    assert not differ, differ


@pytest.mark.heavy   # three short rough adhesive paths: 1 and 2 ranks
def test_a_too_coarse_step_is_divided_until_its_pieces_agree(coll):
    """The rough benchmark surface at 128^2, the full LJ curve (w = 0.05 E* dx, z0 = dx), the
    predicted Newton step: from the state at 0.33 z0 above the lowest point, one unloading
    step of 0.4 z0.  Taken whole, it lands 1.3 z0 away from the quasi-static state (the path
    in sub-steps of 0.0125 z0, lower in energy).  With ``agreement`` the step is checked against
    its quarters, divided where they part, and lands on the quasi-static state; the point
    records its sub-steps and the check's verdict.  Truth: the limit of small steps."""
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    grid, h = _bench_rough(128)
    z0 = grid.dx
    law = make_law("lj", work_of_adhesion=0.05 * grid.dx, z0=z0)
    values = [h.min()[1] + z0 * 0.33, h.min()[1] - z0 * 0.07]
    last = {}
    for name, max_step, agreement in (("limit", 0.0125, 0.0), ("whole", 0.0, 0.0), ("agreed", 0.0, 1e-3)):
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"agree{name}_",
                             petsc_options={"strategy": "newton"})
        path = sweep(pb, values, max_step=max_step * z0, agreement=agreement * z0,
                     on_state=lambda k, st, pt: last.update({name: (grid.gather(st.gap), st.energy)}))
        assert all(p.converged for p in path.points), [p.reason for p in path.points]
        solver = path.points[-1].solver
    gap, energy = last["limit"]
    assert coll.max(np.abs(last["whole"][0] - gap)) > 0.5 * z0      # the case needs the check
    assert last["whole"][1] > energy
    assert coll.max(np.abs(last["agreed"][0] - gap)) < 1e-6 * z0
    assert re.search(r" \((4|16) sub-steps; (pieces agree at|sub-steps of .* not checked)", solver), solver


@pytest.mark.serial   # the plan: no solve
def test_the_plan_says_how_a_sweeps_sub_steps_are_checked():
    """A scene's plan (what --dry-run prints) names the sub-steps and how they are checked: on
    an isolated sphere (Newton) sub-steps of 0.1 z0 by default, quarters with protocol.agreement;
    on a periodic cell (the energy descent) whole steps checked by increments by default."""
    from contactpetsc.app import builder, runner, scenes
    from contactpetsc.grid import SurfaceGrid
    base = dict(name="plan", geometry=dict(kind="sphere", radius=30e-9, nx=32, dx=0.3e-9),
                material=dict(e_star=10e9), interaction=dict(law="lj", work_of_adhesion=0.3, z0=0.3e-9),
                protocol=dict(values=[-0.3e-9, 0.0, 0.3e-9]))

    def plan(periodic=False, options=None, **proto):
        scene = dict(base, protocol=dict(base["protocol"], **proto), solver=dict(options=options or {}))
        if periodic:
            scene["geometry"] = dict(kind="self-affine", nx=32, dx=0.3e-9, hurst=0.8, rms_height=0.6e-9, seed=1)
        scene = scenes.validate(scene)
        grid = SurfaceGrid(32, 32, 0.3e-9, periodic=periodic)
        return "\n".join(runner.plan(scene, grid, builder.build_law(scene)))

    assert "2 longer than 0.1 of the law's range (protocol.max_step), taken in 20 equal sub-steps" in plan()
    assert "protocol.agreement" not in plan()
    text = plan(agreement=1e-3, agreement_levels=3)
    assert "each sub-step checked against its 4 equal pieces to 0.001 of the law's range (protocol.agreement), " \
        "divided into them at most 3 times where they part" in text, text
    text = plan(periodic=True)
    assert "equal sub-steps" not in text and "each step checked by the energy descent's increments to 0.001 of the " \
        "law's range (protocol.agreement): descended in increments of at most 0.25 of the range " \
        "(protocol.agreement_increment), then in 4, ... 16 times as many until two agree; snaps within a step " \
        "are in its state" in text, text
    text = plan(periodic=True, agreement=0.0)
    assert "taken in 20 equal sub-steps" in text and "protocol.agreement" not in text, text
    # the strategy as the run's problem reads it, the option's dash and all
    text = plan(periodic=True, options={"-strategy": "newton"})
    assert "taken in 20 equal sub-steps" in text and "protocol.agreement" not in text, text


@pytest.mark.serial   # a scene's comparison: no solve
def test_a_restart_compares_the_sub_steps_its_steps_were_taken_in():
    """A run stored before protocol.agreement existed (sub-steps of 0.1, no check) restarts
    unchanged without adhesion, and with adhesion on a periodic cell only where the scene
    asks for the old sub-steps: the default there (whole steps, checked) is another path."""
    from contactpetsc.app import rundir, scenes
    from contactpetsc.app.steppers import resolve_sub_steps
    from contactpetsc.grid import SurfaceGrid
    grid = SurfaceGrid(32, 32, 0.3e-9, periodic=True)
    cell = dict(name="cell", geometry=dict(kind="self-affine", nx=32, dx=0.3e-9, hurst=0.8, rms_height=0.6e-9, seed=1),
                material=dict(e_star=10e9), protocol=dict(values=[0.0, 0.3e-9]))
    adhesive = dict(cell, interaction=dict(law="lj", work_of_adhesion=0.3, z0=0.3e-9))

    def stored(scene):   # as scene.json was written before the keys existed
        out = json.loads(json.dumps(resolve_sub_steps(scenes.validate(scene), grid)))
        out["protocol"] = {k: v for k, v in out["protocol"].items() if not k.startswith("agreement")}
        out["protocol"]["max_step"] = 0.1
        return out

    for scene in (cell, adhesive):
        old = stored(scene)
        now = resolve_sub_steps(scenes.validate(scene), grid)
        diff = rundir.differences(old, now, 1)
        assert diff == ([] if scene is cell else ["protocol.agreement: 0.0 on disk, 0.001 now",
                                                  "protocol.agreement_increment: 0.0 on disk, 0.25 now",
                                                  "protocol.max_step: 0.1 on disk, 0.0 now"]), diff
    again = dict(adhesive, protocol=dict(adhesive["protocol"], max_step=0.1, agreement=0.0))
    assert rundir.differences(stored(adhesive), resolve_sub_steps(scenes.validate(again), grid), 1) == []


@pytest.mark.serial   # a scene's run, its printed warning
def test_a_run_warns_of_steps_whose_check_did_not_settle(tmp_path, capfd):
    """A 32^2 periodic cell (full LJ, the energy descent) with an agreement no two ways meet
    (1e-14 of the range) and one level: every step after the first (0.5 z0: probed in 2
    increments of 0.25) is taken in 8, recorded as not agreeing with 2, and the run names those
    steps at its end."""
    import csv
    from contactpetsc.app import runner, scenes
    scene = scenes.validate(dict(
        name="unsettled", geometry=dict(kind="self-affine", nx=32, dx=1e-9, hurst=0.8, rms_height=2e-9, seed=4),
        material=dict(e_star=1e9), interaction=dict(law="lj", work_of_adhesion=0.05, z0=1e-9),
        protocol=dict(values=[-1e-9, -0.5e-9, 0.0], agreement=1e-14, agreement_levels=1),
        output=dict(directory=str(tmp_path / "out"), fields=False, plots=False)))
    runner.run(scene)
    with open(tmp_path / "out" / "curve.csv") as f:
        solvers = [r["solver"] for r in csv.DictReader(f)]
    assert all(s.endswith("(8 increments, not agreeing with 2)") for s in solvers[1:]), solvers
    assert "warning: in 2 step(s) (2, 3) the check of the sub-steps did not settle" in capfd.readouterr().out


class _Bistable:
    """A duck-typed problem for ``sweep``: a state that stays on its branch (gap 0) under steps
    of at most ``reach`` [m] and snaps to another (gap 1) under a longer one, as an asperity
    snaps out of order under a coarse step; it counts its solves."""

    def __init__(self, reach, strategy="newton"):
        self.reach, self.strategy, self.approach, self.off, self.solves = reach, strategy, None, 0.0, []
        self.descends = strategy == "descent"

    def solve(self, approach, raise_on_failure=True, check_stability=None, fallback=True, increments=None,
              tangent=True):
        from types import SimpleNamespace
        assert increments is None or self.strategy == "descent"
        step = 0.0 if self.approach is None else abs(approach - self.approach) / (increments or 1)
        if step > self.reach * (1 + 1e-9):
            self.off = 1.0
        self.approach = approach
        self.solves.append(approach)
        gap = PETSc.Vec().createSeq(1, comm=PETSc.COMM_SELF)
        gap.set(self.off)
        nan = float("nan")
        return SimpleNamespace(approach=approach, central_gap=nan, force=-approach, adhesive_force=nan,
                               contact_fraction=0.0, stable=None, converged=True, solver="bistable",
                               fft_pairs=1.0, wall_time=0.0, newton_iterations=1, linear_iterations=1,
                               complementarity_error=0.0, adhesive_error=0.0, total_error=0.0, reason="",
                               stiffness=-1.0, stability_margin=nan, fallback=False, gap=gap,
                               descent_increments=(increments or 1) if self.descends else 0,
                               release_fields=lambda: None)

    def snapshot(self):
        from types import SimpleNamespace
        return SimpleNamespace(approach=self.approach, off=self.off, destroy=lambda: None)

    def restore(self, snap):
        self.approach, self.off = snap.approach, snap.off

    def out_of_time(self):
        return False


@pytest.mark.serial   # bookkeeping of sweep: no grid
def test_agreement_divides_a_step_into_quarters_until_they_agree():
    """A step of 1 m on a branch left by any step longer than 0.3 m: the whole step (a probe)
    and its quarters part, so each quarter is checked in turn against its own quarters (a
    probe and four solves each) and taken: 1 + 5 + 4 x 5 solves, ending on the branch, with
    the pieces and the agreed sub-step recorded and every solve counted in the step's cost.
    With one level the quarters are taken unchecked after the first division.  Truth: counting."""
    pb = _Bistable(0.3)
    path = sweep(pb, [0.0, 1.0], agreement=0.5, levels=2)
    assert len(pb.solves) == 1 + 5 + 4 * 5, pb.solves
    assert pb.off == 0.0
    assert path.points[-1].solver == "bistable (16 sub-steps; pieces agree at sub-steps of 2.500e-01 m)"
    assert path.points[-1].fft_pairs == len(pb.solves) - 1
    pb = _Bistable(0.3)
    path = sweep(pb, [0.0, 1.0], agreement=0.5, levels=1)
    assert len(pb.solves) == 1 + 5 + 4 and pb.off == 0.0, pb.solves
    assert path.points[-1].solver == "bistable (4 sub-steps; sub-steps of 2.500e-01 m not checked)"
    pb = _Bistable(0.2)      # a quarter of the step is too long, yet agrees with the whole:
    sweep(pb, [0.0, 1.0], agreement=0.5, levels=2)
    assert pb.off == 1.0     # the check sees no finer than its quarters


@pytest.mark.serial   # bookkeeping of sweep: no grid
def test_agreement_under_the_descent_compares_the_step_in_more_increments():
    """Under the descent strategy the step is not divided: it is descended whole (a probe), then
    in 4 and 16 increments, until two agree.  A step of 1 m on a branch left by any increment
    longer than 0.3 m: the probe leaves it, 4 increments keep it but part from the probe, 16
    agree with 4: four solves in all, on the branch, the verdict in the solver column.  With
    one level the 4 increments are taken, recorded as not agreeing; with the probe itself in
    increments of at most 0.3 m (4), 16 agree with it at once.  Truth: counting."""
    pb = _Bistable(0.3, strategy="descent")
    path = sweep(pb, [0.0, 1.0], agreement=0.5, levels=2)
    assert len(pb.solves) == 1 + 3 and pb.off == 0.0, pb.solves
    assert path.points[-1].solver == "bistable (16 increments agree with 4)"
    assert path.points[-1].fft_pairs == 3
    pb = _Bistable(0.3, strategy="descent")
    path = sweep(pb, [0.0, 1.0], agreement=0.5, levels=1)
    assert len(pb.solves) == 1 + 2 and pb.off == 0.0, pb.solves
    assert path.points[-1].solver == "bistable (4 increments, not agreeing with 1)"
    pb = _Bistable(0.3, strategy="descent")      # the probe in increments of at most 0.3 m: 4
    path = sweep(pb, [0.0, 1.0], agreement=0.5, levels=2, foot=0.3)
    assert len(pb.solves) == 1 + 2 and pb.off == 0.0, pb.solves
    assert path.points[-1].solver == "bistable (16 increments agree with 4)"


class _LinearBranch:
    """A duck-typed problem for ``sweep`` (solve, snapshot, restore, out_of_time): one smooth
    branch, force = -approach [N], stiffness -1; it counts its solves."""

    def __init__(self):
        self.solves = []

    def solve(self, approach, raise_on_failure=True, check_stability=None, fallback=True):
        from types import SimpleNamespace
        self.solves.append(approach)
        nan = float("nan")
        return SimpleNamespace(approach=approach, central_gap=nan, force=-approach, adhesive_force=nan,
                               contact_fraction=0.0, stable=None, converged=True, solver="linear",
                               fft_pairs=1.0, wall_time=0.0, newton_iterations=1, linear_iterations=1,
                               complementarity_error=0.0, adhesive_error=0.0, total_error=0.0, reason="",
                               stiffness=-1.0, stability_margin=nan, fallback=False)

    def snapshot(self):
        from types import SimpleNamespace
        return SimpleNamespace(destroy=lambda: None)

    def restore(self, snap):
        pass

    def out_of_time(self):
        return False


@pytest.mark.parametrize("start", [0.0, 1.3e-6, -4.1e-5])
def test_max_step_takes_each_step_in_the_fewest_equal_sub_steps(start):
    """A step of 7.37 nm with max_step 0.1 nm is 74 solves, the last at the step's approach
    exactly, also far from the origin (the sub-steps' sum rounds there: an extra solve a few
    ulps short of the target had followed); steps of exactly max_step, up and down, are one
    solve each.  Truth: counting."""
    pb = _LinearBranch()
    step, longest = 7.37e-9, 1e-10
    path = sweep(pb, [start, start + step, start + step - 3 * longest, start + step - 2 * longest], max_step=longest)
    assert len(pb.solves) == 1 + 74 + 3 + 1, len(pb.solves)
    assert pb.solves[74] == start + step
    assert [p.solver for p in path.points] == ["linear", "linear (74 sub-steps)", "linear (3 sub-steps)", "linear"]
    assert np.max(np.abs(np.diff(pb.solves[:75]))) <= longest * (1 + 1e-9)
