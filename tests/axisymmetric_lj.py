"""An independent axisymmetric solver for a rigid sphere on an elastic half-space with the
Lennard-Jones law (Greenwood 1997's problem): a test tool, the truth the 3-D solver is
compared with (tests/test_axisymmetric_reference.py, run_scripts/checks/axisymmetric_comparison.py).

It shares no code with contactpetsc: numpy and scipy only.

Model (units are the caller's, consistent: lengths [m], pressures and E* [Pa], w [J/m^2]):

- rigid paraboloid h(r) = r^2 / (2R) against a half-space of reduced modulus E*;
- gap g(r) = h(r) + u(r) - delta (delta the approach, u the surface displacement, positive
  into the half-space under compression);
- pressure (positive compressive) from the gap, the paper's eq. (8) (full LJ curve, Derjaguin):
  p(g) = 8w/(3 z0) ((z0/z)^9 - (z0/z)^3), z = g + z0;
  or eq. (7) (``law="hardwall-lj"``: g >= 0, p = p_LJ(g) for g > 0, any p >= 0 at g = 0;
  with w = 0 this is Signorini's problem, Hertz);
- pressure piecewise constant on annuli [rho_j, rho_j+1], collocation at the annuli's mid
  radii; the displacement of a uniformly loaded disk of radius a (Johnson, Contact
  Mechanics, eq. 3.22; Timoshenko & Goodier) at radius r:
  u = 4 p a/(pi E*) E(r/a) for r <= a, u = 4 p r/(pi E*) [E(a/r) - (1 - a^2/r^2) K(a/r)]
  for r > a (complete elliptic integrals of modulus k), an annulus the difference of two disks.

The full-LJ equilibrium curve (every state, stable or not: the whole S-curve) is traced by
pseudo-arclength continuation, its steps measured in (alpha*, W*, central gap / z0):
Greenwood's central-gap control (the approach an unknown), generalised so that it also passes
the points where the central gap, the approach or the load turn back.  The unknowns are the
ring gaps and the approach; Newton with the dense Jacobian, its systems solved by GMRES
preconditioned with the LU factorization of an earlier Jacobian (``KeptLU``: the same Newton
iterates to the same tolerance, with a factorization every few steps of the curve instead of
several per step).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import lu_factor, lu_solve
from scipy.optimize import minimize_scalar
from scipy.special import ellipe, ellipk


# -- the elastic half-space ---------------------------------------------------------------

def disk_displacement(r, a, e_star):
    """Surface displacement [m] at radius r [m] of a unit pressure on a disk of radius a [m]."""
    r = np.asarray(r, dtype=float)
    out = np.empty(np.broadcast(r, a).shape)
    r, a = np.broadcast_arrays(r, a)
    inside = r <= a
    k2 = np.where(inside, (r / np.where(a > 0, a, 1.0)) ** 2, 0.0)
    out[inside] = 4.0 * a[inside] / (np.pi * e_star) * ellipe(k2[inside])
    o = ~inside
    m = (a[o] / r[o]) ** 2
    out[o] = 4.0 * r[o] / (np.pi * e_star) * (ellipe(m) - (1.0 - m) * ellipk(m))
    return out


def ring_mesh(spacing: float, r_fine: float, r_out: float, growth: float = 1.03) -> np.ndarray:
    """Ring edges [m]: uniform ``spacing`` to ``r_fine``, then growing by ``growth`` per ring
    to ``r_out``."""
    edges = list(np.arange(0.0, r_fine + 0.5 * spacing, spacing))
    h = spacing
    while edges[-1] < r_out:
        h *= growth
        edges.append(edges[-1] + h)
    return np.array(edges)


class Rings:
    """Annuli with edges ``edges`` [m]: collocation radii, areas, influence matrix [m/Pa]."""

    def __init__(self, edges: np.ndarray, e_star: float):
        self.edges = np.asarray(edges, dtype=float)
        self.e_star = float(e_star)
        lo, hi = self.edges[:-1], self.edges[1:]
        self.r = 0.5 * (lo + hi)                       # collocation radii
        self.area = np.pi * (hi ** 2 - lo ** 2)
        r = self.r[:, None]
        self.K = disk_displacement(r, hi[None, :], e_star) - disk_displacement(r, lo[None, :], e_star)
        # the displacement at r = 0: 2 p (b - a) / E* for an annulus a < r < b
        self.K_centre = 2.0 * (hi - lo) / e_star

    def displacement(self, pressure):
        return self.K @ pressure

    def load(self, pressure) -> float:
        return float(self.area @ pressure)

    def load_in_square(self, pressure, half_width: float) -> float:
        """The load [N] of the rings' pressure inside the square |x|, |y| <= half_width [m]
        (the window of a 3-D grid), each ring's part of the square exactly."""
        return float(np.diff(_disk_in_square(self.edges, half_width)) @ pressure)


