"""``ContactProblem``: non-adhesive (Signorini) contact solved by SNES VI Newton.

Unknown: the nodal pressure p [Pa] (argued in docs/formulation.md): the
constraint p >= 0 is a plain variable bound (``SNESVISetVariableBounds``),
the residual is the gap

    F(p) = g = h + K p - delta          (reference paper, eq. 5)

and the VI "p >= 0, g >= 0, p g = 0" is exactly the Signorini condition,
eq. (4).  Its Jacobian is K itself, applied matrix-free by FFT; the
reduced-space Newton method (``vinewtonrsls``) solves K_II dp_I = -g_I on the
inactive set by CG, preconditioned by the Fourier inverse (``SpectralPC``,
the default) or the multilevel MLMI cycle (``mlmi.py``).

Controls: ``approach`` (displacement control, delta given) or a load
(``mean_pressure``, or ``force`` for an isolated contact = mean_pressure *
nx*dx * ny*dy).  Load control is a safeguarded Newton iteration on delta
around displacement-controlled solves: the load W(delta) is increasing and
convex, its slope dW/d delta = mean(z) comes from one reduced solve
K_II z = 1 on the converged contact set, and z predicts the next pressure,
so each outer step is one exact Newton step of the load-controlled problem
on the current contact set.  Steps that leave the bracket [delta_lo, delta_hi]
of known loads bisect instead; intermediate solves are inexact, and the
first solve is nested (full multigrid): coarser grids first, their pressure
and approach the fine grid's start.  On a periodic cell K has no mean mode, so
delta is the approach to the mean plane of the deformed surface and full
contact is singular under displacement control: load control handles it.

Options (prefix ``contact_`` by default) are read after the code defaults,
so every PETSc option works: ``-contact_snes_monitor``,
``-contact_ksp_monitor``, ``-contact_ksp_type``, ``-log_view``, ...  Own
options (all listed with defaults in docs/formulation.md):
``-contact_preconditioner spectral|mlmi|none``, ``-contact_tol``
(complementarity error relative to the length scale), ``-contact_load_tol``
(relative load error), ``-contact_newton_ksp_rtol``, ``-contact_fmg``,
``-contact_fmg_prolong constant|bilinear`` (transfer of the coarse pressure
in the nested iteration; constant is the default, bilinear measured worse on
the benchmark), ``-contact_slope_warm_start`` (slope solves K_II z = 1 start
from the previous z, the first one from the coarse grid's; default true), ...
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_guard
from ..grid import SurfaceGrid
from ..lifetime import destroy_at_exit
from ..operators.elastic import HalfSpaceOperator, half_space
from ..geometry.surfaces import rms_height
from .history import SolveHistory
from .reduced import ContactJacobian
from .transfer import can_halve, halved, prolong_bilinear, prolong_constant, restrict

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
    #: max |min(K_ii p, g)| / min(length_scale, delta - min h): the measure converged to tol
    interference_error: float
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
        Composite surface h [m] on ``grid`` (e.g. from ``contactpetsc.geometry.surfaces``).
    e_star : float
        Effective modulus E* [Pa].
    prefix : str
        PETSc options prefix of the SNES, KSP and PC (default ``contact_``).
    length_scale : float, optional
        Length [m] the complementarity error is measured in; defaults to
        the rms height of h (the benchmark convention), or dx if h is flat.
    operator : HalfSpaceOperator, optional
        Reuse an operator built on the same grid (its E* must equal ``e_star``).
    tol, load_tol : float, optional
        Code defaults of ``-<prefix>tol`` (complementarity error relative to
        ``length_scale``, 1e-10) and ``-<prefix>load_tol`` (relative, 1e-10).
    preconditioner : str, optional
        Code default of ``-<prefix>preconditioner``: spectral, mlmi or none.
    fmg : bool, optional
        Code default of ``-<prefix>fmg`` (nested iteration on the first solve, on).
    Options given on the command line override these code defaults.
    """

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, *,
                 prefix: str = "contact_", length_scale: float | None = None,
                 operator: HalfSpaceOperator | None = None, tol: float | None = None,
                 load_tol: float | None = None, preconditioner: str | None = None,
                 fmg: bool | None = None, _root: "ContactProblem | None" = None):
        check_heights(grid, heights)
        for name, value in (("tol", tol), ("load_tol", load_tol)):
            if value is not None:
                check_tolerance(value, name)
        self.grid, self.heights, self.prefix = grid, heights, prefix
        self._defaults = dict(tol=tol, load_tol=load_tol, preconditioner=preconditioner, fmg=fmg)
        self._root = _root if _root is not None else self
        self._coarse = None
        self.op = operator if operator is not None else half_space(grid, e_star, prefix=prefix)
        if not np.isclose(self.op.e_star, e_star, rtol=1e-12, atol=0.0):
            raise ValueError(f"e_star = {e_star!r} Pa differs from the operator's E* = {self.op.e_star!r} Pa")
        self.e_star = self.op.e_star
        self.kappa = self.op.self_influence
        if length_scale is None:
            rms = rms_height(grid, heights)
            # a flat surface (rms at round-off of its heights) has no length of its own
            flat = rms <= 1e-12 * max(abs(heights.max()[1]), abs(heights.min()[1]))
            length_scale = grid.dx if flat or rms == 0 else rms
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ValueError(f"length_scale (m) must be finite and > 0, got {length_scale!r}")
        self.length_scale = float(length_scale)
        self.history = _root.history if _root is not None else SolveHistory()
        self._snes = self._jac = self._slope_ksp = None
        self._retired_pairs = 0.0  # weighted FFT pairs of released coarse problems' operators
        self._levels = None     # MLMI levels (shared with the coarse problems)
        self._slope_cache = None  # (inactive set, slope, z) of the last slope solve
        self._z_guess = None      # initial guess of the next slope solve (full grid)
        self._dp = None           # dp/d delta of the last slope solve (one Vec, reused)
        self._work = None         # grid-sized scratch of the convergence measures
        self._n_solves = 0
        self._pressure = grid.create_vec(0.0)   # last converged pressure: the next warm start
        self._approach = None
        self._target = None
        self._h_min = None

    # -- set-up ------------------------------------------------------------------
    def _build(self):
        """The SNES, built once with code defaults, then ``setFromOptions``."""
        if self._snes is not None:
            return self._snes
        g = self.grid
        d = self._defaults
        # checked before any PETSc object exists: a refusal leaves nothing half-built
        opts = PETSc.Options(self.prefix)
        self.tol = check_tolerance(opts.getReal("tol", 1e-10 if d["tol"] is None else d["tol"]),
                                   f"tol (-{self.prefix}tol)")
        self.load_tol = check_tolerance(opts.getReal("load_tol", 1e-10 if d["load_tol"] is None else d["load_tol"]),
                                        f"load_tol (-{self.prefix}load_tol)")
        self._jac = ContactJacobian(self.op, self.prefix)
        n_local, n = g.nx * g.ny_local, g.nx * g.ny
        J = destroy_at_exit(PETSc.Mat().createPython(((n_local, n), (n_local, n)), self._jac, comm=g.comm))
        J.setUp()
        snes = destroy_at_exit(PETSc.SNES().create(comm=g.comm))
        snes.setOptionsPrefix(self.prefix)
        snes.setType("vinewtonrsls")
        self._x, self._f = g.create_vec(0.0), g.create_vec(0.0)
        self._x_best = g.create_vec(0.0)   # the iterate of smallest error of the running solve
        snes.setFunction(self._residual, self._f)
        snes.setVariableBounds(g.create_vec(0.0), g.create_vec(PETSc.INFINITY))
        snes.setJacobian(self._jacobian, J, J)
        snes.setTolerances(rtol=0.0, atol=0.0, stol=0.0, max_it=100)
        snes.setConvergenceTest(self._converged)
        # petsc4py 3.18 has no SNESLineSearch object: code defaults go into the options
        # database, only where the user gave nothing, before setFromOptions
        opts = PETSc.Options(self.prefix)
        if not opts.hasName("snes_linesearch_type"):
            # backtracking: full steps (basic) diverged on the finest grid of the 4096^2
            # benchmark (residual 1e-2 -> 3 in 17 steps, from the prolonged 2048^2 state);
            # bt converges there in 6 steps and costs 9-17 % more FFT pairs at 256-2048^2
            opts.setValue("snes_linesearch_type", "bt")
        if not opts.hasName("snes_linesearch_maxstep"):
            opts.setValue("snes_linesearch_maxstep", "1e300")   # PETSc's 1e8 is in Pa here
        ksp = snes.getKSP()
        ksp.setType("cg")
        # inexact Newton: the semismooth Newton method converges linearly with
        # rate ~ rtol once the contact set has settled, so a loose Krylov
        # tolerance costs at most a Newton step or two and saves many Krylov steps
        ksp.setTolerances(rtol=opts.getReal("newton_ksp_rtol", 1e-1), max_it=500)
        pc = ksp.getPC()
        choice = opts.getString("preconditioner", d["preconditioner"] or "spectral").lower()
        if choice not in PRECONDITIONERS:
            raise ValueError(f"-{self.prefix}preconditioner must be one of "
                             f"{sorted(PRECONDITIONERS)}, got {choice!r}")
        if PRECONDITIONERS[choice] is None:
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType(PRECONDITIONERS[choice])
        self.preconditioner = choice
        self.max_outer = opts.getInt("load_max_it", 50)
        # load control: inexact inner solves (see _solve_load); 1e-3 rather than 1e-4
        # saves 8-13 % of the FFT pairs on the benchmark (256^2-2048^2)
        self.inner_tol0 = opts.getReal("load_inner_tol", 1e-3)
        self.inner_eta = opts.getReal("load_inner_eta", 0.1)
        # nested iteration (full multigrid): first solve on a 2x coarser grid
        self.fmg = opts.getBool("fmg", True if d["fmg"] is None else d["fmg"])
        self.fmg_min_size = opts.getInt("fmg_min_size", 32)
        self.fmg_tol = opts.getReal("fmg_tol", 1e-4)
        self.fmg_prolong = opts.getString("fmg_prolong", "constant").lower()
        if self.fmg_prolong not in ("bilinear", "constant"):
            raise ValueError(f"-{self.prefix}fmg_prolong must be bilinear or constant, got {self.fmg_prolong!r}")
        self.slope_warm = opts.getBool("slope_warm_start", True)
        snes.setFromOptions()
        # -<prefix>pc_type ... may have replaced our choice: record what is in use
        python_type = pc.getPythonType() if pc.getType() == "python" else None
        self.preconditioner = next((k for k, v in PRECONDITIONERS.items() if v and v == python_type),
                                   python_type or pc.getType())
        self._inner_tol = self.tol
        slope = self._slope_ksp = destroy_at_exit(PETSc.KSP().create(comm=g.comm))
        slope.setOptionsPrefix(self.prefix + "slope_")
        slope.setType("cg")
        # the slope only sets the next approach (outer Newton): a loose solve is enough
        slope.setTolerances(rtol=1e-2, max_it=500)
        slope.getPC().setType(pc.getType())
        if python_type:
            slope.getPC().setPythonType(python_type)
        slope.setFromOptions()
        if python_type == PRECONDITIONERS["mlmi"]:
            # built here (not at the first PC set-up) so that the coarse problems of the
            # nested iteration share the levels' grids and operators
            if self._levels is None:
                from .mlmi import build_levels
                self._levels = build_levels(self.op, opts.getInt("mlmi_levels", 8),
                                            opts.getInt("mlmi_min_size", 8))
            self._jac.cache["mlmi_levels"] = self._levels
        self._snes = snes
        return snes

    # -- SNES callbacks ------------------------------------------------------------
    @collective_guard
    def _residual(self, snes, x, f):
        g = self.grid
        gap = g.rows(f)
        self.op.apply(g.rows(x, readonly=True), gap)
        gap += g.rows(self.heights, readonly=True)
        gap -= self._approach

    def _jacobian(self, snes, x, J, P):
        pass  # K does not depend on p: nothing to update

    def _measures(self, x, f):
        """(complementarity error relative to the length scale and to ``_gap_scale``,
        mean pressure, contact fraction)."""
        g = self.grid
        comm = g.mpi_comm
        p = g.rows(x, readonly=True)
        if self._work is None:
            self._work = np.empty_like(p)   # one buffer for every evaluation: no per-iteration allocation
        nat = np.multiply(p, self.kappa, out=self._work)
        np.minimum(nat, g.rows(f, readonly=True), out=nat)
        # max |min(K_ii p, g)| without an |.| temporary: the larger of max and -min
        local = max(float(nat.max()), -float(nat.min()))
        err = comm.allreduce(local, op=MPI.MAX)
        sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p)], float))
        n = g.nx * g.ny
        return err / self.length_scale, err / self._gap_scale(), sums[0] / n, sums[1] / n

    def _gap_scale(self) -> float:
        """The length [m] the convergence test measures gaps in: the length scale, or under
        displacement control the interference delta - min(h) where that is smaller (a small
        interference gives small pressures, whose gap errors K_ii p are below any tolerance
        of the length scale; under load control the relative load error sees them)."""
        if self._target is not None or self._approach is None:
            return self.length_scale
        if self._h_min is None:
            self._h_min = float(self.heights.min()[1])
        interference = self._approach - self._h_min
        return min(self.length_scale, interference) if interference > 0 else self.length_scale

    @collective_guard
    def _converged(self, snes, it, norms):
        x, f = snes.getSolution(), snes.getFunction()[0]
        err, err_gap, mean_p, frac = self._measures(x, f)
        load_err = (abs(mean_p - self._target) / self._target) if self._target else float("nan")
        solver = "snes-vi+" + self.preconditioner
        if self._root is not self:
            solver += f"@{self.grid.nx}x{self.grid.ny}"
        self.history.append(
            solve=self._root._n_solves, iteration=it, fft_pairs=self._fft_pairs(),
            linear_iterations=self._lin0 + snes.getLinearSolveIterations(),
            complementarity_error=err, load_error=load_err, approach=self._approach,
            mean_pressure=mean_p, contact_fraction=frac, solver=solver, interference_error=err_gap)
        self._last_error = err
        if not err_gap >= self._best[0]:   # NaN never replaces a real iterate
            self._best = (err_gap, it)
            x.copy(self._x_best)
        return convergence_verdict(snes, it, err_gap, self._inner_tol)

    def _operators(self) -> dict:
        ops = {id(self.op): self.op}
        for lev in (self._levels or []):
            ops[id(lev.op)] = lev.op
        if self._coarse:
            ops.update(self._coarse._operators())
        return ops

    def _fft_pairs(self) -> float:
        """FFT pairs of every operator of the root problem (coarse grids weighted by size), cumulative."""
        root = self._root
        return root._retired_pairs + _weighted_pairs(root._operators().values(), root.grid)

    def _release_coarse(self) -> None:
        """Free the coarse problems of the nested iteration once their solution is prolonged.

        They are used once, on the first solve; kept, they would hold a third
        of the fine problem's memory through every later solve.  Their FFT
        pairs stay counted (``_retired_pairs``); the MLMI levels they share
        with the fine problem stay alive.  Collective.
        """
        coarse = self._coarse
        if not coarse:
            return
        root = self._root
        kept = {id(lev.op) for lev in (self._levels or [])}
        gone = [op for k, op in coarse._operators().items() if k not in kept]
        root._retired_pairs += _weighted_pairs(gone, root.grid)
        coarse._destroy_solvers()
        self._coarse = False
        PETSc.garbage_cleanup(self.grid.comm)

    def _destroy_solvers(self) -> None:
        """Destroy the SNES and KSP of this problem and of its coarse problems: their
        callbacks hold the problem, a cycle that Python's collector cannot see."""
        if self._coarse:
            self._coarse._destroy_solvers()
        for obj in (self._snes, self._slope_ksp):
            if obj is not None:
                obj.destroy()
        self._snes = self._slope_ksp = None

    def _solve_at(self, approach: float, pressure: PETSc.Vec, tol: float | None = None):
        """One displacement-controlled SNES solve from ``pressure`` to complementarity
        error ``tol`` (default: the problem's); returns (converged, reason)."""
        snes = self._build()
        self._approach = float(approach)
        self._inner_tol = self.tol if tol is None else max(tol, self.tol)
        pressure.copy(self._x)
        self._lin0 = self.history[-1].linear_iterations if len(self.history) else 0
        self._best = (np.inf, -1)
        snes.solve(None, self._x)
        self._newton += snes.getIterationNumber()
        self._linear += snes.getLinearSolveIterations()
        self._root._n_solves += 1
        reason = snes.getConvergedReason()
        name = _reason_name(reason)
        if reason < 0:
            # a failed SNES leaves whatever its last stage wrote in the solution (after a
            # failed line search: a random vector, VecSetRandom in PETSc's VI Newton): go
            # back to the iterate of smallest error, or to the start if none was measured
            (self._x_best if self._best[1] >= 0 else pressure).copy(self._x)
            name += (f" (state: the iterate of smallest complementarity error, {self._best[0]:.3e} at "
                     f"Newton iteration {self._best[1]})" if self._best[1] >= 0 else " (state: the initial guess)")
        return reason > 0, name

    def _approach_slope(self):
        """(dW/d delta [Pa/m] as d(mean p)/d delta, z = dp/d delta) on the last solve's inactive set.

        Solves K_II z = 1 with its own KSP (options prefix ``<prefix>slope_``),
        preconditioned like the Newton steps.
        """
        g = self.grid
        inactive = (g.rows(self._x, readonly=True) > 0) | (g.rows(self._f, readonly=True) <= 0)
        cached = self._slope_cache
        if cached is not None:
            same = cached[0].shape == inactive.shape and np.array_equal(cached[0], inactive)
            if g.mpi_comm.allreduce(bool(same), op=MPI.LAND):
                return cached[1], cached[2]   # same set, same K_II: same z
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
        guess = self._z_guess if self.slope_warm else None
        if guess is not None:
            # the last z (or the coarse grid's): the set changes little between outer steps
            ctx.from_full(g.rows(guess, readonly=True), z)
        else:
            z.set(0.0)
        ksp.setInitialGuessNonzero(guess is not None)
        ksp.solve(b, z)
        self._linear += ksp.getIterationNumber()
        if self._dp is None:
            self._dp = g.create_vec()
        dp = self._dp   # overwritten in place: the warm start z was read above
        dp.set(0.0)
        ctx.to_full(z, g.rows(dp))
        # petsc4py defers freeing parallel objects to PETSc's garbage until exit:
        # destroy the per-solve temporaries explicitly (collective, all ranks here)
        for obj in (b, z, A, index_set):
            obj.destroy()
        slope = dp.sum() / (self.grid.nx * self.grid.ny)
        self._slope_cache = (inactive, slope, dp)
        self._z_guess = dp
        return slope, dp

    def _solve_load(self, target: float):
        """Safeguarded, inexact Newton on delta; returns (converged, reason).

        W(delta) = mean p is increasing and (for contact of rough surfaces,
        typically) convex, so after the first step the Newton iterates approach
        the root from above; a step is only replaced by bisection when it leaves
        the bracket [lo, hi] of evaluated approaches.  The inner solves are
        inexact: their complementarity tolerance is ``inner_eta`` times the
        last approach update (in units of the length scale), never above
        ``load_inner_tol``; the last solve is to the full tolerance.

        Periodic cells: mean(g) = mean(h) - delta >= 0, so delta <= mean(h) =
        ``bound``, and delta = mean(h) means full contact, where mean p is set
        by the initial guess (the reduced Jacobian keeps the mean of the step at
        zero): a step beyond ``bound`` tries full contact once, with the
        initial pressure's mean set to the target.
        """
        g = self.grid
        n = g.nx * g.ny
        lo = lo0 = float(self.heights.min()[1])  # delta <= min h: no contact, no load
        lo_exact = hi_exact = True
        hi = np.inf                         # smallest evaluated approach with a load above the target
        bound = self.heights.sum() / n if g.periodic else np.inf
        tried_full = False
        delta = self._approach if self._approach is not None else lo
        p = self._pressure.copy()
        inner = max(self.tol, self.inner_tol0)
        slope = 0.0
        reason = "no iteration"
        for _ in range(self.max_outer):
            ok, reason = self._solve_at(delta, p, inner)
            if not ok:
                if delta < bound:
                    return False, reason   # a real failure of the inner solve: report it
                # full contact tried below the full-contact load: no equilibrium there
                hi = min(hi, delta)
                p = self._pressure.copy()
                delta = 0.5 * (lo + min(hi, bound))
                continue
            self._x.copy(p)
            p.copy(self._pressure)
            w = p.sum() / n
            load_err = abs(w - target) / target
            # the load error that a complementarity error tol (a gap error of tol * L,
            # i.e. an approach error of that size) allows: a tighter load_tol cannot be met
            load_tol = max(self.load_tol, 2.0 * slope * self.tol * self.length_scale / target)
            if load_err <= load_tol and load_err > MAX_TOL and self._root is self:
                # a coarse level's state is only a start; the reported one must carry its load
                return False, (f"LOAD_ERROR_UNCONTROLLED (relative load error {load_err:.3e}: at this load the "
                               f"complementarity tol {self.tol:.1e} allows load errors up to {load_tol:.3e}; "
                               f"lower -{self.prefix}tol)")
            if load_err <= load_tol:
                if inner <= self.tol:
                    return True, reason
                inner = self.tol   # right load, loose solve: tighten at the same approach
                continue
            # brackets from inexact (loose) solves are soft: a Newton step may cross them
            exact = inner <= self.tol
            if w < target:
                lo, lo_exact = max(lo, delta), exact
            else:
                hi, hi_exact = min(hi, delta), exact
            slope, dp = self._approach_slope()
            new = delta + (target - w) / slope if slope > 0 else np.inf
            if np.isfinite(new):
                if new >= hi and not hi_exact:
                    hi = np.inf
                if new <= lo and not lo_exact:
                    lo = lo0
            upper = min(hi, bound)
            if lo < new < upper:
                p.axpy(new - delta, dp)  # Newton predictor on the current contact set
                rows = g.rows(p)
                np.maximum(rows, 0.0, out=rows)
            elif new >= bound and hi > bound and not tried_full:
                tried_full = True  # full contact: delta = mean h, mean p from the guess
                new = bound
                p.axpy(new - delta, dp)
                p.shift(target - p.sum() / n)
                rows = g.rows(p)
                np.maximum(rows, 0.0, out=rows)
            elif np.isfinite(upper):
                new = 0.5 * (lo + upper)
            else:
                new = lo + 2.0 * max(delta - lo, self.length_scale)
            inner = max(self.tol, min(self.inner_tol0, self.inner_eta * abs(new - delta) / self.length_scale))
            delta = new
        return False, f"DIVERGED_LOAD_ITERATION ({self.max_outer} approach updates; last SNES {reason})"

    # -- nested iteration (full multigrid) ---------------------------------------------
    def _coarse_problem(self):
        """The same problem on the 2x coarser grid (h averaged over 2 x 2 blocks), or None."""
        if self._coarse is not None:
            return self._coarse or None
        self._coarse = False
        g = self.grid
        if (not self.fmg or not can_halve(g) or max(g.nx, g.ny) // 2 < self.fmg_min_size
                or min(g.nx, g.ny) // 2 < 2):
            return None
        levels = self._levels
        if levels and len(levels) > 1:
            gc, op = levels[1].grid, levels[1].op
        else:
            gc = halved(g)
            # FFTW_MEASURE planning would cost more than the coarse solves themselves
            op = half_space(gc, self.e_star, prefix=self.prefix, planner="estimate")
        hc = gc.create_vec()
        gc.rows(hc)[...] = restrict(g.rows(self.heights, readonly=True))
        d = dict(self._defaults, preconditioner=self.preconditioner, fmg=True)
        coarse = ContactProblem(gc, hc, self.e_star, prefix=self.prefix, length_scale=self.length_scale,
                                operator=op, _root=self._root, **d)
        coarse._levels = levels[1:] if levels and len(levels) > 1 else None
        coarse._build()
        coarse.tol, coarse.load_tol = max(self.fmg_tol, self.tol), max(1e-6, self.load_tol)
        coarse.fmg, coarse.fmg_min_size, coarse.fmg_tol = self.fmg, self.fmg_min_size, self.fmg_tol
        self._coarse = coarse
        return coarse

    def _nested_guess(self, approach, mean_pressure) -> bool:
        """Initial (p, delta) from the coarse problem's solution, prolonged; False if none.

        The coarse dp/d delta (load control) is prolonged too: it starts the
        first fine slope solve."""
        coarse = self._coarse_problem()
        if coarse is None:
            return False
        st = coarse.solve(approach=approach, mean_pressure=mean_pressure, raise_on_failure=False)
        self._newton += st.newton_iterations
        self._linear += st.linear_iterations
        if not st.converged:
            self._release_coarse()
            return False
        g = self.grid
        if self.fmg_prolong == "bilinear":
            prolong = lambda a: prolong_bilinear(a, coarse.grid)  # noqa: E731
        else:
            prolong = prolong_constant
        g.rows(self._pressure)[...] = prolong(coarse.grid.rows(st.pressure, readonly=True))
        if coarse._slope_cache is not None and self.slope_warm:
            # the coarse dp/d delta: the initial guess of the first fine slope solve
            z = g.create_vec()
            g.rows(z)[...] = prolong(coarse.grid.rows(coarse._slope_cache[2], readonly=True))
            self._z_guess = z
        self._approach = st.approach
        self._release_coarse()
        return True

    # -- public API ------------------------------------------------------------------
    def warm_start(self, pressure: PETSc.Vec, approach: float) -> None:
        """Start the next solve from this state (e.g. a step read back on restart)."""
        pressure.copy(self._pressure)
        self._approach = float(approach)

    def snes(self) -> PETSc.SNES:
        """The SNES (built on first request), for PETSc users."""
        return self._build()

    def solve(self, *, approach: float | None = None, mean_pressure: float | None = None,
              force: float | None = None, raise_on_failure: bool = True) -> ContactState:
        """Solve for one approach delta [m] or one load (mean pressure [Pa] or total force [N]).

        The previous solution is the initial guess (warm start along a loading path);
        the first solve starts from the same problem solved on 2x coarser grids
        (nested iteration, ``-<prefix>fmg``, down to ``-<prefix>fmg_min_size`` nodes,
        to complementarity error ``-<prefix>fmg_tol``).
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
        if mean_pressure is not None and mean_pressure < MIN_LOAD * self.e_star:
            # far below any load a contact can carry measurably: the approach that gives it
            # is lost in the round-off of the heights, so its load error cannot be controlled
            name, value, unit, low = (("force", force, "N", MIN_LOAD * self.e_star * area) if force is not None
                                      else ("mean_pressure", mean_pressure, "Pa", MIN_LOAD * self.e_star))
            raise ValueError(f"{name} = {value!r} {unit}: accepted range [{low:.3e}, inf) {unit} "
                             f"(a mean pressure of at least {MIN_LOAD:g} E*: a smaller load is lost in "
                             f"the round-off of the approach)")
        self._build()
        self._target = mean_pressure
        self._newton = self._linear = 0
        pairs0, t0 = self._fft_pairs(), self.history.elapsed()
        if self._approach is None:
            # no previous state: nested iteration, the solution on the 2x coarser grid
            self._nested_guess(approach, mean_pressure)
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
        err, err_gap, mean_p, frac = self._measures(p, gap)
        load_err = abs(mean_p - mean_pressure) / mean_pressure if mean_pressure else float("nan")
        state = ContactState(
            pressure=p, gap=gap, displacement=v, approach=self._approach, mean_pressure=mean_p,
            force=mean_p * area, contact_fraction=frac, complementarity_error=err,
            interference_error=err_gap, load_error=load_err, converged=converged, reason=reason,
            newton_iterations=self._newton, linear_iterations=self._linear,
            fft_pairs=self._fft_pairs() - pairs0, wall_time=self.history.elapsed() - t0)
        # free the parallel temporaries petsc4py parked in PETSc's garbage (collective)
        PETSc.garbage_cleanup(g.comm)
        if not converged and raise_on_failure:
            ksp_reason = _reason_name(self._snes.getKSP().getConvergedReason(), PETSc.KSP.ConvergedReason)
            raise ContactSolveError(
                f"contact solve did not converge: {reason} after {state.newton_iterations} Newton "
                f"iterations (last KSP: {ksp_reason}); complementarity error {err:.3e} "
                f"(tol {self.tol:.1e}) of length scale {self.length_scale:.3e} m, "
                f"load error {load_err:.3e} (tol {self.load_tol:.1e})")
        return state


#: accepted range (0, MAX_TOL] of error tolerances (complementarity, self-consistency, pressure
#: and relative load errors): a larger one accepts states that are not solutions at all
#: (1e300 marks the zero guess converged), and 1e-2 is already a coarse solve
MAX_TOL = 1e-2
#: the smallest mean pressure of load control, in units of E*
MIN_LOAD = 1e-12


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


def _weighted_pairs(ops, fine: SurfaceGrid) -> float:
    """FFT pairs of ``ops`` in units of ``fine``-grid pairs (a coarse pair weighs its size)."""
    n0 = fine.nx * fine.ny
    return float(sum(op.fft_pairs * (op.grid.nx * op.grid.ny) / n0 for op in ops))


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


def _reason_name(reason: int, kind=PETSc.SNES.ConvergedReason) -> str:
    """The name of a SNES (or, with ``kind``, KSP) converged/diverged reason."""
    return next((k for k, v in vars(kind).items() if v == reason and isinstance(v, int)), str(reason))
