"""``AdhesiveProblem``: adhesive contact (reference paper, sections 2 and 3.1) by SNES VI Newton.

Unknowns (argued in docs/formulation.md): the contact pressure q >= 0 and
the adhesive pressure a, stored apart as in the paper, p = q + a.  For the
full Lennard-Jones curve (eq. 8) there is no wall and a alone is the
pressure.  The residual is

    F_q = g = h + K p - delta          (q >= 0, g >= 0, q g = 0: eq. 7a)
    F_a = kappa (a - a(g))             (a(g): the law, nodal or element-integrated)

so the bound q >= 0 is a plain variable bound of ``SNESVINEWTONRSLS`` and the
VI is exactly eq. (7) (or eq. 8).  ``adhesive_jacobian.py`` has the Jacobian,
its reduced version and the block preconditioner (spectral or MLMI on the
contact-like rows).

Globalisation: the problem is non-convex.  Newton steps only ever start from
a converged neighbouring state (tangent predictor), with a backtracking line
search (``bt``) on the VI residual norm for hard-wall laws -- a trust region
would also do, but the line search keeps the full Newton step whenever it
reduces the residual, which is what warm-started steps need -- and full
steps (``basic``) for the full LJ curve, whose residual norm is dominated by
the stiff repulsive rows (measured better).  When Newton fails, a
relaxation path takes over (``solve``); when it stalls (no smaller error in
``-<prefix>stall_steps`` steps: full steps cycling where a few nodes of one
contact edge sit at their own fold), pseudo-transient continuation goes on
from its best iterate.  Every
converged state is checked for stability (``stability.py``): the smallest
eigenvalue of the displacement-space Hessian relative to the elastic one,
1 - lambda_max(A S), by Lanczos; an unstable state is reported as such
(``AdhesiveState.stable`` False), never passed off as a point of the path.

Controls: ``approach`` delta [m] (displacement control) or ``central_gap``
[m] (the gap at the apex node is prescribed and delta follows: Greenwood's
device, which traces the unstable branch of the S-shaped curve of a sphere).

Errors (in units of z0, the law's range): the complementarity error
max |min(K_ii q, g)|, the self-consistency error max K_ii |a - a(g)|, and the
paper's E_Total (rms of the gap change when a is replaced by a(g), steps 1-4 of
section 2), computed for every converged state.  These are K_ii times pressure
errors and vanish with the pressures when w / (E* z0) is small, so a state
converges only when the pressure error on the law's own scale (``_measures``:
relative to the peak attraction P) is below the tolerance too.
"""
from __future__ import annotations

import time
import warnings
from dataclasses import dataclass

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_guard
from ..grid import SurfaceGrid
from ..lifetime import destroy_at_exit
from ..operators.elastic import HalfSpaceOperator, half_space
from ..physics.interactions import InteractionLaw
from ..physics.resolution import RESOLUTION_NODES, UnderResolvedWarning, check_resolution
from ..physics.traction import AdhesiveTraction
from .adhesive_jacobian import AdhesiveJacobian, minloc
from .history import SolveHistory
from .problem import ContactSolveError, _reason_name, check_heights, check_tolerance, convergence_verdict
from .transfer import can_halve, halved, prolong_bilinear, prolong_constant, restrict


def newton_ksp_type(hard_wall: bool) -> str:
    """The Krylov method of the Newton and PTC steps (code default of ``-<prefix>ksp_type``).

    Full LJ curve: BiCGStab.  Its two operator and two PC applies per iteration cost
    one FFT pair each, like two GMRES iterations, but it keeps no basis: GMRES's
    Gram-Schmidt over up to 30 vectors of the whole grid cost as much as the FFTs (rough
    benchmark at 1024^2: 24 against 35 ms per FFT pair, and no failed state on four
    approach sets where GMRES failed one after 20,000 pairs; docs/performance.md, session
    8).  Hard-wall laws: GMRES (not measured against BiCGStab).
    """
    return "gmres" if hard_wall else "bcgs"


class AdhesiveSolveError(ContactSolveError):
    """An adhesive solve that did not converge (same message on every rank)."""


@dataclass
class AdhesiveState:
    """A solved adhesive contact state; Vecs on the problem's grid."""
    pressure: PETSc.Vec           #: total p = q + a [Pa]
    contact_pressure: PETSc.Vec   #: q >= 0 [Pa] (zero for the full LJ curve)
    adhesive_pressure: PETSc.Vec  #: a [Pa]
    gap: PETSc.Vec                #: g [m]
    displacement: PETSc.Vec       #: v = K p [m]
    approach: float               #: delta [m]
    central_gap: float            #: gap at the centre node [m]
    mean_pressure: float          #: [Pa]
    force: float                  #: net normal force [N] (negative = tensile)
    adhesive_force: float         #: sum of the negative pressures times the element area [N]
    contact_fraction: float       #: fraction of nodes with p > 0
    complementarity_error: float  #: [z0]
    adhesive_error: float         #: max K_ii |a - a(g)| [z0]
    #: max of |a - a(g)| / (P + |a(g)|) and |min(q / P, g / z0)|, P the law's peak attraction [-]
    pressure_error: float
    total_error: float            #: the paper's E_Total [z0]
    stable: bool | None           #: None when not checked
    stability_margin: float       #: 1 - lambda_max(A S): > 0 stable, < 0 unstable
    stiffness: float              #: tangent dF/d delta [N/m] (displacement control); NaN if not computed (-<prefix>stiffness false)
    converged: bool
    reason: str
    newton_iterations: int
    linear_iterations: int
    fft_pairs: float
    wall_time: float
    check_time: float = 0.0       #: [s] of wall_time spent on the stability check and the tangent
    #: False when the Lanczos estimate had not settled after -<prefix>stability_steps: a positive
    #: margin is then an upper bound (None when not checked)
    stability_converged: bool | None = None
    solver: str = "newton"
    fallback: bool = False        #: Newton from the previous state failed: a relaxation path was followed