def _disk_in_square(radius, half):
    """Area of the disk of radius ``radius`` centred in the square of half-width ``half``."""
    rad = np.asarray(radius, dtype=float)
    c = np.clip(half / np.where(rad > 0, rad, 1.0), 0.0, 1.0)
    caps = 4.0 * (rad ** 2 * np.arccos(c) - half * np.sqrt(np.maximum(rad ** 2 - half ** 2, 0.0)))
    # the four caps beyond the sides overlap once the disk reaches the corners (rad > sqrt(2) half):
    # from there the disk holds the whole square (pi rad^2 - caps falls below 4 half^2 there, and
    # taking the smaller of the two under-counted every ring beyond the corners)
    return np.where(rad <= half, np.pi * rad ** 2,
                    np.where(rad >= np.sqrt(2.0) * half, 4 * half ** 2, np.pi * rad ** 2 - caps))


# -- the law ------------------------------------------------------------------------------

@dataclass
class LennardJones:
    """Eq. (2)/(8): p(g) [Pa] = 8w/(3 z0) ((z0/z)^9 - (z0/z)^3), z = g + z0."""
    work_of_adhesion: float
    z0: float

    def pressure(self, g):
        s = self.z0 / (g + self.z0)
        return 8.0 * self.work_of_adhesion / (3.0 * self.z0) * (s ** 9 - s ** 3)

    def derivative(self, g):
        s = self.z0 / (g + self.z0)
        return 8.0 * self.work_of_adhesion / (3.0 * self.z0 ** 2) * (-9.0 * s ** 10 + 3.0 * s ** 4)


# -- the solver ---------------------------------------------------------------------------

class KeptLU:
    """Solves J x = b for Jacobians J that change little from one solve to the next: GMRES
    (right-preconditioned) with the LU factorization of an earlier J as the preconditioner,
    renewed from J itself only where GMRES needs more than ``max_krylov`` iterations.  The
    solution is J's (to ``rtol``), whatever J the factorization came from."""

    def __init__(self, max_krylov: int = 30):
        self.max_krylov = max_krylov
        self.lu = None
        self.factorizations = 0

    def solve(self, matvec, matrix, b, rtol: float):
        """x with ``matvec(x) = b`` to ``rtol`` (relative, 2-norm); ``matrix()`` assembles J
        for a renewal."""
        if self.lu is None or self.lu[0].shape[0] != len(b):
            self._renew(matrix())
        x = self._gmres(matvec, b, rtol)
        if x is None:
            self._renew(matrix())
            x = self._gmres(matvec, b, rtol)
        if x is None:
            raise RuntimeError("KeptLU: GMRES with a fresh factorization did not converge")
        return x

    def _renew(self, matrix):
        self.lu = lu_factor(matrix, check_finite=False)
        self.factorizations += 1

    def _gmres(self, matvec, b, rtol):
        beta = np.linalg.norm(b)
        if beta == 0.0:
            return np.zeros_like(b)
        m = self.max_krylov
        V = np.empty((m + 1, len(b)))
        Z = np.empty((m, len(b)))
        H = np.zeros((m + 1, m))
        V[0] = b / beta
        for k in range(m):
            Z[k] = lu_solve(self.lu, V[k], check_finite=False)
            w = matvec(Z[k])
            for i in range(k + 1):              # modified Gram-Schmidt
                H[i, k] = w @ V[i]
                w = w - H[i, k] * V[i]
            H[k + 1, k] = np.linalg.norm(w)
            e1 = np.zeros(k + 2)
            e1[0] = beta
            y = np.linalg.lstsq(H[:k + 2, :k + 1], e1, rcond=None)[0]
            if np.linalg.norm(e1 - H[:k + 2, :k + 1] @ y) <= rtol * beta or H[k + 1, k] == 0.0:
                return Z[:k + 1].T @ y
            V[k + 1] = w / H[k + 1, k]
        return None


