"""Scalar results of a contact state, in the reference paper's terms (section 3.1).

``adhesion_ratios``: the adhesive load ratio, |adhesive force| / (|adhesive
force| + compressive force) (1: no compressive pressure; 0.5: no net force;
0: no adhesion), and the adhesive area ratio, the adhesive nodes over the
adhesive plus compressive nodes; both ignore nodes whose adhesive pressure is
below 1 % of the law's peak attraction (the paper's cut-off).
Greenwood's nondimensional sphere variables: alpha* = delta / z0 and
W* = W / (2 pi R w).
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI

CUTOFF = 0.01  #: the paper's cut-off, relative to the peak attraction


def adhesion_ratios(grid, pressure, peak_attraction: float) -> tuple[float, float]:
    """(adhesive load ratio, adhesive area ratio) of a pressure Vec [Pa]; collective."""
    p = grid.rows(pressure, readonly=True)
    adhesive = p < -CUTOFF * peak_attraction
    compressive = p > 0
    sums = np.array([-p[adhesive].sum(), p[compressive].sum(), adhesive.sum(), compressive.sum()], float)
    grid.mpi_comm.Allreduce(MPI.IN_PLACE, sums)
    f_adh, f_comp, n_adh, n_comp = sums
    load = f_adh / (f_adh + f_comp) if f_adh + f_comp > 0 else float("nan")
    area = n_adh / (n_adh + n_comp) if n_adh + n_comp > 0 else float("nan")
    return float(load), float(area)


def greenwood(approach: float, force: float, radius: float, work_of_adhesion: float, z0: float):
    """(alpha*, W*) of a sphere."""
    return approach / z0, force / (2.0 * np.pi * radius * work_of_adhesion)


def _allsum(grid, values) -> np.ndarray:
    out = np.array(values, dtype=float)
    grid.mpi_comm.Allreduce(MPI.IN_PLACE, out)
    return out


def contact_area(grid, pressure) -> float:
    """Area of the nodes in compressive contact (p > 0) [m^2]; collective."""
    n = np.count_nonzero(grid.rows(pressure, readonly=True) > 0)
    return float(_allsum(grid, [n])[0]) * grid.element_area


def mean_gap(grid, gap, pressure=None) -> float:
    """Mean separation of the surfaces [m]: the mean of max(g, 0) over the grid, or over the
    non-contacting nodes (p <= 0) when ``pressure`` is given; collective.

    A node where material was flattened (p = H under a hardness: g < 0, its plastic
    displacement -g) is touching, at separation 0, not at a negative gap; Tamaas reports the
    same mean.  Without a hardness g >= 0 up to the solve's error, and this is mean(g)."""
    g = np.maximum(grid.rows(gap, readonly=True), 0.0)
    keep = np.ones(g.shape, bool) if pressure is None else grid.rows(pressure, readonly=True) <= 0
    total, n = _allsum(grid, [g[keep].sum(), keep.sum()])
    return float(total / n) if n else float("nan")


def forces(grid, pressure) -> tuple[float, float]:
    """(net force, adhesive force) [N]: the sums of all and of the negative pressures times
    the element area; collective."""
    p = grid.rows(pressure, readonly=True)
    net, adh = _allsum(grid, [p.sum(), p[p < 0].sum()]) * grid.element_area
    return float(net), float(adh)


def hysteresis(approach_loading, force_loading, approach_unloading, force_unloading) -> float:
    """Area between the loading and the unloading force-approach curves [J].

    int (F_loading - F_unloading) d delta over the approaches both curves
    cover, each curve linear between its samples (the trapezoid rule on the
    union of both sets of samples, so two piecewise-linear curves give their
    exact area).  Positive when unloading is more tensile than loading (energy
    dissipated by jumps).  Each curve is sorted by approach; its samples must
    be distinct approaches.
    """
    curves = []
    for a, f in ((approach_loading, force_loading), (approach_unloading, force_unloading)):
        a, f = np.asarray(a, float), np.asarray(f, float)
        if a.shape != f.shape or a.ndim != 1 or a.size < 2:
            raise ValueError("each curve needs matching 1-D arrays of >= 2 approaches and forces")
        order = np.argsort(a)
        a, f = a[order], f[order]
        if np.any(np.diff(a) == 0):
            raise ValueError("a curve has repeated approaches (split it into loading and unloading)")
        curves.append((a, f))
    (al, fl), (au, fu) = curves
    lo, hi = max(al[0], au[0]), min(al[-1], au[-1])
    if not lo < hi:
        return 0.0
    x = np.union1d(np.concatenate([al, au]), [lo, hi])
    x = x[(x >= lo) & (x <= hi)]
    diff = np.interp(x, al, fl) - np.interp(x, au, fu)
    return float(np.sum(0.5 * (diff[1:] + diff[:-1]) * np.diff(x)))


def path_hysteresis(path, every: int = 1) -> float:
    """``hysteresis`` of a ``paths.Path`` [J]: its converged loading and unloading points,
    with the located jumps' end points added (jump-on to loading, jump-off to unloading)
    so that a jump is steep between its bracketing approaches, not spread over a step.

    ``every`` = k keeps every k-th of the path's sample approaches (counted over both
    branches together, so branches sampled at the same approaches keep the same ones) and
    all jump end points: ``hysteresis_estimate`` compares k = 1 and 2.  Sample both
    branches at the same approaches: where the two curves coincide their interpolants then
    coincide too, and contribute nothing."""
    pts = [p for p in path.points if p.converged]
    kept = set(sorted({p.approach for p in pts if p.branch in ("loading", "unloading")})[::every])
    curves = {}
    for branch, kind in (("loading", "jump-on"), ("unloading", "jump-off")):
        samples = {p.approach: p.force for p in pts if p.branch == branch and p.approach in kept}
        for j in path.jumps:
            if j.kind == kind:
                samples.setdefault(j.approach_before, j.force_before)
                samples.setdefault(j.approach_after, j.force_after)
        curves[branch] = samples
    if min(len(c) for c in curves.values()) < 2:
        return 0.0
    (al, fl), (au, fu) = (zip(*sorted(c.items())) for c in curves.values())
    return hysteresis(al, fl, au, fu)


