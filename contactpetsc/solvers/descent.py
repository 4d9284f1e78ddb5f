"""Energy descent: an adhesive state as a local minimum of the total energy (PETSc TAO).

A strategy that drives an ``AdhesiveProblem`` (it owns none of the physics): from a start
state it descends the total potential energy at fixed approach delta,

    E(u) / dA = 1/2 u . K^-1 u + sum_i Phi(g_i),      g = h + u - delta,

over the surface displacement u [m] (docs/formulation.md, "Energy descent"), with TAO's
bound-constrained Newton line search (``bnls``: Hessian K^-1 + diag Phi''(g), truncated CG,
negative curvature handled by the line search's shift) preconditioned by the compliance K,
diagonal in Fourier space (one FFT pair), scaled down on the nodes in repulsive contact:
P = S K S, S_ii = (1 + f min(1, K_ii Phi''(g_i)))^-1/2 where Phi'' > 0, the Hessian's diagonal
term that K alone ignores (why f and the min: docs/formulation.md, "Energy descent"), or by
the V-cycle on the Hessian where K's CG is slow (``descent_cycle.py``).  Every accepted step lowers
the energy, so the state reached is a minimum next to the start: across a snap the path
does not climb, and no pseudo-time is spent on it.  The gradient is p - a(g) per node [Pa],
p = K^-1 u (+ the mean pressure): zero where the state is an equilibrium.  TAO itself sees the dimensionless
v = u / z0 and the energy times K_ii / z0^2 (K_ii the compliance's diagonal [m/Pa]): gradient,
Hessian and steps of order one in any units, so that its absolute step sizes and shifts mean
the same in nanometres as in metres.

* Full LJ curve (no wall): the mean of u, which K^-1 does not see and the approach fixes,
  is projected out exactly: g = h + (u - mean u) - delta, p = K^-1 u + mean a(g); the
  Hessian is K^-1 + P0 diag Phi'' P0 (P0 takes out the mean) + 1 / K_ii on the mean.
  The gaps are held above a floor, TAO's lower bound on v: the gap where the law's repulsion
  is F times the start's largest pressure (at least the peak attraction), at the start's
  mean of v (the energy does not see the mean, which drifts during the descent and moves
  the floor's gap with it; the start is projected onto the bound).  A node that snaps in is
  stopped there by the line search's projection, each node on its own, instead of cutting
  the one step length of the whole grid short; where the floor holds a node (at the bound,
  pushed below it) it is lowered, its pressure 8x, the third time removed, and the descent
  goes on.  The stopping test is the unconstrained error, so a state reached is never held.
* Hard wall: the bound u >= delta - h is TAO's variable bound (the contact nodes are its
  active set; the multiplier q = p - a(g) >= 0).  The mean of u is held by a penalty
  c/2 N mean(u)^2 + W N mean(u), W updated between TAO's rounds until the offset is within
  what Newton measures (``descent_mean.MeanMultiplier``); Newton then closes the last offset.

Its stopping test is the problem's own error measures (``AdhesiveProblem._measures``) on
the descent iterate, to ``-<prefix>descent_tol`` (default: the problem's ``tol``, half of it with a
hard wall on a cell; Newton's polish then only confirms the state and builds its Jacobian).  The
nodal rule only (Phi the law's energy at the nodes), on a periodic grid, where K^-1 is diagonal
in Fourier space, or on an isolated window split along y: there u lives on the window's padded
grid, whose circulant's inverse is diagonal, with the law on the window's nodes and no mean to
hold (``descent_space.py``).

A descent whose energy has fallen by at most 1e-12 of itself in ``stall_its`` iterations
(default 10; 0: never) has stalled in round-off: it stops, failed, and Newton polishes its
iterate (a hard wall's Tabor 5 sphere next to its pull-off ran to TAO's cap in zero steps).

Options (prefix ``<problem prefix>descent_``): ``tol`` (error measure, z0), ``max_rounds``, ``stall_its``,
``preconditioner`` (``descent_cycle.py``)
and ``offset_tol`` (a hard wall's rounds, ``descent_mean.py``), ``pc_contact_factor`` (f above,
default 10; 0: the compliance alone), ``floor_factor`` (F above,
default 4; 0: no floor), ``max_step`` and ``step_tol`` (``descent_step.py``), and every ``tao_*``
option (code defaults: ``descent_options.TAO_DEFAULTS`` and ``natural_norm``;
``-<prefix>descent_tao_monitor`` prints its iterations); read and checked in ``descent_options.py``.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..log_events import log_event
from .adhesive_residual import total_pressure
from .base import reason_name
from .descent_contexts import Compliance, Hessian
from .descent_cycle import DescentCycle
from .descent_floor import GapFloor
from .descent_mean import MeanMultiplier
from .descent_options import TAO_DEFAULTS, descent_options, natural_norm, require_descent
from .descent_space import descent_space
from .descent_stopping import STALL_DECREASE, TAO_REASON, StoppingTest

class EnergyDescent(StoppingTest):
    """Descend the total energy of ``problem`` (an ``AdhesiveProblem``) at one approach.

    ``descend(approach, start)`` leaves the state reached in the problem's unknowns
    ([q,] a) and returns (converged, reason, iterations, linear iterations).
    """

    def __init__(self, problem, tol: float | None = None):
        require_descent(problem, "EnergyDescent")
        self.p = problem
        # the unknown's grid: the cell, or an isolated window's padded grid (``descent_space``)
        self.space = space = descent_space(problem)
        grid = space.grid
        self.comm, self.grid = grid.mpi_comm, grid
        self.prefix = problem.prefix + "descent_"
        self.shape = (grid.ny_local, grid.nx)
        self.offset = grid.offset
        self.n = grid.nx * grid.ny
        self.nodes = problem.grid.nx * problem.grid.ny      # the law's (the window's)
        self.win = space.window
        # the mean of u: a null mode of K^-1 on a cell (a hard wall's penalty, the full LJ
        # curve's projection), none on an isolated window
        self.projects_mean = space.projects_mean and not problem.hard_wall
        opts = PETSc.Options(self.prefix)
        # inside the problem's own tolerance, the descent's error and a hard wall's offset
        # together: Newton's confirmation then converges at its first iterate.  Its backtracking
        # line search failed from hard-wall states descended to 1e-4 - 1e-7, or to tol with an
        # offset of tol, and handed them on to the relaxation's cycles.  The full LJ curve and
        # a window have no offset: tol itself (half of it cost more descent, in the coarse levels too)
        cell_wall = problem.hard_wall and space.projects_mean
        self.tol = tol if tol is not None else opts.getReal("tol", (0.5 if cell_wall else 1.0) * problem.tol)
        options = descent_options(problem.prefix)
        self.pc_contact_factor, self.floor_factor = options.pc_contact_factor, options.floor_factor
        self.stall_its, self.stalled, self._energies = options.stall_its, False, []
        # the V-cycle on the Hessian where the compliance ignores what matters (descent_cycle.py)
        # (``auto`` on an isolated window only: on a periodic cell it gained little on the rough
        # benchmark's paths, and its set-ups raised the resident size's high-water mark)
        pc = options.preconditioner
        multigrid = pc == "multigrid" or (pc == "auto" and not space.projects_mean)
        self.cycle = DescentCycle(self, auto=pc == "auto") if multigrid else None
        for key, value in TAO_DEFAULTS.items():
            problem.set_default(key, value, self.prefix)
        op = problem.op
        fft = op.fft
        norm = 1.0 / (fft.Nx * fft.Ny)
        stiffness = op.inverse_kernel / norm             # modal stiffness E* |q| / 2 [Pa/m], 0 on the mean
        self.c = self.comm.allreduce(float(stiffness.max()), op=MPI.MAX) if cell_wall else 0.0
        # a hard wall's mean multiplier and rounds on a cell (none on the full LJ curve or a window)
        self.mean = MeanMultiplier(problem, self.prefix, self.c, tol) if cell_wall else None
        mean_mode = stiffness == 0
        # the mean mode (no stiffness of its own): a hard wall's penalty c, else 1 / K_ii, the
        # Hessian's scale there (a unit would be off by the units' scale in metres and pascals)
        mean_value = 1.0 / self.c if self.c else problem.kappa
        self.mean_compliance = mean_value        # the preconditioners' on the mean (times 1 / K_ii)
        compliance = np.where(mean_mode, mean_value, 1.0 / np.where(mean_mode, 1.0, stiffness))
        self._k_inv = op.inverse_pairs
        # K / K_ii: the preconditioner's compliance in the dimensionless v
        self._compliance = op.as_pairs(compliance * (norm / problem.kappa))
        self.h = space.from_problem(problem.grid.rows(problem.heights, readonly=True))   # the window's
        # TAO works in v = u / z0 on the energy times K_ii / z0^2: gradient, Hessian and steps of
        # order one at any units (in metres and pascals BNK's gradient steps and shifts, of
        # absolute size, were off by many orders and its line search failed from the first steps)
        self.length = problem.z0
        self.kappa = problem.kappa
        self.delta = 0.0
        self.curvature = np.zeros(self.shape)        # zero outside a window
        self._scratch = None         # a window-sized array for the law's values (not on a cell)
        self.pc_scale = None         # S of the preconditioner (None: S = 1)
        self._embed = None           # the full array the products on a proper inactive set embed in
        self._dx = None              # the Hessian product's diagonal term
        # the last evaluation's fields, overwritten by the next one (never two sets alive):
        # (v copy, g, a, K^-1 u) rows, mean u and p0; ``_valid`` whether they are v's
        self._rows, self._mean_u, self._p0, self._valid = None, 0.0, 0.0, False
        self.pc_applies = 0
        self.floor = None            # the full LJ curve's gap floor (``descent_floor.GapFloor``)
        # ``descend``'s target on the descent's rows (a window's split its own) and its distance
        # [m], and whether it was reached
        self._target, self.reached = None, False

    @property
    def max_rounds(self) -> int:
        """A hard wall's most rounds (``MeanMultiplier``; 1 on the full LJ curve)."""
        return self.mean.max_rounds if self.mean is not None else 1

    # -- PETSc objects ------------------------------------------------------------------
    def shell(self, sizes, ctx) -> PETSc.Mat:
        mat = PETSc.Mat().createPython((sizes, sizes), ctx, comm=self.grid.comm)
        mat.setOption(PETSc.Mat.Option.SYMMETRIC, True)
        mat.setUp()
        return mat

    # -- the energy -----------------------------------------------------------------------
    def _sum(self, value: float) -> float:
        return self.comm.allreduce(value)

    def fields(self, x: PETSc.Vec):
        """(g, a, mean u, K^-1 u, p0) at TAO's variable ``x`` (v = u / z0; rows [m] and [Pa]); the
        pressure is p = K^-1 u + p0 [Pa] (p0 the hard wall's multiplier W + c mean u, or the
        full LJ curve's mean of a), not kept as a row of its own.  One FFT pair, or none where
        they are the last evaluation's (collective).  The rows are the descent's own, valid
        until the next evaluation at another ``x``; ``self._rows[0]`` is v (u = z0 v is not
        kept: every use of it is a product with z0)."""
        v = x.getArray(readonly=True).reshape(self.shape)
        # the cache is used by all ranks or none: a rank whose rows did not change while
        # another's did would skip the FFT's and the sums' collectives (a hang on 3 ranks)
        same = self._valid and np.array_equal(self._rows[0], v)
        if self.comm.allreduce(same, op=MPI.LAND):
            return self._rows[1], self._rows[2], self._mean_u, self._rows[3], self._p0
        if self._rows is None:
            self._rows = (np.empty(self.shape), np.empty(self.h.shape), np.empty(self.h.shape), np.empty(self.shape))
        v_copy, g, a, k_inv_u = self._rows
        v_copy[...] = v
        p = self.p
        mean_u = self._sum(float(v_copy.sum())) * self.length / self.n if self.space.projects_mean else 0.0
        self.space.convolve(self._k_inv, v_copy, k_inv_u)
        k_inv_u *= self.length
        np.multiply(v_copy[self.win], self.length, out=g)
        g += self.h
        if self.projects_mean:
            g -= mean_u + self.delta
        else:
            g -= self.delta
        p.traction.pressure(g, out=a)
        if self.mean is not None:
            self._p0 = self.mean.pressure(mean_u)
        else:
            self._p0 = self._sum(float(a.sum())) / self.n if self.projects_mean else 0.0
        self._mean_u, self._valid = mean_u, True
        return g, a, mean_u, k_inv_u, self._p0

    def objective_gradient(self, tao, x, gradient) -> float:
        """TAO's objective at v = u / z0: E(u) / dA (1/2 u . K^-1 u + sum Phi(g), [J/m^2] summed
        over the nodes) times K_ii / z0^2, and its gradient (p - a(g)) K_ii / z0."""
        grad = gradient.getArray().reshape(self.shape)
        g, a, mean_u, k_inv_u, p0 = self.fields(x)
        # the law's energy in the gradient's array first on a cell (no grid-sized temporary)
        local = (0.5 * self.length * float(np.dot(self._rows[0].ravel(), k_inv_u.ravel()))
                 + float(self.p.traction.energy(g, out=self._law_rows(grad)).sum()))
        energy = self._sum(local)
        np.add(k_inv_u, p0, out=grad)       # p, then p - a
        grad[self.win] -= a
        if self.mean is not None:
            energy += self.mean.energy(mean_u, self.n)
        elif self.projects_mean:
            grad -= self._sum(float(grad.sum())) / self.n    # the mean is a null direction
        grad *= self.kappa / self.length
        return energy * self.kappa / self.length ** 2

    def hessian(self, tao, x, H, P):
        if self.cycle is not None:
            self.cycle.choose(tao.getKSP())
        self.set_curvature(self.fields(x)[0])
        H.getPythonContext().shift_value = 0.0

    def _law_rows(self, rows: np.ndarray) -> np.ndarray:
        """An array for the law's values at the window's nodes: ``rows`` itself where they are
        the window's (a cell), else the descent's window-sized scratch."""
        if rows.shape == self.h.shape:
            return rows
        if self._scratch is None:
            self._scratch = np.empty(self.h.shape)
        return self._scratch

    def set_curvature(self, g: np.ndarray) -> None:
        """The Hessian's diagonal term Phi''(g) = -da/dg at the gaps g [m] (the window's), and
        the preconditioner's scaling S from it."""
        d = self.p.traction.nodal_derivative(g, out=self._law_rows(self.curvature))
        np.negative(d, out=self.curvature[self.win])
        if self.cycle is not None:
            self.cycle.stale = True
        if self.pc_contact_factor:
            s = np.clip(self.kappa * self.curvature, 0.0, 1.0, out=self.pc_scale)
            s *= self.pc_contact_factor
            s += 1.0
            np.sqrt(s, out=s)
            self.pc_scale = np.divide(1.0, s, out=s)
        else:
            self.pc_scale = None

    def at_state(self) -> np.ndarray:
        """The Hessian's diagonal term and the preconditioner's scaling at the problem's present
        state, from its own gaps (``AdhesiveCallbacks._gap``, one FFT pair); returns those [m]."""
        p = self.p
        g = self.space.from_problem(p._current_gap(p.blocks(p._x, readonly=True)))
        self.set_curvature(g)
        return g

    def hessian_mult(self, x: np.ndarray, y: np.ndarray) -> None:
        """y = H x on rows of the dimensionless v = u / z0 (the scaled energy's Hessian); ``y``
        may be ``x`` (the diagonal term is taken before the convolution overwrites it)."""
        if self._dx is None:
            # lives as long as the descent: a fresh grid-sized array per product cost a page-
            # faulting allocation each time, and the product's own temporary was alive at the
            # descent's peak anyway
            self._dx = np.empty(self.shape)
        if not self.projects_mean:
            dx = np.multiply(self.curvature, x, out=self._dx)
            shift = self.c * (self._sum(float(x.sum())) / self.n) if self.c else 0.0
        else:
            # P0 D P0 + 1 / K_ii on the mean (the compliance's inverse there): symmetric on
            # every vector, a mean component included, which the scaled preconditioner's
            # output has
            mean_x = self._sum(float(x.sum())) / self.n
            dx = np.subtract(x, mean_x, out=self._dx)
            dx *= self.curvature
            shift = mean_x / self.kappa - self._sum(float(dx.sum())) / self.n
        self.space.convolve(self._k_inv, x, y)
        y += dx
        if shift:
            y += shift
        y *= self.kappa     # the Hessian in v = u / z0 of the scaled energy

    def precondition(self, x: np.ndarray, y: np.ndarray) -> None:
        """y = S K S x / K_ii on rows of v = u / z0 (dimensionless): the compliance, scaled
        down on the repulsive nodes; ``y`` may be ``x`` (the FFT's spectrum is a buffer of its own)."""
        s = self.pc_scale
        if s is None:
            self.space.convolve(self._compliance, x, y)
        else:
            self.space.convolve(self._compliance, np.multiply(s, x, out=y), y)
            y *= s

    # -- the strategy ------------------------------------------------------------------------
    def descend(self, approach: float, start: PETSc.Vec, target: tuple | None = None) -> tuple[bool, str, int, int]:
        """From the unknowns ``start`` ([q,] a of a state, usually the last converged one),
        descend the energy at approach delta [m]; the state reached is written to the problem's
        unknowns (hard wall: at approach delta - m, |m| <= offset_tol z0, for Newton to close).
        ``target``: (gap rows [m] on the problem's rows, distance [m]) of a state to recognise:
        the descent stops, ``reached``, once every gap is within the distance of it
        (``branch_check``: is it that state?)."""
        ev = log_event("CPEnergyDescent")
        ev.begin()
        try:
            return self._descend(float(approach), start, target)
        finally:
            ev.end()

    def _descend(self, approach, start, target):
        p, grid = self.p, self.grid
        self.delta = approach
        if target is not None:
            self._target = (self.space.from_problem(target[0]), target[1])
        self._valid = False
        pressure0 = total_pressure(p.blocks(start, readonly=True))
        # the start's displacement: u = K p (zero mean on a cell), the bound projected
        x = self.space.create_vec()
        u = grid.rows(x)
        self.space.displacement(pressure0, u)
        if p.hard_wall:
            if self.mean is not None:
                self.mean.start(self._sum(float(pressure0.sum())) / self.n)
            np.maximum(u[self.win], approach - self.h, out=u[self.win])
        else:
            largest = self.comm.allreduce(float(pressure0.max(initial=0.0)), op=MPI.MAX)
        del pressure0       # a grid array that TAO's peak need not hold
        u /= self.length
        gradient = x.duplicate()
        H = self.shell((grid.n_local, self.n), Hessian(self))
        tao = PETSc.TAO().create(comm=grid.comm)
        tao.setOptionsPrefix(self.prefix)
        tao.setObjectiveGradient(self.objective_gradient, gradient)
        tao.setHessian(self.hessian, H)
        bounds = ()
        self.floor = None
        if p.hard_wall or self.floor_factor:
            lower, upper = x.duplicate(), x.duplicate()
            upper.set(PETSc.INFINITY)
            if p.hard_wall:
                lower.set(PETSc.NINFINITY)      # outside a window: no law, no bound
                grid.rows(lower)[self.win] = (approach - self.h) / self.length
            else:
                self.floor = GapFloor(self, largest)
                self.floor.set_bound(grid.rows(lower), u)
            tao.setVariableBounds((lower, upper))
            bounds = (lower, upper)
        tao.setSolution(x)
        tao.setTolerances(gatol=0.0, grtol=0.0, gttol=0.0)
        tao.setConvergenceTest(self._converged)
        tao.setFromOptions()
        ksp = tao.getKSP()
        if ksp is not None:
            natural_norm(ksp, self.prefix)
            pc = ksp.getPC()
            pc.setType("python")
            pc.setPythonContext(Compliance(self))
        self._lin0 = p.history[-1].linear_iterations if len(p.history) else 0
        self.last_error = np.inf
        self.spent = self.stalled = False
        try:
            try:
                code, iterations, rounds = self._rounds(tao, x, bounds)
                at_bound = None
                if p.hard_wall:
                    at_bound = grid.rows(x, readonly=True)[self.win] <= grid.rows(bounds[0], readonly=True)[self.win]
            finally:
                # TAO's vectors before the state's: the start's copy (``saved_start``) is made as
                # the state is written, not beside TAO's peak
                for obj in (tao, H, gradient) + bounds:
                    obj.destroy()
                if self.cycle is not None:
                    self.cycle.release()
            self._write_state(x, at_bound)
        finally:
            x.destroy()
        # a spent budget leads the reason, as Newton's does: the run's message names it
        if self.spent:
            reason = f"{p.budget_reason}, in the descent ("
        elif self.stalled:
            reason = (f"descent stalled (its energy down by at most {STALL_DECREASE:.0e} of itself in "
                      f"{self.stall_its} iterations, error {self.last_error:.3e}; ")
        else:
            reason = f"descent {reason_name(code, TAO_REASON)} ("
        reason += f"{iterations} TAO iterations"
        floors = self.floor.lowered if self.floor is not None else 0
        reason += f", {rounds} rounds)" if p.hard_wall else (f", the gap floor lowered {floors}x)" if floors else ")")
        return code > 0, reason, iterations, self.pc_applies

    def _rounds(self, tao, x, bounds) -> tuple[int, int, int]:
        """TAO's solves from ``x``: a hard wall's rounds (its multiplier W updated between
        them, ``MeanMultiplier``), the full LJ curve's floor lowered where it holds nodes;
        (TAO's reason, iterations, rounds)."""
        grid, mean = self.grid, self.mean
        iterations = rounds = 0
        while True:
            self.pinned = False
            tao.solve()
            rounds += 1
            iterations += tao.getIterationNumber()
            code = tao.getConvergedReason()
            if self.pinned:
                # the floor held nodes that the state needs below it: lowered (its
                # pressure 8x, the third time removed), the descent goes on from there
                self.floor.lower(grid.rows(bounds[0]), grid.rows(x, readonly=True))
                continue
            if mean is None or self.reached:
                return code, iterations, rounds
            mean_u = self.fields(x)[2]
            if code < 0 and mean.visible < np.inf and self.last_error <= self.tol:
                # a round asked below the tolerance (``MeanMultiplier.target``) that TAO could
                # not reach: its state is within the tolerance, the rounds go on from it
                code = TAO_REASON.CONVERGED_USER
                self.stalled = False
            if code < 0 or rounds >= mean.max_rounds or mean.closed(mean_u):
                return code, iterations, rounds
            mean.update(mean_u)
            self._valid = False

    def _write_state(self, x: PETSc.Vec, at_bound: np.ndarray | None) -> None:
        """The problem's unknowns from TAO's variable x: a = a(g), q = p - a >= 0 (hard wall)
        on the nodes ``at_bound``, those TAO holds at its bound (compared in TAO's own scaled
        variable: u = z0 v rounds, and a contact node read as one ulp above the wall in metres
        lost its multiplier and sent Newton's confirmation off)."""
        p = self.p
        g, a, _, k_inv_u, p0 = self.fields(x)
        p.saved_start()      # the unknowns as they were, for the solve's fallbacks, before they change
        xb = p.blocks(p._x)
        # p = K^-1 u + p0 in place (on a cell; a window's scratch): no grid-sized temporary
        # beside the start's copy, and the fields are the last evaluation's no longer
        pressure = np.add(k_inv_u[self.win], p0, out=self._law_rows(k_inv_u))
        if p.hard_wall:
            # the multiplier lives on the contact nodes, where u sits on its bound: elsewhere
            # p - a is the descent's residual, ~1e-9 of the peak attraction, which the VI's
            # Newton and the tangent would take for contact rows (q > 0)
            self.space.to_problem(np.where(at_bound, np.maximum(pressure - a, 0.0), 0.0), xb[0])
            self.space.to_problem(a, xb[1])
        else:
            self.space.to_problem(pressure, xb[0])
        self._valid = False
