"""The reference paper's studies (examples/studies) at reduced size, and the metrics they use.

Truths: closed-form areas between two curves (hysteresis); the DMT pull-off
-2 pi R w at a small Tabor parameter and the Maugis-Dugdale pull-off at
mu = 2 (lambda = 1.16 mu); ratios in [0, 1] and the adhesive load ratio 0.5
at zero net load (its definition); the exact invariance of the gaps under
E* -> c E*, w -> c w at a fixed approach (same Tabor parameter, the paper's
Fig. 8 claim); forces per atom summing to the net force; hysteresis >= 0.
The studies run in-process, so under ``mpirun -n 2 pytest`` they run on 2 ranks.
"""
import importlib
import os
import sys

import numpy as np
import pytest

from contactpetsc import metrics

pytestmark = pytest.mark.heavy   # the studies at reduced size: 1 and 2 ranks

STUDIES = os.path.join(os.path.dirname(__file__), os.pardir, "examples", "studies")


def study(name):
    if STUDIES not in sys.path:
        sys.path.insert(0, STUDIES)
    return importlib.import_module(name)


# -- metrics ----------------------------------------------------------------------------------------
@pytest.mark.serial   # metrics on numpy curves: no communicator
def test_hysteresis_of_analytic_curves():
    """F_load = d^2, F_unload = d^2 - sin(pi d / 2) on [0, 2]: area 4 / pi (trapezoid, fine
    samples, unequal sampling of the two curves, unloading given in falling order)."""
    a = np.linspace(0.0, 2.0, 2001)
    b = np.linspace(2.0, -0.5, 1703)          # wider than the loading range: clipped to [0, 2]
    area = metrics.hysteresis(a, a ** 2, b, b ** 2 - np.sin(np.pi * b / 2))
    assert abs(area - 4 / np.pi) < 1e-6


@pytest.mark.serial
def test_hysteresis_of_piecewise_linear_curves_is_exact():
    """A triangle between a straight loading line and an unloading line with one kink at
    samples the loading curve does not have: exact area 0.5 * base * height."""
    area = metrics.hysteresis([0.0, 3.0], [1.0, 4.0], [3.0, 1.3, 0.0], [4.0, 2.3 - 0.8, 1.0])
    assert abs(area - 0.5 * 3.0 * 0.8) < 1e-14
    assert metrics.hysteresis([0, 1], [0, 1], [2, 3], [0, 1]) == 0.0    # no common range
    with pytest.raises(ValueError, match="repeated"):
        metrics.hysteresis([0, 0, 1], [0, 1, 2], [0, 1], [0, 1])


def _sampled_loop(step, refine=4):
    """A closed quasi-static loop with jumps, as ``paths.sweep`` would sample it on the grid
    -3, -3 + step, ..., 3 (loading, then unloading through the same approaches): loading
    F_L = -1 / (1 + (d + 2)^2) up to the jump-on at a = -0.37, then the adhered branch
    F_A = d - 1.2 + 0.3 sin(3 d), which unloading follows down to the jump-off at b = -1.73.
    Jumps bracketed by ``refine`` bisections of their step.  Exact area:
    int_b^a (F_L - F_A) dd in closed form."""
    from types import SimpleNamespace as NS

    a, b = -0.37, -1.73
    f_l = lambda d: -1.0 / (1.0 + (d + 2.0) ** 2)      # noqa: E731
    f_a = lambda d: d - 1.2 + 0.3 * np.sin(3.0 * d)    # noqa: E731
    grid = np.round(np.arange(-3.0, 3.0 + 1e-9, step), 12)

    def bracket(x):
        k = np.floor((x + 3.0) / step)
        lo = -3.0 + k * step
        width = step / 2 ** refine
        lo += np.floor((x - lo) / width) * width
        return lo, lo + width

    pts = [NS(converged=True, branch="loading", approach=d, force=f_l(d) if d < a else f_a(d)) for d in grid]
    pts += [NS(converged=True, branch="unloading", approach=d, force=f_a(d) if d > b else f_l(d))
            for d in grid[::-1]]
    lo, hi = bracket(a)
    jumps = [NS(kind="jump-on", approach_before=lo, approach_after=hi, force_before=f_l(lo), force_after=f_a(hi))]
    lo, hi = bracket(b)
    jumps.append(NS(kind="jump-off", approach_before=hi, approach_after=lo, force_before=f_a(hi),
                    force_after=f_l(lo)))
    prim_l = lambda d: -np.arctan(d + 2.0)                                # noqa: E731
    prim_a = lambda d: 0.5 * d * d - 1.2 * d - 0.1 * np.cos(3.0 * d)       # noqa: E731
    exact = (prim_l(a) - prim_l(b)) - (prim_a(a) - prim_a(b))
    return NS(points=pts, jumps=jumps), exact


