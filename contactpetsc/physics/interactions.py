"""Interaction laws: surface traction as a function of the gap, p(g) [Pa], g [m].

Sign convention of the reference paper: p > 0 is compressive (repulsive),
p < 0 adhesive; g = h + v - delta is the continuum gap (eq. 5) and
z = g + z0 the atomic separation (eq. 6).  Every law gives the pressure, its
derivative dp/dg (for the Newton Jacobian) and the interaction energy per
unit area Phi(g) [J/m^2] with p = -dPhi/dg and Phi -> 0 as g -> infinity.
``hard_wall`` says whether g >= 0 is a constraint (contact pressure then
comes from the complementarity problem, eq. 7a) or not (eq. 8).
``repulsive_branch`` says whether a law without a wall is repulsive exactly
below g = 0 (z < z0) and invertible there, the contact of eq. 8 that the
paper's relaxation relaxes apart (``relaxation_laws``).

Laws
----
``none``         Signorini (eq. 4): hard wall, no adhesion.
``hardwall-lj``  eq. (7): hard wall, Lennard-Jones attraction for g > 0,
                 p = p_LJ(g + z0), zero at contact, Phi(0) = -w.
``lj``           eq. (8): the full Lennard-Jones curve (Derjaguin
                 approximation, eq. 2), p = 8w/(3 z0) ((z0/z)^9 - (z0/z)^3)
                 for all g > -z0; Phi(z) = (w/3)((z0/z)^8 - 4 (z0/z)^2), so
                 Phi(z0) = -w.  Peak attraction 16 w / (9 sqrt(3) z0) at
                 z = 3^(1/6) z0 (the paper's text prints (1/3)^(1/6) z0, which
                 lies in the repulsive range: a typo).
``exponential``  hard wall, p = -(w/rho) exp(-g/rho), Phi = -w exp(-g/rho).
``dugdale``      Maugis-Dugdale: hard wall, p = -sigma0 for 0 < g < w/sigma0.

Each law declares its parameters (``Parameter``: name, unit, accepted range, meaning) and is
registered by name (``register_law``); the scene schema, its docs and ``make_law`` read the
registry, so a new law is one class here (docs/formulation.md, "Interaction laws").
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: an open interval (0, inf): (low, high, low included?, high included?)
POSITIVE = (0.0, math.inf, False, False)


class Parameter(NamedTuple):
    """A law parameter as a scene gives it: ``interaction.<name>`` [unit] in ``range``."""
    name: str
    unit: str
    doc: str
    range: tuple = POSITIVE


#: the parameter every adhesive law takes
WORK_OF_ADHESION = Parameter("work_of_adhesion", "J/m^2", "work of adhesion w")


class InteractionLaw:
    """Base class.  ``work_of_adhesion`` w [J/m^2]; subclasses define the rest."""

    name = "base"
    hard_wall = True
    work_of_adhesion = 0.0
    #: the constructor's keyword arguments, work_of_adhesion first (``make_law``, the scene schema)
    parameters: tuple = ()
    #: one line for the docs (docs/scenes.md lists the registered laws)
    summary = ""
    #: a singular law's gap [m] below which the traction is continued linearly (physics.traction)
    safe_gap = None
    #: no wall, p > 0 exactly where g < 0 and p(g) invertible there (the cubic solution f of
    #: eq. 8): the paper's relaxation applies, with target gap f(p) at positive-pressure nodes
    repulsive_branch = False
    #: the pressure continuous in the gap off the wall: a state's force then follows smooth
    #: branches between folds (a step law's moves in a sawtooth at the grid's scale, which its
    #: zero derivative does not see)
    smooth = True

    def pressure(self, gap):
        raise NotImplementedError

    def derivative(self, gap):
        """dp/dg [Pa/m]."""
        raise NotImplementedError

    def energy(self, gap):
        """Phi(g) [J/m^2], p = -dPhi/dg."""
        raise NotImplementedError

    @property
    def adhesive(self) -> bool:
        return self.work_of_adhesion > 0

    def segment_mean_pressure(self, gap_a, gap_b):
        """Mean pressure along a linear gap profile from gap_a to gap_b [Pa].

        The reference paper's element integration (Fig. 3 and the integral
        below it): int p dx / (x_b - x_a) = (Phi(g_a) - Phi(g_b)) / (g_b - g_a),
        the pointwise pressure where the two gaps coincide.
        """
        a = np.asarray(gap_a, dtype=float)
        b = np.asarray(gap_b, dtype=float)
        d = b - a
        close = np.abs(d) <= 1e-6 * self.length_scale()
        with np.errstate(divide="ignore", invalid="ignore"):
            secant = (self.energy(a) - self.energy(b)) / np.where(close, 1.0, d)
        # where the gaps nearly coincide: midpoint rule, exact to O(d^2)
        return np.where(close, self.pressure(0.5 * (a + b)), secant)

    def length_scale(self) -> float:
        """The law's range [m] (z0, rho or the Dugdale range)."""
        return 1.0

    def __repr__(self):
        return f"{type(self).__name__}({self.name})"


