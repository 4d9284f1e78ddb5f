"""Atomic-scale tips as hard-sphere surface profiles (reference paper, section 3.3, Figs. 10-12).

The four tips of Luan & Robbins (2006, Phys. Rev. E 74, 026111), nominally
spheres of radius R, differ only in where their atoms sit:

``bent-commensurate``    an fcc crystal with a (001) face, its layers bent onto
                         the sphere (each atom lifted by the sphere's height
                         R - sqrt(R^2 - rho^2) at its in-plane position), with
                         the counter-surface's nearest-neighbour spacing d;
``bent-incommensurate``  the same with spacing ``ratio`` d (default 0.94 d);
``amorphous``            cut from an amorphous block: random positions at the
                         crystal's number density, relaxed by soft-sphere
                         repulsion until no two atoms are closer than
                         0.97 ``min_spacing`` d (default 0.85 d), keeping those inside
                         the sphere;
``stepped``              cut from the fcc crystal: the atoms whose centres lie
                         inside the sphere, so the (001) terraces end in
                         atomic steps.

Hard-sphere profile (the reference paper's Fig. 10a): every atom is a sphere
of radius r_a (default d / 2, touching neighbours); the tip's surface above
a grid node at in-plane distance s <= r_a from an atom centre at height z_a is
that atom's lowest point there, z_a - sqrt(r_a^2 - s^2), and the profile is
the lowest of these over all atoms -- the first atom the counter-surface
meets.  Nodes that no atom covers (none with the default radius) take the
highest covered height.  The apex sits over the grid's centre node, the
height field is shifted to min h = 0 (assumption 1), and each node records
the atom that forms it (its footprint, for forces per atom:
``metrics.atom_forces``).

Parameters of the reference paper and of Luan & Robbins (lengths in the LJ
diameter sigma): R = 100 sigma; counter-surface nearest-neighbour spacing
d = 2^(1/6) sigma (the LJ pair minimum), incommensurate spacing 0.94 d; LJ
epsilon and r0 = sigma converted to the continuum law by
``physics.interactions.lj_from_atomistic``: z0 = (2/15)^(1/6) r0,
w = 9 epsilon / (2 pi z0^2).  The reference paper does not list the
spacings, the amorphous density or the atom radius: those above are ours.

Every rank builds the same atom list (seeded) and evaluates only its own
rows, so the profile does not depend on the number of ranks.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..grid import GridError, SurfaceGrid
from .surfaces import centre

KINDS = ("bent-commensurate", "bent-incommensurate", "amorphous", "stepped")
LJ_SPACING = 2.0 ** (1.0 / 6.0)   #: nearest-neighbour spacing d of the counter-surface [sigma]


@dataclass
class Tip:
    """Atom centres (n, 3) [m]: in-plane (x, y) about the apex, height z above the apex level."""
    kind: str
    atoms: np.ndarray
    atom_radius: float    #: hard-sphere radius r_a [m]
    radius: float         #: nominal tip radius R [m]
    spacing: float        #: nearest-neighbour spacing of the tip's atoms [m]


def fcc_001(spacing: float, half_width: float, depth: float, offset=(0.0, 0.0)) -> np.ndarray:
    """Atom centres of an fcc crystal with a (001) face at z = 0, growing upwards to ``depth``.

    Layers are square lattices of nearest-neighbour spacing d, a distance
    d / sqrt(2) apart, every other one shifted by (d/2, d/2); one atom of the
    first layer sits at ``offset``.  Covers |x|, |y| <= half_width.
    """
    d = float(spacing)
    n = int(np.ceil(half_width / d)) + 1
    k = np.arange(-n, n + 1)
    ix, iy = np.meshgrid(k, k, indexing="ij")
    layers = []
    for layer in range(int(np.floor(depth / (d / np.sqrt(2.0)))) + 1):
        shift = 0.5 * d * (layer % 2)
        x = ix.ravel() * d + shift + offset[0]
        y = iy.ravel() * d + shift + offset[1]
        keep = (np.abs(x) <= half_width) & (np.abs(y) <= half_width)
        layers.append(np.column_stack([x[keep], y[keep], np.full(keep.sum(), layer * d / np.sqrt(2.0))]))
    return np.concatenate(layers)


def _sphere_height(radius, rho2):
    return radius - np.sqrt(np.maximum(radius * radius - rho2, 0.0))


def _window(grid: SurfaceGrid, atom_radius: float) -> float:
    """Half-width about the centre node that the atoms must cover [m]."""
    lx, ly = grid.lengths
    return 0.5 * max(lx, ly) + 2.0 * atom_radius


def make_tip(kind: str, grid: SurfaceGrid, radius: float, spacing: float, *,
             atom_radius: float | None = None, ratio: float = 0.94, min_spacing: float = 0.85,
             layers: int | None = None, seed: int = 0) -> Tip:
    """One of the four tips (``KINDS``) of radius R [m], counter-surface spacing d [m],
    with atoms over the grid's window in a shell ``layers`` (001) layer spacings deep:
    default 3 for the crystals, 8 for the amorphous tip (its disorder leaves nodes uncovered
    by a shallower shell).  Collective over the grid's communicator (its memory check)."""
    if kind not in KINDS:
        raise ValueError(f"tip kind must be one of {KINDS}, got {kind!r}")
    for name, v in (("radius", radius), ("spacing", spacing)):
        if not (np.isfinite(v) and v > 0):
            raise GridError(f"{name} (m) must be finite and > 0, got {v!r}")
    grid.check_memory()   # collective: a window too big for memory is refused in its own terms
    d = spacing * ratio if kind == "bent-incommensurate" else spacing
    r_a = 0.5 * d if atom_radius is None else float(atom_radius)
    half = _window(grid, r_a)
    if half >= radius:
        raise GridError(f"the grid's window ({2 * half:.3e} m) is wider than the tip (R = {radius:.3e} m)")
    if layers is None:
        layers = 8 if kind == "amorphous" else 3
    shell = layers * d / np.sqrt(2.0) + 1e-9 * d
    if kind.startswith("bent"):
        atoms = fcc_001(d, half, shell)
        atoms[:, 2] += _sphere_height(radius, atoms[:, 0] ** 2 + atoms[:, 1] ** 2)
    else:
        depth = _sphere_height(radius, 2 * half * half) + shell
        if kind == "stepped":
            atoms = fcc_001(d, half, depth)
        else:
            atoms = _amorphous_block(d, half, depth, radius, shell, min_spacing, seed)
        # cut from the block: centres inside the sphere (centre at height R over the apex),
        # within ``shell`` of its surface
        dist = np.sqrt(atoms[:, 0] ** 2 + atoms[:, 1] ** 2 + (atoms[:, 2] - radius) ** 2)
        atoms = atoms[(dist <= radius * (1 + 1e-12)) & (dist >= radius - shell)]
    atoms[:, 2] -= atoms[:, 2].min()
    return Tip(kind, atoms, r_a, float(radius), float(d))


