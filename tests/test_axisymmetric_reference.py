"""The 3-D sphere against an independent axisymmetric solver, and that solver against closed forms.

The truth is ``tests/axisymmetric_lj.py`` (ring loads with the closed-form displacement of a
uniformly loaded disk, numpy/scipy only, the whole S-curve by continuation): checked here
against Hertz (Johnson eq. 3.41 for the displacement of the Hertz pressure, the force-approach
law with the hard wall and w = 0), the DMT limit of the pull-off (-2 pi R w, small Tabor
parameter) and the JKR limit (-1.5 pi R w, large), and against itself with rings half as wide;
its linear solver (GMRES with a kept LU factorization) against a dense solve.
Then the 3-D solver's loading and unloading path and pull-off of a mu = 1 sphere (an S-curve:
jumps on and off) against it.  Greenwood's units: E* = z0 = 1, R = 100 z0, w = sqrt(mu^3 / R),
W* = W / (2 pi R w).
"""
import numpy as np
import pytest

import axisymmetric_lj as axi

R = 100.0


def work(mu):
    return np.sqrt(mu ** 3 / R)


def pull_off_star(mu, top=0.5, refine=1.0):
    w = work(mu)
    sph = axi.AxisymmetricSphere(R, 1.0, w, 1.0, axi.default_mesh(R, w, 1.0, 1.0, top, refine=refine))
    states = sph.trace(-3.0 - 2.0 * mu, top)
    return sph.pull_off(states).load / (2 * np.pi * R * w), sph, states


@pytest.mark.serial
def test_ring_loads_give_the_hertz_displacement():
    """Hertz pressure p0 sqrt(1 - r^2/a^2) on rings: u = pi p0 (2a^2 - r^2) / (4 a E*) inside
    (Johnson 3.41); the error (the square-root edge) falls with the ring width."""
    errors = []
    for rings in (20, 40, 80):
        edges = np.linspace(0.0, 1.0, rings + 1)
        r = axi.Rings(edges, 2.0)
        p = np.sqrt(1.0 - r.r ** 2)
        u = r.displacement(p)
        exact = np.pi * (2.0 - r.r ** 2) / (4.0 * 2.0)
        errors.append(np.max(np.abs(u - exact)) / exact[0])
        assert abs(r.load(p) / (2.0 / 3.0 * np.pi) - 1.0) < 4e-3
    assert errors[-1] < 6e-4 and errors[0] > 2.0 * errors[1] > 4.0 * errors[2], errors


@pytest.mark.serial
def test_kept_factorization_solves_the_current_system():
    """KeptLU: GMRES preconditioned with the LU of an earlier matrix gives the current
    matrix's solution (against numpy's dense solve), renewing the factorization only when
    the earlier matrix is too far off for ``max_krylov`` iterations."""
    rng = np.random.default_rng(5)
    n = 60
    A = np.eye(n) + 0.3 * rng.standard_normal((n, n)) / np.sqrt(n)
    kept = axi.KeptLU(max_krylov=10)
    b = rng.standard_normal(n)
    for change in (0.0, 1e-3, 1e-2, 3.0):
        B = A + change * rng.standard_normal((n, n)) / np.sqrt(n)
        x = kept.solve(lambda v: B @ v, lambda: B, b, rtol=1e-10)
        assert np.max(np.abs(x - np.linalg.solve(B, b))) < 1e-8 * np.max(np.abs(x))
        # small changes keep the first factorization; the large one renews it
        assert kept.factorizations == (1 if change < 1 else 2), (change, kept.factorizations)


@pytest.mark.serial
def test_signorini_sphere_is_hertz():
    """Hard wall, w = 0: F = (4/3) E* sqrt(R) delta^1.5."""
    sph = axi.AxisymmetricSphere(R, 1.0, 0.0, 1.0, axi.ring_mesh(0.1, 30.0, 200.0), law="hardwall-lj")
    for delta in (1.0, 4.0):
        st = sph.solve_approach(delta)
        assert abs(st.load / (4.0 / 3.0 * np.sqrt(R) * delta ** 1.5) - 1.0) < 1e-4


@pytest.mark.serial
def test_pull_off_tends_to_dmt_at_small_tabor_parameters():
    """W* -> -1 (DMT, -2 pi R w) as mu -> 0, from above: full LJ curve at mu = 0.02, 0.1, and
    the hard-wall law at mu = 0.02 (the paper's Fig. 4b: the hard wall gives DMT there)."""
    small, _, _ = pull_off_star(0.02)
    larger, _, _ = pull_off_star(0.1)
    assert -1.0 < small < -0.998 and small < larger < -0.98, (small, larger)
    w = work(0.02)
    sph = axi.AxisymmetricSphere(R, 1.0, w, 1.0, axi.default_mesh(R, w, 1.0, 1.0, 0.2), law="hardwall-lj")
    st, loads = None, []
    for delta in np.arange(-0.2, 0.1, 0.02):
        st = sph.solve_approach(delta, start=st)
        loads.append(st.load / (2 * np.pi * R * w))
    assert abs(min(loads) + 1.0) < 5e-3, min(loads)


