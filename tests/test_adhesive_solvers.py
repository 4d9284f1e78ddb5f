"""The adhesive solvers: Newton VI, the relaxation, their fallbacks and preconditioners.

Independent truths: agreement of two different solvers (or preconditioners), an uninterrupted
loading path, COMM_WORLD against COMM_SELF.  Units: z0 = 1, E* = 1 (Greenwood's).
"""
import numpy as np
from petsc4py import PETSc

from contactpetsc.grid import SurfaceGrid
from contactpetsc.paths import sweep
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import self_affine

from adhesive_setup import sphere_problem


def test_rank_independence_of_adhesive_states(coll):
    states = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        pb = sphere_problem(1.0, law="lj", n=48, dx=1.5, comm=comm, prefix="ranks_")
        pb.solve(approach=-1.0)
        st = pb.solve(approach=0.5)
        states.append(pb.grid.gather(st.gap))
    assert coll.max(np.abs(states[0] - states[1])) < 1e-7


def test_rough_periodic_lj_converges(coll):
    """The adhesive rough benchmark's setting at reduced size: lj, z0 = dx, w = 0.05 E* dx."""
    n = 64
    grid = SurfaceGrid(n, n, 1.0, periodic=True)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)
    pb = AdhesiveProblem(grid, h, 1.0, make_law("lj", work_of_adhesion=0.05, z0=1.0))
    hmin = h.min()[1]
    for delta in (hmin + 0.5, hmin + 1.0):
        st = pb.solve(approach=delta)
        assert st.converged and st.stable
        assert max(st.complementarity_error, st.adhesive_error) <= 1e-8
    assert 0 < st.contact_fraction < 0.5 and st.adhesive_force < 0


def test_stalled_newton_hands_over_to_ptc_and_ends_in_the_same_state(coll):
    """Newton crippled to one Krylov iteration per step stalls; with -stall_steps 1 PTC takes
    over from its best iterate and must reach the state plain Newton reaches."""
    n = 64
    grid = SurfaceGrid(n, n, 1.0, periodic=True)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)
    opts = PETSc.Options()
    opts.setValue("stalled_stall_steps", 1)
    # one GMRES iteration: a step too poor to converge (one BiCGStab iteration still does here)
    opts.setValue("stalled_ksp_type", "gmres")
    opts.setValue("stalled_ksp_max_it", 1)
    # PTC alone (the default chain descends first: test_descent.py)
    opts.setValue("stalled_fallback", "ptc")
    states = []
    try:
        for prefix in ("plain_", "stalled_"):
            # Newton first (the full LJ curve's default on a periodic grid descends first)
            pb = AdhesiveProblem(grid, h, 1.0, make_law("lj", work_of_adhesion=0.05, z0=1.0), prefix=prefix,
                                 petsc_options={"strategy": "newton"})
            states.append(pb.solve(approach=h.min()[1] + 0.5))
    finally:
        for name in ("stall_steps", "ksp_type", "ksp_max_it", "fallback"):
            opts.delValue("stalled_" + name)
    plain, stalled = states
    assert "+ptc" not in plain.solver and stalled.solver.endswith("+ptc")
    assert stalled.converged and stalled.stable
    assert abs(stalled.force - plain.force) < 1e-7 * abs(plain.force)
    assert coll.max(np.abs(grid.rows(stalled.gap, readonly=True) - grid.rows(plain.gap, readonly=True))) < 1e-6


def test_a_step_too_long_for_newton_is_reached_in_sub_steps(coll):
    """Newton limited to 5 steps and no fallback cannot go from 1 to 7 z0 in one step; the
    sweep halves the step from the last converged state and must reach the state that steps
    of 2 z0 reach (the branch is the same: mu = 0.5, in compression, no jumps)."""
    opts = PETSc.Options()
    # tol 1e-7: five Newton steps then reach it from steps of 0.75 z0 (not from one of 6 z0)
    for key, value in dict(max_it=5, tol=1e-7, fallback="ptc", ptc_max_it=1, stall_steps=0).items():
        opts.setValue("short_" + key, value)
    try:
        ref = sphere_problem(0.5, law="lj", n=48, dx=1.0, radius=100.0, prefix="long_ref_")
        fine = sweep(ref, [1.0, 3.0, 5.0, 7.0])
        plain = ref.solve(approach=7.0)
        for substeps in (0, 3):
            pb = sphere_problem(0.5, law="lj", n=48, dx=1.0, radius=100.0, prefix="short_")
            seen = []
            path = sweep(pb, [1.0, 7.0], substeps=substeps, on_state=lambda k, st, pt: seen.append(st))
            assert [p.approach for p in path.points] == [1.0, 7.0]
            assert path.points[1].converged == bool(substeps), path.points[1].reason
        stepped = pb.solve(approach=7.0)
    finally:
        for key in ("max_it", "tol", "fallback", "ptc_max_it", "stall_steps"):
            opts.delValue("short_" + key)
    assert all(p.converged for p in fine.points) and not fine.jumps
    assert "sub-step" in path.points[1].solver and not path.jumps
    # the tries' and sub-steps' Newton steps are counted: one solve makes at most 5 + 1 (PTC)
    assert seen[-1].newton_iterations > 6
    assert abs(stepped.force - plain.force) < 1e-7 * abs(plain.force)
    assert coll.max(np.abs(pb.grid.rows(stepped.gap, readonly=True) - ref.grid.rows(plain.gap, readonly=True))) < 1e-6


