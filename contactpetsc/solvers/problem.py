"""``ContactProblem``: non-adhesive (Signorini) contact solved by SNES VI Newton.

Unknown: the nodal pressure p [Pa] (argued in docs/formulation.md): the
constraint p >= 0 is a plain variable bound (``SNESVISetVariableBounds``),
the residual is the gap

    F(p) = g = h + K p - delta          (reference paper, eq. 5)

and the VI "p >= 0, g >= 0, p g = 0" is exactly the Signorini condition,
eq. (4).  A hardness H (perfectly plastic asperities) is the upper bound p <= H
of the same VI: p = 0 => g >= 0, 0 < p < H => g = 0, p = H => g <= 0, the
overlap -g of a node at p = H its plastic displacement (``plasticity.py``).
Its Jacobian is K itself, applied matrix-free by FFT; the reduced-space Newton
method (``vinewtonrsls``) solves K_II dp_I = -g_I on the inactive set by CG,
preconditioned by the Fourier inverse (``SpectralPC``,
the default) or the multilevel MLMI cycle (``mlmi.py``).

Controls: ``approach`` (displacement control, delta given) or a load
(``mean_pressure``, or ``force`` for an isolated contact = mean_pressure *
nx*dx * ny*dy).  Load control is one Newton iteration in (p, delta), delta the
multiplier of the load constraint, each step a projected CG solve
(``contact_load.JointLoadNewton``); with a hardness, a safeguarded Newton
iteration on delta around displacement-controlled solves (docs/formulation.md,
"Controls").  The first solve is nested: coarser grids first.  On a periodic cell K has no mean mode, so
delta is the approach to the mean plane of the deformed surface and full
contact is singular under displacement control: load control handles it.

Options (prefix ``contact_``; every PETSc option of the SNES, KSP and PC but another SNES
type: ``base.check_snes_options``) are read after the code defaults; the package's own are
registered in ``options.py`` (docs/formulation.md, "Options").
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..collective import collective_guard, max_error
from ..grid import SurfaceGrid
from ..lifetime import destroy_at_exit
from ..operators.elastic import HalfSpaceOperator
from ..geometry.surfaces import rms_height
from .backtracking import Backtracking
from .base import (VI_ZERO_TOLERANCE, ContactSolveError, VIProblem, check_tolerance, convergence_verdict,
                   reason_name, weighted_pairs, with_options)
from .contact_load import MIN_LOAD, ContactLoadControl, JointLoadNewton
from .history import SolveHistory
from .nested import NestedIteration
from .options import LINESEARCH_MAX_STEP, code_default, print_help
from .pc_registry import PRECONDITIONERS, preconditioner_name
from .reduced import ContactJacobian
from .plasticity import check_hardness, plastic_measures
from .states import ContactState

#: code defaults of the Newton steps' ``-<prefix>snes_linesearch_type`` and ``ksp_type``:
#: ``basic`` with our backtracking pre-check (``backtracking.py``; full steps alone diverged on
#: the finest grid of the largest contact benchmark, docs/performance.md), and CG (K_II is
#: symmetric positive definite)
NEWTON_LINESEARCH, NEWTON_KSP = "basic", "cg"


#: an rms height below this fraction of the heights or of the cell size is round-off: a plane
FLAT_RMS = 1e-12


class ContactProblem(NestedIteration, Backtracking, JointLoadNewton, ContactLoadControl, VIProblem):
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
        Length [m] the complementarity error is measured in; defaults to the rms height of h
        (the benchmark convention), or dx if h is flat (rms below ``FLAT_RMS`` of its heights or cell).
    operator : HalfSpaceOperator, optional
        Reuse an operator built on the same grid (its E* must equal ``e_star``).
    tol, load_tol : float, optional
        Code defaults of ``-<prefix>tol`` (complementarity error relative to
        ``length_scale``, 1e-10) and ``-<prefix>load_tol`` (relative, 1e-10).
    preconditioner : str, optional
        Code default of ``-<prefix>preconditioner``: spectral, mlmi or none.
    fmg : bool, optional
        Code default of ``-<prefix>fmg`` (nested iteration on the first solve, on).
    hardness : float, optional
        H [Pa], the largest pressure a node carries (perfectly plastic asperities);
        None (default) or inf: elastic.
    petsc_options : dict, optional
        PETSc options under ``prefix`` while the problem builds and solves (``VIProblem``).
    Options given on the command line override these code defaults.
    """

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, *,
                 prefix: str = "contact_", length_scale: float | None = None,
                 operator: HalfSpaceOperator | None = None, tol: float | None = None,
                 load_tol: float | None = None, preconditioner: str | None = None,
                 fmg: bool | None = None, hardness: float | None = None, petsc_options: dict | None = None,
                 _root: "ContactProblem | None" = None):
        for name, value in (("tol", tol), ("load_tol", load_tol)):
            if value is not None:
                check_tolerance(value, name)
        self.hardness = check_hardness(hardness)
        super().__init__(grid, heights, e_star, prefix=prefix, operator=operator, petsc_options=petsc_options)
        self._defaults = dict(tol=tol, load_tol=load_tol, preconditioner=preconditioner, fmg=fmg)
        self._root = _root if _root is not None else self
        self._coarse = None
        if length_scale is None:
            rms = rms_height(grid, heights)
            # a flat surface has no length of its own: rms at round-off of its heights, or of the
            # cell (a detrended plane keeps round-off eps s L of its tilt's span, slope s <= 1)
            flat = rms <= FLAT_RMS * max(abs(heights.max()[1]), abs(heights.min()[1]), *grid.lengths)
            length_scale = grid.dx if flat or rms == 0 else rms
        if not (np.isfinite(length_scale) and length_scale > 0):
            raise ValueError(f"length_scale (m) must be finite and > 0, got {length_scale!r}")
        self.length_scale = float(length_scale)
        self.history = _root.history if _root is not None else SolveHistory()
        self._jac = self._slope_ksp = None
        self._retired_pairs = 0.0  # weighted FFT pairs of released coarse problems' operators
        self._levels = None     # MLMI levels (shared with the coarse problems)
        self._slope_cache = None  # (inactive set, slope, z) of the last slope solve
        self._z_guess = None      # initial guess of the next slope solve (full grid)
        self._dp = None           # dp/d delta of the last slope solve (one Vec, reused)
        self._work = None         # grid-sized scratch of the convergence measures
        self._work2 = None        # and a second one, with a hardness
        self._pressure = grid.create_vec(0.0)   # last converged pressure: the next warm start
        self._approach = None
        self._target = None
        self._joint = False       # load control by the joint Newton step (contact_load.py)
        self._last_gap_error = self._prev_gap_error = None   # the forcing's error history
        self._tangent = None      # M 1 of the last joint Newton step (full rows): the path's predictor
        self._warned_joint = False   # the warning of a Krylov type that turns the joint step off
        self._h_min = None

    # -- set-up ------------------------------------------------------------------
    @with_options
    def _build(self):
        """The SNES, built once with code defaults, then ``setFromOptions``."""
        if self._snes is not None:
            return self._snes
        grid = self.grid
        print_help("contact", self.prefix, self.grid.comm)
        # checked before any PETSc object exists: a refusal leaves nothing half-built
        self.check_snes_options(self.prefix)
        opts = PETSc.Options(self.prefix)
        self.tol = check_tolerance(opts.getReal("tol", self._default("tol")),
                                   f"tol (-{self.prefix}tol)")
        self.load_tol = check_tolerance(opts.getReal("load_tol", self._default("load_tol")),
                                        f"load_tol (-{self.prefix}load_tol)")
        self._jac = ContactJacobian(self.op, self.prefix)
        n_local, n = grid.n_local, grid.nx * grid.ny
        self._J = J = destroy_at_exit(PETSc.Mat().createPython(((n_local, n), (n_local, n)), self._jac,
                                                               comm=grid.comm))
        J.setUp()
        self._x, self._f = grid.create_vec(0.0), grid.create_vec(0.0)
        self._x_best = grid.create_vec(0.0)   # the iterate of smallest error of the running solve
        upper = self.hardness if np.isfinite(self.hardness) else PETSc.INFINITY
        snes = self.make_vi_snes(self.prefix, (grid.create_vec(0.0), grid.create_vec(upper)),
                                 code_default("contact", "snes_max_it"))
        self.set_default("snes_linesearch_type", NEWTON_LINESEARCH)
        self.set_default(LINESEARCH_MAX_STEP, "1e300")   # PETSc's 1e8 is in Pa here
        ksp = snes.getKSP()
        ksp.setType(NEWTON_KSP)
        # inexact Newton: the semismooth Newton method converges linearly with
        # rate ~ rtol once the contact set has settled, so a loose Krylov
        # tolerance costs at most a Newton step or two and saves many Krylov steps
        ksp.setTolerances(rtol=opts.getReal("newton_ksp_rtol", code_default("contact", "newton_ksp_rtol")),
                          max_it=code_default("contact", "ksp_max_it"))
        pc = ksp.getPC()
        choice = opts.getString("preconditioner", self._default("preconditioner")).lower()
        if choice not in PRECONDITIONERS:
            raise ValueError(f"-{self.prefix}preconditioner must be one of "
                             f"{sorted(PRECONDITIONERS)}, got {choice!r}")
        if PRECONDITIONERS[choice] is None:
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType(PRECONDITIONERS[choice])
        self.preconditioner = choice
        self.max_outer = opts.getInt("load_max_it", code_default("contact", "load_max_it"))
        # load control: inexact inner solves (see _solve_load; docs/performance.md)
        self.inner_tol0 = opts.getReal("load_inner_tol", code_default("contact", "load_inner_tol"))
        self.inner_eta = opts.getReal("load_inner_eta", code_default("contact", "load_inner_eta"))
        # nested iteration (full multigrid): first solve on a 2x coarser grid
        self._nested_options(opts)
        self.forcing = opts.getBool("newton_ksp_forcing", code_default("contact", "newton_ksp_forcing"))
        self.load_joint = opts.getBool("load_joint", code_default("contact", "load_joint"))
        self.load_joint_given = opts.hasName("load_joint")
        self.slope_warm = opts.getBool("slope_warm_start", code_default("contact", "slope_warm_start"))
        snes.setFromOptions()
        if opts.getString("snes_linesearch_type", NEWTON_LINESEARCH) == "basic":
            # the code default; another -<prefix>snes_linesearch_type (bt, l2, cp) runs as PETSc has it
            snes.setLineSearchPreCheck(self._backtrack)
            self.vi_zero_tolerance = opts.getReal("snes_vi_zero_tolerance", VI_ZERO_TOLERANCE)
        # -<prefix>pc_type ... may have replaced our choice: record what is in use
        python_type = pc.getPythonType() if pc.getType() == "python" else None
        self.preconditioner = preconditioner_name(python_type, pc.getType())
        self._inner_tol = self.tol
        slope = self._slope_ksp = destroy_at_exit(PETSc.KSP().create(comm=grid.comm))
        slope.setOptionsPrefix(self.prefix + "slope_")
        slope.setType("cg")
        # the slope only sets the next approach (outer Newton): a loose solve is enough
        slope.setTolerances(rtol=1e-2, max_it=500)
        slope.getPC().setType(pc.getType())
        if python_type:
            slope.getPC().setPythonType(python_type)
        slope.setFromOptions()
        if self.preconditioner == "mlmi":
            # built here (not at the first PC set-up) so that the coarse problems of the
            # nested iteration share the levels' grids and operators
            if self._levels is None:
                from .mlmi import build_levels
                self._levels = build_levels(self.op, opts.getInt("mlmi_levels", code_default("contact", "mlmi_levels")),
                                            opts.getInt("mlmi_min_size", code_default("contact", "mlmi_min_size")))
            self._jac.pc_data.mlmi_levels = self._levels
        self._snes = snes
        return snes

    # -- SNES callbacks ------------------------------------------------------------
    @collective_guard
    def _residual(self, snes, x, f):
        x, f = self.grid.rows(x, readonly=True), self.grid.rows(f)
        if not self._reuse_trial(x, f):   # the line search's trial point (backtracking.py)
            self._evaluate_residual(x, f)

    def _evaluate_residual(self, x: np.ndarray, out: np.ndarray) -> None:
        if self._joint:
            self._joint_gap(x, out)
        else:
            self.gap(x, out)

    def _jacobian(self, snes, x, J, P):
        pass  # K does not depend on p: nothing to update

    def _measures(self, x, f):
        """(complementarity error relative to the length scale and to ``_gap_scale``,
        mean pressure, contact fraction).

        The error is the VI's natural residual with the pressure turned into a length by K_ii:
        max |mid(K_ii (p - H), g, K_ii p)|, i.e. max |min(K_ii p, g)| without a hardness."""
        grid = self.grid
        comm = grid.mpi_comm
        p = grid.rows(x, readonly=True)
        if self._work is None:
            self._work = np.empty_like(p)   # one buffer for every evaluation: no per-iteration allocation
        nat = self._work
        if np.isfinite(self.hardness):
            np.subtract(p, self.hardness, out=nat)
            nat *= self.kappa
            np.maximum(nat, grid.rows(f, readonly=True), out=nat)
            if self._work2 is None:
                self._work2 = np.empty_like(p)
            np.minimum(nat, np.multiply(p, self.kappa, out=self._work2), out=nat)
        else:
            np.multiply(p, self.kappa, out=nat)
            np.minimum(nat, grid.rows(f, readonly=True), out=nat)
        # max |min(K_ii p, g)| without an |.| temporary: the larger of max and -min
        local = max(float(nat.max()), -float(nat.min()))
        err = max_error(comm, local)
        sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p)], float))
        n = grid.nx * grid.ny
        return err / self.length_scale, err / self._gap_scale(), sums[0] / n, sums[1] / n

    def _gap_scale(self) -> float:
        """The length [m] the convergence test measures gaps in: the length scale, or under
        displacement control the interference delta - min(h) where that is smaller (a small
        interference gives small pressures, whose gap errors K_ii p are below any tolerance
        of the length scale; under load control the relative load error sees them).  With a
        hardness, at most K_ii H: a node at the wrong bound (open where g < 0, at H where
        g > 0) adds only K_ii H to the natural residual, which a tolerance of a larger
        length would pass (floored at 1e-6 of the length: gap errors of tol times less
        would be round-off of the heights)."""
        scale = self.length_scale
        if self._target is None and self._approach is not None:
            if self._h_min is None:
                self._h_min = float(self.heights.min()[1])
            interference = self._approach - self._h_min
            scale = min(scale, interference) if interference > 0 else scale
        return min(scale, max(self.kappa * self.hardness, 1e-6 * scale))

    @collective_guard
    def _converged(self, snes, it, norms):
        x, f = snes.getSolution(), snes.getFunction()[0]
        err, err_gap, mean_p, frac = self._measures(x, f)
        load_err = (abs(mean_p - self._target) / self._target) if self._target else float("nan")
        solver = "snes-vi+" + self.preconditioner
        if self._root is not self:
            solver += f"@{self.grid.nx}x{self.grid.ny}"
        self.history.append(
            solve=self._root._n_solves, iteration=it, fft_pairs=self.fft_pairs(),
            linear_iterations=self._lin0 + snes.getLinearSolveIterations(),
            complementarity_error=err, load_error=load_err, approach=self._approach,
            mean_pressure=mean_p, contact_fraction=frac, solver=solver, interference_error=err_gap)
        self._last_error = err
        self._last_gap_error = err_gap
        if err_gap < self._best[0]:   # NaN never replaces a real iterate (nor the start, inf)
            self._best = (err_gap, it)
            x.copy(self._x_best)
        verdict = convergence_verdict(snes, it, err_gap, self._inner_tol)
        if self._line_search_failed and verdict == PETSc.SNES.ConvergedReason.ITERATING:
            verdict = PETSc.SNES.ConvergedReason.DIVERGED_LINE_SEARCH
        if (self._joint and verdict == PETSc.SNES.ConvergedReason.CONVERGED_FNORM_ABS
                and not load_err <= self.load_tol):
            # the load is part of the joint problem's error: the step after the last clip
            verdict = convergence_verdict(snes, it, np.inf if np.isnan(load_err) else 1.0, self._inner_tol)
        return verdict

    def _operators(self) -> dict:
        ops = {id(self.op): self.op}
        for lev in (self._levels or []):
            ops[id(lev.op)] = lev.op
        if self._coarse:
            ops.update(self._coarse._operators())
        return ops

    def fft_pairs(self) -> float:
        """FFT pairs of every operator of the root problem (coarse grids weighted by size), cumulative."""
        root = self._root
        return root._retired_pairs + weighted_pairs(root._operators().values(), root.grid)

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
        self._trial, self._line_search_failed = None, False
        snes.solve(None, self._x)
        self._newton += snes.getIterationNumber()
        self._linear += snes.getLinearSolveIterations()
        self._root._n_solves += 1
        reason = snes.getConvergedReason()
        name = reason_name(reason)
        if reason < 0:
            # a failed SNES leaves whatever its last stage wrote in the solution (after a
            # failed line search: a random vector, VecSetRandom in PETSc's VI Newton): go
            # back to the iterate of smallest error, or to the start if none was measured
            (self._x_best if self._best[1] >= 0 else pressure).copy(self._x)
            name += (f" (state: the iterate of smallest complementarity error, {self._best[0]:.3e} at "
                     f"Newton iteration {self._best[1]})" if self._best[1] >= 0 else " (state: the initial guess)")
        return reason > 0, name

    # -- public API ------------------------------------------------------------------
    def warm_start(self, pressure: PETSc.Vec, approach: float) -> None:
        """Start the next solve from this state (e.g. a step read back on restart)."""
        pressure.copy(self._pressure)
        self._approach = float(approach)

    @with_options
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
        grid = self.grid
        area = grid.lengths[0] * grid.lengths[1]
        if force is not None:
            mean_pressure = force / area
        for name, v in (("approach", approach), ("mean_pressure/force", mean_pressure)):
            if v is not None and not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        if mean_pressure is not None and mean_pressure <= 0:
            raise ValueError(f"mean_pressure / force must be > 0 without adhesion, got {mean_pressure!r}")
        if mean_pressure is not None and mean_pressure >= self.hardness:
            # every node carries at most H: a mean pressure H is full plastic contact at any
            # approach past max(h), a larger one has no solution
            name, value, unit, high = (("force", force, "N", self.hardness * area) if force is not None
                                       else ("mean_pressure", mean_pressure, "Pa", self.hardness))
            raise ValueError(f"{name} = {value!r} {unit}: accepted range (0, {high:.6g}) {unit} below the "
                             f"hardness H = {self.hardness:.6g} Pa (no node carries more than H)")
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
        pairs0, t0 = self.fft_pairs(), self.history.elapsed()
        if self._approach is None:
            # no previous state: nested iteration, the solution on the 2x coarser grid
            self._nested_guess(approach, mean_pressure)
        if mean_pressure is None:
            converged, reason = self._solve_at(approach, self._pressure)
            if converged:
                self._x.copy(self._pressure)
        else:
            # with a hardness W(delta) is a staircase: the outer iteration on delta handles it;
            # it also takes over where the joint iteration fails (from the last converged state)
            converged, reason = False, None
            if self._load_by_joint():
                start = self._pressure.copy()
                converged, reason = self._solve_load_joint(mean_pressure)
                if not converged:
                    start.copy(self._pressure)
                start.destroy()
            if not converged:
                joint = reason
                converged, reason = self._solve_load(mean_pressure)
                if joint is not None:
                    reason = f"{reason} (after the joint load iteration's {joint})"
        p = self._x.copy()
        v, gap = grid.create_vec(), grid.create_vec()
        self.gap(grid.rows(p, readonly=True), grid.rows(gap), displacement=grid.rows(v))
        err, err_gap, mean_p, frac = self._measures(p, gap)
        load_err = abs(mean_p - mean_pressure) / mean_pressure if mean_pressure else float("nan")
        plastic = plastic_measures(grid, p, gap, self.hardness)
        state = ContactState(
            pressure=p, gap=gap, displacement=v, approach=self._approach, mean_pressure=mean_p,
            force=mean_p * area, contact_fraction=frac, complementarity_error=err,
            interference_error=err_gap, load_error=load_err, converged=converged, reason=reason,
            newton_iterations=self._newton, linear_iterations=self._linear,
            fft_pairs=self.fft_pairs() - pairs0, wall_time=self.history.elapsed() - t0, **plastic)
        # free the parallel temporaries petsc4py parked in PETSc's garbage (collective)
        PETSc.garbage_cleanup(grid.comm)
        if not converged and raise_on_failure:
            ksp_reason = reason_name(self._snes.getKSP().getConvergedReason(), PETSc.KSP.ConvergedReason)
            raise ContactSolveError(
                f"contact solve did not converge: {reason} after {state.newton_iterations} Newton "
                f"iterations (last KSP: {ksp_reason}); complementarity error {err:.3e} "
                f"(tol {self.tol:.1e}) of length scale {self.length_scale:.3e} m, "
                f"load error {load_err:.3e} (tol {self.load_tol:.1e})")
        return state
