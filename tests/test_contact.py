"""Contact solver: Hertz, Westergaard, rough surfaces, ranks, failures, histories.

Runs serially and under ``mpirun -n 2/3``; every assertion is on a value
reduced over COMM_WORLD, so all ranks reach the same verdict.  Each test uses
its own options prefix so that options set here do not leak into other tests.
"""
import csv
import itertools

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.geometry import surfaces
from contactpetsc.grid import SurfaceGrid
from contactpetsc.solvers import ContactProblem, ContactSolveError

E_STAR = 1.0
_ids = itertools.count()


def prefix(name):
    return f"t{next(_ids)}{name}_"


def recheck(prob, st):
    """Independent measures from the returned fields: (compl. error, min p, min gap, max p*gap) / scales."""
    g = prob.grid
    p = g.rows(st.pressure, readonly=True)
    gap = prob.op.apply(p, np.empty_like(p)) + g.rows(prob.heights, readonly=True) - st.approach
    L = prob.length_scale
    comm = g.mpi_comm
    from mpi4py import MPI
    pmax = comm.allreduce(float(p.max()), op=MPI.MAX)
    nat = comm.allreduce(float(np.abs(np.minimum(prob.kappa * p, gap)).max()), op=MPI.MAX) / L
    pmin = comm.allreduce(float(p.min()), op=MPI.MIN)
    gmin = comm.allreduce(float(gap.min()), op=MPI.MIN) / L
    pg = comm.allreduce(float(np.abs(p * gap).max()), op=MPI.MAX) / (pmax * L)
    return nat, pmin, gmin, pg


# -- Hertz: isolated sphere --------------------------------------------------------------
R, A = 1.0, 1e-2            # sphere radius, Hertz contact radius [m]
DELTA = A * A / R           # Hertz approach for contact radius A
F_HERTZ = 4.0 / 3.0 * E_STAR * np.sqrt(R) * DELTA ** 1.5
P0 = 2.0 * E_STAR * A / (np.pi * R)


def hertz(elements, control):
    n = int(round(3.2 * elements))
    n += n % 2
    g = SurfaceGrid(n, n, A / elements, periodic=False)
    prob = ContactProblem(g, surfaces.sphere(g, R), E_STAR, length_scale=DELTA, prefix=prefix("hertz"))
    st = prob.solve(approach=DELTA) if control == "approach" else prob.solve(force=F_HERTZ)
    radius = np.sqrt(st.contact_fraction * g.lengths[0] * g.lengths[1] / np.pi)
    return prob, st, radius


@pytest.mark.parametrize("control", ["approach", "force"])
def test_hertz_converges_under_refinement(coll, control):
    errs = []
    for el in (5, 10, 20):
        prob, st, radius = hertz(el, control)
        assert coll.all(st.converged) and coll.max(st.complementarity_error) <= 1e-10
        if control == "approach":
            e_load = abs(st.force / F_HERTZ - 1)
        else:
            e_load = abs(st.approach / DELTA - 1)
            assert coll.max(st.load_error) <= 1e-9
        errs.append((e_load, abs(st.pressure.max()[1] / P0 - 1), abs(radius / A - 1)))
    errs = np.array(errs)
    # ~20 elements across the contact radius: load/approach, peak pressure, radius within 1 %
    assert coll.max(errs[-1]) <= 0.01, errs
    # observed orders: peak pressure ~2, contact radius (node counting) >= 1
    order_p = np.log2(errs[:-1, 1] / errs[1:, 1])
    order_a = np.log2(errs[:-1, 2] / errs[1:, 2])
    assert coll.max(-order_p) <= -1.8, order_p
    assert coll.max(-order_a) <= -1.2, order_a
    assert coll.max(errs[:, 0]) <= 1e-3, errs  # load-approach: within 0.1 % on all three grids