def test_load_from_rest_gives_the_state_of_a_first_loading(coll):
    """-<prefix>load_from_rest: the first solve is the end of a loading path from separation."""
    opts = PETSc.Options("rest_")
    opts.setValue("load_from_rest", "true")
    try:
        direct = sphere_problem(1.0, law="lj", n=64, dx=1.0, radius=100.0, prefix="rest_")
        st = direct.solve(approach=0.5)
    finally:
        opts.delValue("load_from_rest")
    path = sphere_problem(1.0, law="lj", n=64, dx=1.0, radius=100.0, prefix="pathref_")
    start = float(path.heights.min()[1]) - 1.0
    for d in np.linspace(start, 0.5, 11)[1:]:
        ref = path.solve(approach=float(d))
    g = direct.grid
    dg = g.rows(st.gap, readonly=True) - g.rows(ref.gap, readonly=True)
    assert st.converged and coll.max(np.abs(dg)) < 1e-6


def test_mlmi_preconditioner_gives_the_same_state(coll):
    """The MLMI cycle as the inner preconditioner of the adhesive Newton steps (hard wall and
    full LJ): the same converged state as with the spectral one."""
    for law in ("hardwall-lj", "lj"):
        states = []
        for pc in ("spectral", "mlmi"):
            pb = sphere_problem(0.5, law=law, n=64, dx=1.0, radius=100.0, preconditioner=pc,
                                prefix=f"pc{pc}{law.replace('-', '')}_")
            pb.solve(approach=-0.5)
            states.append(pb.solve(approach=0.5))
        assert all(st.converged for st in states)
        g = states[0].gap
        dg = pb.grid.rows(g, readonly=True) - pb.grid.rows(states[1].gap, readonly=True)
        assert coll.max(np.abs(dg)) < 1e-6


def test_ptc_alone_reaches_newtons_state_on_any_rank_count(coll):
    """Newton switched off (max_it 0): PTC alone goes from the previous state to the next one;
    it must reach the state Newton reaches from the same start, and the same on one rank as
    on all (its shift follows a global error measure)."""
    n = 64
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    opts = PETSc.Options()
    for key, value in dict(max_it=0, predictor="false", fmg="false", fallback="ptc", strategy="newton").items():
        opts.setValue("ptconly_" + key, value)
    gaps = []
    try:
        for comm, prefix in ((PETSc.COMM_WORLD, "newton_"), (PETSc.COMM_WORLD, "ptconly_"),
                             (PETSc.COMM_SELF, "ptconly_")):
            grid = SurfaceGrid(n, n, 1.0, periodic=True, comm=comm)
            h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)
            pb = AdhesiveProblem(grid, h, 1.0, law, prefix=prefix, petsc_options={"strategy": "newton"})
            hmin = h.min()[1]
            first = AdhesiveProblem(grid, h, 1.0, law, prefix="first_")
            first.solve(approach=hmin + 0.5)
            a = grid.create_vec()
            grid.rows(a)[...] = first.blocks(first._x, readonly=True)[-1]
            pb.warm_start(None, a, hmin + 0.5)
            st = pb.solve(approach=hmin + 1.0)
            assert st.converged and st.stable
            assert ("+ptc" in st.solver) == (prefix == "ptconly_")
            gaps.append(grid.gather(st.gap))
    finally:
        for key in ("max_it", "predictor", "fmg", "fallback", "strategy"):
            opts.delValue("ptconly_" + key)
    assert coll.max(np.abs(gaps[1] - gaps[0])) < 1e-6
    assert coll.max(np.abs(gaps[2] - gaps[1])) < 1e-7


def test_a_states_fields_are_the_gap_and_displacement_of_its_pressure(coll):
    """A state's gap and displacement fields are h + K p - delta and K p of its own pressure,
    made afresh here, and its pressure is q + a, whatever came between Newton's last residual
    and the fields (the stability check, the tangent, a descent and its Newton polish): the
    fields reuse the residual's gap rows where they are the state's.  The sphere's window under
    the Newton strategy (both laws) and a rough periodic cell under the descent strategy."""
    grid = SurfaceGrid(64, 64, 1.0, periodic=True)
    rough = AdhesiveProblem(grid, self_affine(grid, hurst=0.8, rms_height=1.0, seed=7), 1.0,
                            make_law("hardwall-lj", work_of_adhesion=0.05, z0=1.0), prefix="fields_rough_")
    h_min = rough.grid.gather(rough.heights).min()
    cases = [(rough, (h_min + 0.5, h_min + 1.0, h_min + 0.7))]
    for law in ("hardwall-lj", "lj"):
        cases.append((sphere_problem(2.0, law=law, n=96, dx=0.5, radius=100.0, prefix=f"fields_{law}_"),
                      (-1.0, -0.5, 0.0, -0.75)))
    for pb, approaches in cases:
        g = pb.grid
        for delta in approaches:
            st = pb.solve(approach=delta)
            assert st.converged and st.stable is not None
            p = g.rows(st.pressure, readonly=True)
            kp = pb.op.apply(p.copy(), np.empty_like(p))
            gap = g.rows(pb.heights, readonly=True) + kp - delta
            scale = coll.max(np.abs(kp)) + 1.0
            assert coll.max(np.abs(g.rows(st.displacement, readonly=True) - kp)) <= 1e-12 * scale
            assert coll.max(np.abs(g.rows(st.gap, readonly=True) - gap)) <= 1e-12 * scale
            q, a = g.rows(st.contact_pressure, readonly=True), g.rows(st.adhesive_pressure, readonly=True)
            assert coll.max(np.abs(p - (q + a if pb.hard_wall else a))) == 0.0
            st.release_fields()
        pb.destroy()
