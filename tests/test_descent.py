"""The energy descent (``solvers/descent.py``): an adhesive state as a local minimum of the total energy.

Independent truths: the equilibrium Newton reaches from the same start (a different method on
the same equations), COMM_WORLD against COMM_SELF, the Lanczos stability check, and the
descent property itself (the state reached across a snap has less energy than the state it
started from).  Units: z0 = 1, E* = 1, dx = 1.
"""
import numpy as np
import pytest
from petsc4py import PETSc

from adhesive_setup import energy_moved
from contactpetsc.grid import SurfaceGrid
from contactpetsc.geometry.surfaces import self_affine
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.solvers import energy_tangent
from contactpetsc.solvers.descent import EnergyDescent


def rough(comm, n=64):
    grid = SurfaceGrid(n, n, 1.0, periodic=True, comm=comm)
    return grid, self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)


@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
@pytest.mark.parametrize("pc_factor, preconditioner", [(0.0, "compliance"), (10.0, "compliance"), (10.0, "multigrid")])
def test_descent_reaches_newtons_state_on_any_rank_count(coll, law_name, pc_factor, preconditioner):
    """From the converged state at one approach, the descent alone (to 1e-9) reaches the state
    Newton reaches at the next approach, and the same on one rank as on all; with the
    compliance alone as its preconditioner, with it scaled on the repulsive nodes, and with the
    V-cycle on the Hessian (a preconditioner changes the way to the minimum, not the minimum)."""
    law = make_law(law_name, work_of_adhesion=0.05, z0=1.0)
    key = law_name.replace("-", "")
    opts = PETSc.Options(f"desc{key}_")
    for name, value in dict(descent_tol=1e-9, descent_offset_tol=1e-11, descent_max_rounds=30,
                            descent_pc_contact_factor=pc_factor, descent_preconditioner=preconditioner).items():
        opts.setValue(name, value)
    pressures = []
    try:
        for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
            grid, h = rough(comm)
            d0, d1 = h.min()[1] + 0.5, h.min()[1] + 1.0
            newton = AdhesiveProblem(grid, h, 1.0, law, prefix=f"newt{key}_", petsc_options={"strategy": "newton"})
            newton.solve(approach=d0)
            start = newton._x.copy()
            reference = newton.solve(approach=d1)
            pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"desc{key}_")
            pb.prepare(d0)
            ok, reason, iterations, _ = EnergyDescent(pb).descend(d1, start)
            assert ok, reason
            assert iterations > 0
            p = pb.blocks(pb._x, readonly=True).sum(axis=0)
            scale = float(law.peak_attraction)
            diff = coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / scale
            assert diff < 1e-6, diff
            pressures.append(grid.gather(_as_vec(grid, p)))
    finally:
        for name in ("descent_tol", "descent_offset_tol", "descent_max_rounds", "descent_pc_contact_factor",
                     "descent_preconditioner"):
            opts.delValue(name)
    assert coll.max(np.abs(pressures[0] - pressures[1])) / float(law.peak_attraction) < 1e-9


def test_a_step_in_increments_is_the_step_in_sub_steps(coll, monkeypatch):
    """``-<prefix>descent_max_step``: a step of 2 z0 descended in 16 increments (each but the
    last to an error of 1e-2) lands in the state the same 16 sub-steps reach when each is
    solved in full (a quasi-static path's), to the solver's tolerance, for less than half their
    FFT pairs; the state's solver names the increments.  After a failed solve the step is
    taken again from the last converged state, in as many increments."""
    from contactpetsc.solvers.newton import VINewton
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    grid = SurfaceGrid(64, 64, 1.0, periodic=True, comm=PETSc.COMM_WORLD)
    h = self_affine(grid, hurst=0.8, rms_height=2.0, seed=11)
    d0 = float(h.min()[1]) + 0.5
    ends = np.linspace(d0, d0 + 2.0, 17)
    full = AdhesiveProblem(grid, h, 1.0, law, prefix="incfull_")
    full.solve(approach=d0)
    pairs = sum(full.solve(approach=float(d)).fft_pairs for d in ends[1:])
    reference = grid.rows(full.solve(approach=float(ends[-1])).gap, readonly=True).copy()
    inc = AdhesiveProblem(grid, h, 1.0, law, prefix="incstep_", petsc_options={"descent_max_step": 0.125})
    inc.solve(approach=d0)
    run = VINewton.run
    with monkeypatch.context() as m:
        m.setattr(VINewton, "run", lambda self: (False, "FAILED_ON_PURPOSE") + run(self)[2:])
        failed = inc.solve(approach=float(ends[-1]), raise_on_failure=False, fallback=False)
    assert not failed.converged
    st = inc.solve(approach=float(ends[-1]))
    assert st.converged and st.stable and st.solver.startswith("descent in 16 increments+"), st.solver
    assert coll.max(np.abs(grid.rows(st.gap, readonly=True) - reference)) <= inc.tol * inc.z0
    assert st.fft_pairs < pairs / 2


