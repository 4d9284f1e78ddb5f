"""The hardness cap p <= H (perfectly plastic asperities) of ``ContactProblem``.

Truths used: H -> inf is the elastic problem (to round-off); the mixed complementarity
conditions (p = 0 => g >= 0, 0 < p < H => g = 0, p = H => g <= 0) rechecked from the
returned fields; the fully plastic limit, where every contact node carries H, so that the
contact area is the load over H (to the few nodes of the elastic rim) and, for a sphere, the
truncated cap's area 2 pi R delta; Hertz's first yield, where the peak pressure
p0 = (2 E* / pi) sqrt(delta / R) reaches H; and serial == MPI.
"""
import itertools

import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactpetsc.geometry import surfaces
from contactpetsc.grid import SurfaceGrid
from contactpetsc.solvers import ContactProblem

E_STAR = 1.0
_ids = itertools.count()


def prefix(name):
    return f"hard{next(_ids)}{name}_"


def rough(n=64, comm=None):
    g = SurfaceGrid(n, n, 1.0 / n, comm=comm)
    h = surfaces.self_affine(g, hurst=0.8, seed=3, rms_slope=0.1, rolloff_wavelength=0.25,
                             short_cutoff_wavelength=4.0 / n)
    return g, h


def recheck(prob, st, hardness):
    """(largest violation of the mixed complementarity conditions relative to the length
    scale, max -g over the nodes at H) from the returned pressure and K p recomputed here."""
    g = prob.grid
    p = g.rows(st.pressure, readonly=True)
    gap = prob.op.apply(p, np.empty_like(p)) + g.rows(prob.heights, readonly=True) - st.approach
    comm, L = g.mpi_comm, prob.length_scale
    assert comm.allreduce(bool(p.min() >= 0 and p.max() <= hardness), op=MPI.LAND)
    below, above = p < hardness, p > 0
    worst = max(float(np.max(-gap[below], initial=0.0)),   # p < H: g >= 0
                float(np.max(gap[above], initial=0.0)))     # p > 0: g <= 0
    plastic = float(np.max(-gap[~below], initial=0.0))
    return comm.allreduce(worst, op=MPI.MAX) / L, comm.allreduce(plastic, op=MPI.MAX)


def difference(a, b):
    d = a.copy()
    d.axpy(-1.0, b)
    return d.norm(PETSc.NormType.INFINITY) / b.norm(PETSc.NormType.INFINITY)


@pytest.mark.parametrize("control", ["mean_pressure", "approach"])
def test_large_hardness_is_the_elastic_problem(coll, control):
    g, h = rough()
    elastic = ContactProblem(g, h, E_STAR, prefix=prefix("el"))
    ref = elastic.solve(mean_pressure=0.005)
    value = 0.005 if control == "mean_pressure" else ref.approach
    st = ContactProblem(g, h, E_STAR, hardness=1e3 * ref.pressure.max()[1],
                        prefix=prefix("big")).solve(**{control: value})
    assert coll.all(st.converged) and st.plastic_fraction == 0.0 and st.plastic_volume == 0.0
    assert coll.max(difference(st.pressure, ref.pressure)) <= 1e-9
    # no cap at all (None, inf) is the same problem
    inf = ContactProblem(g, h, E_STAR, hardness=np.inf, prefix=prefix("inf")).solve(mean_pressure=0.005)
    assert coll.max(difference(inf.pressure, ref.pressure)) <= 1e-14


@pytest.mark.parametrize("preconditioner", ["spectral", "mlmi"])
def test_small_hardness_carries_the_load_on_area_load_over_hardness(coll, preconditioner):
    """H well below the elastic pressures: nearly every contact node is at H, so the plastic
    area <= P / H <= the contact area, the two within the nodes of the elastic rim."""
    g, h = rough()
    n = g.nx * g.ny
    ref = ContactProblem(g, h, E_STAR, prefix=prefix("el")).solve(mean_pressure=0.005)
    hardness = 0.02 * ref.pressure.max()[1]
    load = 0.3 * hardness
    prob = ContactProblem(g, h, E_STAR, hardness=hardness, preconditioner=preconditioner, prefix=prefix("pl"))
    st = prob.solve(mean_pressure=load)
    worst, plastic = recheck(prob, st, hardness)
    assert coll.all(st.converged) and coll.max(st.load_error) <= 1e-9
    assert coll.max(worst) <= 1e-9 and coll.max(st.complementarity_error) <= 1e-10
    assert st.plastic_fraction <= load / hardness * (1 + 1e-12) and load / hardness <= st.contact_fraction * (1 + 1e-12)
    assert (st.contact_fraction - st.plastic_fraction) * n <= 0.05 * st.plastic_fraction * n
    assert 0.25 < st.plastic_fraction <= 0.3
    assert coll.max(abs(st.max_plastic_displacement / plastic - 1)) <= 1e-9 and plastic > 0
    # the volume: -g summed over the nodes at H (times dx dy), recomputed from the gap field
    p, gap = g.rows(st.pressure, readonly=True), g.rows(st.gap, readonly=True)
    volume = g.mpi_comm.allreduce(float(-gap[p >= hardness].sum())) * g.dx * g.dy
    assert coll.max(abs(st.plastic_volume / volume - 1)) <= 1e-12
    # a load at or above H has no solution: refused, naming the key
    coll.raises(ValueError, ["mean_pressure", "hardness"], prob.solve, mean_pressure=hardness)