def test_hertz_load_control_from_converged_state_is_cheap(coll):
    prob, st, _ = hertz(20, "approach")
    st2 = prob.solve(force=st.force * (1 + 1e-3))
    assert coll.all(st2.converged)
    assert coll.max(st2.newton_iterations) <= 4, st2.newton_iterations


# -- Westergaard: 1-D sinusoid on a 2-D periodic grid ------------------------------------
NX, NY, LAM, H0 = 256, 4, 1.0, 1e-3
Q = 2 * np.pi / LAM
P_STAR = E_STAR * Q * H0 / 2  # full contact from mean pressure p* on


def sinusoid():
    g = SurfaceGrid(NX, NY, LAM / NX)
    h = surfaces.from_function(g, lambda x, y: H0 * (1 - np.cos(Q * x)))
    return g, h


def test_sinusoid_full_contact_exact(coll):
    g, h = sinusoid()
    pbar = 2.0 * P_STAR
    prob = ContactProblem(g, h, E_STAR, prefix=prefix("full"))
    st = prob.solve(mean_pressure=pbar)
    x, _ = g.coordinates()
    exact = pbar + P_STAR * np.cos(Q * x)      # (nx, ny_loc)
    err = np.abs(g.local_array(st.pressure, readonly=True) - exact).max() / P_STAR
    assert coll.all(st.converged) and coll.max(st.contact_fraction) == 1.0
    assert coll.max(err) <= 1e-9, err
    assert coll.max(abs(st.approach - H0) / H0) <= 1e-9   # delta = mean h in full contact


@pytest.mark.parametrize("ratio", [0.1, 0.5])
def test_sinusoid_partial_contact_westergaard(coll, ratio):
    """Johnson (Contact Mechanics, 13.2): pbar / p* = sin^2(pi a / lambda),
    p = 2 pbar cos(psi) sqrt(sin^2 psi_a - sin^2 psi) / sin^2 psi_a, psi = pi x / lambda."""
    g, h = sinusoid()
    pbar = ratio * P_STAR
    prob = ContactProblem(g, h, E_STAR, prefix=prefix("partial"))
    st = prob.solve(mean_pressure=pbar)
    nat, pmin, gmin, _ = recheck(prob, st)
    assert coll.all(st.converged) and coll.max(nat) <= 1e-10 and coll.max(-pmin) <= 0
    psi_a = np.arcsin(np.sqrt(ratio))
    a = psi_a * LAM / np.pi
    a_num = st.contact_fraction * LAM / 2
    assert coll.max(abs(a_num - a)) <= 2 * g.dx, (a_num, a)
    x, _ = g.coordinates()
    psi = np.pi * np.where(x > LAM / 2, x - LAM, x) / LAM
    s2 = np.sin(psi_a) ** 2 - np.sin(psi) ** 2
    exact = np.where(s2 > 0, 2 * pbar * np.cos(psi) * np.sqrt(np.maximum(s2, 0)) / np.sin(psi_a) ** 2, 0)
    peak = 2 * pbar / np.sin(psi_a)
    assert coll.max(abs(st.pressure.max()[1] / peak - 1)) <= 1e-3
    err = np.abs(g.local_array(st.pressure, readonly=True) - exact).max() / peak
    assert coll.max(err) <= 0.03, err   # the square-root edges limit the pointwise error


# -- rough periodic surface ----------------------------------------------------------------
def rough(n=128, comm=None, **kw):
    g = SurfaceGrid(n, n, 1.0 / n, comm=comm)
    h = surfaces.self_affine(g, hurst=0.8, seed=3, rms_slope=0.1, rolloff_wavelength=0.25,
                             short_cutoff_wavelength=4.0 / n)
    return g, h