def test_the_gap_floor_does_not_hold_the_state(coll):
    """The full LJ curve's gap floor (``-<prefix>descent_floor_factor``) caps the steps of nodes
    that snap, never the state: with a floor far above the gaps the state needs (the repulsion
    there a quarter of the start's largest pressure) the descent lowers it until it holds no
    node, and lands in Newton's state, as with the default floor (which holds no node on this
    step) and without one, on one rank as on all."""
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    scale = float(law.peak_attraction)
    pressures = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        grid, h = rough(comm)
        d0, d1 = h.min()[1] + 0.5, h.min()[1] + 1.0
        newton = AdhesiveProblem(grid, h, 1.0, law, prefix="floornewt_", petsc_options={"strategy": "newton"})
        newton.solve(approach=d0)
        start = newton._x.copy()
        reference = newton.solve(approach=d1)
        assert not reference.solver.startswith("descent")
        for factor in (0.25, 4.0, 0.0):
            prefix = f"floor{int(100 * factor)}_"
            opts = PETSc.Options(prefix)
            opts.setValue("descent_floor_factor", factor)
            opts.setValue("descent_tol", 1e-9)
            try:
                pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix)
                pb.prepare(d0)
                ok, reason, _, _ = EnergyDescent(pb).descend(d1, start)
            finally:
                opts.delValue("descent_floor_factor")
                opts.delValue("descent_tol")
            assert ok, reason
            assert ("gap floor lowered" in reason) == (factor == 0.25), reason
            p = pb.blocks(pb._x, readonly=True)[0]
            assert coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / scale < 1e-6
        pressures.append(grid.gather(_as_vec(grid, p)))
    assert coll.max(np.abs(pressures[0] - pressures[1])) / scale < 1e-9


def test_a_spent_time_budget_is_named_by_the_descent(coll):
    """A descent that stops because ``-<prefix>time_budget`` is spent says so first: the run's
    message looks for WALL_TIME_BUDGET there, as after Newton (the descent's reason had read
    DIVERGED_MAXITS); the same descent without a budget converges."""
    import time
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    d0, d1 = h.min()[1] + 0.5, h.min()[1] + 1.0
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="descbudget_")
    pb.solve(approach=d0)
    start = pb._x.copy()
    pb.time_budget, pb._budget_start = 1e-6, time.monotonic()
    pb.prepare(d0)
    ok, reason, _, _ = EnergyDescent(pb).descend(d1, start)
    assert not ok and reason.startswith("WALL_TIME_BUDGET") and "in the descent" in reason, reason
    pb.time_budget = 0.0
    pb.prepare(d0)
    ok, reason, _, _ = EnergyDescent(pb).descend(d1, start)
    assert ok and reason.startswith("descent CONVERGED"), reason