class NoAdhesion(InteractionLaw):
    """Signorini contact, eq. (4): hard wall, zero traction at any positive gap."""

    name = "none"
    summary = "Signorini contact (eq. 4): hard wall, no adhesion"

    def __init__(self, work_of_adhesion: float = 0.0):
        # a work of adhesion with a law that has none would be silently ignored
        if work_of_adhesion != 0:
            raise ValueError(f"work_of_adhesion = {work_of_adhesion!r} J/m^2 with law 'none' (no adhesion): "
                             f"accepted value 0; choose {', '.join(adhesive_laws())} for adhesion")

    def pressure(self, gap):
        return np.zeros_like(np.asarray(gap, dtype=float))

    derivative = pressure
    energy = pressure


def check_parameters(law, **values) -> None:
    """ValueError naming the parameter, its value and its accepted range (the law's ``parameters``)."""
    for p in type(law).parameters:
        value = values[p.name]
        lo, hi, lo_in, hi_in = p.range
        try:
            ok = bool(np.isfinite(value) and (value >= lo if lo_in else value > lo)
                      and (value <= hi if hi_in else value < hi))
        except TypeError:
            ok = False
        if not ok:
            bounds = f"{'[' if lo_in else '('}{lo:g}, {hi:g}{']' if hi_in else ')'}"
            raise ValueError(f"{p.name} = {value!r}: accepted range {bounds} {p.unit} (finite)")


SAFE_SEPARATION = 0.5  #: z_safe / z0 for the full Lennard-Jones curve (physics.traction)