def _amorphous_block(d, half, depth, radius, shell, min_spacing, seed, sweeps=200):
    """Random atoms at the fcc number density sqrt(2)/d^3 in the shell under the sphere,
    pushed apart pairwise until none are closer than 0.97 min_spacing d (the pushes
    approach min_spacing d only asymptotically)."""
    from scipy.spatial import cKDTree
    rng = np.random.default_rng(int(seed))
    lo = np.array([-half, -half, -0.5 * d])
    hi = np.array([half, half, depth])
    n = int(round(np.sqrt(2.0) / d ** 3 * np.prod(hi - lo)))
    pts = lo + (hi - lo) * rng.random((n, 3))
    # only the shell near the sphere's surface matters: drop the rest before relaxing
    dist = np.sqrt(pts[:, 0] ** 2 + pts[:, 1] ** 2 + (pts[:, 2] - radius) ** 2)
    pts = pts[(dist <= radius + 0.5 * d) & (dist >= radius - shell - 1.5 * d)]
    dmin = min_spacing * d
    for _ in range(sweeps):
        pairs = cKDTree(pts).query_pairs(dmin, output_type="ndarray")
        sep = pts[pairs[:, 1]] - pts[pairs[:, 0]]
        length = np.linalg.norm(sep, axis=1)
        if len(pairs) == 0 or length.min() >= 0.97 * dmin:
            break
        push = (0.5 * (dmin - length) / np.maximum(length, 1e-12 * d))[:, None] * sep * 1.05
        move = np.zeros_like(pts)
        np.add.at(move, pairs[:, 0], -push)
        np.add.at(move, pairs[:, 1], push)
        pts += move
    else:
        raise GridError(f"amorphous tip: atoms still closer than {min_spacing} d after {sweeps} sweeps")
    return pts