@pytest.mark.serial
@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
def test_the_descents_hessian_is_symmetric_and_its_preconditioner_positive(coll, law_name):
    """CG needs both: the Hessian symmetric on every vector (its mean component included, which
    the scaled preconditioner's output has) and S K S symmetric positive definite, S = 1 where
    Phi'' <= 0.  Dense on a 16^2 state with nodes in repulsive contact."""
    law = make_law(law_name, work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_SELF, n=16)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"descsym{law_name.replace('-', '')}_")
    approach = float(h.min()[1]) + 1.0      # contact at a few per cent of the nodes
    state = pb.solve(approach=approach)
    assert 0.01 < state.contact_fraction < 0.5
    descent = EnergyDescent(pb)
    descent.at_state()
    if not pb.hard_wall:
        assert (descent.curvature > 0).any()    # nodes in repulsive contact: S < 1 there
    n = descent.n
    H, P = np.empty((n, n)), np.empty((n, n))
    e, y = np.zeros(descent.shape), np.empty(descent.shape)
    for j in range(n):
        e.reshape(-1)[:] = 0.0
        e.reshape(-1)[j] = 1.0
        descent.hessian_mult(e, y)
        H[:, j] = y.reshape(-1)
        descent.precondition(e, y)
        P[:, j] = y.reshape(-1)
    assert np.abs(H - H.T).max() <= 1e-12 * np.abs(H).max()
    assert np.abs(P - P.T).max() <= 1e-12 * np.abs(P).max()
    assert np.linalg.eigvalsh(0.5 * (P + P.T)).min() > 0
    assert np.all(descent.pc_scale[descent.curvature <= 0] == 1.0)
    assert descent.pc_scale.min() < 1.0 or pb.hard_wall


@pytest.mark.serial
@pytest.mark.parametrize("w", [0.05, 0.3])
@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
def test_the_descents_cycle_is_symmetric_positive_on_the_inactive_set(coll, law_name, w):
    """``-<prefix>descent_preconditioner multigrid``: CG needs the V-cycle on the Hessian
    symmetric positive definite on TAO's inactive set (a hard wall's contact nodes clamped; the
    mean of the full LJ curve's v as the compliance sends it).  Dense on a 16^2 stable state in
    contact, weakly and strongly adhesive (w = 0.3 E* z0: the snap number K_ii max da/dg
    0.42, six times w = 0.05's)."""
    import warnings
    from contactpetsc.solvers.reduced import InactiveSet
    law = make_law(law_name, work_of_adhesion=w, z0=1.0)
    grid, h = rough(PETSc.COMM_SELF, n=16)
    key = law_name.replace("-", "") + str(int(100 * w))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")      # w = 0.3 is under-resolved on dx = z0, knowingly
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"desccyc{key}_",
                             petsc_options={"descent_preconditioner": "multigrid"})
    state = pb.solve(approach=float(h.min()[1]) + 1.0)
    assert 0.01 < state.contact_fraction < 0.5 and state.stable
    with pb.inserted_options():
        descent = EnergyDescent(pb)
    assert descent.cycle is not None
    g = descent.at_state()
    free = np.flatnonzero(g.reshape(-1) > 1e-12) if pb.hard_wall else np.arange(descent.n)
    assert free.size < descent.n or not pb.hard_wall
    inactive = InactiveSet(PETSc.IS().createGeneral(free.astype(PETSc.IntType), comm=PETSc.COMM_SELF), 0, descent.n)
    x = PETSc.Vec().createSeq(free.size)
    y = x.duplicate()
    T = np.empty((free.size, free.size))
    for j in range(free.size):
        x.set(0.0)
        x.setValue(j, 1.0)
        descent.cycle.apply(inactive, x, y)
        T[:, j] = y.getArray()
    assert np.abs(T - T.T).max() <= 1e-12 * np.abs(T).max()
    assert np.linalg.eigvalsh(0.5 * (T + T.T)).min() > 0


@pytest.mark.parametrize("option, value, message", [
    ("descent_pc_contact_factor", "-1", "descent_pc_contact_factor must be finite and >= 0"),
    ("descent_pc_contact_factor", "nan", "descent_pc_contact_factor must be finite and >= 0"),
    ("descent_floor_factor", "-4", "descent_floor_factor must be finite and >= 0"),
    ("descent_floor_factor", "inf", "descent_floor_factor must be finite and >= 0"),
    ("descent_tao_bnk_max_cg_its", "5", "descent_tao_bnk_max_cg_its must be 0"),
    ("descent_max_step", "-0.1", "descent_max_step must be finite and >= 0"),
    ("descent_step_tol", "0", "descent_step_tol must be finite and > 0"),
    ("descent_stall_its", "-1", "descent_stall_its must be >= 0"),
    ("descent_preconditioner", "mlmi", "descent_preconditioner must be auto, compliance, multigrid")])
