"""The adhesive traction field a(g) [Pa] on a grid, from the gap field g [m].

Two discretisations of an interaction law (``interactions.py``):

* nodal: a_i = p(g_i), the law sampled at the node (reference paper, eq. 2);
* element-integrated (the paper's Fig. 3 and the integral under it): each
  node's element is the square of side dx x dy around it; along each of the
  four non-diagonal directions the gap is interpolated linearly to the
  neighbour, and a_i is the mean of the exact averages of p over the four
  half-segments from the node to the mid-points,

      a_i = 1/4 sum_j m(g_i, (g_i + g_j)/2),
      m(g_a, g_b) = (Phi(g_a) - Phi(g_b)) / (g_b - g_a).

  Every segment between two nodes is split between them, so the total force
  is the integral of p along the piecewise-linear gap profile, whatever
  the position of the nodes relative to the adhesive zone.

Hard-wall laws only act for g >= 0 (eq. 7), where every converged state's gaps lie; below
the wall, where only iterates go, a law is continued by its Taylor polynomial at g = 0 (a
slope that jumped there, from 0 to the hard-wall LJ law's -6 p_s / z0, made the VI Newton's
direction no descent direction wherever an inexact Krylov step moved contact nodes across it:
docs/performance.md, "The adhesive sphere's states").
A singular law declares a ``safe_gap``: the full Lennard-Jones curve (eq. 8)
is singular at z = g + z0 = 0, and below z = z_safe (0.5 z0, where the law's pressure is already 504 times the
adhesive pressure scale 8w/(3 z0)) it is continued linearly, so that no
Newton iterate produces NaN; a converged state that reaches that range is
flagged by ``beyond_safe_range``.
"""
from __future__ import annotations

import numpy as np

from ..grid import SurfaceGrid
from .interactions import InteractionLaw


#: nodes per block of a nodal evaluation into a caller's array: the law's temporaries (three or
#: four arrays in its products) are a block's, not the grid's, and stay in cache
BLOCK = 1 << 15


def node_blocks(size: int):
    """Slices of ``BLOCK`` nodes that cover ``size`` nodes (of a flattened array)."""
    return (slice(start, start + BLOCK) for start in range(0, size, BLOCK))


def blockwise(fn, g: np.ndarray, out: np.ndarray) -> np.ndarray:
    """out = fn(g), node by node, evaluated a block of ``BLOCK`` nodes at a time (``fn`` maps a
    1-D array of gaps to its values); ``out`` (the shape of ``g``) returned.  An ``out`` that is
    not contiguous (whose flat view would be a copy) is filled whole."""
    if not out.flags.c_contiguous:
        out[...] = fn(g.reshape(-1)).reshape(g.shape)
        return out
    flat_g, flat_out = g.reshape(-1), out.reshape(-1)
    for block in node_blocks(flat_g.size):
        flat_out[block] = fn(flat_g[block])
    return out


