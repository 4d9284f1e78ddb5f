"""``ContactProblem``: non-adhesive (Signorini) contact solved by SNES VI Newton.

Unknown: the nodal pressure p [Pa] (argued in docs/formulation.md): the
constraint p >= 0 is a plain variable bound (``SNESVISetVariableBounds``),
the residual is the gap

    F(p) = g = h + K p - delta          (reference paper, eq. 5)

and the VI "p >= 0, g >= 0, p g = 0" is exactly the Signorini condition,
eq. (4).  Its Jacobian is K itself, applied matrix-free by FFT; the
reduced-space Newton method (``vinewtonrsls``) solves K_II dp_I = -g_I on the
inactive set with a Krylov method preconditioned by MLMI (``mlmi.py``).

Controls: ``approach`` (displacement control, delta given) or a load
(``mean_pressure``, or ``force`` for an isolated contact = mean_pressure *
nx*dx * ny*dy).  Load control is a safeguarded Newton iteration on delta
around displacement-controlled solves: the load W(delta) is increasing and
convex, its slope dW/d delta = mean(z) comes from one reduced solve
K_II z = 1 on the converged contact set, and z predicts the next pressure,
so each outer step is one exact Newton step of the load-controlled problem
on the current contact set.  Steps that leave the bracket [delta_lo, delta_hi]
of known loads bisect instead.  On a periodic cell K has no mean mode, so
delta is the approach to the mean plane of the deformed surface and full
contact is singular under displacement control: load control handles it.

Options (prefix ``contact_`` by default) are read after the code defaults,
so every PETSc option works: ``-contact_snes_monitor``,
``-contact_ksp_monitor``, ``-contact_ksp_type``, ``-log_view``, ...  Own
options: ``-contact_preconditioner mlmi|spectral|none``,
``-contact_tol`` (complementarity error relative to the length scale),
``-contact_load_tol`` (relative load error).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..grid import SurfaceGrid
from ..lifetime import destroy_at_exit
from ..operators.elastic import HalfSpaceOperator, half_space
from ..surfaces import rms_height
from .history import SolveHistory
from .reduced import ContactJacobian

PRECONDITIONERS = {
    "mlmi": "contactpetsc.solvers.mlmi.MLMIPC",
    "spectral": "contactpetsc.solvers.preconditioners.SpectralPC",
    "none": None,
}


class ContactSolveError(RuntimeError):
    """A solve that did not converge; raised on every rank with the same message."""


@dataclass
class ContactState:
    """A converged (or failed) contact state.  Vecs live on the problem's grid."""
    pressure: PETSc.Vec       #: p [Pa], compressive positive
    gap: PETSc.Vec            #: g = h + v - delta [m]
    displacement: PETSc.Vec   #: v = K p [m]
    approach: float           #: delta [m]
    mean_pressure: float      #: [Pa]
    force: float              #: total normal force [N] = mean_pressure * area
    contact_fraction: float   #: fraction of nodes with p > 0
    complementarity_error: float  #: max |min(K_ii p, g)| / length_scale
    load_error: float         #: |mean p - target| / target (load control), else NaN
    converged: bool
    reason: str               #: SNES converged/diverged reason
    newton_iterations: int
    linear_iterations: int
    fft_pairs: float          #: fine-grid FFT pairs of this solve (coarse levels weighted)
    wall_time: float          #: [s]