def test_bad_descent_options_are_refused_by_name(coll, option, value, message):
    grid, h = rough(PETSc.COMM_WORLD, n=16)
    pb = AdhesiveProblem(grid, h, 1.0, make_law("lj", work_of_adhesion=0.05, z0=1.0), prefix="descbad_",
                         petsc_options={option: value})
    with pytest.raises(ValueError, match="descbad_" + message):
        pb.solve(approach=float(h.min()[1]) + 0.5)


@pytest.mark.parametrize("ksp_type", ["minres", "gmres"])
def test_a_users_krylov_method_for_the_descent_keeps_its_own_norm(coll, ksp_type):
    """The descent's CG tests its natural norm by default; a Krylov method the user chose
    that refuses that norm (MINRES, GMRES) keeps its own and reaches Newton's state (the
    natural norm given to them had raised inside TAOSolve)."""
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD, n=32)
    d0, d1 = h.min()[1] + 0.5, h.min()[1] + 0.6
    newton = AdhesiveProblem(grid, h, 1.0, law, prefix="kspnewt_", petsc_options={"strategy": "newton"})
    newton.solve(approach=d0)
    reference = newton.solve(approach=d1)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"ksp{ksp_type}_",
                         petsc_options={"descent_tao_bnk_ksp_type": ksp_type})
    pb.solve(approach=d0)
    state = pb.solve(approach=d1, raise_on_failure=False)
    assert state.converged and state.solver.startswith("descent"), (state.reason, state.solver)
    p = grid.rows(state.pressure, readonly=True)
    assert coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / float(law.peak_attraction) < 1e-6


def hard_wall_step(tag, step, options, tol=None):
    """Newton's states at d0 and d0 + ``step`` [z0] on the rough surface with the hard-wall LJ
    law, and the descent from the first to the second approach with the descent ``options``
    (under the prefix ``<tag>desc_``) to ``tol`` (None: its default): (grid, law, problem,
    descent, converged, reason, Newton's state at d0 + step, d0 + step)."""
    law = make_law("hardwall-lj", work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    d0, d1 = h.min()[1] + 0.5, h.min()[1] + 0.5 + step
    newton = AdhesiveProblem(grid, h, 1.0, law, prefix=f"{tag}newt_", petsc_options={"strategy": "newton"})
    newton.solve(approach=d0)
    start = newton._x.copy()
    reference = newton.solve(approach=d1)
    opts = PETSc.Options(f"{tag}desc_")
    for name, value in options.items():
        opts.setValue(name, value)
    try:
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"{tag}desc_")
        pb.prepare(d0)
        descent = EnergyDescent(pb, tol=tol)
        ok, reason, _, _ = descent.descend(d1, start)
    finally:
        for name in options:
            opts.delValue(name)
    return grid, law, pb, descent, ok, reason, reference, d1


def rounds_in(reason):
    """The rounds a hard-wall descent's reason names ("descent ... (N TAO iterations, R rounds)")."""
    return int(reason.split(", ")[1].split()[0])


def test_a_short_hard_wall_descent_on_any_rank_count(coll):
    """A step of 0.1 z0 with a hard wall, where the bounded line search's trial points leave
    some ranks' rows unchanged: the descent's evaluations stay collective (a rank-local cache
    test had hung on 3 ranks) and reach Newton's state."""
    # descended to 1e-9 with the mean held to 1e-11: the line search's last trial points move
    # a few nodes of one rank only
    grid, law, pb, _, ok, reason, reference, _ = hard_wall_step(
        "short", 0.1, dict(descent_tol=1e-9, descent_offset_tol=1e-11, descent_max_rounds=30))
    assert ok, reason
    p = pb.blocks(pb._x, readonly=True).sum(axis=0)
    assert coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / float(law.peak_attraction) < 1e-5


