"""The adhesive sphere against closed forms: DMT at small Tabor parameter, Signorini as w -> 0,
the Maugis-Dugdale limits.  Units: z0 = 1, E* = 1 (Greenwood's).
"""
import numpy as np
import pytest

from contactpetsc.paths import sweep
from contactpetsc.pull_off import refine_pull_off
from contactpetsc.physics.closed_forms import dmt_force, maugis_pull_off_bar
from contactpetsc.solvers.problem import ContactProblem

from adhesive_setup import R, work_for, sphere_problem


# one rank: on two, the DMT pull-off of a path without jumps is test_studies'
# test_smooth_sphere_small_tabor_is_dmt's, and a Signorini problem on the adhesive one's
# operator test_vanishing_adhesion_gives_the_signorini_solution's
@pytest.mark.serial
def test_small_tabor_parameter_gives_dmt(coll):
    """mu = 0.02, hard-wall LJ: pull-off -2 pi R w within 2 %; in contact, the adhesive force
    is the DMT one (the law over the Hertz gap outside the contact, Muller et al.) within 2 %,
    and the load is the non-adhesive load on the same grid plus that force (2 %)."""
    pb = sphere_problem(0.02, n=192, dx=2.0)
    w = work_for(0.02)
    path = sweep(pb, np.arange(-1.0, 0.41, 0.1))
    assert coll.all(all(p.converged and p.stable for p in path.points))
    assert not path.jumps
    assert abs(refine_pull_off(pb, path, xtol=0.005) / (-2 * np.pi * R * w) - 1) < 0.02
    signorini = ContactProblem(pb.grid, pb.heights, 1.0, operator=pb.op, prefix="dmt_ref_",
                               length_scale=1.0, tol=1e-10)
    for delta in (0.5, 1.0, 2.0):
        st = pb.solve(approach=delta)
        _, f_dmt = dmt_force(pb.law, 1.0, R, delta)
        assert abs(st.adhesive_force / f_dmt - 1) < 0.02
        plain = signorini.solve(approach=delta).force
        assert abs(st.force - (plain + f_dmt)) < 0.02 * plain   # one ring of nodes at the edge


def test_vanishing_adhesion_gives_the_signorini_solution(coll):
    pb = sphere_problem(1e-4, n=48, dx=2.0)
    st = pb.solve(approach=2.0)
    ref = ContactProblem(pb.grid, pb.heights, 1.0, operator=pb.op, prefix="w0_ref_",
                         length_scale=1.0, tol=1e-10).solve(approach=2.0)
    w = work_for(1e-4)
    # the adhesive force is O(2 pi R w); the pressures differ by at most that much per element
    assert abs(st.force - ref.force) < 1.1 * 2 * np.pi * R * w
    dp = pb.grid.rows(st.pressure, readonly=True) - pb.grid.rows(ref.pressure, readonly=True)
    assert coll.max(np.abs(dp)) < 0.05 * coll.max(pb.grid.rows(ref.pressure, readonly=True))


@pytest.mark.serial   # a closed form: no communicator
def test_maugis_dugdale_limits():
    assert abs(maugis_pull_off_bar(1e-4) + 2.0) < 1e-3
    assert abs(maugis_pull_off_bar(1e4) + 1.5) < 1e-3
    values = [maugis_pull_off_bar(lam) for lam in (0.1, 0.5, 1.0, 2.0, 5.0)]
    assert all(np.diff(values) > 0)   # from DMT towards JKR
