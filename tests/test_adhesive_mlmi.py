"""The multilevel preconditioner of the whole adhesive Newton system (``AdhesiveMLMIPC``).

Truths: with one level the cycle is the dense solve of K + C, and the elimination of the
contact rows is exact, so the preconditioner is the exact inverse of the reduced Jacobian
(an algebraic identity, any law with a diagonal linearisation); a multilevel cycle is the
same linear operator on any number of ranks (serial == MPI).  The ``auto`` choice: the snap
number against its closed form (the LJ tail's steepest slope, Love's self-influence), and the
state it converges to against the spectral preconditioner's.
"""
import warnings

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.physics.resolution import UnderResolvedWarning
from contactpetsc.solvers.adhesive_mlmi import AdhesiveMLMIPC
from contactpetsc.solvers.pc_registry import AUTO_MLMI_SNAP

from adhesive_setup import sphere_problem, work_for


def reduced_jacobian_and_pc(pb):
    """The reduced Jacobian on the solved state's inactive set (contact nodes' q, every a)
    and the MLMI preconditioner set up on it."""
    g = pb.grid
    blocks = pb.blocks(pb._x, readonly=True)
    local = np.arange(blocks.size).reshape(blocks.shape)
    keep = [local[-1].ravel()]
    if pb.hard_wall:
        keep.insert(0, local[0][blocks[0] > 0])
    idx = (np.concatenate(keep) + pb.offset).astype(PETSc.IntType)
    iset = PETSc.IS().createGeneral(idx, comm=g.comm)
    sub = pb._J.createSubMatrix(iset, iset)
    pc = PETSc.PC().create(comm=g.comm)
    pc.setType("python")
    pc.setPythonContext(AdhesiveMLMIPC())
    pc.setOperators(sub, sub)
    pc.setUp()
    return sub, pc


@pytest.mark.parametrize("law", ["hardwall-lj", "lj"])
def test_one_level_cycle_inverts_the_reduced_jacobian(coll, law):
    """mlmi_levels 1 on a 32^2 grid: M J x = x to round-off (on the contact rows, the a rows
    and the gap-form repulsive rows of the full LJ curve)."""
    prefix = f"amlmi_exact_{law.replace('-', '')}_"
    opts = PETSc.Options()
    try:
        pb = sphere_problem(1.0, law=law, n=32, dx=0.5, radius=50.0, prefix=prefix, stability_check=False,
                            preconditioner="spectral")   # the hierarchy is built at the first cycle
        st = pb.solve(approach=0.5)
        assert st.converged
        opts[f"{prefix}mlmi_levels"] = 1   # read when the cycle is first set up
        J, pc = reduced_jacobian_and_pc(pb)
        x, y = J.createVecs()
        rng = np.random.default_rng(3 + coll.rank)
        x.setArray(rng.standard_normal(x.getLocalSize()))
        b, z = J.createVecs()
        J.mult(x, b)
        pc.apply(b, z)
        z.axpy(-1.0, x)
        assert z.norm(PETSc.NormType.INFINITY) < 1e-8 * x.norm(PETSc.NormType.INFINITY)
    finally:
        opts.delValue(f"{prefix}mlmi_levels")


def test_cycle_is_rank_independent(coll):
    """A 4-level cycle applied to the same vector on COMM_SELF and on all ranks: the same result."""
    out = {}
    for name, comm in (("self", PETSc.COMM_SELF), ("world", PETSc.COMM_WORLD)):
        # 48 rows split into 48, 24 or 16 per rank on 1, 2 or 3 ranks: halved rank-locally twice
        pb = sphere_problem(1.0, n=48, dx=0.5, radius=50.0, comm=comm, preconditioner="mlmi",
                            prefix=f"amlmi_ranks_{name}_", stability_check=False)
        st = pb.solve(approach=0.5)
        assert st.converged
        g = pb.grid
        # the same right-hand side on both: a smooth field of the global node positions
        j, i = np.mgrid[g.ys:g.ye, 0:g.nx]
        full = np.zeros(pb.blocks(pb._x, readonly=True).shape)
        full[...] = np.sin(0.3 * i + 0.2 * j) + np.cos(0.05 * i * j)
        J, pc = reduced_jacobian_and_pc(pb)
        b, z = J.createVecs()
        J.getPythonContext().from_full(full, b)
        pc.apply(b, z)
        # (a solve frees its hierarchy: the set-up above made it again)
        assert len(pb._jac.pc_data.mlmi_levels) >= 3
        res = np.zeros_like(full)
        J.getPythonContext().to_full(z, res)
        gathered = np.concatenate(comm.tompi4py().allgather(res[-1]), axis=0)
        mask = np.concatenate(comm.tompi4py().allgather(pb.blocks(pb._x, readonly=True)[0] > 0), axis=0)
        out[name] = (gathered, mask)
    (a, ma), (b_, mb) = out["self"], out["world"]
    same_set = np.array_equal(ma, mb)
    assert coll.all(same_set)
    assert coll.max(np.abs(a - b_)) < 1e-9 * max(coll.max(np.abs(a)), 1e-300)


