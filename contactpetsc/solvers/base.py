"""The VI skeleton shared by ``ContactProblem`` and ``AdhesiveProblem`` (docs/formulation.md,
"Options"): one SNES VI Newton under an options prefix with bounds, code defaults,
our own convergence test, the FFT-pair tally, reason names, the gap formula, and the
``petsc_options`` dict pushed under the prefix only while the problem reads options.
"""
from __future__ import annotations

import functools
from contextlib import contextmanager

import numpy as np
from petsc4py import PETSc

from ..grid import SurfaceGrid
from ..operators.elastic import HalfSpaceOperator, half_space
from .options import code_default

#: accepted range (0, MAX_TOL] of error tolerances (complementarity, self-consistency, pressure
#: and relative load errors): a larger one accepts states that are not solutions at all
#: (1e300 marks the zero guess converged), and 1e-2 is already a coarse solve
MAX_TOL = 1e-2

#: code default of ``-<prefix>snes_vi_zero_tolerance``: an unknown within it of a bound, with the
#: residual of the bound's sign, is active (the Newton step holds it).  PETSc's 1e-8 is in the
#: unknowns' units, Pa here: it held every loaded node of a mean pressure below 1e-8 Pa whatever
#: E* (load control never reached the load) and, at small E*, nodes of small pressure near the
#: contact edges.  0: active only at the bound (where the projection puts them), unit-free
VI_ZERO_TOLERANCE = 0.0


#: the SNES type of every problem, and why no other: ``check_snes_options``
VI_SNES = "vinewtonrsls"
VI_SNES_WHY = (
    "contact is a variational inequality, p >= 0: the unbounded types (newtonls, ...) refuse the "
    "bounds; vinewtonssls scales and shifts the Jacobian in place, which the matrix-free FFT "
    "operator cannot, its Fischer-Burmeister function mixes p [Pa] with the gap [m], and its "
    "full-space steps bypass the preconditioners and load control, built on the reduced space")


class ContactSolveError(RuntimeError):
    """A solve that did not converge; raised on every rank with the same message."""


class AdhesiveSolveError(ContactSolveError):
    """An adhesive solve that did not converge (same message on every rank)."""


def check_tolerance(value, name: str) -> float:
    """``value`` as a float in (0, MAX_TOL]; a ValueError naming ``name`` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number in (0, {MAX_TOL:g}], got {value!r}")
    if not (np.isfinite(value) and 0.0 < value <= MAX_TOL):
        raise ValueError(f"{name} = {value!r}: accepted range (0, {MAX_TOL:g}]")
    return float(value)


def check_heights(grid: SurfaceGrid, heights: PETSc.Vec) -> None:
    """Refuse ``heights`` laid out for another grid (ValueError naming the field and both
    shapes; collective): ``SurfaceGrid.check_vec``."""
    grid.check_vec(heights, "heights")


def convergence_verdict(snes: PETSc.SNES, it: int, err: float, tol: float) -> int:
    """The SNES reason for error measure ``err`` at iteration ``it``: NaN diverges, ``tol``
    converges, the SNES's max_it stops, else iterate (our own measures replace SNES norms)."""
    if not np.isfinite(err):
        return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
    if err <= tol:
        return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
    if it >= snes.getTolerances()[3]:
        return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
    return PETSc.SNES.ConvergedReason.ITERATING


def reason_name(reason: int, kind=PETSc.SNES.ConvergedReason) -> str:
    """The name of a SNES (or, with ``kind``, KSP) converged/diverged reason."""
    return next((k for k, v in vars(kind).items() if v == reason and isinstance(v, int)), str(reason))


def weighted_pairs(ops, fine: SurfaceGrid) -> float:
    """FFT pairs of ``ops`` in units of ``fine``-grid pairs (a coarse pair weighs its size)."""
    n0 = fine.nx * fine.ny
    return float(sum(op.fft_pairs * (op.grid.nx * op.grid.ny) / n0 for op in ops))


def pieces(step: float, max_step: float) -> int:
    """The equal pieces of at most ``max_step`` (0: any) a step of ``step`` is taken in (a
    path's sub-steps, a descent's increments); a step of exactly max_step, give or take a
    rounding, is one."""
    if not (max_step > 0 and np.isfinite(step)):
        return 1
    return max(int(np.ceil(abs(step) / max_step * (1.0 - 1e-9))), 1)


