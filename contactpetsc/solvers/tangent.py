"""States of ``AdhesiveProblem``: snapshots to come back to, the stability check and the
``AdhesiveState`` (docs/formulation.md, "Adhesive contact: unknowns and Newton"); the tangent
is ``predictor.py``'s."""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .base import with_options
from .fallback import FALLBACKS
from .states import AdhesiveState


class Snapshot:
    """A copy of a problem's unknowns ``x``, its ``approach`` [m] and tangent (approach [m],
    dx/d delta, dF/d delta [N/m]) or None.  Frees its Vecs with ``destroy()`` (or as a
    context manager); ``AdhesiveProblem.restore`` copies from it, so it may be reused."""

    def __init__(self, x: PETSc.Vec, approach: float, tangent, descending_loading: bool = False):
        self.x, self.approach, self.tangent = x, approach, tangent
        self.descending_loading = descending_loading

    def destroy(self) -> None:
        """Free the Vecs (collective); safe to call twice."""
        if self.x is not None:
            self.x.destroy()
        if self.tangent is not None and self.tangent[1] is not None:
            self.tangent[1].destroy()
        self.x = self.tangent = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.destroy()
        return False


class TangentAndState:
    """Mixin of ``AdhesiveProblem``: snapshots, stability and the solved state."""

    @with_options
    def snapshot(self) -> Snapshot:
        """The current unknowns, approach and tangent, and whether the next loading step descends
        first: to come back to (e.g. to bisect a jump)."""
        self._build()
        return Snapshot(self._x.copy(), self._approach, self.predictor.copy(), self.descending_loading)

    def restore(self, snap: Snapshot) -> None:
        """Make ``snap`` the present state (``snap`` stays valid: it is copied)."""
        snap.x.copy(self._x)
        self._approach = self._start_approach = snap.approach
        self.predictor.restore(snap.tangent)
        self.descending_loading = snap.descending_loading
        self._started = True

    def _inactive_set(self) -> PETSc.IS:
        """Global indices of the unknowns off their bounds: q > 0 (contact) and every a."""
        xb = self.blocks(self._x, readonly=True)
        local = [np.flatnonzero(xb[0] > 0)] if self.hard_wall else []
        local.append(np.arange(xb[-1].size) + (xb[-1].size if self.hard_wall else 0))
        idx = (np.concatenate(local) + self.offset).astype(PETSc.IntType)
        return PETSc.IS().createGeneral(idx, comm=self.grid.comm)

    def net_force(self) -> float:
        """The net force [N] of the present unknowns, sum of p dx dy (collective)."""
        p = self.blocks(self._x, readonly=True).sum(axis=0)
        return self.grid.mpi_comm.allreduce(float(p.sum())) * self.grid.element_area

    def make_state(self, converged, reason, newton, linear, pairs0, t0, margin, solver,
                   tangent=False) -> AdhesiveState:
        """The ``AdhesiveState`` of the present unknowns: fields, errors, the stability
        ``margin`` given, the tangent stiffness if ``tangent``; ``pairs0``/``t0``: the FFT
        pairs and history time at the start of the solve."""
        grid = self.grid
        comm = grid.mpi_comm
        xb = self.blocks(self._x, readonly=True)
        # the scratch gap: Newton's last residual's, no FFT pair where it was at these unknowns
        beyond = comm.allreduce(self.traction.beyond_safe_range(self._current_gap(xb)), op=MPI.LOR)
        if beyond and converged:
            converged, reason = False, "LJ_BEYOND_SAFE_RANGE (z < 0.5 z0: pressure beyond the law's sane range)"
        # the tangent before the state's five fields: its solve's memory and theirs do not add up
        stiffness = float("nan")
        if tangent and converged:
            self.predictor.due()
            t_check = self.history.elapsed()
            if self.predictor.stiffness_due:
                stiffness = self.predictor.stiffness()
            self.check_time += self.history.elapsed() - t_check
        else:
            self.predictor.drop()
        q, p, gap, v = (grid.create_vec(0.0) for _ in range(4))
        if self.hard_wall:
            grid.rows(q)[...] = xb[0]
            a = grid.create_vec()
            grid.rows(a)[...] = xb[-1]
            np.add(xb[0], xb[-1], out=grid.rows(p))
        else:
            # the full LJ curve carries all of p as a (q = 0): one Vec for both, read-only
            # fields of the state, a grid-sized double per node less on the caller's side
            grid.rows(p)[...] = xb[-1]
            a = p
        f = self.create_unknown()
        self._residual(None, self._x, f)    # its gap and K p the scratch rows (the tangent's too)
        gap_rows = grid.rows(gap)
        gap_rows[...] = self._g
        grid.rows(v)[...] = self._v
        err_c, err_a, err_p, mean_p, frac = self._measures(self._x, f)
        f.destroy()
        total = self.total_error(a_rows=xb[-1], gap_rows=gap_rows)
        prow = grid.rows(p, readonly=True)
        adhesive_force = comm.allreduce(float(prow[prow < 0].sum())) * grid.element_area
        stable = None if not np.isfinite(margin) else bool(margin > 0)
        area = grid.lengths[0] * grid.lengths[1]
        energy = float("nan") if self.element_integration else grid.element_area * comm.allreduce(
            0.5 * float(np.sum(prow * grid.rows(v, readonly=True))) + float(np.sum(self.traction.energy(gap_rows))))
        return AdhesiveState(
            pressure=p, contact_pressure=q, adhesive_pressure=a, gap=gap, displacement=v,
            approach=self._approach, central_gap=self.centre_value(gap_rows),
            mean_pressure=mean_p, force=mean_p * area, adhesive_force=adhesive_force,
            contact_fraction=frac, complementarity_error=err_c, adhesive_error=err_a,
            pressure_error=err_p, total_error=total, stable=stable, stability_margin=margin, stiffness=stiffness,
            interference_error=float("nan"), load_error=float("nan"), converged=converged,
            reason=reason, newton_iterations=newton, linear_iterations=linear,
            fft_pairs=self.fft_pairs() - pairs0, wall_time=self.history.elapsed() - t0,
            check_time=self.check_time,
            stability_converged=self.stability_check.settled if np.isfinite(margin) else None,
            solver=solver, fallback=solver.endswith(tuple("+" + m for m in FALLBACKS)), energy=energy)

    def total_error(self, a_rows: np.ndarray, gap_rows: np.ndarray) -> float:
        """The paper's E_Total [z0]: rms of K (a(g) - a), the gap change when the trial
        adhesive pressures a are replaced by the law's values at the current gap g."""
        grid = self.grid
        da = self.traction.pressure(gap_rows) - a_rows
        dg = self.op.apply(da, np.empty_like(da))
        return float(np.sqrt(grid.mpi_comm.allreduce(float(np.sum(dg * dg))) / (grid.nx * grid.ny))) / self.z0