@pytest.mark.parametrize("max_rounds", [1, 2, 30])
def test_a_converged_hard_wall_descent_is_at_its_tolerance_whichever_round_is_last(coll, max_rounds):
    """A hard wall's rounds but the last stop at an error below the mean offset they leave;
    the last one (its offset within offset_tol, or the max_rounds-th) is descended to the
    tolerance: a descent reported converged is at its tolerance, the offset at most the one
    Newton's polish closes, and it is Newton's state."""
    grid, law, pb, descent, ok, reason, reference, d1 = hard_wall_step(
        "round", 0.5, dict(descent_max_rounds=max_rounds))
    assert ok, reason
    assert descent.last_error <= descent.tol, (descent.last_error, reason)
    rounds = rounds_in(reason)
    assert rounds <= max_rounds
    pb.prepare(d1)
    ok, reason, _, _ = pb.newton.run()      # the polish closes the offset left
    assert ok, reason
    p = pb.blocks(pb._x, readonly=True).sum(axis=0)
    assert coll.max(np.abs(p - grid.rows(reference.pressure, readonly=True))) / float(law.peak_attraction) < 1e-6


def test_a_loose_hard_wall_descent_holds_the_mean_no_tighter(coll):
    """A descent to a loose error (an increment of a step, ``descent_step.py``, 1e-2) ends its
    rounds once the mean offset is within that error: before, its rounds stopped at their first
    iterate (error within 1e-2, offset above 1e-9 z0) and moved W blindly to max_rounds."""
    _, _, _, descent, ok, reason, _, _ = hard_wall_step("loose", 0.05, {}, tol=1e-2)
    assert ok, reason
    assert descent.last_error <= 1e-2
    rounds = rounds_in(reason)
    assert rounds < descent.max_rounds, reason


def _as_vec(grid, rows):
    v = grid.create_vec()
    grid.rows(v)[...] = rows
    return v


def test_a_snap_in_is_a_descent_to_a_stable_state(coll):
    """A step across a snap-in (w = 0.3 E* dx) with Newton capped at 3 steps, too few for any
    state here: the fallback descends from the last state (to 1e-9, so Newton's polish has
    nothing left to do) to a converged, stable state of lower energy than that state has at
    the new approach, the same on one rank as on all."""
    law = make_law("lj", work_of_adhesion=0.3, z0=1.0)
    opts = PETSc.Options("snapdesc_")
    # Newton first (the full LJ curve's default on a periodic grid descends first)
    for name, value in dict(max_it=3, descent_tol=1e-9, strategy="newton").items():
        opts.setValue(name, value)
    gaps = []
    try:
        for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
            grid, h = rough(comm)
            hmin = h.min()[1]
            pb = AdhesiveProblem(grid, h, 1.0, law, prefix="snapdesc_")
            before = pb.solve(approach=hmin - 0.5)
            after = pb.solve(approach=hmin)
            assert after.solver.endswith("+descent") and after.fallback, after.solver
            assert after.converged and after.stable
            assert after.energy < energy_moved(before, law, grid, 0.5)
            gaps.append(grid.gather(after.gap))
    finally:
        for name in ("max_it", "descent_tol", "strategy"):
            opts.delValue(name)
    assert coll.max(np.abs(gaps[0] - gaps[1])) < 1e-7


def test_a_descent_stalled_at_the_state_is_polished_not_followed(coll):
    """The snap-in above, the fallback's descent held to an error it cannot reach (1e-16: its
    line search stalls in round-off with its iterate at the state, as next to a fold) and cut
    at 60 iterations: it fails, and Newton polishes its iterate to the state the converging
    descent reaches (gaps to 1e-7), where the chain had started PTC again from the last state;
    the solver names the descent last, and the state is stable."""
    law = make_law("lj", work_of_adhesion=0.3, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    hmin = h.min()[1]
    gaps = []
    for tag, tol, its in (("stalldesc_", 1e-16, 60), ("convdesc_", 1e-9, 500)):
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=tag,
                             petsc_options=dict(max_it=3, strategy="newton", descent_tol=tol, descent_tao_max_it=its))
        pb.solve(approach=hmin - 0.5)
        after = pb.solve(approach=hmin)
        assert after.converged and after.stable and after.solver.endswith("+descent"), after.solver
        gaps.append(grid.gather(after.gap, root=None))
    assert coll.max(np.abs(gaps[0] - gaps[1])) < 1e-7