def hysteresis_estimate(path) -> tuple[float, float]:
    """(hysteresis [J], its sampling error [J]) of a ``paths.Path``.

    The error is |H(h) - H(2h)| (``path_hysteresis`` with every sample and with every
    other one: the trapezoid rule's error on the smooth parts, and on jumps the sweep did
    not detect, is no larger than that change) plus, for each located jump, half its
    approach bracket times its force change (a jump anywhere inside its bracket: the
    linear interpolation across the bracket is off by at most that).
    """
    fine = path_hysteresis(path)
    coarse = path_hysteresis(path, every=2)
    located = sum(0.5 * abs(j.approach_after - j.approach_before) * abs(j.force_after - j.force_before)
                  for j in path.jumps)
    return fine, abs(fine - coarse) + located


def jump_in_stages(approach, force, contact_fraction, jumps=None):
    """Stages A, B, C of the reference paper's Fig. 9b on a loading path: indices into the
    samples (approach [m] rising, net force [N], contact_fraction).

    A -> B is the largest fall of the net force between consecutive samples while the
    approach grows, among samples A that are already in contact (contact_fraction > 0:
    an asperity's jump-in on a contact that exists, not the whole body's first jump-in
    from separation); with ``jumps`` (the (approach_before, approach_after) [m] of the
    path's located jump-ons) only a fall across one of them counts (a smooth stretch of
    falling force, the adhered sphere's own, is not a jump-in).  C is the first sample
    after B whose force is back to A's (the positive contact has grown to offset the new
    adhesion).  Returns (A, B, C), C None when the force does not come back; None when
    no fall qualifies.
    """
    a, f, c = (np.asarray(x, float) for x in (approach, force, contact_fraction))
    if not (a.shape == f.shape == c.shape and a.ndim == 1):
        raise ValueError("approach, force and contact_fraction must be 1-D arrays of one length")
    if np.any(np.diff(a) <= 0):
        raise ValueError("approach must rise from sample to sample (a loading path)")
    ok = c[:-1] > 0
    if jumps is not None:
        ok &= np.array([any(lo <= before and after <= hi for before, after in jumps)
                        for lo, hi in zip(a[:-1], a[1:])], dtype=bool)
    fall = np.where(ok & (np.diff(f) < 0), f[:-1] - f[1:], 0.0)
    if fall.size == 0 or fall.max() <= 0:
        return None
    i = int(np.argmax(fall))
    back = np.flatnonzero(f[i + 2:] >= f[i])
    return i, i + 1, (i + 2 + int(back[0]) if back.size else None)


def nearest_atom(grid, atoms_xy) -> np.ndarray:
    """Index of the atom nearest each local node in the plane, (ny_loc, nx): each atom's
    footprint is its Voronoi cell on the grid (ties: the lower index)."""
    from scipy.spatial import cKDTree
    x, y = grid.coordinates()
    _, idx = cKDTree(np.asarray(atoms_xy, float)[:, :2]).query(np.column_stack([x.T.ravel(), y.T.ravel()]))
    return idx.reshape(grid.ny_local, grid.nx)


def atom_forces(grid, pressure, owner, n_atoms: int) -> np.ndarray:
    """Force on each atom [N] (compressive positive): the nodal pressure times the element
    area summed over the atom's footprint, the nodes with ``owner`` == its index
    ((ny_loc, nx) ints; < 0 for nodes of no atom).  The same array on every rank."""
    p = grid.rows(pressure, readonly=True).ravel()
    own = np.asarray(owner).ravel()
    keep = own >= 0
    f = np.bincount(own[keep], weights=p[keep], minlength=n_atoms)[:n_atoms]
    return _allsum(grid, f) * grid.element_area


def window_reach(grid, pressure, threshold: float = 0.0) -> tuple[float, float]:
    """How far the pressure-carrying zone (nodes with |p| > ``threshold`` [Pa]) reaches toward
    the edge of a non-periodic window: (reach, edge share); collective.

    reach = the largest max(|2 i / (nx - 1) - 1|, |2 j / (ny - 1) - 1|) over those nodes: the
    fraction of the window's half-width (along x or y, from its centre) the zone reaches, 1 on
    the edge rows and columns; the edge share is the fraction of the edge nodes in the zone.
    An isolated half-space has no pressure outside the window, so a zone that reaches the edge
    is cut there (forces off the isolated contact's).  (0, 0) without any such node.
    """
    carrying = np.abs(grid.rows(pressure, readonly=True)) > threshold
    j, i = np.nonzero(carrying)
    j = j + grid.ys
    nx, ny = grid.nx, grid.ny
    reach = float(np.max(np.maximum(np.abs(2.0 * i / (nx - 1) - 1.0),
                                    np.abs(2.0 * j / (ny - 1) - 1.0)))) if i.size else 0.0
    rows = np.arange(grid.ys, grid.ys + carrying.shape[0])
    edge = carrying[:, [0, -1]].sum() + carrying[(rows == 0) | (rows == ny - 1), 1:-1].sum()
    reach = grid.mpi_comm.allreduce(reach, op=MPI.MAX)
    share = float(_allsum(grid, [edge])[0]) / (2 * nx + 2 * ny - 4)
    return reach, share