def lj_tail_snap_number(w, z0, dx, e_star=1.0):
    """K_ii max da/dg in closed form for the hard-wall LJ law a = -(8 w / 3 z0) (s^3 - s^9),
    s = z0 / (z0 + g): da/dg = (8 w / 3 z0^2) (3 s^4 - 9 s^10), largest at s^6 = 2/15, where
    it is (8 w / 3 z0^2) 1.8 (2/15)^(2/3); K_ii of a square element on an isolated half-space
    is Love's 4 asinh(1) dx / (pi E*)."""
    return 8.0 * w / (3.0 * z0 ** 2) * 1.8 * (2.0 / 15.0) ** (2.0 / 3.0) * 4.0 * np.arcsinh(1.0) * dx / (np.pi * e_star)


def test_snap_number_is_the_closed_form(coll):
    from contactpetsc.solvers.factory import grid_snap_number
    pb = sphere_problem(0.9, n=32, dx=1.0, radius=100.0, prefix="amlmi_snap_")
    truth = lj_tail_snap_number(work_for(0.9, 100.0), 1.0, 1.0)
    assert abs(pb.snap_number - truth) < 1e-6 * truth
    assert abs(grid_snap_number(pb.law, pb.grid, 1.0) - truth) < 1e-6 * truth


def test_auto_picks_per_grid_from_the_snap_number_and_gives_the_same_state(coll):
    """``auto`` (the default): mlmi where the grid's snap number is in the window of its law
    (hard wall, full LJ curve), spectral elsewhere -- with a hard wall per grid, so the nested iteration's coarse grid (dx doubled: snap doubled) may
    choose otherwise; recorded in the state's solver and the history.  The converged state is
    the one the spectral preconditioner gives."""
    lo, hi = AUTO_MLMI_SNAP["hard wall"]
    snap = lj_tail_snap_number(work_for(0.9, 100.0), 1.0, 1.0)
    assert lo <= snap <= hi < 2 * snap      # this fine grid: mlmi; its 2x coarser grid: spectral
    soft = sphere_problem(0.1, n=32, dx=1.0, radius=100.0, prefix="amlmi_auto_soft_")
    soft.snes()
    assert lj_tail_snap_number(work_for(0.1, 100.0), 1.0, 1.0) < lo and soft.preconditioner == "spectral"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UnderResolvedWarning)   # stiff by design
        wallless = sphere_problem(1.6, law="lj", n=32, dx=1.0, radius=100.0, prefix="amlmi_auto_lj_")
        mild = sphere_problem(0.9, law="lj", n=64, dx=1.0, radius=100.0, prefix="amlmi_auto_ljmild_")
        wallless.snes()
        mild.snes()
        mild_coarse = mild.coarse_levels.coarse()
    lj_lo, lj_hi = AUTO_MLMI_SNAP["full LJ"]
    # the full LJ curve: spectral below its window, mlmi in it; its coarse grids follow the finest
    assert mild.snap_number < lj_lo and mild.preconditioner == "spectral"
    # (a grid split over ranks that cannot halve it evenly has no coarse level: 64^2 on 3 ranks)
    assert mild_coarse is None or (mild_coarse.snap_number >= lj_lo and mild_coarse.preconditioner == "spectral")
    assert lj_lo <= wallless.snap_number <= lj_hi and wallless.preconditioner == "mlmi"
    states = []
    for pc in ("auto", "spectral"):
        pb = sphere_problem(0.9, n=64, dx=1.0, radius=100.0, preconditioner=pc, prefix=f"amlmi_auto_{pc}_",
                            stability_check=False)
        pb.snes()
        if pc == "auto":
            coarse = pb.coarse_levels.coarse()
            assert pb.preconditioner == "mlmi" and (coarse is None or coarse.preconditioner == "spectral")
        pb.solve(approach=-0.5)
        states.append(pb.solve(approach=0.5))
        if pc == "auto":
            assert states[-1].solver.startswith("newton-vi+mlmi")
            assert "newton-vi+mlmi" in pb.history.column("solver")
    assert all(st.converged for st in states)
    g = pb.grid
    dg = g.rows(states[0].gap, readonly=True) - g.rows(states[1].gap, readonly=True)
    assert coll.max(np.abs(dg)) < 1e-6