@pytest.mark.serial
@pytest.mark.parametrize("step", [1.0, 0.5, 0.25])
def test_hysteresis_estimate_of_a_closed_loop(step):
    """A loop with a jump-on and a jump-off (closed form, ``_sampled_loop``): the estimate is
    within its stated error of the exact area, positive, and the error shrinks with the step;
    curves sampled at the same approaches contribute nothing where they coincide."""
    path, exact = _sampled_loop(step)
    value, error = metrics.hysteresis_estimate(path)
    assert exact > 0 and value > 0
    assert abs(value - exact) <= error
    assert error < 0.25 * exact * step
    same = _sampled_loop(step)[0]
    same.points = [p for p in same.points if p.approach > 0.5]    # only the coinciding part
    same.jumps = []
    assert metrics.path_hysteresis(same) == 0.0


@pytest.mark.serial
def test_jump_in_stages_of_a_path_with_known_jumps():
    """A loading path in closed form, sampled every 0.5: no contact and F = -1 / (1 + (d + 2)^2)
    up to d = -2, with the whole body's jump-in there (-0.8 -> -2.5, a fall of 1.7); then in
    contact F = d, less 1.2 from an asperity's jump-in between 0.5 and 1 (a fall of 0.7), and
    less 0.6 more at 2.5 alone (a fall of 0.1).
    A-B is the asperity's jump (0.5 -> 1.0, the largest fall in contact, not the body's
    larger one from separation); C is the first sample with d - 1.2 >= 0.5, d = 2.0."""
    d = np.round(np.arange(-4.0, 4.01, 0.5), 10)
    touching = d >= -2.0
    f = np.where(touching, d - 1.2 * (d > 0.7) - 0.6 * (d == 2.5), -1.0 / (1.0 + (d + 2.0) ** 2))
    f = np.where(touching & (d < -1.9), -2.5, f)          # the body's jump-in: -0.5 -> -2.5
    a, b, c = metrics.jump_in_stages(d, f, touching.astype(float))
    assert (d[a], d[b], d[c]) == (0.5, 1.0, 2.0)
    # no return to A's force before the path ends: C is None
    assert metrics.jump_in_stages(d[:12], f[:12], touching[:12])[2] is None
    # no fall in contact: no stages
    assert metrics.jump_in_stages(d, np.where(touching, d, f), touching) is None
    with pytest.raises(ValueError, match="rise"):
        metrics.jump_in_stages(d[::-1], f, touching)
    # a deeper smooth fall (2.0 -> 2.5, 1.0) that is no located jump: the jump-on still wins
    deep = np.where(d == 2.5, f - 1.0, f)
    assert metrics.jump_in_stages(d, deep, touching)[:2] == (12, 13)     # without jumps: d = 2.0 -> 2.5
    assert metrics.jump_in_stages(d, deep, touching, jumps=[(0.7, 0.72), (-2.2, -2.1)])[:2] == (a, b)
    assert metrics.jump_in_stages(d, deep, touching, jumps=[(-2.2, -2.1)]) is None