def test_a_descent_in_round_off_stops_where_it_would_have_stayed(coll):
    """``-<prefix>descent_stall_its``: a descent held to an error it cannot reach (1e-16) stops,
    stalled and named so, once its energy has not fallen for ten iterations, far below its
    iteration cap; its state is where the same descent without the stall test is at its cap
    of 150 iterations (gaps to 1e-9 z0): the iterations it saved made no progress."""
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    d0, d1 = h.min()[1] + 0.5, h.min()[1] + 1.0
    gaps, iterations = [], []
    for tag, stall_its in (("stall10_", 10), ("stall0_", 0)):
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=tag, petsc_options=dict(
            strategy="newton", descent_stall_its=stall_its, descent_tao_max_it=150))
        pb.solve(approach=d0)
        start = pb._x.copy()
        pb.prepare(d0)
        with pb.inserted_options():      # the descent reads its options as the solve does
            ok, reason, its, _ = EnergyDescent(pb, tol=1e-16).descend(d1, start)
        assert not ok
        assert ("stalled" in reason) == bool(stall_its), reason
        iterations.append(its)
        g = pb.blocks(pb._x, readonly=True).sum(axis=0)     # the state's pressures
        gaps.append(grid.gather(_as_vec(grid, g)))
    assert iterations[1] == 150 and iterations[0] < 100, iterations
    assert coll.max(np.abs(gaps[0] - gaps[1])) / float(law.peak_attraction) < 1e-9


# one rank: on more, the descent on a split grid is test_descent_reaches_newtons_state_on_any_rank_count's
# and test_a_snap_in_is_a_descent_to_a_stable_state's
@pytest.mark.serial
@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
def test_the_descent_strategy_follows_newtons_path(coll, law_name):
    """``-<prefix>strategy descent`` (every step a descent from the last state, then Newton;
    the default) lands in the states of ``-<prefix>strategy newton`` (the predicted Newton
    step) along a loading path without jumps."""
    law = make_law(law_name, work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    hmin = h.min()[1]
    key = law_name.replace("-", "")
    paths = [AdhesiveProblem(grid, h, 1.0, law, prefix=f"{name}{key}_", petsc_options={"strategy": name})
             for name in ("newton", "descent")]
    for d in (0.25, 0.75, 1.25):
        newton, descended = (pb.solve(approach=hmin + d) for pb in paths)
        assert not newton.solver.startswith("descent+")
        assert descended.solver.startswith("descent+") and descended.converged and descended.stable
        dg = grid.rows(newton.gap, readonly=True) - grid.rows(descended.gap, readonly=True)
        assert coll.max(np.abs(dg)) < 1e-6


@pytest.mark.parametrize("law_name", ["lj", "hardwall-lj"])
def test_a_stalled_polish_under_the_descent_strategy_goes_on_through_the_chain(coll, law_name):
    """Under the descent strategy a Newton polish that stalls (here at its first step: the
    descent stops at 1e-3 and a step must cut the error a millionfold) hands over to the chain
    without the descent, which it has just run: the full LJ curve's PTC from the polish's best
    iterate, a hard wall's relaxation from the last state, each to the state the predicted
    Newton step reaches, stable, the same on one rank as on all."""
    law = make_law(law_name, work_of_adhesion=0.05, z0=1.0)
    key = law_name.replace("-", "")
    gaps = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        grid, h = rough(comm)
        hmin = h.min()[1]
        newton = AdhesiveProblem(grid, h, 1.0, law, prefix=f"stallnewt{key}_", petsc_options={"strategy": "newton"})
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"stall{key}_",
                             petsc_options=dict(descent_tol=1e-3, stall_steps=1, stall_progress=1e-6))
        for d in (0.25, 0.75):
            reference, st = newton.solve(approach=hmin + d), pb.solve(approach=hmin + d)
            chain = st.solver.split("+")
            assert chain[0] == "descent" and st.fallback, st.solver
            assert chain[-1] == ("ptc" if law_name == "lj" else "relaxation"), st.solver
            assert "descent" not in chain[1:], st.solver
            assert st.converged and st.stable, st.reason
            dg = grid.rows(reference.gap, readonly=True) - grid.rows(st.gap, readonly=True)
            assert coll.max(np.abs(dg)) < 1e-7
        gaps.append(grid.gather(st.gap))
    assert coll.max(np.abs(gaps[0] - gaps[1])) < 1e-7