class AdhesiveTraction:
    """a(g) and its linearisation on the local rows of ``grid``.

    Parameters
    ----------
    law : InteractionLaw
    grid : SurfaceGrid
    element_integration : bool
        Nodal sampling (False) or the four-neighbour element integration (True).
    """

    def __init__(self, law: InteractionLaw, grid: SurfaceGrid, element_integration: bool = False):
        self.law, self.grid = law, grid
        self.element_integration = bool(element_integration)
        self.g_safe = None if law.hard_wall else law.safe_gap
        # where the law is continued by its Taylor polynomial: a singular law's safe gap, a
        # hard wall's g = 0 (the law C1 through the wall)
        self._g_cont = 0.0 if law.hard_wall else self.g_safe
        if self._g_cont is not None:
            self._p_cont = float(law.pressure(self._g_cont))
            self._d_cont = float(law.derivative(self._g_cont))
            self._e_cont = float(law.energy(self._g_cont))
        nx = grid.nx
        self._lo, self._hi = np.empty(nx), np.empty(nx)
        self.diagonal = None      # d a_i / d g_i after ``linearise``
        self._coupling = None     # (dx-, dx+, dy-, dy+) d a_i / d g_j

    # -- pointwise law with the guards above -------------------------------------
    def _continued(self, g, values, order: int):
        """``values`` of the law at max(g, g_c), below g_c (``_g_cont``) replaced by the law's Taylor
        polynomial there in t = g - g_c: pressure (order 1: p + p' t), energy (order 2: the
        integral of the former, Phi - t (p + p' t / 2)), derivative (order 0: p').  Only the
        nodes below are touched: a full-grid np.where cost as much as the law itself."""
        g = np.asarray(g)
        below = g < self._g_cont
        if not below.any():
            return values
        values = np.asarray(values)
        if order == 0:
            values[below] = self._d_cont
        else:
            t = g[below] - self._g_cont
            values[below] = (self._p_cont + self._d_cont * t if order == 1
                             else self._e_cont - t * (self._p_cont + 0.5 * self._d_cont * t))
        return values[()]

    def _pressure(self, g):
        if self._g_cont is None:
            return self.law.pressure(g)
        return self._continued(g, self.law.pressure(np.maximum(g, self._g_cont)), 1)

    def nodal_derivative(self, g, out: np.ndarray | None = None):
        """da/dg [Pa/m] of the guarded pointwise law at the gaps ``g`` [m] (below a hard wall or a
        singular law's safe gap, the slope there); into ``out`` when given (a block at a time)."""
        if out is not None:
            return blockwise(self.nodal_derivative, g, out)
        if self._g_cont is None:
            return self.law.derivative(g)
        return self._continued(g, self.law.derivative(np.maximum(g, self._g_cont)), 0)

    def _energy(self, g):
        if self._g_cont is None:
            return self.law.energy(g)
        return self._continued(g, self.law.energy(np.maximum(g, self._g_cont)), 2)

    def _segment(self, a, b):
        """(m, dm/da, dm/db) of the mean pressure along a linear profile from gap a to b."""
        d = b - a
        close = np.abs(d) <= 1e-6 * self.law.length_scale()
        safe_d = np.where(close, 1.0, d)
        m = np.where(close, self._pressure(0.5 * (a + b)), (self._energy(a) - self._energy(b)) / safe_d)
        half = 0.5 * self.nodal_derivative(0.5 * (a + b))
        dma = np.where(close, half, (m - self._pressure(a)) / safe_d)
        dmb = np.where(close, half, (self._pressure(b) - m) / safe_d)
        return m, dma, dmb

    def _neighbours(self, g):
        """Gaps of the four neighbours (x-, x+, y-, y+) as (ny_loc, nx) arrays; the edge
        of an isolated grid repeats the edge node (no segment beyond the window)."""
        grid = self.grid
        lo, hi = grid.halo_rows(g, self._lo, self._hi, edge="repeat")
        if grid.periodic:
            xm, xp = np.roll(g, 1, axis=1), np.roll(g, -1, axis=1)
        else:
            xm = np.concatenate([g[:, :1], g[:, :-1]], axis=1)
            xp = np.concatenate([g[:, 1:], g[:, -1:]], axis=1)
        ym = np.concatenate([lo[None, :], g[:-1]], axis=0)
        yp = np.concatenate([g[1:], hi[None, :]], axis=0)
        return xm, xp, ym, yp

    # -- public ----------------------------------------------------------------------
    def pressure(self, g: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """a(g) [Pa] on local rows (collective with element integration); into ``out`` when
        given (nodal: a block at a time, ``blockwise``)."""
        if not self.element_integration:
            if out is not None:
                return blockwise(self._pressure, g, out)
            a = self._pressure(g)
        else:
            a = 0.25 * sum(self._segment(g, 0.5 * (g + gj))[0] for gj in self._neighbours(g))
        if out is None:
            return a
        out[...] = a
        return out

    def linearise(self, g: np.ndarray) -> None:
        """Store da/dg at ``g`` for ``apply_derivative`` (collective with element integration)."""
        if not self.element_integration:
            self.diagonal = self.nodal_derivative(g)
            self._coupling = None
            return
        diag = np.zeros_like(g)
        coupling = []
        for gj in self._neighbours(g):
            _, dma, dmb = self._segment(g, 0.5 * (g + gj))
            diag += 0.25 * (dma + 0.5 * dmb)
            coupling.append(0.125 * dmb)
        self.diagonal, self._coupling = diag, coupling

    def apply_derivative(self, dg: np.ndarray, out: np.ndarray) -> np.ndarray:
        """out = (da/dg) dg, the linearised traction change [Pa] (collective with element integration)."""
        np.multiply(self.diagonal, dg, out=out)
        if self._coupling is not None:
            for c, dgj in zip(self._coupling, self._neighbours(dg)):
                out += c * dgj
        return out

    def energy(self, g: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
        """Interaction energy per unit area Phi(g) [J/m^2] at the nodes (nodal rule); into
        ``out`` when given (a block at a time)."""
        return self._energy(g) if out is None else blockwise(self._energy, g, out)

    @property
    def invertible(self) -> bool:
        """True when ``repulsive_gap`` applies: the nodal rule of the full LJ curve."""
        return self.g_safe is not None and not self.element_integration

    def repulsive_gap(self, a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(G(a), G'(a)): the inverse of the nodal law on its repulsive branch (a >= 0) [m, m/Pa].

        With t = (z0/z)^3 the law (eq. 8) reads p = p_s (t^3 - t), a cubic in t
        that is increasing and convex for t >= 1 (z <= z0): Newton from
        t = 1 + (a/p_s)^(1/3), which lies above the root, converges monotonically.
        Below z_safe the linear continuation is inverted exactly.
        """
        law = self.law
        r = np.maximum(a, 0.0) / law.p_scale
        t = 1.0 + np.cbrt(r)
        for _ in range(60):
            dt = (t * (t * t - 1.0) - r) / (3.0 * t * t - 1.0)
            t -= dt
            if np.all(np.abs(dt) <= 1e-15 * t):
                break
        gap = law.z0 / np.cbrt(t) - law.z0
        gap = np.where(a > self._p_cont, self.g_safe + (a - self._p_cont) / self._d_cont, gap)
        slope = 1.0 / self.nodal_derivative(gap)
        # a < 0 has no repulsive preimage: continue G linearly (C1 at a = 0), so that a
        # node in the wall with an attractive trial pressure still gets a gap-form row
        # whose only root is on the branch
        d0 = -6.0 * law.p_scale / law.z0
        return np.where(a < 0, a / d0, gap), np.where(a < 0, 1.0 / d0, slope)

    def beyond_safe_range(self, g: np.ndarray) -> bool:
        """True where the full LJ curve was continued linearly (local; reduce across ranks)."""
        return bool(self.g_safe is not None and np.any(g < self.g_safe))