def test_area_gap_and_forces_of_a_known_field(coll):
    """A pressure +p on x < L/4, -p/2 on L/4 <= x < L/2, 0 elsewhere; gap 0 on the compressive
    part, 3 elsewhere: contact area, forces and mean gaps by hand."""
    from contactpetsc.grid import SurfaceGrid
    g = SurfaceGrid(16, 13, 0.5, periodic=False)
    x = np.arange(16)[:, None] * np.ones((1, 13))
    p = np.where(x < 4, 2.0, np.where(x < 8, -1.0, 0.0))
    gap = np.where(x < 4, 0.0, 3.0)
    pv, gv = g.vec_from_array(p), g.vec_from_array(gap)
    area = 4 * 13 * 0.25
    assert coll.max(abs(metrics.contact_area(g, pv) - area)) < 1e-14
    net, adh = metrics.forces(g, pv)
    assert coll.max(abs(net - (2.0 - 1.0) * area)) < 1e-12 and coll.max(abs(adh + area)) < 1e-12
    assert coll.max(abs(metrics.mean_gap(g, gv) - 3.0 * 12 / 16)) < 1e-14
    assert coll.max(abs(metrics.mean_gap(g, gv, pv) - 3.0)) < 1e-14


# -- smooth spheres (Figs. 4-5) -----------------------------------------------------------------------
def test_smooth_sphere_small_tabor_is_dmt(coll):
    """mu = 0.02, hard-wall law: the DMT pull-off -2 pi R w (3 %), no jumps, no hysteresis."""
    ss = study("smooth_sphere")
    up = np.round(np.arange(-1.0, 0.21, 0.2), 10)
    c = ss.greenwood_case(0.02, 1000.0, "hardwall-lj", 48, 5.0, np.concatenate([up, up[-2::-1]]),
                          prefix="t_low_")
    scale = 2 * np.pi * 1000.0 * c["w"]
    assert coll.max(abs(c["pull_off"] / scale + 1)) < 0.03
    assert not c["path"].jumps
    assert coll.max(abs(metrics.path_hysteresis(c["path"])) / (scale * 1.0)) < 1e-3


# one rank: on two, the central-gap and edge-gap paths through the S-curve are
# test_adhesive_paths', jumps and pull-off test_axisymmetric_reference's, and this study's
# greenwood_case test_smooth_sphere_small_tabor_is_dmt's
@pytest.mark.serial
def test_smooth_sphere_higher_tabor_jumps_and_maugis_pull_off(coll):
    """mu = 1 (the example's Fig. 4c path at mu = 2 costs minutes), full LJ: jump-on first,
    jump-off last, ending at a smaller approach than the jump-on; pull-off within 8 % of
    Maugis-Dugdale (lambda = 1.16 mu), between DMT and JKR; positive hysteresis; the central-gap
    path passes through unstable states (the S-curve)."""
    from contactpetsc.physics.closed_forms import maugis_pull_off_bar
    ss = study("smooth_sphere")
    mu, r = 1.0, 100.0
    w = np.sqrt(mu ** 3 / r)
    dx = 3.2 * study("common").jkr_contact_radius(r, w, 1.0) / 32     # p_peak dx / E* = 0.25 z0
    app = np.concatenate([np.arange(-3.0, 0.01, 0.5), np.arange(-0.5, -3.51, -0.5)])
    c = ss.greenwood_case(mu, r, "lj", 32, dx, np.round(app, 10), prefix="t_high_", refine=2,
                          central_gaps=np.array([2.0, 1.6, 1.2, 0.8, 0.4]))
    kinds = [j.kind for j in c["path"].jumps]
    assert kinds[0] == "jump-on" and kinds[-1] == "jump-off"
    assert c["path"].jumps[-1].approach_after < c["path"].jumps[0].approach_after
    bar = c["pull_off"] / (np.pi * r * w)
    assert coll.max(abs(bar / maugis_pull_off_bar(1.16 * mu) - 1)) < 0.08 and -2.0 < bar < -1.5
    assert metrics.path_hysteresis(c["path"]) > 0
    stable = [p.stable for p in c["s_curve"].points if p.converged]
    assert stable[0] and False in stable


