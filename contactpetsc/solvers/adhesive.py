"""``AdhesiveProblem``: adhesive contact (reference paper, sections 2 and 3.1) by SNES VI Newton.

Unknowns (argued in docs/formulation.md): the contact pressure q >= 0 and
the adhesive pressure a, stored apart as in the paper, p = q + a.  For the
full Lennard-Jones curve (eq. 8) there is no wall and a alone is the
pressure.  The residual is

    F_q = g = h + K p - delta          (q >= 0, g >= 0, q g = 0: eq. 7a)
    F_a = kappa (a - a(g))             (a(g): the law, nodal or element-integrated)

so the bound q >= 0 is a plain variable bound of ``SNESVINEWTONRSLS`` and the
VI is exactly eq. (7) (or eq. 8).  ``adhesive_jacobian.py`` has the Jacobian,
its reduced version and the block preconditioner (spectral on the contact-like
rows); ``adhesive_mlmi.py`` the multilevel cycle on the whole system.

Globalisation (the problem is non-convex): Newton steps only start from a
converged neighbouring state (tangent predictor; line search ``newton_linesearch``);
where Newton fails or stalls, the fallback chain (``fallback.py``) follows
a relaxation path.  Every converged state is checked for stability
(``stability.py``, 1 - lambda_max of the pencil A, (K^-1)_NN); an unstable state is
reported as such, never passed off as a point of the path.

Controls: ``approach`` delta [m] (displacement control) or ``central_gap``
[m] (the gap at the apex node is prescribed and delta follows: Greenwood's
device, which traces the unstable branch of the S-shaped curve of a sphere).

Errors (``_measures``): the complementarity error max |min(K_ii q, g)| and the
self-consistency error max K_ii |a - a(g)| in z0 (with the paper's E_Total per
state) vanish with the pressures when w / (E* z0) is small, so a state also
needs the pressure error relative to the law's peak attraction below the tolerance.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from ..grid import SurfaceGrid
from ..operators.elastic import HalfSpaceOperator
from ..physics.interactions import InteractionLaw
from ..physics.resolution import check_resolution, resolution_note, snap_number, steepest_slope
from ..physics.traction import AdhesiveTraction
from .adhesive_jacobian import AdhesiveJacobian
from .adhesive_levels import CoarseLevels
from .adhesive_residual import AdhesiveCallbacks
from .branch_check import BranchCheck
from .base import AdhesiveSolveError, VIProblem, check_tolerance, reason_name, with_options
from .continuation import Continuation
from .control_node import ControlNode
from .descent_step import descend_step
from .descent_options import descent_applies, descent_options, require_descent, strategy_option
from .fallback import FallbackChain
from .history import SolveHistory
from .load_control import solve_force
from .newton import VINewton, newton_linesearch
from .options import code_default, print_help
from .pc_registry import ADHESIVE_PRECONDITIONERS, auto_adhesive_preconditioner
from .predictor import TangentPredictor
from .states import AdhesiveState
from .stability import StabilityCheck
from .tangent import TangentAndState

__all__ = ["AdhesiveProblem", "AdhesiveSolveError", "AdhesiveState"]

class AdhesiveProblem(AdhesiveCallbacks, Continuation, ControlNode, TangentAndState, VIProblem):
    """Adhesive contact of an elastic half-space with a rigid composite surface h.

    Parameters
    ----------
    grid : SurfaceGrid
    heights : PETSc.Vec
        Composite surface h [m].
    e_star : float
        Effective modulus E* [Pa].
    law : InteractionLaw
        A law with adhesion (``physics.interactions.adhesive_laws``; ``none``: use ``ContactProblem``).
    element_integration : bool
        Code default of ``-<prefix>element_integration`` (off).
    prefix : str
        Options prefix of the SNES, KSP and PC (default ``adhesion_``).
    tol : float
        Code default of ``-<prefix>tol``: the errors above, in z0 (1e-8).
    preconditioner : str
        Code default of ``-<prefix>preconditioner``: auto (default: mlmi or spectral per grid from
        its snap number, ``pc_registry.auto_adhesive_preconditioner``), spectral, mlmi or none.
    stability_check : bool or "auto"
        Code default of ``-<prefix>stability_check`` (on): true checks every converged state,
        false none, auto lets a sweep leave it out away from folds (``fold_watch.py``).
    centre : (i, j), optional
        Node of the central-gap control; default: the lowest node of h.
    petsc_options : dict, optional
        PETSc options under ``prefix`` while the problem builds and solves (``VIProblem``).
    """

    option_table = "adhesion"

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, law: InteractionLaw, *,
                 element_integration: bool | None = None, prefix: str = "adhesion_",
                 operator: HalfSpaceOperator | None = None, tol: float | None = None,
                 preconditioner: str | None = None, stability_check: bool | str | None = None,
                 centre: tuple[int, int] | None = None, petsc_options: dict | None = None):
        if not law.adhesive:
            raise ValueError(f"law {law.name!r} has no adhesion: use ContactProblem")
        grid.require_slabs("the adhesive solver")
        if tol is not None:
            check_tolerance(tol, "tol")
        super().__init__(grid, heights, e_star, prefix=prefix, operator=operator, petsc_options=petsc_options)
        self.law = law
        self.z0 = law.length_scale()
        self.pressure_scale = float(law.peak_attraction)   #: P [Pa], the pressure error's unit
        with self.inserted_options():
            self.element_integration = PETSc.Options(prefix).getBool(
                "element_integration", bool(element_integration) if element_integration is not None
                else code_default("adhesion", "element_integration"))
        self.traction = AdhesiveTraction(law, grid, self.element_integration)
        self.zone_nodes = check_resolution(law, self.e_star, max(grid.dx, grid.dy))
        self.snap_number = snap_number(law, self.kappa)   # K_ii max da/dg
        self.hard_wall = law.hard_wall
        self.n_blocks = 2 if self.hard_wall else 1
        self._defaults = dict(tol=tol, preconditioner=preconditioner, stability_check=stability_check)
        comm = grid.mpi_comm
        n_local = self.n_blocks * grid.nx * grid.ny_local
        self.offset = comm.scan(n_local) - n_local
        self.n_local, self.n_global = n_local, comm.allreduce(n_local)
        self.set_control_node(centre)
        self.centre_owner = None        # set while central-gap control is active
        self.shift = 0.0                # pseudo-transient continuation shift (0: plain Newton)
        self.newton = None              # VI Newton (``VINewton``), made with the solvers
        self.check_time = 0.0          # stability check and tangent time of the current solve
        self.predictor = None           # the tangent predictor (``TangentPredictor``), made with the solvers
        self.branch_check = None        # the branch check (``BranchCheck``), made with the solvers
        self.stability_check = None     # the stability check (``StabilityCheck``), made with the solvers
        self.history = SolveHistory()
        self._x = None
        self._started = False           # a state exists (solved, warm-started or restored)
        self._approach = None
        self._central_gap = None
        self._gap_rows = None           # repulsive rows in gap form at the last Jacobian (mask)
        self._gap_slope = None          # G'(a) on those rows
        self._gap_at = None             # (flat positions, G'(a)) of those rows
        self._adhesive_residual = np.nan  # local max kappa |a - a(g)| at the last residual
        self._pressure_residual = np.nan  # local max |a - a(g)| / (P + |a(g)|) there
        self.coarse_levels = None       # the nested iteration (``CoarseLevels``), made with the solvers
        self.fallback = None            # the fallback chain (``FallbackChain``), made with the solvers
        # the compliance's CG iterations that the last descent's V-cycle beat to its end (``auto``:
        # the next descent starts with the cycle, held to them; 0: it starts with the compliance)
        self.descent_cycle_won = 0
        self._start_approach = None     # approach [m] of the state in the unknowns (its last solve's if converged)
        #: the next loading step descends first: Newton failed on a loading step since the approach
        #: last fell (``-<prefix>loading_descent``; kept in snapshots and a run's step files)
        self.descending_loading = False
        self._released_pairs = 0.0      # weighted FFT pairs of the preconditioner levels ``release`` freed
        self._prev_approach = None
        self._budget_start = None       # time.monotonic() at the first solve under a time budget
        self._scratch = None            # (gap, displacement) rows: ``_g``, ``_v``
        self._x_start = None            # the running solve's start (``saved_start``)

    # -- scratch rows (made on demand, freed by ``release``) ----------------------------------
    def _scratch_rows(self, k: int) -> np.ndarray:
        if self._scratch is None:
            shape = (self.grid.ny_local, self.grid.nx)
            self._scratch = (np.zeros(shape), np.zeros(shape))
        return self._scratch[k]

    _g = property(lambda self: self._scratch_rows(0), doc="the gap [m] of the last residual or Jacobian")
    _v = property(lambda self: self._scratch_rows(1), doc="the displacement K p [m] of the last residual")

    # -- layout ------------------------------------------------------------------------
    def blocks(self, vec: PETSc.Vec, readonly: bool = False) -> np.ndarray:
        """The rank's part of an unknown Vec as (n_blocks, ny_loc, nx): [q,] a."""
        return vec.getArray(readonly=readonly).reshape(self.n_blocks, self.grid.ny_local, self.grid.nx)

    def create_unknown(self) -> PETSc.Vec:
        v = PETSc.Vec().createMPI((self.n_local, self.n_global), comm=self.grid.comm)
        v.set(0.0)
        return v

    def vi_bounds(self) -> tuple[PETSc.Vec, PETSc.Vec] | None:
        """The VI's bounds on the unknowns, made for one Newton run (``VINewton.run``, which
        destroys them): a hard wall's q >= 0 (a free); None for the full LJ curve, whose SNES
        VI makes its infinite ones itself.  Between states neither is kept (two unknown Vecs,
        4 doubles per grid point)."""
        if not self.hard_wall:
            return None
        lower, upper = self.create_unknown(), self.create_unknown()
        upper.set(PETSc.INFINITY)
        lower.set(PETSc.NINFINITY)
        self.blocks(lower)[0] = 0.0
        return lower, upper

    # -- set-up ---------------------------------------------------------------------------
    @with_options
    def _build(self):
        if self._snes is not None:
            return self._snes
        print_help("adhesion", self.prefix, self.grid.comm)
        # checked before any PETSc object exists: a refusal leaves nothing half-built
        self.check_snes_options(self.prefix, self.prefix + "ptc_")
        opts = PETSc.Options(self.prefix)
        self.tol = check_tolerance(opts.getReal("tol", self._default("tol")),
                                   f"tol (-{self.prefix}tol)")
        self.max_it = opts.getInt("max_it", code_default("adhesion", "max_it"))
        self.stability_check = StabilityCheck(self, self._default("stability_check"))
        self.fallback = FallbackChain(self)
        # every state descends from the last where the descent applies: the full LJ curve's
        # predicted Newton steps hop between neighbouring branches (paths at 1/64 of a step
        # still alternate between two states on consecutive steps), while the descent's states
        # follow the branch a quasi-static path follows (docs/performance.md, "Quasi-static
        # limit of a load-unload path"); a hard wall's predicted Newton step reaches the same
        # quasi-static states, but it is no descent (at a jump it runs and fails before the
        # fallback descends) and holds a third more memory (docs/performance.md, "The hard
        # wall under the descent strategy")
        self.strategy = strategy_option(self.prefix, descent_applies(self) and self.grid.periodic)
        if self.strategy == "descent":
            require_descent(self, f"-{self.prefix}strategy descent")
        descent_options(self.prefix)    # bad input is refused at set-up, not at the first descent
        # past the wall-time budget every solve stops (WALL_TIME_BUDGET): a batch job ends
        # cleanly with its finished steps written, an unresolvable case in bounded time
        self.time_budget = opts.getReal("time_budget", code_default("adhesion", "time_budget"))
        if not self.time_budget >= 0.0:
            raise ValueError(f"-{self.prefix}time_budget must be >= 0 s (0: no budget), got {self.time_budget!r}")
        self.predictor = TangentPredictor(self)
        self.branch_check = BranchCheck(self)
        # under the Newton strategy: after a loading step whose Newton failed, descend the loading
        # steps that follow.  With a hard wall the nodes at an advancing contact edge snap onto it
        # one after another, which the tangent's prediction cannot see; the receding neck of an
        # unloading step it predicts.  By default on an isolated window with a hard-wall law that
        # has a slope: the full LJ curve's Newton converges on those steps for fewer pairs, and
        # a step law's zone edge has an equilibrium on either side of the step, of which the
        # descent may take the other (docs/performance.md, "The adhesive sphere's states")
        by_default = self.hard_wall and not self.grid.periodic and steepest_slope(self.law) > 0.0
        self.loading_descent = (opts.getBool("loading_descent", by_default)
                                and self.strategy == "newton" and descent_applies(self))
        # off by default: at hard-wall, high-Tabor jump-ins the relaxation fallback can need
        # thousands of cycles from rest; sweeps that start from separation get the same state
        self.load_from_rest = opts.getBool("load_from_rest", code_default("adhesion", "load_from_rest"))
        self.initial_step = opts.getReal("initial_step", code_default("adhesion", "initial_step"))
        form = opts.getString("repulsive_rows", code_default("adhesion", "repulsive_rows")).lower()
        if form not in ("gap", "pressure"):
            raise ValueError(f"-{self.prefix}repulsive_rows must be gap or pressure, got {form!r}")
        # the gap form needs the law's inverse: the nodal rule of the full LJ curve
        self.gap_form = form == "gap" and self.traction.invertible
        self.step_limit = opts.getReal("step_limit", 0.5 if self.traction.invertible else 0.0)
        self.coarse_levels = CoarseLevels(self)
        choice = opts.getString("preconditioner", self._default("preconditioner")).lower()
        if choice != "auto" and choice not in ADHESIVE_PRECONDITIONERS:
            raise ValueError(f"-{self.prefix}preconditioner must be auto, spectral, mlmi or none, got {choice!r}")
        # auto: chosen from this grid's own snap number, so each level of the nested
        # iteration (whose snap number doubles per coarsening) chooses for itself
        self.preconditioner_choice = choice
        self.preconditioner = auto_adhesive_preconditioner(self.snap_number, self.hard_wall) if choice == "auto" else choice
        self._jac = AdhesiveJacobian(self)
        from ..lifetime import destroy_at_exit
        J = destroy_at_exit(PETSc.Mat().createPython(((self.n_local, self.n_global),) * 2,
                                                     self._jac, comm=self.grid.comm))
        J.setUp()
        # no residual Vec of the problem's own: each Newton run makes one (``VINewton.run``)
        self._x, self._f = self.create_unknown(), None
        self._x_solve_best = None   # the iterate of smallest error of the running solve
        self._solve_best = (np.inf, "")
        self._J = J
        self.newton = VINewton(self, self.prefix, newton_linesearch(self.hard_wall), self.max_it,
                               code_default("adhesion", "ksp_max_it"), polishes=self.strategy == "descent")
        self._snes = self.newton.snes
        self.fallback.build()
        return self._snes

    def release(self) -> None:
        """Free what only a running solve needs (memory between states; docs/performance.md,
        "Memory of an adhesive path"): the best iterates, the preconditioners' levels and
        arrays, the products' scratch (each Newton run frees its SNES's work vectors); under
        the descent strategy the nested iteration's levels too (they gave the first state;
        every later state is descended from the last).  All are made again on demand.
        Collective."""
        if self.newton is None:
            return      # not built: nothing made yet
        self.newton.release()
        if self.fallback.ptc is not None:
            self.fallback.ptc.release()
        self._released_pairs += self._jac.release()
        self._scratch = self._gap_mark = None
        self._drop_solve_best()
        self._drop_start()
        if self.strategy == "descent":
            self.coarse_levels.release()

    # -- public API --------------------------------------------------------------------------
    @property
    def descends(self) -> bool:
        """Whether a solve at an approach descends from the last state (``-<prefix>strategy
        descent``, the default on periodic grids with the nodal rule); sets the problem up."""
        self._build()
        return self.strategy == "descent"

    def solve_force(self, force: float, *, rel_tol: float = 1e-8, max_updates: int = 30,
                    raise_on_failure: bool = True) -> AdhesiveState:
        """Load control where it is stable: ``load_control.solve_force`` on this problem."""
        return solve_force(self, force, rel_tol=rel_tol, max_updates=max_updates,
                           raise_on_failure=raise_on_failure)

    @with_options
    def solve(self, *, approach: float | None = None, central_gap: float | None = None,
              raise_on_failure: bool = True, check_stability=None,
              fallback: bool = True, increments: int | None = None, tangent: bool = True) -> AdhesiveState:
        """Solve at one approach delta [m] or one central gap [m].

        ``check_stability``: None (``-<prefix>stability_check``), a bool, or a function
        ``(newton, force) -> bool`` that decides from Newton's converged state (its
        iterations, net force [N]) whether it is checked (``paths.sweep`` under ``auto``);
        where Newton fails, the fallback's states are checked.

        Starts from the previous solution (warm start along a loading path, with
        the tangent predictor under displacement control); the first solve starts
        from the Signorini solution, or with ``-<prefix>load_from_rest`` loads from
        separation (``_load_from_rest``).  Under displacement control, when Newton
        fails or lands on an unstable state, ``fallback`` continues with
        pseudo-transient continuation from the previous state (a jump).

        ``increments``: under the descent strategy, the step from the last state is descended
        in that many equal increments (``descent_step.descend_step``) instead of those of
        ``-<prefix>descent_max_step``.  ``tangent``: false leaves the state's tangent stiffness out
        (NaN) whatever ``-<prefix>stiffness`` says: a probe that is not kept (``paths``).
        """
        if (approach is None) == (central_gap is None):
            raise ValueError("give exactly one of approach (m) or central_gap (m)")
        for name, v in (("approach", approach), ("central_gap", central_gap)):
            if v is not None and not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        self._build()
        self._gap_mark = None   # the scratch gap is not this solve's (``_current_gap``)
        # PETSc objects the caller has let go of (a path's state before last) are freed here,
        # not at the end of this solve: they would be alive at its descent's peak
        PETSc.garbage_cleanup(self.grid.comm)
        # the first state (coarse grids, Signorini) is part of this solve's cost
        pairs0, t0 = self.fft_pairs(), self.history.elapsed()
        if self.out_of_time():
            if raise_on_failure:
                raise AdhesiveSolveError(f"adhesive solve not started: {self.budget_reason}")
            if self._approach is None:
                self._approach = float(approach) if approach is not None else self.centre_value(
                    self.grid.rows(self.heights, readonly=True)) - float(central_gap)
            return self.make_state(False, self.budget_reason + " (state: the last converged state's pressures)",
                               0, 0, pairs0, t0, float("nan"), self.solver_name)
        reason = self.no_equilibrium(approach) if approach is not None else None
        if reason:
            if raise_on_failure:
                raise AdhesiveSolveError(f"adhesive solve at approach {approach:.4e} m: {reason}")
            self._approach = float(approach)
            return self.make_state(False, reason, 0, 0, pairs0, t0, float("nan"), self.solver_name)
        if not self._started:
            if approach is not None and self.load_from_rest:
                return self._load_from_rest(approach, raise_on_failure, check_stability)
            if approach is not None:
                self._initial_guess(approach)
            else:
                h_c = self.centre_value(self.grid.rows(self.heights, readonly=True))
                self._initial_guess(h_c - central_gap)
            self._started = True
        if central_gap is not None:
            self.centre_owner = self._centre_rank
            self._central_gap = float(central_gap)
        else:
            self.centre_owner = None
            self._prev_approach, self._approach = self._approach, float(approach)
        self.check_time = 0.0
        self._solve_best = (np.inf, "")
        self._drop_start()
        # -<prefix>strategy descent: the energy descent from the last state, Newton polishes;
        # loading: a step up from the state in the unknowns (not a failed solve's approach)
        loading = (approach is not None and self._start_approach is not None
                   and float(approach) > self._start_approach)
        if not loading:
            self.descending_loading = False
        descend = approach is not None and (self.strategy == "descent" or self.descending_loading)
        if descend:
            # from the unknowns themselves: the descent saves them as it writes its state
            # (``saved_start``), so that its peak does not hold a copy
            ok, d_reason, d_newton, d_linear, increments, _ = descend_step(self, float(approach), self._x, increments)
            # the descent's PETSc objects (and through their contexts its arrays) are freed
            # here, not at the end of the solve: Newton and the check come first
            PETSc.garbage_cleanup(self.grid.comm)
        x_start = self.saved_start()
        if not descend:
            self.branch_check.start(approach)     # a descended step is the check's own truth
        coarse_predicted = (not descend and approach is not None
                            and self.coarse_levels.predict(float(approach), self._prev_approach))
        if not (coarse_predicted or descend) and approach is not None:
            self.predictor.predict(float(approach))
        check = self.stability_check.by_default if check_stability is None else check_stability
        # only where PTC or the descent would take over
        self.newton.watch_stalls = fallback and approach is not None and self.fallback.takes_over_stalls()
        converged, reason, newton, linear = self.newton.run()
        self.newton.watch_stalls = False
        solver = self.solver_name
        if descend:
            steps = f" in {increments} increments" if increments > 1 else ""
            solver, newton, linear = f"descent{steps}+{solver}", newton + d_newton, linear + d_linear
            if not ok:
                reason += f" (after {d_reason})"
        if callable(check):
            check = not converged or bool(check(newton, self.net_force()))
        margin = self.stability_check.margin() if (converged and check) else float("nan")
        if fallback and approach is not None and (not converged or margin <= 0) and not self.out_of_time():
            if converged:
                reason = f"UNSTABLE (stability margin {margin:.3e})"
            converged, reason, newton, linear, margin, solver = self.fallback.follow(
                approach, x_start, check, newton, linear, solver, reason, skip=("descent",) if descend else ())
        elif (converged and fallback and approach is not None and not margin <= 0 and not self.out_of_time()
              and not descend and self.branch_check.missed(approach)):
            # a state the check replaces is checked, whatever a sweep's watch decided for Newton's
            taken, n2, l2, m2, increments = self.branch_check.follow(approach, x_start,
                                                                     check or callable(check_stability))
            newton, linear, reason = newton + n2, linear + l2, reason + self.branch_check.note
            if taken:
                margin, descend, solver = m2, True, f"{solver}+branch-descent"
        if self.loading_descent and loading and not descend and converged and solver.endswith("+descent"):
            self.descending_loading = True
        if not converged:
            # the state reported: the iterate of smallest error (never what a failed SNES
            # left in its solution); the next solve starts from the last converged state
            if np.isfinite(self._solve_best[0]):
                self._x_solve_best.copy(self._x)
                reason += (f" (state: the iterate of smallest error, {self._solve_best[0]:.3e}, at "
                           f"{self._solve_best[1]}; the next solve starts from the last converged state)")
            else:
                x_start.copy(self._x)
                reason += " (state: the last converged state's pressures; no iterate was measured)"
            reason += resolution_note(self.snap_number, self.zone_nodes)
        # neither the best iterate nor (once converged) the start is wanted any more: freed
        # before the state's tangent, whose Krylov solve is a path's peak of memory
        self._drop_solve_best()
        if converged:
            self._drop_start()
        state = self.make_state(converged, reason, newton, linear, pairs0, t0, margin,
                                solver, tangent=tangent and approach is not None and converged)
        state.descent_increments = increments if descend else 0
        if converged:
            self._start_approach = self._approach
        else:
            x_start.copy(self._x)   # keep the last good state as the next start (freed by ``release``)
        self.centre_owner = None
        self.release()
        PETSc.garbage_cleanup(self.grid.comm)
        if not converged and raise_on_failure:
            ksp_reason = reason_name(self.newton.last_ksp_reason, PETSc.KSP.ConvergedReason)
            raise AdhesiveSolveError(
                f"adhesive solve did not converge: {reason} after {newton} Newton iterations "
                f"(last KSP: {ksp_reason}); complementarity error {state.complementarity_error:.3e}, "
                f"self-consistency error {state.adhesive_error:.3e} z0, pressure error "
                f"{state.pressure_error:.3e} of the peak attraction (tol {self.tol:.1e})")
        return state