def with_options(method):
    """Run a public method with the problem's options inserted (``VIProblem.inserted_options``),
    its grid and heights checked first (collective) when it is called from outside: a user who
    destroyed them gets an error naming them instead of PETSc's segmentation fault."""
    @functools.wraps(method)
    def wrapped(self, *args, **kwargs):
        if self._options_depth == 0:
            check_heights(self.grid, self.heights)
        with self.inserted_options():
            return method(self, *args, **kwargs)
    return wrapped


def _option_text(value) -> str | None:
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    return str(value)


class VIProblem:
    """Base of the SNES VI problems: h, E*, the operator K and the options prefix.

    ``petsc_options`` (a dict, keys without the prefix or the leading dash) is inserted
    into PETSc's options database under the prefix while the problem builds or solves,
    and removed afterwards; options already in the database (the command line) win.
    """

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, *, prefix: str,
                 operator: HalfSpaceOperator | None, petsc_options: dict | None):
        check_heights(grid, heights)
        if not isinstance(prefix, str) or not prefix or prefix.startswith("-"):
            raise ValueError(f"prefix must be a non-empty options prefix without a leading dash, got {prefix!r}")
        self.grid, self.heights, self.prefix = grid, heights, prefix
        self.petsc_options = {str(k).lstrip("-"): v for k, v in dict(petsc_options or {}).items()}
        self._inserted: list[str] | None = None
        self._options_depth = 0
        self._snes = None
        self._J = None
        self._n_solves = 0
        with self.inserted_options():
            self.op = operator if operator is not None else half_space(grid, e_star, prefix=prefix)
        if not np.isclose(self.op.e_star, e_star, rtol=1e-12, atol=0.0):
            raise ValueError(f"e_star = {e_star!r} Pa differs from the operator's E* = {self.op.e_star!r} Pa")
        self.e_star = self.op.e_star
        self.kappa = self.op.self_influence

    # -- options ------------------------------------------------------------------------
    #: the table of ``options.TABLES`` this problem's own options are registered in
    option_table = "contact"

    def _default(self, key: str):
        """The code default of ``-<prefix><key>``: the constructor's keyword, else the registry's."""
        given = self._defaults.get(key)
        return code_default(self.option_table, key) if given is None else given

    @contextmanager
    def inserted_options(self):
        """``petsc_options`` under the prefix for the duration (nested uses insert once);
        every option inserted here, code defaults included, is removed on exit."""
        outer = self._options_depth == 0
        if outer:
            self._inserted = []
            before = set(PETSc.Options().getAll())
            for key, value in self.petsc_options.items():
                self.set_default(key, value)
        self._options_depth += 1
        try:
            yield
        finally:
            self._options_depth -= 1
            if outer:
                opts = PETSc.Options()
                # and what PETSc added under the prefix meanwhile (newer PETSc sets the new
                # name of a deprecated option a user gave)
                added = [k for k in opts.getAll() if k not in before and k.startswith(self.prefix)]
                for name in set(self._inserted) | set(added):
                    opts.delValue(name)
                self._inserted = None

    def set_default(self, key: str, value, prefix: str | None = None) -> None:
        """Insert ``-<prefix><key> value`` unless the database has it; removed again at the end
        of the present ``inserted_options`` block (petsc4py 3.18 has no SNESLineSearch
        object: code defaults of sub-objects go through the database)."""
        name = (self.prefix if prefix is None else prefix) + key
        opts = PETSc.Options()
        if opts.hasName(name):
            return
        opts.setValue(name, _option_text(value))
        if self._inserted is not None:
            self._inserted.append(name)

    def check_snes_options(self, *prefixes: str) -> None:
        """Refuse SNES options under ``prefixes`` that the problems cannot honour, before anything
        is built: ``-<prefix>snes_rtol`` / ``snes_atol`` (our convergence test measures gap and
        pressure errors, not residual norms: they would be ignored) and a ``-<prefix>snes_type``
        other than ``VI_SNES`` (``VI_SNES_WHY``)."""
        for prefix in prefixes:
            opts = PETSc.Options(prefix)
            given = [f"-{prefix}{k}" for k in ("snes_rtol", "snes_atol") if opts.hasName(k)]
            if given:
                raise ValueError(f"{', '.join(given)}: not used (the convergence test measures gap and "
                                 f"pressure errors, docs/formulation.md); set -{self.prefix}tol instead")
            kind = opts.getString("snes_type", VI_SNES) if opts.hasName("snes_type") else VI_SNES
            if kind != VI_SNES:
                raise ValueError(f"-{prefix}snes_type {kind}: not supported; accepted: {VI_SNES} "
                                 f"({VI_SNES_WHY})")

    # -- the VI -------------------------------------------------------------------------
    def make_vi_snes(self, prefix: str, bounds, max_it: int) -> PETSc.SNES:
        """A ``vinewtonrsls`` SNES on the problem's residual, Jacobian and bounds, with our
        convergence test; ``setFromOptions`` is left to the caller (code defaults first), which
        has called ``check_snes_options`` before building anything."""
        from ..lifetime import destroy_at_exit
        snes = destroy_at_exit(PETSc.SNES().create(comm=self.grid.comm))
        snes.setOptionsPrefix(prefix)
        snes.setType(VI_SNES)
        self.attach_vi_snes(snes, bounds)
        snes.setTolerances(rtol=0.0, atol=0.0, stol=0.0, max_it=max_it)
        snes.setConvergenceTest(self._converged)
        self.set_default("snes_vi_zero_tolerance", VI_ZERO_TOLERANCE, prefix)
        return snes

    def attach_vi_snes(self, snes: PETSc.SNES, bounds, f: PETSc.Vec | None = None) -> None:
        """Give ``snes`` the problem's residual (into ``f``, else the problem's ``_f``), Jacobian
        and ``bounds`` (lower, upper; None: the VI's own infinite ones): at creation, and, for
        an adhesive problem, at each Newton run (``VINewton.run``: its reset drops them)."""
        snes.setFunction(self._residual, self._f if f is None else f)
        if bounds is not None:
            snes.setVariableBounds(*bounds)
        snes.setJacobian(self._jacobian, self._J, self._J)

    def gap(self, pressure: np.ndarray, out: np.ndarray, displacement: np.ndarray | None = None) -> np.ndarray:
        """g = h + K p - delta [m] on this rank's rows for pressure rows ``p`` [Pa]; K p goes
        into ``displacement`` when given.  delta: ``control_approach`` (reference paper, eq. 5)."""
        v = self.op.apply(pressure, out if displacement is None else displacement)
        h = self.grid.rows(self.heights, readonly=True)
        if v is out:
            out += h
        else:
            np.add(h, v, out=out)
        out -= self.control_approach(out)
        return out

    def fft_pairs(self) -> float:
        """FFT pairs so far, in fine-grid units (coarse levels weighted by their size)."""
        raise NotImplementedError

    def control_approach(self, h_plus_v: np.ndarray) -> float:
        """delta [m] of the gap formula, given h + K p (central-gap control derives it)."""
        return self._approach

    # -- public --------------------------------------------------------------------------
    @property
    def approach(self) -> float | None:
        """delta [m] of the present state (None before the first solve)."""
        return self._approach

    @property
    def solver(self) -> PETSc.SNES:
        """The SNES (built on first request)."""
        return self.snes()

    def snes(self) -> PETSc.SNES:
        """The SNES (built on first request), for PETSc users."""
        with self.inserted_options():
            return self._build()

    @property
    def jacobian_context(self):
        """The Python context of ``J`` (built on first request)."""
        self.snes()
        return self._jac

    @property
    def x(self) -> PETSc.Vec:
        """The SNES's unknowns (built on first request)."""
        self.snes()
        return self._x

    @property
    def J(self) -> PETSc.Mat:
        """The matrix-free Jacobian (a Python Mat; built on first request)."""
        self.snes()
        return self._J

    def destroy(self) -> None:
        """Free the solvers and their work vectors (collective); the problem cannot solve again."""
        self._destroy_solvers()
        if self._J is not None:
            self._J.destroy()
            self._J = None
        PETSc.garbage_cleanup(self.grid.comm)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy()
        return False