# one rank: on two, greenwood_case with the hard-wall law is test_smooth_sphere_small_tabor_is_dmt's,
# jumps and pull-off test_axisymmetric_reference's, and the relaxation and PTC this path falls
# back to at its jump-on test_relaxation's and test_adhesive_solvers'
@pytest.mark.serial
def test_smooth_sphere_hard_wall_law_at_higher_tabor(coll):
    """mu = 1, hard-wall law (the example's mu = 2 path costs minutes): every state converged,
    a jump-on and a later jump-off at a smaller approach, pull-off within 8 % of Maugis-Dugdale
    (lambda = 1.16 mu), between DMT and JKR; positive hysteresis."""
    from contactpetsc.physics.closed_forms import maugis_pull_off_bar
    ss = study("smooth_sphere")
    mu, r = 1.0, 100.0
    w = np.sqrt(mu ** 3 / r)
    dx = 3.2 * study("common").jkr_contact_radius(r, w, 1.0) / 48     # the zone spans 4.6 dx
    app = np.concatenate([np.arange(-2.5, 1.01, 0.5), np.arange(0.5, -2.51, -0.5)])
    c = ss.greenwood_case(mu, r, "hardwall-lj", 48, dx, np.round(app, 10), prefix="t_high_wall_", refine=4)
    assert all(p.converged and p.stable for p in c["path"].points)
    assert [j.kind for j in c["path"].jumps] == ["jump-on", "jump-off"]
    on, off = c["path"].jumps
    assert off.approach_after < on.approach_before
    bar = c["pull_off"] / (np.pi * r * w)
    assert coll.max(abs(bar / maugis_pull_off_bar(1.16 * mu) - 1)) < 0.08 and -2.0 < bar < -1.5
    assert metrics.path_hysteresis(c["path"]) > 0


def test_adhesion_ratios_of_smooth_spheres(coll):
    """Both ratios in [0, 1]; more load, smaller ratios; the same mu, R and load with w and E*
    both 4x: a different load ratio (the paper: mu alone does not fix the adhesive share)."""
    ss = study("smooth_sphere")
    ref, heavy, same_mu = (ss.ratio_case(*case, n=32) for case in
                           (ss.RATIO_CASES[0], ss.RATIO_CASES[3], ss.RATIO_CASES[4]))
    for row in (ref, heavy, same_mu):
        assert 0 <= row["load_ratio"] <= 1 and 0 <= row["area_ratio"] <= 1
        assert coll.max(abs(row["force"] / row["load"] - 1)) < 1e-3
    assert heavy["load_ratio"] < ref["load_ratio"]
    assert abs(same_mu["tabor"] / ref["tabor"] - 1) < 1e-12
    assert abs(same_mu["load_ratio"] - ref["load_ratio"]) > 0.02


# -- rough spheres (Figs. 6-9) --------------------------------------------------------------------
# one rank: on two, this study's rough sphere loaded to the load is test_case_run_records_every_state's
# and test_same_tabor_parameter_same_gaps_at_the_same_approach's, and unloading is a sweep
@pytest.mark.serial
def test_rough_sphere_small(coll):
    """Rough sphere (mu = 1) at 32^2: the load is met, ratios in [0, 1], pull-off tensile and no
    stronger than the smooth sphere's JKR/DMT bound, hysteresis >= 0 within its sampling error
    (a closed quasi-static cycle dissipates energy, never creates it)."""
    from contactpetsc.geometry import surfaces
    rs = study("rough_sphere")
    grid, _ = rs.make_grid(32, 1.0)
    base = rs.roughness(grid)
    w = rs.work_for(1.0)
    for rms in (0.0, 2.0):
        h = surfaces.rough_sphere(grid, rs.R, surfaces.scale_to_rms(grid, base, rms * rs.Z0))
        path, at, _ = rs.load_unload(grid, h, rs.E_STAR, w, 1.0, prefix=f"t_rough{rms:g}_")
        lr, ar = metrics.adhesion_ratios(grid, at["pressure"], at["law"].peak_attraction)
        assert 0 <= lr <= 1 and 0 <= ar <= 1
        assert coll.max(abs(at["state"].force / rs.LOAD - 1)) < 1e-3
        assert -2 * np.pi * rs.R * w * 1.02 < path.pull_off_force < 0
        value, error = metrics.hysteresis_estimate(path)
        assert value >= -error and error < 0.5 * abs(path.pull_off_force) * rs.Z0