@pytest.mark.parametrize("pc", ["none", "spectral", "mlmi"])
def test_rough_surface_complementarity(coll, pc):
    g, h = rough()
    prob = ContactProblem(g, h, E_STAR, preconditioner=pc, prefix=prefix("rough"))
    st = prob.solve(mean_pressure=0.005 * E_STAR)
    nat, pmin, gmin, pg = recheck(prob, st)
    assert coll.all(st.converged)
    assert coll.max(st.complementarity_error) <= 1e-10 and coll.max(nat) <= 1e-10, nat
    assert coll.max(-pmin) <= 0.0 and coll.max(-gmin) <= 1e-10 and coll.max(pg) <= 1e-10
    assert coll.max(st.load_error) <= 1e-9
    assert 0.02 < st.contact_fraction < 0.3
    # the three preconditioners give the same solution
    ref = ContactProblem(g, h, E_STAR, preconditioner="spectral", tol=1e-12,
                         prefix=prefix("roughref")).solve(mean_pressure=0.005 * E_STAR)
    d = st.pressure.copy()
    d.axpy(-1.0, ref.pressure)
    assert coll.max(d.norm(PETSc.NormType.INFINITY) / ref.pressure.max()[1]) <= 1e-7


def test_rank_independence(coll):
    """COMM_WORLD and COMM_SELF solutions agree to 1e-10 (relative, max norm)."""
    kw = dict(tol=1e-12, load_tol=1e-12)
    g, h = rough(64)
    st = ContactProblem(g, h, E_STAR, prefix=prefix("world"), **kw).solve(mean_pressure=0.005)
    gs, hs = rough(64, comm=PETSc.COMM_SELF)
    ss = ContactProblem(gs, hs, E_STAR, prefix=prefix("self"), **kw).solve(mean_pressure=0.005)
    pw, ps = g.gather(st.pressure), gs.gather(ss.pressure)
    assert coll.max(np.abs(pw - ps).max() / ps.max()) <= 1e-10


def test_line_search_takes_bt_steps_without_the_slope_product(coll):
    """The default line search (``basic`` with the backtracking pre-check, backtracking.py) and
    PETSc's ``bt`` take the same steps here (the same pressure to the last bit), and ours costs
    exactly one FFT pair less per Newton step: bt's product J Y for its initial slope."""
    g, h = rough(64)
    ours = ContactProblem(g, h, E_STAR, prefix=prefix("ls"), fmg=False).solve(mean_pressure=0.005)
    bt = ContactProblem(g, h, E_STAR, prefix=prefix("lsbt"), fmg=False,
                        petsc_options={"snes_linesearch_type": "bt"}).solve(mean_pressure=0.005)
    assert coll.all(ours.converged and bt.converged)
    assert ours.newton_iterations == bt.newton_iterations > 0
    assert bt.fft_pairs - ours.fft_pairs == ours.newton_iterations
    d = ours.pressure.copy()
    d.axpy(-1.0, bt.pressure)
    assert coll.max(d.norm(PETSc.NormType.INFINITY)) == 0.0


def test_failure_raises_everywhere(coll):
    g, h = rough(64)
    pre = prefix("fail")
    opts = PETSc.Options(pre)
    opts.setValue("snes_max_it", 1)
    try:
        prob = ContactProblem(g, h, E_STAR, prefix=pre, fmg=False)
        msgs = coll.raises(ContactSolveError, ["DIVERGED", "KSP"], prob.solve, mean_pressure=0.005)
        assert len(set(msgs)) == 1, msgs
        prob2 = ContactProblem(g, h, E_STAR, prefix=pre, fmg=False)
        coll.raises(ContactSolveError, ["DIVERGED_MAX_IT"], prob2.solve, approach=float(h.max()[1]) / 2)
    finally:
        opts.delValue("snes_max_it")