def test_loading_path_across_the_mean_plane(coll):
    """Load control past delta = mean(h) (only possible with a cap: negative gaps), and back."""
    g, h = rough(32)
    ref = ContactProblem(g, h, E_STAR, prefix=prefix("el")).solve(mean_pressure=0.005)
    hardness = 0.05 * ref.pressure.max()[1]
    prob = ContactProblem(g, h, E_STAR, hardness=hardness, prefix=prefix("path"))
    mean_h = h.sum() / (g.nx * g.ny)
    fractions = []
    for ratio in (0.2, 0.6, 0.95, 0.5):
        st = prob.solve(mean_pressure=ratio * hardness)
        worst, _ = recheck(prob, st, hardness)
        assert coll.all(st.converged) and coll.max(worst) <= 1e-9 and coll.max(st.load_error) <= 1e-9
        fractions.append(st.plastic_fraction)
        if ratio == 0.95:
            assert st.approach > mean_h     # the mean gap is negative: plastic overlap
    assert fractions[0] < fractions[1] < fractions[2] and fractions[3] < fractions[2]


def test_rank_independence(coll):
    kw = dict(tol=1e-12, load_tol=1e-12)
    g, h = rough(64)
    gs, hs = rough(64, comm=PETSc.COMM_SELF)
    hardness = 2e-3
    st = ContactProblem(g, h, E_STAR, hardness=hardness, prefix=prefix("world"), **kw).solve(mean_pressure=5e-4)
    ss = ContactProblem(gs, hs, E_STAR, hardness=hardness, prefix=prefix("self"), **kw).solve(mean_pressure=5e-4)
    pw, ps = g.gather(st.pressure), gs.gather(ss.pressure)
    assert coll.max(np.abs(pw - ps).max() / ps.max()) <= 1e-10
    assert coll.max(abs(st.plastic_fraction - ss.plastic_fraction)) == 0.0 and st.plastic_fraction > 0


# -- a sphere: first yield and the fully plastic limit -----------------------------------------
R, A = 1.0, 1e-2            # sphere radius, Hertz contact radius [m]
DELTA = A * A / R           # Hertz approach for contact radius A
P0 = 2.0 * E_STAR * A / (np.pi * R)    # Hertz peak pressure at DELTA


def sphere(elements=16):
    n = int(round(3.2 * elements))
    n += n % 2
    g = SurfaceGrid(n, n, A / elements, periodic=False)
    return g, surfaces.sphere(g, R)


@pytest.mark.parametrize("ratio, yields", [(1.02, False), (0.98, True)])
def test_sphere_yields_where_the_hertz_peak_reaches_the_hardness(coll, ratio, yields):
    g, h = sphere()
    elastic = ContactProblem(g, h, E_STAR, length_scale=DELTA, prefix=prefix("hz")).solve(approach=DELTA)
    st = ContactProblem(g, h, E_STAR, hardness=ratio * P0, length_scale=DELTA,
                        prefix=prefix("hzh")).solve(approach=DELTA)
    assert coll.all(st.converged)
    assert (st.plastic_fraction > 0) == yields
    if not yields:   # the same solution, to the solver's tolerance (Newton's paths differ)
        assert coll.max(difference(st.pressure, elastic.pressure)) <= 1e-8
    else:
        assert st.force < elastic.force and st.max_plastic_displacement > 0


@pytest.mark.parametrize("control", ["approach", "force"])
def test_sphere_fully_plastic_limit_is_the_truncated_cap(coll, control):
    """H << p0: the contact is the flattened cap, area pi a^2 = 2 pi R delta, force H times it."""
    g, h = sphere(20)
    hardness = 1e-3 * P0
    prob = ContactProblem(g, h, E_STAR, hardness=hardness, length_scale=DELTA, prefix=prefix("cap"))
    area = g.lengths[0] * g.lengths[1]
    truncated = 2 * np.pi * R * DELTA
    st = (prob.solve(approach=DELTA) if control == "approach"
          else prob.solve(force=hardness * truncated))
    worst, _ = recheck(prob, st, hardness)
    assert coll.all(st.converged) and coll.max(worst) <= 1e-8
    carried = st.force / hardness   # the area that carries H
    assert st.plastic_fraction * area <= carried * (1 + 1e-12) and carried <= st.contact_fraction * area * (1 + 1e-12)
    assert coll.max(abs(st.contact_fraction * area / truncated - 1)) <= 0.02
    assert coll.max(abs(st.force / (hardness * truncated) - 1)) <= 0.02
    assert coll.max(abs(st.max_plastic_displacement / DELTA - 1)) <= 0.01   # the apex: -g = delta
    if control == "force":
        coll.raises(ValueError, ["force", "hardness"], prob.solve, force=1.01 * hardness * area)