class ContactProblem:
    """Contact of an elastic half-space with a rigid composite surface h, no adhesion.

    Parameters
    ----------
    grid : SurfaceGrid
    heights : PETSc.Vec
        Composite surface h [m] on ``grid`` (e.g. from ``contactpetsc.surfaces``).
    e_star : float
        Effective modulus E* [Pa].
    prefix : str
        PETSc options prefix of the SNES, KSP and PC (default ``contact_``).
    length_scale : float, optional
        Length [m] the complementarity error is measured in; defaults to
        the rms height of h (the benchmark convention), or dx if h is flat.
    operator : HalfSpaceOperator, optional
        Reuse an operator built on the same grid.
    """

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, *,
                 prefix: str = "contact_", length_scale: float | None = None,
                 operator: HalfSpaceOperator | None = None):
        self.grid, self.heights, self.prefix = grid, heights, prefix
        self.op = operator if operator is not None else half_space(grid, e_star, prefix=prefix)
        self.e_star = self.op.e_star
        self.kappa = self.op.self_influence
        if length_scale is None:
            length_scale = rms_height(grid, heights) or grid.dx
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ValueError(f"length_scale (m) must be finite and > 0, got {length_scale!r}")
        self.length_scale = float(length_scale)
        self.history = SolveHistory()
        self._snes = self._jac = None
        self._n_solves = 0
        self._pressure = grid.create_vec(0.0)   # last converged pressure: the next warm start
        self._approach = None
        self._target = None

    # -- set-up ------------------------------------------------------------------
    def _build(self):
        """The SNES, built once with code defaults, then ``setFromOptions``."""
        if self._snes is not None:
            return self._snes
        g = self.grid
        self._jac = ContactJacobian(self.op, self.prefix)
        n_local, n = g.nx * g.ny_local, g.nx * g.ny
        J = destroy_at_exit(PETSc.Mat().createPython(((n_local, n), (n_local, n)), self._jac, comm=g.comm))
        J.setUp()
        snes = destroy_at_exit(PETSc.SNES().create(comm=g.comm))
        snes.setOptionsPrefix(self.prefix)
        snes.setType("vinewtonrsls")
        self._x, self._f = g.create_vec(0.0), g.create_vec(0.0)
        snes.setFunction(self._residual, self._f)
        snes.setVariableBounds(g.create_vec(0.0), g.create_vec(PETSc.INFINITY))
        snes.setJacobian(self._jacobian, J, J)
        snes.setTolerances(rtol=0.0, atol=0.0, stol=0.0, max_it=100)
        snes.setConvergenceTest(self._converged)
        # petsc4py 3.18 has no SNESLineSearch object: code defaults go into the options
        # database, only where the user gave nothing, before setFromOptions
        opts = PETSc.Options(self.prefix)
        if not opts.hasName("snes_linesearch_type"):
            opts.setValue("snes_linesearch_type", "basic")
        ksp = snes.getKSP()
        ksp.setType("cg")
        ksp.setTolerances(rtol=1e-8, max_it=500)
        pc = ksp.getPC()
        choice = opts.getString("preconditioner", "spectral").lower()
        if choice not in PRECONDITIONERS:
            raise ValueError(f"-{self.prefix}preconditioner must be one of "
                             f"{sorted(PRECONDITIONERS)}, got {choice!r}")
        if PRECONDITIONERS[choice] is None:
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType(PRECONDITIONERS[choice])
        self.preconditioner = choice
        self.tol = opts.getReal("tol", 1e-10)
        self.load_tol = opts.getReal("load_tol", 1e-10)
        self.max_outer = opts.getInt("load_max_it", 50)
        snes.setFromOptions()
        slope = self._slope_ksp = destroy_at_exit(PETSc.KSP().create(comm=g.comm))
        slope.setOptionsPrefix(self.prefix + "slope_")
        slope.setType("cg")
        slope.setTolerances(rtol=1e-8, max_it=500)
        slope.getPC().setType(pc.getType())
        if pc.getType() == "python":
            slope.getPC().setPythonType(PRECONDITIONERS[choice])
        slope.setFromOptions()
        self._snes = snes
        return snes

    # -- SNES callbacks ------------------------------------------------------------
    def _residual(self, snes, x, f):
        g = self.grid
        gap = g.rows(f)
        self.op.apply(g.rows(x, readonly=True), gap)
        gap += g.rows(self.heights, readonly=True)
        gap -= self._approach

    def _jacobian(self, snes, x, J, P):
        pass  # K does not depend on p: nothing to update

    def _measures(self, x, f):
        """(complementarity error [relative], mean pressure, contact fraction)."""
        g = self.grid
        comm = g.mpi_comm
        p = g.rows(x, readonly=True)
        nat = np.minimum(self.kappa * p, g.rows(f, readonly=True))
        err = comm.allreduce(float(np.abs(nat).max()), op=MPI.MAX) / self.length_scale
        sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p > 0)], float))
        n = g.nx * g.ny
        return err, sums[0] / n, sums[1] / n

    def _converged(self, snes, it, norms):
        x, f = snes.getSolution(), snes.getFunction()[0]
        err, mean_p, frac = self._measures(x, f)
        load_err = (abs(mean_p - self._target) / self._target) if self._target else float("nan")
        self.history.append(
            solve=self._n_solves, iteration=it, fft_pairs=self._fft_pairs(),
            linear_iterations=self._lin0 + snes.getLinearSolveIterations(),
            complementarity_error=err, load_error=load_err, approach=self._approach,
            mean_pressure=mean_p, contact_fraction=frac, solver="snes-vi+" + self.preconditioner)
        self._last_error = err
        if not np.isfinite(err):
            return PETSc.SNES.ConvergedReason.DIVERGED_FNORM_NAN
        if err <= self.tol:
            return PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
        if it >= snes.getTolerances()[3]:
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT
        return PETSc.SNES.ConvergedReason.ITERATING

    def _fft_pairs(self) -> float:
        pairs = float(self.op.fft_pairs)
        if self._jac is not None:
            for lev in self._jac.cache.get("mlmi_levels", [])[1:]:
                pairs += lev.weight * lev.op.fft_pairs
        return pairs

    def _solve_at(self, approach: float, pressure: PETSc.Vec):
        """One displacement-controlled SNES solve from ``pressure``; returns (converged, reason)."""
        snes = self._build()
        self._approach = float(approach)
        pressure.copy(self._x)
        self._lin0 = self.history[-1].linear_iterations if len(self.history) else 0
        snes.solve(None, self._x)
        self._newton += snes.getIterationNumber()
        self._linear += snes.getLinearSolveIterations()
        self._n_solves += 1
        reason = snes.getConvergedReason()
        return reason > 0, _reason_name(reason)

    def _approach_slope(self):
        """(dW/d delta [Pa/m] as d(mean p)/d delta, z = dp/d delta) on the last solve's inactive set.

        Solves K_II z = 1 with its own KSP (options prefix ``<prefix>slope_``),
        preconditioned like the Newton steps.
        """
        g = self.grid
        inactive = (g.rows(self._x, readonly=True) > 0) | (g.rows(self._f, readonly=True) <= 0)
        local = (np.flatnonzero(inactive) + g.nx * g.ys).astype(PETSc.IntType)
        index_set = PETSc.IS().createGeneral(local, comm=g.comm)
        J = self._snes.getJacobian()[0]
        A = J.createSubMatrix(index_set, index_set)
        ctx = A.getPythonContext()
        ksp = self._slope_ksp
        ksp.reset()  # the inactive set, hence the size, changes between calls
        ksp.setOperators(A, A)
        b, z = A.createVecs()
        b.set(1.0)
        z.set(0.0)
        ksp.solve(b, z)
        self._linear += ksp.getIterationNumber()
        dp = self.grid.create_vec(0.0)
        full = np.zeros_like(ctx.full_in)
        ctx.to_full(z, full)
        self.grid.rows(dp)[...] = full
        return dp.sum() / (self.grid.nx * self.grid.ny), dp

    def _solve_load(self, target: float):
        """Safeguarded Newton on delta (see the module docstring); returns (converged, reason)."""
        g = self.grid
        n = g.nx * g.ny
        lo = float(self.heights.min()[1])  # delta <= min h: no contact, no load
        # periodic: K p has zero mean, so the mean gap is mean(h) - delta >= 0 at equilibrium
        hi = self.heights.sum() / n if g.periodic else np.inf
        delta = self._approach if self._approach is not None else lo
        p = self._pressure.copy()
        reason = "no iteration"
        for _ in range(self.max_outer):
            ok, reason = self._solve_at(delta, p)
            if not ok:
                # e.g. beyond full contact on a periodic cell: no equilibrium, too far
                hi = min(hi, delta)
                p = self._pressure.copy()
                delta = 0.5 * (lo + hi)
                continue
            self._x.copy(p)
            p.copy(self._pressure)
            w = p.sum() / n
            load_err = abs(w - target) / target
            if load_err <= self.load_tol:
                return True, reason
            if w < target:
                lo = max(lo, delta)
            else:
                hi = min(hi, delta)
            slope, dp = self._approach_slope()
            step = (target - w) / slope if slope > 0 else np.inf
            new = delta + step
            if not (lo < new < hi) or (np.isfinite(hi) and new > hi - 1e-3 * (hi - lo)):
                new = 0.5 * (lo + hi) if np.isfinite(hi) else lo + 2.0 * max(delta - lo, self.length_scale)
            else:
                p.axpy(new - delta, dp)  # Newton predictor on the current contact set
                rows = g.rows(p)
                np.maximum(rows, 0.0, out=rows)
            delta = new
        return False, f"DIVERGED_LOAD_ITERATION ({self.max_outer} approach updates; last SNES {reason})"

    # -- public API ------------------------------------------------------------------
    def snes(self) -> PETSc.SNES:
        """The SNES (built on first request), for PETSc users."""
        return self._build()

    def solve(self, *, approach: float | None = None, mean_pressure: float | None = None,
              force: float | None = None, raise_on_failure: bool = True) -> ContactState:
        """Solve for one approach delta [m] or one load (mean pressure [Pa] or total force [N]).

        The previous solution is the initial guess (warm start along a loading path).
        """
        given = [v is not None for v in (approach, mean_pressure, force)]
        if sum(given) != 1:
            raise ValueError("give exactly one of approach (m), mean_pressure (Pa) or force (N)")
        g = self.grid
        area = g.lengths[0] * g.lengths[1]
        if force is not None:
            mean_pressure = force / area
        for name, v in (("approach", approach), ("mean_pressure/force", mean_pressure)):
            if v is not None and not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        if mean_pressure is not None and mean_pressure <= 0:
            raise ValueError(f"mean_pressure / force must be > 0 without adhesion, got {mean_pressure!r}")
        self._build()
        self._target = mean_pressure
        self._newton = self._linear = 0
        pairs0, t0 = self._fft_pairs(), self.history.elapsed()
        if mean_pressure is None:
            converged, reason = self._solve_at(approach, self._pressure)
            if converged:
                self._x.copy(self._pressure)
        else:
            converged, reason = self._solve_load(mean_pressure)
        p = self._x.copy()
        v = g.create_vec()
        self.op.apply(g.rows(p, readonly=True), g.rows(v))
        gap = v.copy()
        gap.axpy(1.0, self.heights)
        gap.shift(-self._approach)
        err, mean_p, frac = self._measures(p, gap)
        load_err = abs(mean_p - mean_pressure) / mean_pressure if mean_pressure else float("nan")
        state = ContactState(
            pressure=p, gap=gap, displacement=v, approach=self._approach, mean_pressure=mean_p,
            force=mean_p * area, contact_fraction=frac, complementarity_error=err,
            load_error=load_err, converged=converged, reason=reason,
            newton_iterations=self._newton, linear_iterations=self._linear,
            fft_pairs=self._fft_pairs() - pairs0, wall_time=self.history.elapsed() - t0)
        if not converged and raise_on_failure:
            ksp_reason = _ksp_reason_name(self._snes.getKSP().getConvergedReason())
            raise ContactSolveError(
                f"contact solve did not converge: {reason} after {state.newton_iterations} Newton "
                f"iterations (last KSP: {ksp_reason}); complementarity error {err:.3e} "
                f"(tol {self.tol:.1e}) of length scale {self.length_scale:.3e} m, "
                f"load error {load_err:.3e} (tol {self.load_tol:.1e})")
        return state


def _reason_name(reason: int) -> str:
    names = {v: k for k, v in vars(PETSc.SNES.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, str(reason))


def _ksp_reason_name(reason: int) -> str:
    names = {v: k for k, v in vars(PETSc.KSP.ConvergedReason).items() if isinstance(v, int)}
    return names.get(reason, str(reason))