class LennardJones(InteractionLaw):
    """Full Lennard-Jones curve, eq. (8): no hard wall, defined for g > -z0."""

    name = "lj"
    hard_wall = False
    repulsive_branch = True
    parameters = (WORK_OF_ADHESION, Parameter("z0", "m", "equilibrium separation"))
    summary = "the full Lennard-Jones curve (eq. 8), no hard wall"

    def __init__(self, work_of_adhesion: float, z0: float):
        check_parameters(self, work_of_adhesion=work_of_adhesion, z0=z0)
        self.work_of_adhesion, self.z0 = float(work_of_adhesion), float(z0)
        self.p_scale = 8.0 * self.work_of_adhesion / (3.0 * self.z0)

    def length_scale(self) -> float:
        return self.z0

    @property
    def safe_gap(self) -> float:
        """g at z = SAFE_SEPARATION z0 [m]: below it the singular curve is continued linearly."""
        return (SAFE_SEPARATION - 1.0) * self.z0

    @property
    def peak_attraction(self) -> float:
        """Largest adhesive stress 16 w / (9 sqrt(3) z0) [Pa], at z = 3^(1/6) z0."""
        return 16.0 * self.work_of_adhesion / (9.0 * np.sqrt(3.0) * self.z0)

    def _s(self, gap) -> np.ndarray:
        """s = z0 / (g + z0), a new array (0-d for a scalar gap)."""
        s = np.add(gap, self.z0, out=np.empty(np.shape(gap)))
        # min with an initial value: a rank's local rows may be empty; a NaN makes the min NaN,
        # and the nodes beside it are then checked one by one (NaN itself passes, as it did)
        smallest = np.min(s, initial=np.inf)
        if smallest <= 0 or (np.isnan(smallest) and np.any(s <= 0)):
            raise FloatingPointError(f"{self.name}: atomic separation z = g + z0 <= 0 (min {np.nanmin(s):.3e} m)")
        return np.divide(self.z0, s, out=s)

    # the powers of s as products, in place: np.power's pow() and a fresh array per operation
    # cost several times the products, and the descent evaluates the law at every energy and
    # Hessian (a scalar gap gives a scalar: ``[()]``)
    def pressure(self, gap):
        """p_s (s^9 - s^3) = p_s s^3 (s^6 - 1) [Pa], eq. (8)."""
        s = self._s(gap)
        s3 = s * s
        s3 *= s
        np.multiply(s3, s3, out=s)
        s -= 1.0
        s *= s3
        s *= self.p_scale
        return s[()]

    def derivative(self, gap):
        """dp/dg = (p_s / z0) (-9 s^10 + 3 s^4) = (3 p_s / z0) s^4 (1 - 3 s^6) [Pa/m]."""
        s = self._s(gap)
        s *= s
        s4 = s * s
        s *= s4
        s *= -3.0
        s += 1.0
        s *= s4
        s *= 3.0 * self.p_scale / self.z0
        return s[()]

    def energy(self, gap):
        """Phi = (w / 3) (s^8 - 4 s^2) = (w / 3) s^2 (s^6 - 4) [J/m^2]."""
        s = self._s(gap)
        s *= s
        s6 = s * s
        s6 *= s
        s6 -= 4.0
        s *= s6
        s *= self.work_of_adhesion / 3.0
        return s[()]


class HardWallLennardJones(LennardJones):
    """Eq. (7): hard wall at g = 0, Lennard-Jones attraction p_LJ(g + z0) for g > 0."""

    name = "hardwall-lj"
    hard_wall = True
    repulsive_branch = False   # the wall carries the contact
    summary = "hard wall and Lennard-Jones attraction (eq. 7)"

    def _g(self, gap):
        return np.maximum(np.asarray(gap, dtype=float), 0.0)

    def pressure(self, gap):
        return super().pressure(self._g(gap))

    def derivative(self, gap):
        return super().derivative(self._g(gap))

    def energy(self, gap):
        return super().energy(self._g(gap))


class Exponential(InteractionLaw):
    """Hard wall and exponential attraction p = -(w/rho) exp(-g/rho)."""

    name = "exponential"
    parameters = (WORK_OF_ADHESION, Parameter("rho", "m", "decay length"))
    summary = "hard wall and exponential attraction (for comparison)"

    def __init__(self, work_of_adhesion: float, rho: float):
        check_parameters(self, work_of_adhesion=work_of_adhesion, rho=rho)
        self.work_of_adhesion, self.rho = float(work_of_adhesion), float(rho)

    def length_scale(self) -> float:
        return self.rho

    @property
    def peak_attraction(self) -> float:
        """w / rho [Pa], at contact."""
        return self.work_of_adhesion / self.rho

    def energy(self, gap):
        g = np.maximum(np.asarray(gap, dtype=float), 0.0)
        return -self.work_of_adhesion * np.exp(-g / self.rho)

    def pressure(self, gap):
        return self.energy(gap) / self.rho

    def derivative(self, gap):
        return -self.energy(gap) / self.rho**2


class Dugdale(InteractionLaw):
    """Maugis-Dugdale: hard wall and constant attraction sigma0 up to the range w / sigma0."""

    name = "dugdale"
    parameters = (WORK_OF_ADHESION, Parameter("sigma0", "Pa", "Dugdale stress"))
    summary = "Maugis-Dugdale: hard wall and constant attraction (for comparison)"
    smooth = False

    def __init__(self, work_of_adhesion: float, sigma0: float):
        check_parameters(self, work_of_adhesion=work_of_adhesion, sigma0=sigma0)
        self.work_of_adhesion, self.sigma0 = float(work_of_adhesion), float(sigma0)
        self.range = self.work_of_adhesion / self.sigma0

    def length_scale(self) -> float:
        return self.range

    @property
    def peak_attraction(self) -> float:
        """sigma0 [Pa]."""
        return self.sigma0

    def pressure(self, gap):
        g = np.asarray(gap, dtype=float)
        return np.where(g < self.range, -self.sigma0, 0.0)

    def derivative(self, gap):
        return np.zeros_like(np.asarray(gap, dtype=float))

    def energy(self, gap):
        g = np.maximum(np.asarray(gap, dtype=float), 0.0)
        return np.where(g < self.range, -self.work_of_adhesion + self.sigma0 * g, 0.0)