def test_case_run_records_every_state(coll, shared_tmp):
    """A Fig. 8 case at 32^2 (``rough_sphere.case_run``): the load met; each saved state's field
    file integrates to the state's net force (sum p dx^2, the force's definition) at its
    approach; history.csv's iterations labelled with the states in order, each state's last
    iteration at its approach; Fig. 8's row drawn from the saved fields alone equals the
    solved state's."""
    from contactpetsc.app.plots import read_csv
    rs = study("rough_sphere")
    common = study("common")
    res = rs.case_run("stiff-w", "small", shared_tmp / "case")
    assert coll.max(abs(res["load"] / rs.LOAD - 1)) < 1e-3
    states = read_csv(str(shared_tmp / "case" / "states_path.csv"))
    history = read_csv(str(shared_tmp / "case" / "history_path.csv"))
    assert states["state"].tolist() == list(range(1, len(states["state"]) + 1))
    assert states["branch"][-1] == "at-load" and res["at_load_state"] == len(states["state"])
    for k, force, approach in zip(states["state"].astype(int), states["force"], states["approach"]):
        f = common.read_state_fields(shared_tmp / "case" / "path", k)
        assert abs(f["pressure"].sum() * res["dx"] ** 2 - force) <= 1e-9 * abs(force)
        assert f["approach"] == approach
        last = np.flatnonzero(history["step"] == k)[-1]
        assert history["approach"][last] == approach
    assert np.all(np.diff(history["step"]) >= 0)
    # Fig. 8's row, from the saved state at the load alone, is the live state's
    row = rs.case_figures([shared_tmp / "case"], shared_tmp / "figs")[0]
    for key in ("load", "load_ratio", "area_ratio", "contact_area"):
        assert abs(row[key] - res[key]) <= 1e-12 * abs(res[key])


def test_same_tabor_parameter_same_gaps_at_the_same_approach(coll):
    """E* -> 4 E*, w -> 4 w at the same approach: the gaps are the same (the problem is
    invariant, p -> 4 p), so the ratios are too (the paper's Fig. 8 discussion)."""
    from contactpetsc.geometry import surfaces
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    rs = study("rough_sphere")
    grid, _ = rs.make_grid(32, 1.0)
    h = surfaces.rough_sphere(grid, rs.R, surfaces.scale_to_rms(grid, rs.roughness(grid), 2 * rs.Z0))
    out = []
    for c in (1.0, 4.0):
        law = make_law("lj", work_of_adhesion=c * rs.work_for(1.0), z0=rs.Z0)
        pb = AdhesiveProblem(grid, h, c * rs.E_STAR, law, prefix=f"t_inv{c:g}_", element_integration=True)
        for d in (-1.0, 1.0, 3.0):
            st = pb.solve(approach=d * rs.Z0)
        out.append((grid.gather(st.gap), metrics.adhesion_ratios(grid, st.pressure, law.peak_attraction)))
    assert coll.max(np.abs(out[0][0] - out[1][0])) < 1e-6 * rs.Z0
    assert coll.max(np.abs(np.subtract(out[0][1], out[1][1]))) < 1e-6


# -- atomic tips (Figs. 10-12) --------------------------------------------------------------------
def test_atomic_tip_small(coll, shared_tmp):
    """Bent commensurate tip at 48^2: forces per atom sum to the net force, a tensile
    pull-off, a positive effective work of adhesion, contact radius growing with load."""
    at = study("atomic_tips")
    cfg = dict(n=48, per_d=2, load_star=0.2, step=0.5)
    row, data = at.tip_study("bent-commensurate", cfg, shared_tmp)
    assert coll.max(abs(row["atom_force_sum"] / row["net_force"] - 1)) < 1e-10
    assert row["pull_off"] < 0 and 0 <= row["effective_work_error"] < 0.2 * row["effective_work"]
    assert np.all(np.diff(data["radii"][data["loads"] > 0]) >= 0)
    assert row["atoms_repulsive"] > 0 and row["atoms_attractive"] > 0