@pytest.mark.parametrize("hessian", [True, False])
def test_the_energy_tangent_is_the_force_slope(coll, monkeypatch, hessian):
    """The full LJ curve's tangent from the energy's Hessian (``energy_tangent.tangent``, what a
    periodic full-LJ state's tangent is) is dp/d delta and dF/d delta: the central differences
    of the pressure field and of the force over two further solves agree to the differences'
    own error, on any rank count; so does the Jacobian's (``-<prefix>tangent_hessian false``,
    which then solves it alone), and the two methods agree."""
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    grid, h = rough(PETSc.COMM_WORLD)
    prefix = f"etan{int(hessian)}_"
    opts = PETSc.Options(prefix)
    for name, value in dict(tol=1e-11, tangent_ksp_rtol=1e-10, tangent_hessian=hessian).items():
        opts.setValue(name, value)
    calls = []
    solve_tangent = energy_tangent.tangent
    monkeypatch.setattr(energy_tangent, "tangent", lambda descent: calls.append(descent) or solve_tangent(descent))
    try:
        pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix)
        d, step = h.min()[1] + 0.75, 1e-3
        st = pb.solve(approach=d)
        assert st.converged and st.stable and np.isfinite(st.stiffness)
        assert len(calls) == int(hessian)
        # (under the descent strategy the predictor keeps the stiffness, not the field: the
        # tangent's solve at the state gives both)
        tv, stiffness = pb.predictor.solve()
        dp = pb.blocks(tv, readonly=True)[0].copy()
        tv.destroy()
        other = solve_tangent(EnergyDescent(pb))
        assert other is not None
        assert other[1] == pytest.approx(stiffness, rel=1e-12 if hessian else 1e-7)
        scale = coll.max(np.abs(dp))
        assert coll.max(np.abs(other[0] - dp)) < (1e-12 if hessian else 1e-6) * scale
        lo, hi = pb.solve(approach=d - step), pb.solve(approach=d + step)
        # second-order differences: their error is step^2 times the third derivative / 6,
        # below 1e-5 of the slopes here
        slope = (hi.force - lo.force) / (2 * step)
        assert coll.max(abs(slope / stiffness - 1)) < 1e-5
        fd = (grid.rows(hi.pressure, readonly=True) - grid.rows(lo.pressure, readonly=True)) / (2 * step)
        assert coll.max(np.abs(fd - dp)) < 1e-4 * scale
    finally:
        for name in ("tol", "tangent_ksp_rtol", "tangent_hessian"):
            opts.delValue(name)


def test_a_hard_wall_descent_leaves_newtons_polish_nothing_to_do(coll):
    """The descent's state is within the problem's tolerance as Newton's confirmation measures
    it, its mean offset m included: Newton's gaps do not carry m, so next to the wall its
    pressure error is m da/dg, 15.6 peak attractions per z0 for the hard-wall LJ law.  Held to
    offset_tol in z0 alone, the offset left Newton a step (with its Krylov solve) to take
    here."""
    grid, law, pb, descent, ok, reason, reference, d1 = hard_wall_step("polish", 1.5, {})
    assert ok, reason
    assert rounds_in(reason) < descent.max_rounds, reason
    pb.prepare(d1)
    ok, reason, newton, _ = pb.newton.run()
    assert ok and newton == 0, (reason, newton)


def test_a_hard_wall_law_without_a_slope_descends(coll):
    """Dugdale's law has no slope (da/dg = 0 inside its range): the offset's effect on Newton's
    measures is m / z0 itself, and the descent on a periodic cell (its default strategy)
    reaches a converged state (the tighter offset had divided by the zero slope)."""
    law = make_law("dugdale", work_of_adhesion=0.05, sigma0=0.05)
    grid, h = rough(PETSc.COMM_WORLD)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="dugd_")
    st = pb.solve(approach=h.min()[1] + 0.5, raise_on_failure=False)
    assert st.converged and st.solver.startswith("descent"), (st.solver, st.reason)