@dataclass
class State:
    approach: float           #: delta [m]
    load: float               #: W [N], positive compressive
    central_gap: float        #: g(0) [m]
    gap: np.ndarray           #: ring gaps [m]
    pressure: np.ndarray      #: ring pressures [Pa]
    newton: int = 0


class AxisymmetricSphere:
    """Rigid sphere R [m] on a half-space E* [Pa] with the LJ law (w [J/m^2], z0 [m]) on ``rings``
    (``Rings``).  ``law``: "lj" (eq. 8) or "hardwall-lj" (eq. 7; w = 0 allowed: Signorini)."""

    def __init__(self, radius: float, e_star: float, work_of_adhesion: float, z0: float, edges,
                 law: str = "lj", tol: float = 1e-11):
        if law not in ("lj", "hardwall-lj"):
            raise ValueError(f"law must be 'lj' or 'hardwall-lj', got {law!r}")
        self.radius, self.e_star, self.z0 = float(radius), float(e_star), float(z0)
        self.w = float(work_of_adhesion)
        self.rings = Rings(edges, e_star)
        self.law_name = law
        self.law = LennardJones(self.w, self.z0)
        self.h = self.rings.r ** 2 / (2.0 * self.radius)
        self.tol = tol * self.z0
        # one kept factorization per kind of system: the gaps at a given approach, and the
        # continuation's bordered system (gaps and approach); linear solves to a relative 1e-8
        # keep Newton's convergence quadratic down to the tolerance
        self._newton_rtol = 1e-8
        self._gap_lu = KeptLU()
        self._arc_lu = KeptLU()

    # full LJ: unknowns the gaps; F(g, delta) = g - h - K p(g) + delta
    def _residual(self, g, delta):
        return g - self.h - self.rings.K @ self.law.pressure(g) + delta

    def _state(self, g, delta, newton=0) -> State:
        p = self.law.pressure(g)
        gc = float(self.rings.K_centre @ p) - delta
        return State(delta, self.rings.load(p), gc, g, p, newton)

    def _damped(self, g, dg):
        """The largest fraction (<= 1) of the step dg keeping z = g + z0 above 0.3 of its value."""
        z = g + self.z0
        shrink = dg < -0.7 * z
        return 1.0 if not shrink.any() else float(np.min(-0.7 * z[shrink] / dg[shrink]))

    def solve_approach(self, delta: float, start: State | None = None, max_it: int = 60) -> State:
        """The state at approach ``delta`` [m] by Newton from ``start`` (default: undeformed)."""
        if self.law_name == "hardwall-lj":
            return self._solve_hard_wall(delta, start, max_it)
        g = (self.h - delta if start is None else start.gap.copy())
        g = np.maximum(g, -0.5 * self.z0)
        n = len(g)
        K = self.rings.K
        for it in range(max_it):
            F = self._residual(g, delta)
            if np.max(np.abs(F)) < self.tol:
                return self._state(g, delta, it)
            dp = self.law.derivative(g)
            dg = -self._gap_lu.solve(lambda v: v - K @ (dp * v), lambda: np.eye(n) - K * dp[None, :], F,
                                     rtol=self._newton_rtol)
            g = g + self._damped(g, dg) * dg
        raise RuntimeError(f"axisymmetric Newton did not converge at approach {delta:g} m")

    def _solve_hard_wall(self, delta, start, max_it):
        """Eq. (7) by semismooth Newton on min(g, p - p_LJ(g)) = 0 (g = h + K p - delta)."""
        K = self.rings.K
        p = np.zeros_like(self.h) if start is None else start.pressure.copy()
        n = len(p)
        for it in range(max_it):
            g = self.h + K @ p - delta
            pa = np.where(g > 0, self.law.pressure(np.maximum(g, 0.0)), 0.0) if self.w > 0 else 0 * g
            dpa = np.where(g > 0, self.law.derivative(np.maximum(g, 0.0)), 0.0) if self.w > 0 else 0 * g
            q = p - pa
            contact = g <= q
            F = np.where(contact, g, q)
            if np.max(np.abs(np.where(contact, g, q * np.max(np.abs(K))))) < self.tol:
                return State(delta, self.rings.load(p), float(self.rings.K_centre @ p) - delta, g, p, it)
            J = np.where(contact[:, None], K, np.eye(n) - dpa[:, None] * K)
            p = p - np.linalg.solve(J, F)
        raise RuntimeError(f"axisymmetric hard-wall Newton did not converge at approach {delta:g} m")

    # -- the whole curve ------------------------------------------------------------------
    def _observables(self, g, delta):
        """(delta / z0, W / (2 pi R w), g(0) / z0) and their gradient [3 x (n+1)]."""
        p, dp = self.law.pressure(g), self.law.derivative(g)
        ws = 2.0 * np.pi * self.radius * self.w
        phi = np.array([delta / self.z0, self.rings.area @ p / ws, (self.rings.K_centre @ p - delta) / self.z0])
        D = np.zeros((3, len(g) + 1))
        D[0, -1] = 1.0 / self.z0
        D[1, :-1] = self.rings.area * dp / ws
        D[2, :-1] = self.rings.K_centre * dp / self.z0
        D[2, -1] = -1.0 / self.z0
        return phi, D

    def _jacobian(self, g):
        n = len(g)
        J = np.empty((n, n + 1))
        J[:, :n] = np.eye(n) - self.rings.K * self.law.derivative(g)[None, :]
        J[:, n] = 1.0
        return J

    def _bordered_matvec(self, dp, row):
        """v -> [J v_g + v_delta, row . v]: the continuation's Jacobian (gaps, approach) times v."""
        return lambda v: np.append(v[:-1] - self.rings.K @ (dp * v[:-1]) + v[-1], row @ v)

    def _tangent(self, x, t_prev):
        """Unit tangent (in the observables) of the curve at x, oriented along t_prev:
        J t = 0, (D t_prev).(D t) = 1; and the observables (phi, D) at x."""
        g = x[:-1]
        phi, D = self._observables(g, x[-1])
        row = (D @ t_prev) @ D
        dp = self.law.derivative(g)
        rhs = np.zeros(len(x))
        rhs[-1] = 1.0
        # the tangent only predicts and orients the next step: a modest tolerance
        t = self._arc_lu.solve(self._bordered_matvec(dp, row), lambda: np.vstack([self._jacobian(g), row]), rhs,
                               rtol=1e-6)
        return t / np.linalg.norm(D @ t), phi, D

    def trace(self, start_approach: float, end_approach: float, step: float = 0.05,
              max_step: float | None = None, max_points: int = 20000) -> list[State]:
        """Every equilibrium (full LJ) from ``start_approach`` [m] (far from contact) until
        the approach exceeds ``end_approach`` [m], by pseudo-arclength continuation with
        steps ``step`` (in the dimensionless (alpha*, W*, g(0)/z0) plane; adapted, at most
        ``max_step``)."""
        if self.law_name != "lj" or self.w <= 0:
            raise ValueError("trace: the whole curve is for the full LJ law (eq. 8) with w > 0")
        max_step = max_step or 4 * step
        st = self.solve_approach(start_approach)
        states = [st]
        x = np.append(st.gap, st.approach)
        n = len(st.gap)
        forward = np.zeros(n + 1)
        forward[-1] = 1.0
        t, phi0, D = self._tangent(x, forward)
        s = step
        while states[-1].approach < end_approach and len(states) < max_points:
            Dt = D @ t
            while True:
                y = x + s * t
                y[:-1] = np.maximum(y[:-1], -0.5 * self.z0)
                ok, it = False, 0
                for it in range(30):
                    F = self._residual(y[:-1], y[-1])
                    phi, Dy = self._observables(y[:-1], y[-1])
                    c = Dt @ (phi - phi0) - s
                    if max(np.max(np.abs(F)), abs(c) * self.z0) < self.tol:
                        ok = True
                        break
                    row = Dt @ Dy
                    dy = -self._arc_lu.solve(self._bordered_matvec(self.law.derivative(y[:-1]), row),
                                             lambda: np.vstack([self._jacobian(y[:-1]), row]), np.append(F, c),
                                             rtol=self._newton_rtol)
                    y = y + self._damped(y[:-1], dy[:-1]) * dy
                if ok:
                    t_new, phi_new, D_new = self._tangent(y, t)
                    # a turn sharper than ~18 degrees in one step may have jumped to another
                    # part of the curve (back across a tight fold): shorter steps
                    if Dt @ (D_new @ t_new) > 0.95 and np.linalg.norm(phi_new - phi0) < 2.0 * s:
                        break
                s *= 0.5
                if s < 1e-8:
                    raise RuntimeError(f"continuation stalled at approach {x[-1]:g} m")
            x, t, phi0, D = y, t_new, phi_new, D_new
            states.append(self._state(y[:-1], y[-1], it))
            s = min(max_step, s * 1.5) if it <= 4 else (s if it <= 8 else 0.7 * s)
        return states


    def pull_off(self, states, xatol: float = 1e-7) -> State:
        """The most tensile state of a traced curve, refined in approach (Brent, bounded by
        the sampled minimum's neighbours, each solve warm-started from the sampled minimum).

        This is the load-controlled pull-off, and also the most tensile state that
        displacement control keeps (the 3-D code's ``pull_off_force``): on the adhered branch
        dW/d delta = 0 there, and that branch stays stable under displacement control past it,
        down to its fold in delta (the jump-off)."""
        loads = np.array([st.load for st in states])
        k = int(np.argmin(loads))
        if k == 0 or k == len(states) - 1:
            raise ValueError("pull_off: the most tensile state is at an end of the traced curve")
        lo, hi = sorted((states[k - 1].approach, states[k + 1].approach))
        res = minimize_scalar(lambda d: self.solve_approach(d, start=states[k]).load, bounds=(lo, hi),
                              method="bounded", options={"xatol": xatol * self.z0})
        return self.solve_approach(float(res.x), start=states[k])


    def on_branch(self, states, approach: float, load_of, target: float) -> State | None:
        """The state at ``approach`` [m] on the piece of the traced curve (monotone in the
        approach) whose load ``load_of(state)`` [N], interpolated there, is nearest ``target``
        [N]: Newton from that piece's traced state nearest in approach.  None where no piece
        spans the approach."""
        alpha = np.array([st.approach for st in states])
        loads = np.array([load_of(st) for st in states])
        best = None
        for i, j in branches(alpha):
            a_b, W_b = alpha[i:j + 1], loads[i:j + 1]
            if not a_b.min() <= approach <= a_b.max():
                continue
            order = np.argsort(a_b)
            d = abs(np.interp(approach, a_b[order], W_b[order]) - target)
            if best is None or d < best[0]:
                best = (d, i + int(np.argmin(np.abs(a_b - approach))))
        return None if best is None else self.solve_approach(approach, start=states[best[1]])