def test_history_and_csv(coll, shared_tmp):
    g, h = rough(64)
    prob = ContactProblem(g, h, E_STAR, prefix=prefix("hist"))
    st = prob.solve(mean_pressure=0.005)
    hist = prob.history
    assert coll.all(len(hist) > 0)
    errs = hist.column("complementarity_error")
    assert coll.max(errs[-1]) <= 1e-10
    pairs = hist.column("fft_pairs")
    assert coll.all(all(b >= a for a, b in zip(pairs, pairs[1:])))
    assert coll.all(st.fft_pairs > 0 and st.newton_iterations > 0 and st.linear_iterations > 0)
    path = shared_tmp / "history.csv"
    if g.mpi_comm.Get_rank() == 0:
        hist.write_csv(str(path))
    g.mpi_comm.Barrier()
    with open(path) as f:
        rows = list(csv.DictReader(f))
    assert coll.all(len(rows) == len(hist) and "complementarity_error" in rows[0])


def test_bilinear_prolongation(coll):
    """Nested-iteration transfer: mean and p >= 0 kept, linear fields reproduced, rank-local halos."""
    from contactpetsc.solvers.transfer import prolong_bilinear
    for periodic in (True, False):
        g = SurfaceGrid(16, 16, 1.0, periodic=periodic)
        x, y = np.meshgrid(np.arange(16.0), np.arange(g.ys, g.ye), indexing="xy")
        lin = prolong_bilinear(x + 2 * y, g)
        X, Y = np.meshgrid(np.arange(32) / 2 - 0.25, np.arange(2 * g.ys, 2 * g.ye) / 2 - 0.25)
        inner = (X > 0.5) & (X < 14.5) & (Y > 0.5) & (Y < 14.5)   # away from wrap / edges
        assert coll.max(np.abs(lin - (X + 2 * Y))[inner].max(initial=0.0)) <= 1e-12
        c = np.random.default_rng(g.ys).random((g.ye - g.ys, 16))
        f = prolong_bilinear(c, g)
        assert coll.all(f.min() >= 0.0)
        if periodic:
            sc, sf = g.mpi_comm.allreduce(c.sum()), g.mpi_comm.allreduce(f.sum())
            assert abs(sf / 4 - sc) <= 1e-12 * sc


def test_restriction_and_constant_prolongation(coll):
    """Nested-iteration transfer: each coarse node is the mean of its 2 x 2 children (the truth:
    the four strided sums), the copy to the children keeps every value, so restricting it gives
    the coarse field back exactly, and both keep the cell's mean."""
    from contactpetsc.solvers.transfer import prolong_constant, restrict
    rng = np.random.default_rng(11 + coll.rank)
    fine = rng.standard_normal((6, 10))
    coarse = restrict(fine)
    blocks = np.array([[fine[2 * j:2 * j + 2, 2 * i:2 * i + 2].mean() for i in range(5)] for j in range(3)])
    up = prolong_constant(coarse)
    ok = (np.allclose(coarse, blocks, rtol=0, atol=1e-15) and np.array_equal(restrict(up), coarse)
          and np.array_equal(up[1::2, 0::2], coarse) and np.array_equal(up[0::2, 1::2], coarse)
          and abs(up.mean() - fine.mean()) <= 1e-15 * max(1.0, abs(fine).max()) * 10)
    assert coll.all(ok)


def test_bilinear_nested_iteration_rank_independent(coll):
    """-contact_fmg_prolong bilinear: converges, 1 and N ranks equal to 1e-10."""
    kw = dict(tol=1e-12, load_tol=1e-12)
    sols = []
    for comm in (PETSc.COMM_WORLD, PETSc.COMM_SELF):
        pre = prefix("bilin")
        PETSc.Options(pre).setValue("fmg_prolong", "bilinear")
        try:
            g, h = rough(64, comm=comm)
            st = ContactProblem(g, h, E_STAR, prefix=pre, **kw).solve(mean_pressure=0.005)
        finally:
            PETSc.Options(pre).delValue("fmg_prolong")
        assert coll.all(st.converged) and coll.max(st.complementarity_error) <= 1e-12
        sols.append(g.gather(st.pressure))
    assert coll.max(np.abs(sols[0] - sols[1]).max() / sols[1].max()) <= 1e-10