class AdhesiveProblem:
    """Adhesive contact of an elastic half-space with a rigid composite surface h.

    Parameters
    ----------
    grid : SurfaceGrid
    heights : PETSc.Vec
        Composite surface h [m].
    e_star : float
        Effective modulus E* [Pa].
    law : InteractionLaw
        ``hardwall-lj``, ``lj``, ``exponential`` or ``dugdale`` (``none``: use ``ContactProblem``).
    element_integration : bool
        Code default of ``-<prefix>element_integration`` (off).
    prefix : str
        Options prefix of the SNES, KSP and PC (default ``adhesion_``).
    tol : float
        Code default of ``-<prefix>tol``: the errors above, in z0 (1e-8).
    preconditioner : str
        Code default of ``-<prefix>preconditioner``: spectral (default), mlmi or none.
    stability_check : bool
        Code default of ``-<prefix>stability_check`` (on).
    centre : (i, j), optional
        Node of the central-gap control; default: the lowest node of h.
    """

    def __init__(self, grid: SurfaceGrid, heights: PETSc.Vec, e_star: float, law: InteractionLaw, *,
                 element_integration: bool | None = None, prefix: str = "adhesion_",
                 operator: HalfSpaceOperator | None = None, tol: float | None = None,
                 preconditioner: str | None = None, stability_check: bool | None = None,
                 centre: tuple[int, int] | None = None):
        if law.name == "none":
            raise ValueError("law 'none' has no adhesion: use ContactProblem")
        check_heights(grid, heights)
        if tol is not None:
            check_tolerance(tol, "tol")
        self.grid, self.heights, self.law, self.prefix = grid, heights, law, prefix
        self.op = operator if operator is not None else half_space(grid, e_star, prefix=prefix)
        if not np.isclose(self.op.e_star, e_star, rtol=1e-12, atol=0.0):
            raise ValueError(f"e_star = {e_star!r} Pa differs from the operator's E* = {self.op.e_star!r} Pa")
        self.e_star = self.op.e_star
        self.kappa = self.op.self_influence
        self.z0 = law.length_scale()
        self.pressure_scale = float(law.peak_attraction)   #: P [Pa], the pressure error's unit
        opts = PETSc.Options(prefix)
        self.element_integration = opts.getBool(
            "element_integration", bool(element_integration) if element_integration is not None else False)
        self.traction = AdhesiveTraction(law, grid, self.element_integration)
        self.zone_nodes = check_resolution(law, self.e_star, max(grid.dx, grid.dy))
        # K_ii max da/dg: above one a single node is unstable on its own (its adhesive
        # stiffness beats its elastic one), so the discrete problem has an equilibrium for
        # every subset of snapped nodes -- the adhesive range is under-resolved by the grid
        probe = np.linspace(0.0, 20.0, 20001) * law.length_scale()
        self.snap_number = float(self.kappa * max(0.0, float(np.max(self.traction._derivative(probe)))))
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
        self._stall_watch = False       # stop a stalled Newton (see -<prefix>stall_steps)
        self._check_time = 0.0          # stability check and tangent time of the current solve
        self._tangent = None            # (approach, dx/d delta, dF/d delta) at the last converged state
        self._tangent_due = None        # approach of the present state when its tangent is not computed yet
        self.compute_tangent = True     # the tangent and stiffness of converged displacement-controlled states
        self.stability_converged = None  # whether the last stability check's Lanczos settled
        self.history = SolveHistory()
        self._snes = None
        self._n_solves = 0
        self._x = None
        self._approach = None
        self._central_gap = None
        self._gap_rows = None           # repulsive rows in gap form at the last Jacobian (mask)
        self._gap_slope = None          # G'(a) on those rows
        self._gap_at = None             # (flat positions, G'(a)) of those rows
        self._adhesive_residual = np.nan  # local max kappa |a - a(g)| at the last residual
        self._pressure_residual = np.nan  # local max |a - a(g)| / (P + |a(g)|) there
        self._coarse = None             # the problem on the 2x coarser grid (nested iteration)
        self._coarse_pairs = 0.0        # FFT pairs of a dropped coarse level (fine-grid units)
        self._prev_approach = None
        self._budget_start = None       # time.monotonic() at the first solve under a time budget
        self._g = np.zeros((grid.ny_local, grid.nx))
        self._v = np.zeros_like(self._g)
        self._v2 = np.zeros_like(self._g)

    # -- layout ------------------------------------------------------------------------
    def set_control_node(self, node: tuple[int, int] | None = None) -> None:
        """The node (i, j) whose gap ``solve(central_gap=...)`` prescribes; None: the lowest
        node of h (the apex of a sphere), the smallest index on ties.  Past the point where
        the apex touches, the central gap no longer picks one state of the S-curve; the gap
        of a node further out, which the contact edge has not reached yet, does (the
        contact radius grows monotonically along the whole curve).  Collective."""
        grid, comm = self.grid, self.grid.mpi_comm
        if node is None:
            h = grid.rows(self.heights, readonly=True)
            k = int(np.argmin(h))
            _, index = minloc(comm, h.reshape(-1)[k], k + grid.nx * grid.ys)
        else:
            i, j = node
            if not (0 <= i < grid.nx and 0 <= j < grid.ny):
                raise ValueError(f"control node {node} outside the {grid.nx} x {grid.ny} grid")
            index = int(j) * grid.nx + int(i)
        self.centre_index = index
        j_c, i_c = divmod(index, grid.nx)
        self._centre_local = (j_c - grid.ys, i_c) if grid.ys <= j_c < grid.ye else None
        self._centre_rank = comm.allreduce(comm.Get_rank() if self._centre_local else 0)

    def control_gap(self) -> float:
        """The present state's gap [m] at the control node (``set_control_node``); collective."""
        if self._approach is None:
            raise RuntimeError("control_gap: no state yet (solve first)")
        return self.centre_value(self._gap(self.blocks(self._x, readonly=True), self._g))

    def blocks(self, vec: PETSc.Vec, readonly: bool = False) -> np.ndarray:
        """The rank's part of an unknown Vec as (n_blocks, ny_loc, nx): [q,] a."""
        return vec.getArray(readonly=readonly).reshape(self.n_blocks, self.grid.ny_local, self.grid.nx)

    def create_unknown(self) -> PETSc.Vec:
        v = PETSc.Vec().createMPI((self.n_local, self.n_global), comm=self.grid.comm)
        v.set(0.0)
        return v

    def centre_value(self, rows: np.ndarray) -> float:
        """rows[centre] broadcast from its owner (collective)."""
        local = float(rows[self._centre_local]) if self._centre_local else 0.0
        return self.grid.mpi_comm.bcast(local, root=self._centre_rank)

    # -- set-up ---------------------------------------------------------------------------
    def _build(self):
        if self._snes is not None:
            return self._snes
        g = self.grid
        d = self._defaults
        opts = PETSc.Options(self.prefix)
        self.tol = check_tolerance(opts.getReal("tol", 1e-8 if d["tol"] is None else d["tol"]),
                                   f"tol (-{self.prefix}tol)")
        self.max_it = opts.getInt("max_it", 100)
        self.stability_check = opts.getBool(
            "stability_check", True if d["stability_check"] is None else d["stability_check"])
        self.stability_steps = opts.getInt("stability_steps", 30)
        self.ptc_shift0 = opts.getReal("ptc_shift", 1.0)
        # Newton without a new smallest error for this many steps has stalled: full steps
        # can cycle for good where one asperity's edge sits at its own fold (rough benchmark
        # at 1024^2: ten nodes of one edge swung between snapped and free for 35 steps, the
        # rest converged); PTC then goes on from the best iterate (0: never)
        self.stall_steps = opts.getInt("stall_steps", 8)
        # bounded: where PTC has not settled in 300 steps it wanders (measured on
        # under-resolved strong adhesion, snap number 4.4: no progress in 800 steps)
        self.ptc_max_it = opts.getInt("ptc_max_it", 300)
        # the relaxation paths tried in turn where Newton fails or ends on an unstable state.
        # Hard-wall laws: the paper's relaxation first, then PTC -- from rest at mu = 2 the
        # relaxation reaches the state where PTC ran its 300 steps (Tabor-2 benchmark sphere),
        # while at the jump-off of a mu = 1 sphere it stopped at its cycle cap and PTC got there
        chain = opts.getString("fallback", "relaxation,ptc" if self.hard_wall else "ptc").lower()
        self.fallback = [m.strip() for m in chain.split(",") if m.strip()]
        if not self.fallback or any(m not in ("relaxation", "ptc") for m in self.fallback):
            raise ValueError(f"-{self.prefix}fallback must be relaxation, ptc or a comma-separated "
                             f"chain of them, got {chain!r}")
        if "relaxation" in self.fallback and not self.hard_wall:
            raise ValueError(f"-{self.prefix}fallback relaxation needs a hard-wall law (the paper's relaxation "
                             f"stores contact pressures apart), got {self.law.name!r}")
        self.fallback_tol = opts.getReal("fallback_tol", 1e-3)
        # a wall-time budget [s] for all of this problem's solves, counted from the first
        # (0: none): past it the running solve stops at its next iteration and every later
        # one at once, with the reason WALL_TIME_BUDGET -- a batch job ends cleanly with its
        # finished steps written, and an unresolvable case ends in bounded time
        self.time_budget = opts.getReal("time_budget", 0.0)
        if not self.time_budget >= 0.0:
            raise ValueError(f"-{self.prefix}time_budget must be >= 0 s (0: no budget), got {self.time_budget!r}")
        self.fallback_max_cycles = opts.getInt("fallback_max_cycles", 5000)
        self.use_predictor = opts.getBool("predictor", True)
        # every displacement-controlled state's tangent stiffness (one Krylov solve; sweeps
        # test jumps with it, load control steps with it).  Off: NaN, and the tangent is
        # solved only where the next step's predictor needs it (no coarse-grid predictor)
        self.stiffness = opts.getBool("stiffness", True)
        # off by default: at hard-wall, high-Tabor jump-ins the relaxation fallback can need
        # thousands of cycles (measured: mu = 2 sphere, 36.6 s from rest against 6.9 s from
        # the Signorini state); sweeps that start from separation get the same state anyway
        self.load_from_rest = opts.getBool("load_from_rest", False)
        self.initial_step = opts.getReal("initial_step", 0.25)
        form = opts.getString("repulsive_rows", "gap").lower()
        if form not in ("gap", "pressure"):
            raise ValueError(f"-{self.prefix}repulsive_rows must be gap or pressure, got {form!r}")
        # the gap form needs the law's inverse: the nodal rule of the full LJ curve
        self.gap_form = form == "gap" and self.traction.invertible
        self.step_limit = opts.getReal("step_limit", 0.5 if self.traction.invertible else 0.0)
        # nested iteration on the first solve: the same problem on 2x coarser grids first
        self.fmg = opts.getBool("fmg", True)
        self.fmg_min_size = opts.getInt("fmg_min_size", 32)
        self.fmg_tol = opts.getReal("fmg_tol", 1e-3)
        self.fmg_steps = opts.getBool("fmg_steps", True)
        choice = opts.getString("preconditioner", d["preconditioner"] or "spectral").lower()
        if choice not in ("spectral", "mlmi", "none"):
            raise ValueError(f"-{self.prefix}preconditioner must be spectral, mlmi or none, got {choice!r}")
        self.preconditioner = choice
        self._jac = AdhesiveJacobian(self)
        J = destroy_at_exit(PETSc.Mat().createPython(((self.n_local, self.n_global),) * 2,
                                                     self._jac, comm=g.comm))
        J.setUp()
        self._x, self._f = self.create_unknown(), self.create_unknown()
        self._x_best = self.create_unknown()
        self._x_solve_best = self.create_unknown()   # the iterate of smallest error of the running solve
        self._solve_best = (np.inf, "")
        lower, upper = self.create_unknown(), self.create_unknown()
        upper.set(PETSc.INFINITY)
        lower.set(PETSc.NINFINITY)
        if self.hard_wall:
            self.blocks(lower)[0] = 0.0
        self._bounds = (lower, upper)
        self._J = J
        # line search: backtracking for hard-wall laws (contact-set changes need damping);
        # full steps for the full LJ curve, whose residual norm is dominated by the stiff
        # repulsive rows and stalls bt (measured on the rough benchmark at 256^2: bt 33-58
        # Newton steps or a fallback, basic 25-56 steps and none)
        self._snes = self._make_snes(self.prefix, "bt" if self.hard_wall else "basic", self.max_it,
                                     1000 if self.hard_wall else 30)
        # pseudo-transient continuation takes full (shifted) steps: the residual norm
        # need not fall monotonically along the relaxation path; and inexact ones (a step
        # of a path need not be solved exactly: with 1000 Krylov iterations a hard-wall
        # PTC at snap number 13.8 made 179 steps in 45 s, with 30 it made its 300 in 20 s)
        self._ptc = self._make_snes(self.prefix + "ptc_", "basic", self.ptc_max_it, 30)
        return self._snes

    def _make_snes(self, prefix: str, linesearch: str, max_it: int, ksp_max_it: int) -> PETSc.SNES:
        """A VI Newton SNES on the shared unknowns, Jacobian and bounds; options under ``prefix``."""
        g = self.grid
        snes = destroy_at_exit(PETSc.SNES().create(comm=g.comm))
        snes.setOptionsPrefix(prefix)
        snes.setType("vinewtonrsls")
        snes.setFunction(self._residual, self._f)
        snes.setVariableBounds(*self._bounds)
        snes.setJacobian(self._jacobian, self._J, self._J)
        snes.setTolerances(rtol=0.0, atol=0.0, stol=0.0, max_it=max_it)
        # an inexact step (Krylov limit reached) is still a step: let the line search judge it
        snes.setMaxLinearSolveFailures(max_it)
        snes.setConvergenceTest(self._converged)
        if self.step_limit > 0:
            snes.setLineSearchPreCheck(self._limit_step)
        opts = PETSc.Options(prefix)
        # petsc4py 3.18 has no SNESLineSearch object: the default goes into the options
        if not opts.hasName("snes_linesearch_type"):
            opts.setValue("snes_linesearch_type", linesearch)
        if not opts.hasName("snes_linesearch_maxstep"):
            # PETSc's default (1e8) is in the unknowns' units, Pa here: it cut every Newton
            # step of a 1 TPa sphere (6056 steps against 126 without it)
            opts.setValue("snes_linesearch_maxstep", "1e300")
        ksp = snes.getKSP()
        ksp.setType(newton_ksp_type(self.hard_wall))
        # with the full LJ curve an inexact step is cheaper than an exact one far from the
        # solution (rough benchmark, 256^2: 30 Krylov iterations at most, 1.7x fewer FFT
        # pairs than 1000; some steps took 450)
        ksp.setTolerances(rtol=PETSc.Options(self.prefix).getReal("newton_ksp_rtol", 1e-2), max_it=ksp_max_it)
        pc = ksp.getPC()
        if self.preconditioner == "none":
            pc.setType("none")
        else:
            pc.setType("python")
            pc.setPythonType("contactpetsc.solvers.adhesive_jacobian.AdhesivePC")
        snes.setFromOptions()
        return snes

    # -- SNES callbacks -----------------------------------------------------------------
    def _gap(self, blocks: np.ndarray, out: np.ndarray) -> np.ndarray:
        """g = h + K p - delta for the unknowns ``blocks``; sets delta under central-gap control."""
        p = blocks.sum(axis=0) if self.n_blocks > 1 else blocks[0]
        self.op.apply(p, self._v)
        h = self.grid.rows(self.heights, readonly=True)
        if self.centre_owner is not None:
            self._approach = self.centre_value(h + self._v) - self._central_gap
        np.add(h, self._v, out=out)
        out -= self._approach
        return out

    @collective_guard
    def _residual(self, snes, x, f):
        xb, fb = self.blocks(x, readonly=True), self.blocks(f)
        g = self._gap(xb, self._g)
        if self.hard_wall:
            fb[0] = g
        fa, a = fb[-1], xb[-1]
        self.traction.pressure(g, out=fa)
        # |a - a(g)| relative to P + |a(g)| (P the law's peak attraction): the pressure
        # error on the law's own scale, which K_ii |a - a(g)| in z0 cannot see when
        # w / (E* z0) is small; on the repulsive side |a(g)| makes it a gap error
        scale = np.abs(fa)
        scale += self.pressure_scale
        np.subtract(a, fa, out=fa)
        self._adhesive_residual = float(np.abs(fa).max()) * self.kappa
        self._pressure_residual = float((np.abs(fa) / scale).max())
        fa *= self.kappa
        if self.gap_form:
            # on the repulsive side (g < 0) the row is g - G(a), G the law's
            # inverse: Newton on a = a(g) there moves g by at most ~g/9 per step when g is
            # too small (a ~ g^-9 is convex); on g = G(a) it goes to G(a) at once
            rows = self._repulsive_rows(a, g)
            fa[rows] = g[rows] - self.traction.repulsive_gap(a[rows])[0]

    @collective_guard
    def _limit_step(self, x, y):
        """Shorten the Newton step x - y so that no gap falls more than ``step_limit`` z0
        below min(g, 0): a linear model taken in the attractive tail can send nodes deep
        into the LJ wall (errors of 1e4 z0 measured), which costs several steps to undo."""
        g = self._g   # the gap at x: the Jacobian was just evaluated there
        dp = -self.blocks(y, readonly=True).sum(axis=0)
        dg = self.op.apply(dp, self._v2)
        if self.centre_owner is not None:
            dg -= self.centre_value(dg)
        floor = np.minimum(g, 0.0) - self.step_limit * self.z0
        deep = (g + dg < floor)
        lam = float(np.min((g[deep] - floor[deep]) / -dg[deep])) if deep.any() else 1.0
        lam = self.grid.mpi_comm.allreduce(lam, op=MPI.MIN)
        if lam < 1.0:
            y.scale(max(lam, 0.1))
        return lam < 1.0

    @staticmethod
    def _repulsive_rows(a: np.ndarray, g: np.ndarray) -> np.ndarray:
        return g < 0

    @collective_guard
    def _jacobian(self, snes, x, J, P):
        xb = self.blocks(x, readonly=True)
        self._gap(xb, self._g)
        self.traction.linearise(self._g)
        if self.gap_form:
            rows = self._repulsive_rows(xb[-1], self._g)
            slope = np.zeros_like(self._g)
            slope[rows] = self.traction.repulsive_gap(xb[-1][rows])[1]
            self._gap_rows, self._gap_slope = rows, slope
            # the rows' flat positions and slopes: the Jacobian applies them once or twice
            # per Krylov iteration, and gathers of a few rows beat boolean masks of all of them
            at = np.flatnonzero(rows)
            self._gap_at = (at, slope.reshape(-1)[at])
        if self.shift:
            # switched evolution relaxation: the shift follows the residual, falling as
            # it falls (towards Newton), rising when a step made it worse
            err, prev = self._last_error, self._ptc_prev
            if prev > 0 and np.isfinite(err):
                self.shift = float(np.clip(self.shift * err / prev, 1e-8, 1e8))
            self._ptc_prev = err

    def _measures(self, x, f):
        """(complementarity error [z0], self-consistency error [z0], pressure error [relative],
        mean p, contact fraction) at the last residual evaluation.

        The pressure error is the largest of |a - a(g)| / (P + |a(g)|) and |min(q / P, g / z0)|
        (P the law's peak attraction, ``pressure_scale``): pressures right on the law's
        own scale, whatever w / (E* z0) -- the errors in z0 are K_ii times pressure errors
        and vanish with the pressures themselves."""
        comm = self.grid.mpi_comm
        xb, fb = self.blocks(x, readonly=True), self.blocks(f, readonly=True)
        p = xb.sum(axis=0)
        errs = np.array([0.0, self._adhesive_residual, self._pressure_residual])
        if self.hard_wall:
            q, g = xb[0], fb[0]
            errs[0] = float(np.abs(np.minimum(self.kappa * q, g)).max()) / self.z0
            errs[2] = max(errs[2], float(np.abs(np.minimum(q / self.pressure_scale, g / self.z0)).max()))
        errs[1] /= self.z0
        comm.Allreduce(MPI.IN_PLACE, errs, op=MPI.MAX)
        sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p > 0)], float))
        n = self.grid.nx * self.grid.ny
        return errs[0], errs[1], errs[2], sums[0] / n, sums[1] / n

    def _fft_pairs(self) -> float:
        """FFT pairs so far in fine-grid units: the operator's, plus those of the coarse
        levels of any MLMI cycle (preconditioner or relaxation), weighted by their size."""
        ops = {id(self.op): self.op}
        levels = self._jac.cache.get("mlmi_levels", ()) if self._snes is not None else ()
        for lev in levels:
            ops[id(lev.op)] = lev.op
        n0 = self.grid.nx * self.grid.ny
        pairs = float(sum(op.fft_pairs * op.grid.nx * op.grid.ny / n0 for op in ops.values()))
        if self._coarse:
            pairs += self._coarse._fft_pairs() / 4.0
        return pairs + self._coarse_pairs

    @collective_guard
    def _converged(self, snes, it, norms):
        x, f = snes.getSolution(), snes.getFunction()[0]
        err_c, err_a, err_p, mean_p, frac = self._measures(x, f)
        self.history.append(
            solve=self._n_solves, iteration=it, fft_pairs=self._fft_pairs(),
            linear_iterations=self._lin0 + snes.getLinearSolveIterations(),
            complementarity_error=err_c, load_error=float("nan"), approach=self._approach,
            mean_pressure=mean_p, contact_fraction=frac, solver=self.solver_name,
            adhesive_error=err_a, pressure_error=err_p)
        # the PTC shift and the stall watch follow the errors in z0 (their trend, not their size)
        err = max(err_c, err_a)
        self._last_error = err
        # converged: gaps right in z0 and pressures right on the law's scale, both to tol
        full = max(err, err_p)
        if not full >= self._solve_best[0]:   # NaN never replaces a real iterate
            self._solve_best = (full, f"{'ptc' if self.shift else 'Newton'} iteration {it}")
            x.copy(self._x_solve_best)
        verdict = convergence_verdict(snes, it, full, self.tol)
        if verdict == PETSc.SNES.ConvergedReason.ITERATING and self._stall_watch and not self.shift:
            if it == 0 or err < self._best[0]:
                self._best = (err, it)
                x.copy(self._x_best)
            elif it - self._best[1] >= self.stall_steps:
                self._stalled = True
                return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT   # named STALLED by _run_snes
        if verdict == PETSc.SNES.ConvergedReason.ITERATING and self.out_of_time():
            return PETSc.SNES.ConvergedReason.DIVERGED_MAX_IT   # named WALL_TIME_BUDGET by _run_snes
        return verdict

    def out_of_time(self) -> bool:
        """Whether the wall-time budget (``-<prefix>time_budget``) is spent; collective (the
        ranks' clocks differ: one rank's verdict would split the ranks between two branches)."""
        if not self.time_budget:
            return False
        if self._budget_start is None:
            self._budget_start = time.monotonic()
        late = time.monotonic() - self._budget_start > self.time_budget
        return bool(self.grid.mpi_comm.allreduce(late, op=MPI.LOR))

    @property
    def budget_reason(self) -> str:
        return (f"WALL_TIME_BUDGET (the {self.time_budget:g} s of -{self.prefix}time_budget are spent; "
                f"finished solves are kept)")

    @property
    def solver_name(self) -> str:
        return f"newton-vi+{self.preconditioner}"

    # -- initial guesses --------------------------------------------------------------------
    def _coarse_problem(self):
        """The same problem on the 2x coarser grid (h averaged over 2 x 2 blocks), or None."""
        if self._coarse is not None:
            return self._coarse or None
        self._coarse = False
        g = self.grid
        # levels coarser than the adhesive range are kept: on the rough benchmark at 512^2
        # (z0 = dx) the levels with dx = 8 and 16 z0 need pseudo-transient continuation,
        # yet without them the 4 z0 level did too and the fine path step took 8x longer
        if not self.fmg or not can_halve(g) or min(g.nx, g.ny) // 2 < self.fmg_min_size:
            return None
        gc = halved(g)
        hc = gc.create_vec()
        gc.rows(hc)[...] = restrict(g.rows(self.heights, readonly=True))
        # FFTW_MEASURE planning would cost more than the coarse solves themselves
        op = half_space(gc, self.e_star, prefix=self.prefix, planner="estimate")
        with warnings.catch_warnings():
            # a coarse grid of the nested iteration resolves less than the fine one by design
            warnings.simplefilter("ignore", UnderResolvedWarning)
            coarse = AdhesiveProblem(gc, hc, self.e_star, self.law, element_integration=self.element_integration,
                                     prefix=self.prefix, operator=op, preconditioner=self.preconditioner,
                                     stability_check=False)
        coarse._build()
        coarse._budget_start = self._budget_start   # one budget for the nested solves
        coarse.tol = max(self.fmg_tol, self.tol)
        coarse.use_predictor = False
        coarse.compute_tangent = False   # a level of the nested iteration needs no predictor or stiffness
        self._coarse = coarse
        return coarse

    def _nested_guess(self, approach: float) -> bool:
        """Unknowns from the coarse problem's solution at ``approach``, prolonged piecewise
        constant (pressures are densities); False when there is none."""
        coarse = self._coarse_problem()
        if coarse is None:
            return False
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if not st.converged:
            self._drop_coarse()
            return False
        xb, xc = self.blocks(self._x), coarse.blocks(coarse._x, readonly=True)
        for k in range(self.n_blocks):
            xb[k] = prolong_constant(xc[k])
        return True

    def _coarse_step(self, approach: float) -> bool:
        """Predictor from the coarse grid: x + P (x_c(delta) - x_c(delta_prev)) (P bilinear), the coarse
        problem stepped along with this one (full approximation); False when the coarse
        problem is not at this problem's previous approach or its step failed."""
        coarse = self._coarse
        if not (coarse and self.fmg_steps and coarse._approach == self._prev_approach):
            return False
        old = coarse._x.copy()
        st = coarse.solve(approach=approach, raise_on_failure=False, check_stability=False)
        if st.converged:
            old.aypx(-1.0, coarse._x)
            xb, dc = self.blocks(self._x), coarse.blocks(old, readonly=True)
            # the increment is smoother than the state: bilinear (the rough benchmark at
            # 1024^2, 25 % contact: 893 FFT pairs against 985 piecewise constant, one
            # Newton step fewer on the fine grid at 512^2)
            for k in range(self.n_blocks):
                xb[k] += prolong_bilinear(dc[k], coarse.grid)
            if self.hard_wall:
                np.maximum(xb[0], 0.0, out=xb[0])
        old.destroy()
        if not st.converged:
            self._drop_coarse()
        return st.converged

    def _drop_coarse(self) -> None:
        """Stop using the coarse level after a failed solve there (even with its fallback):
        a grid that cannot follow the path gives no useful start, and costs a fallback run
        at every later step.  Its FFT pairs stay counted."""
        self._coarse_pairs += self._coarse._fft_pairs() / 4.0
        self._coarse = False

    def _initial_guess(self, approach: float) -> None:
        """First state at ``approach``: the coarse grid's solution (nested iteration), or
        the non-adhesive (Signorini) solution where the bodies overlap, the undeformed
        bodies otherwise, with a = a(g) of that state."""
        g = self.grid
        xb = self.blocks(self._x)
        if self._nested_guess(approach):
            return
        xb[...] = 0.0
        gap = g.rows(self.heights, readonly=True) - approach
        if g.mpi_comm.allreduce(float(gap.min()), op=MPI.MIN) < 0:
            from .problem import ContactProblem
            from .problem import ContactSolveError
            cp = ContactProblem(g, self.heights, self.e_star, operator=self.op,
                                prefix=self.prefix + "initial_", tol=1e-6, length_scale=self.z0)
            try:
                st = cp.solve(approach=approach)
            except ContactSolveError:
                # no Signorini state here (a periodic cell pressed beyond its mean plane):
                # start from the undeformed bodies; Newton says whether a state exists
                st = None
            if st is not None:
                gap = g.rows(st.gap, readonly=True).copy()
                xb[0 if self.hard_wall else -1] = g.rows(st.pressure, readonly=True)
        xb[-1] += self.traction.pressure(np.maximum(gap, 0.0) if self.hard_wall else gap)

    def warm_start(self, contact_pressure: PETSc.Vec | None, adhesive_pressure: PETSc.Vec,
                   approach: float) -> None:
        """Start the next solve from these pressures [Pa] at this approach [m] (a previous
        step, or one read back on restart); ``contact_pressure`` is ignored without a wall."""
        self._build()
        xb = self.blocks(self._x)
        g = self.grid
        if self.hard_wall:
            xb[0] = g.rows(contact_pressure, readonly=True)
        xb[-1] = g.rows(adhesive_pressure, readonly=True)
        self._approach = float(approach)
        self._started = True

    # -- public API --------------------------------------------------------------------------
    def snes(self) -> PETSc.SNES:
        """The SNES (built on first request), for PETSc users."""
        return self._build()

    def snapshot(self):
        """The current unknowns, approach and tangent: to come back to (e.g. to bisect a jump)."""
        self._build()
        self._ensure_tangent()
        tangent = None if self._tangent is None else (self._tangent[0], self._tangent[1].copy(), self._tangent[2])
        return self._x.copy(), self._approach, tangent

    def restore(self, snap) -> None:
        x, approach, tangent = snap
        x.copy(self._x)
        self._approach = approach
        self._drop_tangent()
        self._tangent = None if tangent is None else (tangent[0], tangent[1].copy(), tangent[2])
        self._started = True

    def _load_from_rest(self, approach, raise_on_failure, check_stability) -> AdhesiveState:
        """The first solve: the state reached by loading from separation (min h - z0) to
        ``approach`` in steps of at most ``-<prefix>initial_step`` z0, each warm-started.
        Adhesive contact has many equilibria at one approach; this picks the physical one
        of a first loading and gives Newton a near start at every step."""
        start = float(self.heights.min()[1]) - self.z0
        self._initial_guess(start)
        self._started = True
        n = max(1, int(np.ceil((approach - start) / (self.initial_step * self.z0))))
        pairs0, t0 = self._fft_pairs(), self.history.elapsed()
        newton = linear = 0
        st = None
        for d in np.linspace(start, approach, n + 1)[1:] if approach > start else [approach]:
            last = d == approach
            st = self.solve(approach=float(d), raise_on_failure=False,
                            check_stability=check_stability if last else False)
            newton, linear = newton + st.newton_iterations, linear + st.linear_iterations
            if not st.converged:
                break
        if not st.converged:
            # a jump on the way that no relaxation path reached (strong adhesion with a hard
            # wall): start again from the Signorini solution at the target itself
            self._initial_guess(approach)
            self._drop_tangent()
            st = self.solve(approach=approach, raise_on_failure=False, check_stability=check_stability)
            newton, linear = newton + st.newton_iterations, linear + st.linear_iterations
            st.solver += " (from the Signorini state: loading from rest failed)"
        st.newton_iterations, st.linear_iterations = newton, linear
        st.fft_pairs, st.wall_time = self._fft_pairs() - pairs0, self.history.elapsed() - t0
        if not st.converged and raise_on_failure:
            raise AdhesiveSolveError(f"adhesive solve did not converge while loading from rest to "
                                     f"{approach:.4e} m: {st.reason} at approach {st.approach:.4e} m")
        return st

    def solve_force(self, force: float, *, rel_tol: float = 1e-8, max_updates: int = 30,
                    raise_on_failure: bool = True) -> AdhesiveState:
        """Load control where it is stable: Newton on the approach for a net force [N].

        Each update solves in displacement control (tangent predictor) and steps
        delta by (F - W) / (dW/d delta).  Under load control a state is stable only
        where dW/d delta > 0; where the slope is not positive (beyond the pull-off
        force, or on the unstable branch) the solve stops with a reason saying so.
        """
        if not np.isfinite(force):
            raise ValueError(f"force must be finite, got {force!r}")
        self._build()
        delta = self._approach
        if delta is None:
            delta = float(self.heights.min()[1])
        scale = max(abs(force), 2.0 * np.pi * self.law.work_of_adhesion * self.z0 * 1e3)
        st = None
        eager, self.stiffness = self.stiffness, True    # the updates step with dW/d delta
        try:
            for _ in range(max_updates):
                st = self.solve(approach=delta, raise_on_failure=False)
                if not st.converged:
                    break
                miss = force - st.force
                if abs(miss) <= rel_tol * scale:
                    return st
                if not (st.stiffness > 0 and st.stable):
                    st.converged = False
                    st.reason = (f"LOAD_CONTROL_UNSTABLE (dW/d delta = {st.stiffness:.3e} N/m at approach "
                                 f"{st.approach:.4e} m, force {st.force:.4e} N): the target is beyond the end of "
                                 f"a stable branch under load control; use displacement control")
                    break
                delta = st.approach + miss / st.stiffness
            else:
                st.converged = False
                st.reason = f"DIVERGED_LOAD_ITERATION ({max_updates} approach updates)"
        finally:
            self.stiffness = eager
        if raise_on_failure:
            raise AdhesiveSolveError(f"load-controlled adhesive solve for {force:.4e} N failed: {st.reason}")
        return st

    def solve(self, *, approach: float | None = None, central_gap: float | None = None,
              raise_on_failure: bool = True, check_stability: bool | None = None,
              fallback: bool = True) -> AdhesiveState:
        """Solve at one approach delta [m] or one central gap [m].

        Starts from the previous solution (warm start along a loading path, with
        the tangent predictor under displacement control); the first solve starts
        from the Signorini solution, or with ``-<prefix>load_from_rest`` loads from
        separation (``_load_from_rest``).  Under displacement control, when Newton
        fails or lands on an unstable state, ``fallback`` continues with
        pseudo-transient continuation from the previous state (a jump).
        """
        if (approach is None) == (central_gap is None):
            raise ValueError("give exactly one of approach (m) or central_gap (m)")
        for name, v in (("approach", approach), ("central_gap", central_gap)):
            if v is not None and not np.isfinite(v):
                raise ValueError(f"{name} must be finite, got {v!r}")
        snes = self._build()
        # the first state (coarse grids, Signorini) is part of this solve's cost
        pairs0, t0 = self._fft_pairs(), self.history.elapsed()
        if self.out_of_time():
            if raise_on_failure:
                raise AdhesiveSolveError(f"adhesive solve not started: {self.budget_reason}")
            if self._approach is None:
                self._approach = float(approach) if approach is not None else self.centre_value(
                    self.grid.rows(self.heights, readonly=True)) - float(central_gap)
            return self._state(False, self.budget_reason + " (state: the last converged state's pressures)",
                               0, 0, pairs0, t0, float("nan"), self.solver_name)
        if approach is not None and self.hard_wall and self.grid.periodic:
            # K has no mean mode on a periodic cell: the mean gap is mean(h) - delta
            g = self.grid
            mean_gap = g.mpi_comm.allreduce(float(g.rows(self.heights, readonly=True).sum())) / (
                g.nx * g.ny) - float(approach)
            if mean_gap < 0:
                reason = (f"NO_EQUILIBRIUM (periodic cell: the mean gap mean(h) - delta = {mean_gap:.4e} m "
                          f"is negative, a hard wall cannot keep g >= 0; state: the last converged state's "
                          f"pressures)")
                if raise_on_failure:
                    raise AdhesiveSolveError(f"adhesive solve at approach {approach:.4e} m: {reason}")
                self._approach = float(approach)
                return self._state(False, reason, 0, 0, pairs0, t0, float("nan"), self.solver_name)
        if not getattr(self, "_started", False):
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
        self._check_time = 0.0
        self._solve_best = (np.inf, "")
        x_start = self._x.copy()
        coarse_predicted = approach is not None and self._coarse_step(float(approach))
        if not coarse_predicted and approach is not None and self.use_predictor:
            self._ensure_tangent()   # x is still the previous state
            if self._tangent is not None:
                # Euler predictor along the branch: x + dx/d delta * (delta - delta_prev)
                self._x.axpy(float(approach) - self._tangent[0], self._tangent[1])
                if self.hard_wall:
                    q = self.blocks(self._x)[0]
                    np.maximum(q, 0.0, out=q)
        check = self.stability_check if check_stability is None else check_stability
        # only where PTC would take over
        self._stall_watch = self.stall_steps > 0 and fallback and approach is not None and "ptc" in self.fallback
        converged, reason, newton, linear = self._run_snes()
        self._stall_watch = False
        solver = self.solver_name
        margin = self._stability() if (converged and check) else float("nan")
        if fallback and approach is not None and (not converged or margin <= 0) and not self.out_of_time():
            # Newton found no state on this branch, or an unstable one (the branch has
            # ended: a jump).  From the last converged state, follow a relaxation path
            # to a stable state, then polish by Newton: the methods of -<prefix>fallback
            # in turn (hard-wall laws: the paper's relaxation, then PTC; lj: PTC).
            stalled = self._stalled
            for method in self.fallback:
                # a stalled Newton was near a state but for a few nodes: PTC from its best iterate
                (self._x_best if stalled and method == "ptc" else x_start).copy(self._x)
                if method == "relaxation":
                    from .relaxation import RelaxationSolver
                    relax = RelaxationSolver(self, tol=self.fallback_tol, max_cycles=self.fallback_max_cycles)
                    ok, reason, n2, l2 = relax.relax(approach)
                    if ok:
                        ok, reason, n3, l3 = self._run_snes()
                        n2, l2 = n2 + n3, l2 + l3
                else:
                    self.shift, self._ptc_prev = self.ptc_shift0, 0.0
                    ok, reason, n2, l2 = self._run_snes(self._ptc)
                    self.shift = 0.0
                solver += "+" + method
                newton, linear = newton + n2, linear + l2
                margin = self._stability() if (ok and check) else float("nan")
                if (ok and not margin <= 0) or self.out_of_time():
                    break
            converged = ok
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
            if self.snap_number > 1.0:
                reason += (f" [under-resolved adhesion: K_ii max da/dg = {self.snap_number:.2f} > 1, every "
                           f"node can snap on its own; refine the grid until this is below 1]")
            elif self.zone_nodes < RESOLUTION_NODES:
                reason += (f" [under-resolved adhesion: the adhesive zone spans {self.zone_nodes:.2g} grid "
                           f"spacings, the criterion is {RESOLUTION_NODES:g}]")
        state = self._state(converged, reason, newton, linear, pairs0, t0, margin,
                            solver, tangent=approach is not None and converged and self.compute_tangent)
        if not converged:
            x_start.copy(self._x)   # keep the last good state as the next start
        x_start.destroy()
        self.centre_owner = None
        PETSc.garbage_cleanup(self.grid.comm)
        if not converged and raise_on_failure:
            ksp_reason = _reason_name(snes.getKSP().getConvergedReason(), PETSc.KSP.ConvergedReason)
            raise AdhesiveSolveError(
                f"adhesive solve did not converge: {reason} after {newton} Newton iterations "
                f"(last KSP: {ksp_reason}); complementarity error {state.complementarity_error:.3e}, "
                f"self-consistency error {state.adhesive_error:.3e} z0, pressure error "
                f"{state.pressure_error:.3e} of the peak attraction (tol {self.tol:.1e})")
        return state

    def _run_snes(self, snes: PETSc.SNES | None = None):
        snes = snes or self._snes
        self._lin0 = self.history[-1].linear_iterations if len(self.history) else 0
        self._stalled = False
        snes.solve(None, self._x)
        self._n_solves += 1
        code = snes.getConvergedReason()
        name = self.budget_reason if code < 0 and self.out_of_time() else _reason_name(code)
        if self._stalled:
            name = (f"STALLED (no smaller error in {self.stall_steps} Newton steps; smallest "
                    f"{self._best[0]:.3e} z0 at step {self._best[1]})")
        return code > 0, name, snes.getIterationNumber(), snes.getLinearSolveIterations()

    def _inactive_set(self) -> PETSc.IS:
        """Global indices of the unknowns off their bounds: q > 0 (contact) and every a."""
        xb = self.blocks(self._x, readonly=True)
        local = [np.flatnonzero(xb[0] > 0)] if self.hard_wall else []
        local.append(np.arange(xb[-1].size) + (xb[-1].size if self.hard_wall else 0))
        idx = (np.concatenate(local) + self.offset).astype(PETSc.IntType)
        return PETSc.IS().createGeneral(idx, comm=self.grid.comm)

    def _drop_tangent(self) -> None:
        if self._tangent is not None:
            self._tangent[1].destroy()
        self._tangent = self._tangent_due = None

    def _ensure_tangent(self) -> None:
        """Compute the tangent of the present state if it is due (see ``_state``)."""
        if self._tangent_due is None:
            return
        approach = self._tangent_due
        self._tangent_due = None
        here, self._approach = self._approach, approach   # the state's own approach
        tv, stiffness = self.tangent()
        self._approach = here
        self._tangent = (approach, tv, stiffness)

    def tangent(self) -> tuple[PETSc.Vec, float]:
        """(dx/d delta, dF/d delta [N/m]) at the current state: J_II t = -dF/d delta on the
        inactive set (contact nodes keep zero gap: dq from it, da from the law)."""
        g = self.grid
        self._jacobian(None, self._x, None, None)
        iset = self._inactive_set()
        J = self._snes.getJacobian()[0]
        A = J.createSubMatrix(iset, iset)
        ctx = A.getPythonContext()
        rhs = np.zeros_like(ctx.full_in)
        ones = np.ones((g.ny_local, g.nx))
        if self.hard_wall:
            rhs[0] = 1.0
        self.traction.apply_derivative(ones, rhs[-1])
        rhs[-1] *= -self.kappa
        if self._gap_rows is not None:
            rhs[-1][self._gap_rows] = 1.0   # d(g - G(a))/d delta = -1
        b, t = A.createVecs()
        ctx.from_full(rhs, b)
        ksp = PETSc.KSP().create(comm=g.comm)
        ksp.setOptionsPrefix(self.prefix + "tangent_")
        ksp.setType("gmres")
        # a predictor and a stiffness for jump detection and load updates: 1e-2 is plenty
        # (a jump is a force change larger than the predicted change itself; the predictor's
        # error is the branch's curvature times the step squared).  1e-3 cost 30-50 % more
        # FFT pairs per state on the rough benchmark at 512^2, 1e-6 ~100 more at 256^2
        ksp.setTolerances(rtol=1e-2, max_it=1000)
        ksp.getPC().setType("python")
        ksp.getPC().setPythonType("contactpetsc.solvers.adhesive_jacobian.AdhesivePC")
        ksp.setOperators(A, A)
        ksp.setFromOptions()
        ksp.solve(b, t)
        full = np.zeros_like(ctx.full_in)
        ctx.to_full(t, full)
        tv = self.create_unknown()
        self.blocks(tv)[...] = full
        ok = ksp.getConvergedReason() > 0
        for obj in (ksp, b, t, A, iset):
            obj.destroy()
        area = g.lengths[0] * g.lengths[1]
        stiffness = g.mpi_comm.allreduce(float(full.sum())) / (g.nx * g.ny) * area if ok else float("nan")
        return tv, stiffness

    # -- results ---------------------------------------------------------------------------------
    def _stability(self) -> float:
        """1 - lambda_max(A S) at the current state (see ``stability.py``); collective."""
        from .stability import stability_margin
        t0 = self.history.elapsed()
        xb = self.blocks(self._x, readonly=True)
        self._gap(xb, self._g)
        margin = stability_margin(self, q_rows=xb[0] if self.hard_wall else None,
                                  steps=self.stability_steps)
        self._check_time += self.history.elapsed() - t0
        return margin

    def _state(self, converged, reason, newton, linear, pairs0, t0, margin, solver,
               tangent=False) -> AdhesiveState:
        g = self.grid
        comm = g.mpi_comm
        xb = self.blocks(self._x, readonly=True)
        q, a, p, gap, v = (g.create_vec(0.0) for _ in range(5))
        if self.hard_wall:
            g.rows(q)[...] = xb[0]
        g.rows(a)[...] = xb[-1]
        g.rows(p)[...] = xb.sum(axis=0)
        gap_rows = self._gap(xb, g.rows(gap))
        g.rows(v)[...] = self._v
        f = self.create_unknown()
        self._residual(None, self._x, f)
        err_c, err_a, err_p, mean_p, frac = self._measures(self._x, f)
        f.destroy()
        total = self.total_error(a_rows=xb[-1], gap_rows=gap_rows)
        prow = g.rows(p, readonly=True)
        adhesive_force = comm.allreduce(float(prow[prow < 0].sum())) * g.element_area
        beyond = comm.allreduce(self.traction.beyond_safe_range(gap_rows), op=MPI.LOR)
        if beyond and converged:
            converged, reason = False, "LJ_BEYOND_SAFE_RANGE (z < 0.5 z0: pressure beyond the law's sane range)"
        stable = None if not np.isfinite(margin) else bool(margin > 0)
        self._drop_tangent()
        stiffness = float("nan")
        if tangent and converged:
            self._tangent_due = self._approach
            if self.stiffness:
                t_check = self.history.elapsed()
                self._ensure_tangent()
                stiffness = self._tangent[2]
                self._check_time += self.history.elapsed() - t_check
        area = g.lengths[0] * g.lengths[1]
        return AdhesiveState(
            pressure=p, contact_pressure=q, adhesive_pressure=a, gap=gap, displacement=v,
            approach=self._approach, central_gap=self.centre_value(gap_rows),
            mean_pressure=mean_p, force=mean_p * area, adhesive_force=adhesive_force,
            contact_fraction=frac, complementarity_error=err_c, adhesive_error=err_a,
            pressure_error=err_p, total_error=total, stable=stable, stability_margin=margin, stiffness=stiffness,
            converged=converged,
            reason=reason, newton_iterations=newton, linear_iterations=linear,
            fft_pairs=self._fft_pairs() - pairs0, wall_time=self.history.elapsed() - t0,
            check_time=self._check_time,
            stability_converged=self.stability_converged if np.isfinite(margin) else None,
            solver=solver, fallback=solver.endswith(("+ptc", "+relaxation")))

    def total_error(self, a_rows: np.ndarray, gap_rows: np.ndarray) -> float:
        """The paper's E_Total [z0]: rms of K (a(g) - a), the gap change when the trial
        adhesive pressures a are replaced by the law's values at the current gap g."""
        g = self.grid
        da = self.traction.pressure(gap_rows) - a_rows
        dg = self.op.apply(da, np.empty_like(da))
        return float(np.sqrt(g.mpi_comm.allreduce(float(np.sum(dg * dg))) / (g.nx * g.ny))) / self.z0