# -- what the curve says --------------------------------------------------------------

def branches(alpha):
    """Index ranges (i, j) of the pieces of a curve monotone in alpha (cut where it turns)."""
    turns = np.nonzero(np.diff(np.sign(np.diff(alpha))))[0] + 1
    cuts = [0, *turns.tolist(), len(alpha) - 1]
    return list(zip(cuts[:-1], cuts[1:]))


def jkr_contact_radius(radius, work_of_adhesion, e_star, approach):
    """JKR's contact radius a [m] at approach delta [m]: a^2/R - sqrt(2 pi a w/E*) = delta
    (the adhered branch; a scale for the mesh only)."""
    a = (2 * np.pi * work_of_adhesion * radius ** 2 / e_star) ** (1 / 3)   # delta = 0
    for _ in range(100):
        f = a * a / radius - np.sqrt(2 * np.pi * a * work_of_adhesion / e_star) - approach
        df = 2 * a / radius - 0.5 * np.sqrt(2 * np.pi * work_of_adhesion / (e_star * a))
        a = max(0.5 * a, a - f / df)
    return a


def default_mesh(radius, work_of_adhesion, e_star, z0, max_approach, refine: float = 1.0,
                 r_out_factor: float = 60.0):
    """Ring edges for a curve up to ``max_approach`` [m]: uniform spacing, the smaller of a
    eighth of the cohesive length 0.75 E* z0^2/w and a sixteenth of sqrt(2 R z0), divided by ``refine``,
    over 1.3 times JKR's contact radius at that approach plus twice sqrt(2 R z0) (the
    adhesive zone at small Tabor parameters); then growing by 4 %/``refine`` per ring to
    r_out = r_out_factor sqrt(2 R z0) (the tail beyond it carries a load of about
    (4/3) 2 pi R w / r_out_factor^4 by Derjaguin's estimate)."""
    l_coh = 0.75 * e_star * z0 ** 2 / work_of_adhesion
    l_geo = np.sqrt(2 * radius * z0)
    spacing = min(l_coh / 8.0, l_geo / 16.0) / refine
    r_fine = 1.3 * jkr_contact_radius(radius, work_of_adhesion, e_star, max_approach) + 2 * l_geo
    return ring_mesh(spacing, r_fine, r_out_factor * l_geo, growth=1.0 + 0.04 / refine)
