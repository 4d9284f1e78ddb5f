"""The nested iteration's coarse levels (``solvers/adhesive_levels.py``): a level put at the fine
state (FAS's tau correction, taken up by its heights) is the coarse equilibrium there."""
import numpy as np
import pytest

from adhesive_setup import sphere_problem


@pytest.mark.parametrize("law", ["hardwall-lj", "lj"])
def test_an_anchored_level_is_the_coarse_equilibrium_at_the_fine_state(coll, law):
    """mu = 1 sphere on 64^2 pressed 2 z0 past first touch: after ``anchor``, the restricted
    state solves the coarse problem at the fine state's approach (complementarity,
    self-consistency and pressure errors at round-off, against the solve's 1e-8), the coarse
    gap is the 2 x 2 mean of the fine one wherever the coarse contact pressure is zero, and
    with a hard wall the contact force is the fine state's (restriction keeps a density's
    mean; the adhesive pressure is the law's at the coarse gap)."""
    pb = sphere_problem(1.0, law=law, stability_check=False)
    st = pb.solve(approach=2.0)
    coarse = pb.coarse_levels.anchor(st.approach)
    x = coarse._x
    f = x.duplicate()
    coarse._residual(None, x, f)
    errors = coarse._measures(x, f)[:3]
    assert coll.max(max(errors)) < 1e-11, errors
    fine_gap = pb.grid.rows(st.gap, readonly=True)
    ny, nx = fine_gap.shape
    mean_gap = fine_gap.reshape(ny // 2, 2, nx // 2, 2).mean(axis=(1, 3))
    xc = coarse.blocks(x, readonly=True)
    gap_c = coarse.gap(xc.sum(axis=0), np.empty(xc.shape[1:]))
    open_ = xc[0] == 0 if pb.hard_wall else np.ones(gap_c.shape, bool)
    assert coll.max(np.abs(gap_c - mean_gap)[open_].max(initial=0.0)) < 1e-11
    if pb.hard_wall:
        fine_sum = coll.comm.allreduce(float(pb.blocks(pb._x, readonly=True)[0].sum()))
        assert fine_sum > 0
        assert abs(4 * coll.comm.allreduce(float(xc[0].sum())) - fine_sum) <= 1e-12 * fine_sum
    f.destroy()
    pb.destroy()


def test_levels_the_descent_no_longer_needs_are_freed_and_remade_as_new(coll, monkeypatch):
    """With the energy descent as the strategy (the full LJ curve on a periodic grid) the coarse
    levels give only the first state: after it they are freed (no coarse problem survives a
    collection, their FFT pairs stay counted), and where they are wanted again they are made
    anew: the first state they give equals a fresh problem's."""
    import gc
    import weakref

    from petsc4py import PETSc

    from contactpetsc.geometry.surfaces import self_affine
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    from contactpetsc.solvers.adhesive_levels import CoarseLevels

    grid = SurfaceGrid(64, 64, 1.0, periodic=True, comm=PETSc.COMM_WORLD)
    h = self_affine(grid, hurst=0.8, rms_height=1.0, seed=7)
    law = make_law("lj", work_of_adhesion=0.05, z0=1.0)
    released = []
    release = CoarseLevels.release

    def watched(levels):
        if levels._coarse:
            released.append(weakref.ref(levels._coarse))
        release(levels)
    monkeypatch.setattr(CoarseLevels, "release", watched)
    # three levels (32^2, 16^2, 8^2): the levels below the first are released too
    options = {"fmg_min_size": 8}
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="release_", petsc_options=options)
    d = float(h.min()[1]) + 0.75
    st = pb.solve(approach=d)
    assert st.converged and pb.strategy == "descent"
    assert released and pb.coarse_levels._coarse is None
    pairs = pb.coarse_levels.fft_pairs()
    assert pairs > 0
    gc.collect()
    assert len(released) == 3 and all(ref() is None for ref in released)
    assert pb.coarse_levels.first_state(d)
    again = pb.blocks(pb._x, readonly=True).copy()
    assert pb.coarse_levels.fft_pairs() > pairs
    fresh = AdhesiveProblem(grid, h, 1.0, law, prefix="release_", petsc_options=options)
    fresh.snes()
    assert fresh.coarse_levels.first_state(d)
    assert coll.max(np.abs(again - fresh.blocks(fresh._x, readonly=True))) == 0.0
    pb.destroy()
    fresh.destroy()
