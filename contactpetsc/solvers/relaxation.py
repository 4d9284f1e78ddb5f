"""The reference paper's own solver (Fig. 2b, section 2): MLMI relaxation of adhesive contact.

Contact (positive) pressures q and adhesive pressures a are stored apart and
summed only for the displacement.  The contact pressure has a target gap
f(q): zero for a hard-wall law (eq. 7a), the cubic solution f of eq. 2 for
the full Lennard-Jones curve (eq. 8; the paper: "the intended or target
residual separation, r, becomes a function of the current nodal pressure
rather than zero, but the process itself is unchanged").  With eq. 8 the
split is at g = 0 (z = z0), where the law changes sign: q carries
p_LJ(min(g, 0)) >= 0 and a carries p_LJ(max(g, 0)) <= 0, whose sum is
p_LJ(g) at every node.  Each adhesive cycle

1. relaxes q to convergence for the current a: projected multilevel
   relaxation q <- max(0, q - omega_c c M_I (g - f(q))) on the set I of
   loaded or penetrating nodes (q > 0 or g < f(q)), M_I one MLMI V-cycle
   (``mlmi.py``) on I and c = K_ii / (K_ii - f'(q)) the share of the node's
   stiffness that is elastic (1 on a wall), until the rms residual
   g - f(q) at those nodes is below ``contact_tol``;
2. measures the self-consistency error E_Total (steps 1-4 of section 2):
   the rms of K (a(g) - a), the change of the gaps if the trial adhesive
   pressures were replaced by the law's values at the current gaps;
3. relaxes the adhesive pressures, a <- a + omega_a (a(g) - a).

Both relaxation coefficients adapt independently (the paper monitors and
optimises them): omega_c is halved when the contact residual grows and
recovers by 10 % per step otherwise; omega_a starts at
1 / (1 + K_ii max |da/dg|) and is halved when E_Total grows, growing 5 %
per cycle otherwise.  Convergence: both errors below 1e-4 z0 (the paper's
values; ``-<prefix>relax_tol``, ``-<prefix>relax_contact_tol``), and on a
periodic cell, whose K has no mean mode (a uniform error of a changes no
gap: E_Total is blind to it), K_ii |mean(a(g) - a)| too.  Both are K_ii times
pressure errors, blind to any a when w / (E* z0) is small (a stiff sphere
passed with the previous approach's a): the pressure error on the law's own
scale, rms(a(g) - a) / P (P the peak attraction), must be below
``relax_tol`` as well (as a fallback, Newton's own test checks it).  The paper
notes that high Tabor parameters need small adhesive relaxation
coefficients; so it is here, which is why Newton is the default.

Laws: ``physics.interactions.relaxation_laws()`` (a hard wall, or a repulsive
branch with the nodal rule: f is the inverse of the nodal law).  Every cycle
is recorded in the problem's history with both of the paper's measures
(``rms_contact_residual`` and ``total_error``, E_Total, in z0), like the
Newton iterations.
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import max_error
from ..physics.interactions import relaxation_laws
from .adhesive_jacobian import _SetView
from .base import AdhesiveSolveError, check_heights, check_tolerance
from .mlmi import MLMIPC
from .options import code_default


class RelaxationSolver:
    """Solve an ``AdhesiveProblem`` by the paper's relaxation, sharing its grid, law and history.

    Options (prefix ``<problem prefix>relax_``): ``tol`` and ``contact_tol`` (z0, 1e-4),
    ``max_cycles`` (adhesive cycles, 20000), ``max_inner`` (contact relaxations per
    cycle, 200), ``omega_max`` (1).  ``monitor``: None or a callable (cycle, gap rows [m])
    called after every cycle's measures (benchmarks evaluate their own error there).
    ``stall``: None, or a solve stops (``DIVERGED_STALLED``) once the adhesive relaxation
    coefficient has fallen below ``stall`` times its first value: E_Total grew at nearly
    every cycle, the pressures no longer move (from an attached state beyond the end of
    its branch; the pull-off search, ``pull_off.RelaxedSearch``, sets it).
    """

    def __init__(self, problem, *, tol: float | None = None, contact_tol: float | None = None,
                 max_cycles: int | None = None):
        if problem.law.name not in relaxation_laws():
            raise ValueError(f"the relaxation solver needs a law with a hard wall or a repulsive branch "
                             f"({', '.join(relaxation_laws())}); law {problem.law.name!r} is solved by Newton "
                             f"(solver = 'newton')")
        if not (problem.hard_wall or problem.traction.invertible):
            raise ValueError(f"the relaxation of law {problem.law.name!r} (eq. 8) needs the nodal rule: its "
                             f"target gap f(p) inverts the nodal law; set element_integration = false "
                             f"(-{problem.prefix}element_integration false) or solve by Newton")
        self.pb = self.problem = problem
        with problem.inserted_options():
            self._read_options(tol, contact_tol, max_cycles)
        self.solver_name = "relaxation-mlmi"
        self.monitor = None
        self.stall = None
        self._mlmi = None

    def _read_options(self, tol, contact_tol, max_cycles) -> None:
        problem = self.pb
        opts = PETSc.Options(problem.prefix + "relax_")

        def default(key, given):
            return code_default("adhesion", "relax_" + key) if given is None else given

        pre = problem.prefix + "relax_"
        self.tol = check_tolerance(opts.getReal("tol", default("tol", tol)), f"tol (-{pre}tol)")
        self.contact_tol = check_tolerance(opts.getReal("contact_tol", default("contact_tol", contact_tol)),
                                           f"contact_tol (-{pre}contact_tol)")
        self.max_cycles = opts.getInt("max_cycles", default("max_cycles", max_cycles))
        self.max_inner = opts.getInt("max_inner", default("max_inner", None))
        self.omega_max = opts.getReal("omega_max", default("omega_max", None))

    # -- the multilevel contact relaxation ------------------------------------------------
    def _cycle(self, mask: np.ndarray, r: np.ndarray) -> np.ndarray:
        """One MLMI V-cycle on the set ``mask`` applied to the gap residual r (pressure units)."""
        if self._mlmi is None:
            self._mlmi = MLMIPC()
        # the levels live in the problem's preconditioner data: shared with an MLMI-preconditioned
        # Newton, and counted by the problem's FFT-pair tally
        self._mlmi.prepare(_SetView(self.pb.jacobian_context, mask))
        out = np.empty_like(r)
        self._mlmi.inner(r * mask, out)
        return out

    def _target_gap(self, q: np.ndarray):
        """(f(q) [m], -f'(q) [m/Pa]): the gap the contact pressure asks for and its softness;
        (0, 0) on a hard wall (eq. 7a), the repulsive branch's inverse for eq. 8."""
        if self.pb.hard_wall:
            return 0.0, 0.0
        gap, slope = self.pb.traction.repulsive_gap(q)
        return gap, -slope

    def _adhesive_target(self, g: np.ndarray) -> np.ndarray:
        """a(g) [Pa]: the law's adhesive pressure at the gaps g, its attractive part (g >= 0) for eq. 8."""
        pb = self.pb
        return pb.traction.pressure(g if pb.hard_wall else np.maximum(g, 0.0))

    def _relax_contact(self, q, a, g):
        """Step 1: q to convergence for fixed a; returns (rms residual [z0], max |min(K_ii q,
        g - f(q))| [z0], relaxations)."""
        pb = self.pb
        comm = pb.grid.mpi_comm
        omega, prev = 1.0, np.inf
        rms = comp = np.inf
        for it in range(self.max_inner + 1):
            pb.gap(q + a, g)
            target, soft = self._target_gap(q)
            r = g - target
            active = (q > 0) | (r < 0)
            sums = comm.allreduce(np.array([float(np.sum(r[active] ** 2)), float(active.sum())]))
            rms = np.sqrt(sums[0] / max(sums[1], 1.0)) / pb.z0
            if rms <= self.contact_tol or it == self.max_inner or sums[1] == 0:
                comp = max_error(comm, np.abs(np.minimum(pb.kappa * q, r)).max()) / pb.z0
                return rms, comp, it
            omega = max(0.5 * omega, 0.05) if rms > prev else min(1.0, 1.1 * omega)
            prev = rms
            dq = self._cycle(active, r)
            # a soft wall (eq. 8) adds -f'(q) to the node's elastic K_ii: the cycle inverts K alone
            q -= (omega * pb.kappa) / (pb.kappa + soft) * dq
            np.maximum(q, 0.0, out=q)
        return rms, comp, self.max_inner

    # -- public ------------------------------------------------------------------------------
    def relax(self, approach: float, polished: bool = False) -> tuple[bool, str, int, int]:
        """Relax the problem's unknowns in place to the state at approach delta [m];
        returns (converged, reason, adhesive cycles, contact relaxations).  ``polished``:
        Newton polishes the state afterwards (a fallback), so the pressure error on the
        law's scale is left to its convergence test."""
        pb = self.pb
        comm = pb.grid.mpi_comm
        delta = float(approach)
        pb.prepare(delta)
        xb = pb.blocks(pb.x)
        if pb.hard_wall:
            q, a = xb[0].copy(), xb[1].copy()
        else:   # eq. 8: one pressure, split at g = 0 where the law changes sign
            q, a = np.maximum(xb[0], 0.0), np.minimum(xb[0], 0.0)
        g = np.empty_like(q)
        n = pb.grid.nx * pb.grid.ny
        d = pb.traction
        omega_a = omega_0 = None
        e_prev = e_total = rms_c = err_p = np.inf
        inner_total = cycle = 0
        converged, reason = False, f"DIVERGED_MAX_CYCLES ({self.max_cycles})"
        for cycle in range(self.max_cycles):
            rms_c, comp, inner = self._relax_contact(q, a, g)
            inner_total += inner
            target = self._adhesive_target(g)
            dg = pb.op.apply(target - a, np.empty_like(g))
            e_total = float(np.sqrt(comm.allreduce(float(np.sum(dg * dg))) / n)) / pb.z0
            err_a = max_error(comm, np.abs(target - a).max()) * pb.kappa / pb.z0
            # and on the law's own scale: E_Total and err_a are K_ii times pressure errors,
            # which pass any a when w / (E* z0) is small
            err_p = float(np.sqrt(comm.allreduce(float(np.sum((target - a) ** 2))) / n)) / pb.pressure_scale
            # a periodic cell's K has no mean mode: E_Total cannot see a uniform error of a
            mean_err = (abs(comm.allreduce(float(np.sum(target - a)))) / n * pb.kappa / pb.z0
                        if pb.grid.periodic else 0.0)
            p = q + a
            sums = comm.allreduce(np.array([p.sum(), np.count_nonzero(p > 0)], float))
            pb.history.append(
                solve=pb.solve_count, iteration=cycle, fft_pairs=pb.fft_pairs(),
                linear_iterations=inner_total, complementarity_error=comp, load_error=float("nan"),
                approach=delta, mean_pressure=sums[0] / n, contact_fraction=sums[1] / n,
                solver=self.solver_name, adhesive_error=err_a, total_error=e_total,
                rms_contact_residual=rms_c, pressure_error=err_p)
            if self.monitor is not None:
                self.monitor(cycle, g)
            if not np.isfinite(e_total):
                reason = "DIVERGED_NAN"
                break
            if (e_total <= self.tol and mean_err <= self.tol and rms_c <= self.contact_tol
                    and (polished or err_p <= self.tol)):
                converged, reason = True, "CONVERGED_E_TOTAL"
                break
            if pb.out_of_time():
                reason = pb.budget_reason
                break
            if omega_a is None:
                d.linearise(g if pb.hard_wall else np.maximum(g, 0.0))
                stiff = comm.allreduce(float(np.abs(d.diagonal).max()), op=MPI.MAX) * pb.kappa
                omega_a = omega_0 = min(self.omega_max, 1.0 / (1.0 + stiff))
            elif e_total > e_prev:
                omega_a *= 0.5
                if self.stall is not None and omega_a < self.stall * omega_0:
                    reason = (f"DIVERGED_STALLED (the adhesive relaxation coefficient fell to {omega_a:.2e}, "
                              f"below {self.stall:g} of its first value: no state near the start)")
                    break
            else:
                omega_a = min(self.omega_max, 1.05 * omega_a)
            e_prev = e_total
            a += omega_a * (target - a)
        pb.record_solve()
        self.errors = (e_total, rms_c, err_p, omega_a)
        if converged and pb.hard_wall:
            xb[0], xb[1] = q, a
        elif converged:
            xb[0] = q + a
        return converged, reason, cycle + 1, inner_total

    def solve(self, *, approach: float, raise_on_failure: bool = True, check_stability: bool | None = None):
        """Relax to the state at approach delta [m] from the problem's current state;
        returns an ``AdhesiveState`` (solver ``relaxation-mlmi``)."""
        check_heights(self.pb.grid, self.pb.heights)     # as the problem's own entries (``with_options``)
        with self.pb.inserted_options():
            return self._solve(approach, raise_on_failure, check_stability)

    def _solve(self, approach, raise_on_failure, check_stability):
        pb = self.pb
        pairs0, t0 = pb.fft_pairs(), pb.history.elapsed()
        pb.check_time = 0.0
        converged, reason, cycles, inner = self.relax(approach)
        check = pb.stability_check.by_default if check_stability is None else check_stability
        margin = pb.stability_check.margin() if (converged and check) else float("nan")
        state = pb.make_state(converged, reason, cycles, inner, pairs0, t0, margin,
                          self.solver_name, tangent=False)
        PETSc.garbage_cleanup(pb.grid.comm)
        if not converged and raise_on_failure:
            e_total, rms_c, err_p, omega_a = self.errors
            raise AdhesiveSolveError(
                f"relaxation did not converge: {reason}; E_Total {e_total:.3e} z0 (tol {self.tol:.1e}), "
                f"pressure error {err_p:.3e} of the peak attraction (tol {self.tol:.1e}), "
                f"contact rms residual {rms_c:.3e} z0 (tol {self.contact_tol:.1e}), "
                f"adhesive relaxation coefficient {omega_a}")
        return state