@pytest.mark.serial
def test_pull_off_tends_to_jkr_at_large_tabor_parameters():
    """W* -> -0.75 (JKR, -1.5 pi R w) as mu grows, from below: mu = 1, 2."""
    at_1, _, _ = pull_off_star(1.0)
    at_2, _, _ = pull_off_star(2.0, top=0.0)
    assert at_1 < at_2 < -0.75, (at_1, at_2)
    assert abs(at_2 + 0.75) < 0.6 * abs(at_1 + 0.75)


@pytest.mark.serial
def test_ring_mesh_convergence_and_the_s_curve_folds():
    """mu = 1: halving the ring width moves the pull-off by < 2e-4 (measured 8e-5), and the
    curve turns back twice in approach (the jump-on and jump-off folds)."""
    coarse, sph, states = pull_off_star(1.0)
    fine, _, _ = pull_off_star(1.0, refine=2.0)
    assert abs(fine - coarse) < 2e-4, (coarse, fine)
    alpha = np.array([s.approach for s in states])
    assert len(axi.branches(alpha)) == 3


@pytest.mark.heavy
@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_3d_sphere_matches_the_axisymmetric_solution(coll, example_sphere_path):
    """mu = 1, 96^2 window of 96 z0 at dx = z0 (conftest's example_sphere_path, this module's R):
    load-approach points of loading and unloading, the jumps and the pull-off against the
    axisymmetric solution (its load inside the same square window).  Tolerances from the
    mesh-convergence study (run_scripts/checks/axisymmetric_comparison.py, docs/validation.md):
    the 3-D pull-off moves by 2.2e-4 between dx = z0 and z0/2 (this case: 1.6e-4 from the
    axisymmetric one), the curve's largest difference halves from 8.8e-4 W* at dx = z0 (this
    case: 6.9e-4); the jumps are bisected to 0.004 z0 and the folds move by ~0.002 z0 with the
    grid."""
    from contactpetsc.paths import good_state
    from contactpetsc.pull_off import refine_pull_off

    mu = 1.0
    w = work(mu)
    ws = 2 * np.pi * R * w
    problem, path = example_sphere_path
    assert problem.law.work_of_adhesion == w and problem.e_star == 1.0    # this module's sphere
    half = problem.grid.nx * problem.grid.dx / 2
    ref, sph, states = pull_off_star(mu)
    load = lambda st: sph.rings.load_in_square(st.pressure, half) / ws   # noqa: E731
    pull = refine_pull_off(problem, path, xtol=1e-3) / ws
    window_pull = load(sph.pull_off(states))
    assert coll.max(abs(pull / window_pull - 1.0)) < 5e-4, (pull, window_pull, ref)

    good = [p for p in path.points if good_state(p)]
    diffs = []
    for p in good:
        st = sph.on_branch(states, p.approach, load, p.force / ws)
        diffs.append(abs(load(st) - p.force / ws))
    assert len(good) >= 15 and coll.max(diffs) < 2e-3, max(diffs)

    alpha = np.array([s.approach for s in states])
    folds = sorted(alpha[i] for i, _ in axi.branches(alpha)[1:])     # jump-off, jump-on
    kinds = {j.kind: j.approach_before for j in path.jumps}
    assert sorted(kinds) == ["jump-off", "jump-on"], path.jumps
    assert coll.max(abs(kinds["jump-on"] - folds[1])) < 0.01, (kinds, folds)
    assert coll.max(abs(kinds["jump-off"] - folds[0])) < 0.01, (kinds, folds)


@pytest.mark.serial   # numpy geometry: no communicator
def test_disk_in_square_area_and_the_outside_of_a_square():
    """The rings' share of a square window (``_disk_in_square``): against a fine count of points
    inside both, either side of the corners (sqrt(2) half-widths); and the rings' integral of r^-6
    outside the square against its closed form 2 (1/4 + 3 pi / 32) / a^4 (polar coordinates)."""
    a, h = 48.0, 0.1
    x = np.arange(-80.0, 80.0, h) + 0.5 * h
    X, Y = np.meshgrid(x, x, indexing="ij")
    inside = (np.abs(X) < a) & (np.abs(Y) < a)
    for r in (30.0, 50.0, 60.0, 67.0, 68.0, 75.0):
        count = np.count_nonzero(inside & (X * X + Y * Y < r * r)) * h * h
        assert float(axi._disk_in_square(np.array([r]), a)[0]) == pytest.approx(count, rel=5e-4)
    e = np.linspace(40.0, 400.0, 36001)
    r = 0.5 * (e[1:] + e[:-1])
    outside = np.diff(np.pi * e ** 2) - np.diff(axi._disk_in_square(e, a))
    assert outside @ r ** -6.0 + np.pi / (2 * 400.0 ** 4) == pytest.approx(2 * (0.25 + 3 * np.pi / 32) / a ** 4,
                                                                          rel=1e-5)