def profile(grid: SurfaceGrid, tip: Tip) -> tuple[PETSc.Vec, np.ndarray]:
    """(heights Vec with min h = 0 [m], owner (ny_loc, nx) ints: the atom forming each node,
    -1 where no atom covers it) of ``tip`` with its apex over the grid's centre node."""
    xc, yc = centre(grid)
    atoms, r = tip.atoms, tip.atom_radius
    ax, ay, az = atoms[:, 0] + xc, atoms[:, 1] + yc, atoms[:, 2]
    i0 = np.rint(ax / grid.dx).astype(int)
    j0 = np.rint(ay / grid.dy).astype(int)
    mi, mj = int(np.ceil(r / grid.dx)) + 1, int(np.ceil(r / grid.dy)) + 1
    near = (j0 + mj >= grid.ys) & (j0 - mj < grid.ye) & (i0 + mi >= 0) & (i0 - mi < grid.nx)
    idx = np.flatnonzero(near)
    nodes, heights, owners = [], [], []
    for di in range(-mi, mi + 1):
        for dj in range(-mj, mj + 1):
            i, j = i0[idx] + di, j0[idx] + dj
            s2 = (i * grid.dx - ax[idx]) ** 2 + (j * grid.dy - ay[idx]) ** 2
            ok = (s2 <= r * r) & (i >= 0) & (i < grid.nx) & (j >= grid.ys) & (j < grid.ye)
            nodes.append((j[ok] - grid.ys) * grid.nx + i[ok])
            heights.append(az[idx[ok]] - np.sqrt(r * r - s2[ok]))
            owners.append(idx[ok])
    nodes, heights, owners = (np.concatenate(a) for a in (nodes, heights, owners))
    # the lowest candidate per node: sort by (node, height), keep each node's first
    order = np.lexsort((owners, heights, nodes))
    nodes, heights, owners = nodes[order], heights[order], owners[order]
    first = np.ones(nodes.size, bool)
    first[1:] = nodes[1:] != nodes[:-1]
    local = np.full(grid.ny_local * grid.nx, np.nan)
    owner = np.full(local.size, -1, dtype=np.int64)
    local[nodes[first]] = heights[first]
    owner[nodes[first]] = owners[first]
    comm = grid.mpi_comm
    covered = ~np.isnan(local)
    top = comm.allreduce(float(local[covered].max()) if covered.any() else -np.inf, op=MPI.MAX)
    if not np.isfinite(top):
        raise GridError("tip profile: no atom covers any node of the grid")
    local[~covered] = top
    h = grid.create_vec()
    grid.rows(h)[...] = local.reshape(grid.ny_local, grid.nx)
    h.shift(-h.min()[1])
    return h, owner.reshape(grid.ny_local, grid.nx)


def atom_radii(tip: Tip) -> np.ndarray:
    """In-plane distance of each atom from the apex axis [m] (Fig. 11's abscissa)."""
    return np.hypot(tip.atoms[:, 0], tip.atoms[:, 1])