#: the registered laws by name (``register_law``)
LAWS: dict = {}


def register_law(cls):
    """Register an ``InteractionLaw`` subclass under its ``name`` (a class decorator): ``make_law``
    builds it and the scene schema accepts it with its ``parameters``."""
    if cls.name in LAWS and LAWS[cls.name] is not cls:
        raise ValueError(f"an interaction law named {cls.name!r} is registered already ({LAWS[cls.name].__name__})")
    if cls.parameters and cls.parameters[0] != WORK_OF_ADHESION:
        raise ValueError(f"law {cls.name!r}: its parameters must start with WORK_OF_ADHESION")
    taken = {"law", "element_integration"} & {p.name for p in cls.parameters}
    if taken:
        raise ValueError(f"law {cls.name!r}: parameter name(s) {sorted(taken)} are scene keys of their own")
    for other in LAWS.values():   # a scene key means one thing for every law that takes it
        for p in cls.parameters:
            clash = [q for q in other.parameters if q.name == p.name and (q.unit, q.range) != (p.unit, p.range)]
            if clash:
                raise ValueError(f"law {cls.name!r}: parameter {p.name!r} differs from law {other.name!r}'s "
                                 f"({p} vs {clash[0]})")
    LAWS[cls.name] = cls
    return cls


for _law in (NoAdhesion, HardWallLennardJones, LennardJones, Exponential, Dugdale):
    register_law(_law)


def adhesive_laws(hard_wall: bool | None = None) -> tuple[str, ...]:
    """Names of the registered laws with adhesion (those that take a work of adhesion), in
    registration order; with ``hard_wall`` only those with (True) or without (False) a hard
    wall, g >= 0 as a constraint."""
    return tuple(name for name, cls in LAWS.items()
                 if WORK_OF_ADHESION in cls.parameters and (hard_wall is None or cls.hard_wall == hard_wall))


def relaxation_laws() -> tuple[str, ...]:
    """Names of the registered adhesive laws the reference paper's relaxation applies to: a hard
    wall (eq. 7, target gap 0 at positive-pressure nodes) or a ``repulsive_branch`` (eq. 8,
    target gap f(p))."""
    return tuple(name for name in adhesive_laws() if LAWS[name].hard_wall or LAWS[name].repulsive_branch)


def make_law(name: str, **params) -> InteractionLaw:
    """Build a registered law by name with its ``parameters`` as keywords, e.g.
    ``make_law("lj", work_of_adhesion=0.1, z0=0.3e-9)``."""
    if name not in LAWS:
        raise ValueError(f"interaction law must be one of {sorted(LAWS)}, got {name!r}")
    return LAWS[name](**params)


def tabor_parameter(radius: float, work_of_adhesion: float, e_star: float, z0: float) -> float:
    """Tabor parameter mu = (R w^2 / (E*^2 z0^3))^(1/3) [-]."""
    return (radius * work_of_adhesion**2 / (e_star**2 * z0**3)) ** (1.0 / 3.0)


def lj_from_atomistic(epsilon: float, r0: float) -> tuple[float, float]:
    """(w [J/m^2], z0 [m]) from atomistic LJ parameters (epsilon [J], r0 [m]), after Fan et al.:
    z0 = (2/15)^(1/6) r0, w = 9 epsilon / (2 pi z0^2)."""
    z0 = (2.0 / 15.0) ** (1.0 / 6.0) * r0
    return 9.0 * epsilon / (2.0 * np.pi * z0**2), z0
