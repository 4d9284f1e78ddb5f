"""Matrix-free Jacobian of the adhesive contact VI, its reduced version and its preconditioner.

Unknowns per node (``AdhesiveProblem``): the contact pressure q >= 0 (hard-wall
laws only) and the adhesive pressure a, stored apart as in the reference
paper; the total pressure is p = q + a.  Residual, in length units:

    F_q = g = h + K p - delta                  (Signorini part, eq. 7a)
    F_a = kappa (a - a(g))                     (self-consistency, eq. 2 / 8)

with kappa = K_ii the self-influence.  Jacobian, for (dq, da), w = K (dq + da):

    J_q = w,        J_a = kappa (da - A w)

where A = da/dg is the traction's linearisation (diagonal, or the 5-point
coupling of element integration).  Under central-gap control delta depends on
p (delta = h_c + v_c - g_c), which subtracts w_c from w: a rank-one term.
The layout of a local block of the unknown Vec is [q rows, a rows].
"""
from __future__ import annotations

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from ..collective import collective_guard
from .adhesive_residual import total_pressure
from .base import weighted_pairs
from .reduced import InactiveSet, PreconditionerData, ReducedContext, python_submatrix, view_context


class AdhesiveJacobian:
    """Python-context Mat of the full adhesive Jacobian."""

    def __init__(self, problem):
        self.problem = problem
        self.op = problem.op
        self.grid = problem.grid
        self.prefix = problem.prefix
        self.pc_data = PreconditionerData()   # shared by the preconditioners of every solve
        self._work = None                     # K p of a product without a wall: made on demand

    def release(self) -> float:
        """Free the products' and the preconditioners' arrays between solves (made again on
        demand, into new ``PreconditionerData``, so that no context can mistake the old for
        it); returns the FFT pairs of the freed coarse levels in fine-grid units."""
        pairs = weighted_pairs([lev.op for lev in self.pc_data.mlmi_levels or () if lev.op is not self.op],
                               self.grid)
        self._work = None
        self.pc_data.release()
        self.pc_data = PreconditionerData()
        return pairs

    def apply_full(self, blocks_in: np.ndarray, blocks_out: np.ndarray) -> np.ndarray:
        """J on (nb, ny_loc, nx) arrays (``blocks_out`` not ``blocks_in``).  With a hard wall the
        products' intermediates live in the output's two blocks (K p in the first, which it is,
        p and then a'(g) K p in the second): no grid array of the Jacobian's own, nor p's
        temporary, at the Newton steps' and the tangent's peaks of memory."""
        pb = self.problem
        if pb.hard_wall:
            w, a_out = blocks_out
            p = np.add(blocks_in[0], blocks_in[1], out=a_out)
        else:
            # one block, in and out: K p needs an array beside the output (the law's derivative
            # with element integration reads K p's neighbours while it writes)
            if self._work is None:
                self._work = np.zeros((self.grid.ny_local, self.grid.nx))
            w, a_out, p = self._work, blocks_out[0], blocks_in[0]
        w = self.op.apply(p, w)
        if pb.centre_owner is not None:
            w -= pb.centre_value(w)
        pb.traction.apply_derivative(w, a_out)
        np.subtract(blocks_in[-1], a_out, out=a_out)
        a_out *= pb.kappa
        if pb._gap_rows is not None:
            at, slope = pb._gap_at
            np.put(a_out, at, np.take(w, at) - slope * np.take(blocks_in[-1], at))
        if pb.shift:
            # pseudo-transient continuation: J + shift * kappa I
            blocks_out += (pb.shift * pb.kappa) * blocks_in
        return blocks_out

    @collective_guard
    def mult(self, mat, x, y):
        pb = self.problem
        self.apply_full(pb.blocks(x, readonly=True), pb.blocks(y))

    @collective_guard
    def createSubMatrix(self, mat, isrow, iscol=None, reuse=None, submat=None):
        return python_submatrix(ReducedAdhesiveJacobian(self, isrow), mat)


class ReducedAdhesiveJacobian(ReducedContext):
    """J restricted to the VI's inactive set (q at contact nodes, every a)."""

    def __init__(self, parent: AdhesiveJacobian, index_set: PETSc.IS):
        self.parent = parent
        pb = self.problem = parent.problem
        g = self.grid = parent.grid
        nb = pb.n_blocks
        self.set = InactiveSet(index_set, pb.offset, nb * g.ny_local * g.nx)
        self.n_local = self.set.n_local
        self.shape = (nb, g.ny_local, g.nx)
        self.masks = np.zeros(self.shape, bool)
        self.masks.reshape(-1)[self.set.idx] = True

    @collective_guard
    def mult(self, mat, x, y):
        full, out = self.full_arrays(x, y)
        self.parent.apply_full(full, out)
        self.finish(out, y)


class _SetView:
    """What a pressure-space preconditioner (``SpectralPC``, ``MLMIPC``) needs of a set."""

    def __init__(self, parent: AdhesiveJacobian, mask: np.ndarray):
        self.parent, self.op, self.grid, self.mask = parent, parent.op, parent.grid, mask


class AdhesivePC:
    """Block preconditioner of the reduced adhesive Jacobian.

    Rows that behave like contact rows, where K dominates (q at contact
    nodes; a where the traction is stiff, -kappa A_ii > 1, the repulsive part
    of the full LJ curve or the wall side of the attraction), are solved
    together by the spectral preconditioner of the non-adhesive solver (the
    Fourier inverse) on their union S, the a rows
    scaled by 1 / (-kappa A_ii) (their row is ~ -kappa A_ii (K da)_i).  The
    remaining a rows are near the identity and get the local (Jacobi) factor
    1 / (kappa (1 - A_ii K_ii)), kept away from zero where A_ii > 0.
    ``-<prefix>preconditioner spectral`` (or ``auto``'s pick); ``mlmi`` is the cycle on the
    whole system (``adhesive_mlmi.py``).
    """

    inner_pc = None       # the pressure-space PC of the contact-like rows, made at the first set-up

    def view(self, pc, viewer=None):
        lines = ["contactpetsc AdhesivePC: block preconditioner of the reduced adhesive Jacobian",
                 f"  contact-like rows: {getattr(self, 'n_union', 0)} (inner "
                 f"{type(self.inner_pc).__name__ if self.inner_pc else 'none'}), the others Jacobi"]
        view_context(viewer, lines)
        if self.inner_pc is not None and getattr(self, "inner_active", False):
            view_context(viewer, ["  " + line for line in self.inner_pc.describe()])

    @collective_guard
    def setUp(self, pc):
        _, P = pc.getOperators()
        ctx = self.ctx = P.getPythonContext()
        pb = ctx.problem
        kappa = pb.kappa
        d = pb.traction.diagonal
        self.kappa = kappa
        masks = ctx.masks
        # gap-form rows w - G'(a) da: stiff like the a rows with da/dg = 1 / G'(a), but
        # already in K units (no scaling)
        if pb._gap_rows is not None:
            gap_rows = pb._gap_rows
            d_eff = np.where(gap_rows, 1.0 / np.where(gap_rows, pb._gap_slope, 1.0), d)
        else:
            # (np.where with the absent slopes would build an array of Python objects)
            gap_rows, d_eff = np.zeros(d.shape, bool), d
        stiff = masks[-1] & (-kappa * d_eff > 1.0)
        q_set = masks[0] if pb.hard_wall else np.zeros_like(stiff)
        stiff &= ~q_set
        self.q_set, self.stiff = q_set, stiff
        self.union = q_set | stiff
        scale = np.where(stiff & ~gap_rows, -kappa * d, 1.0)
        self.inv_scale = np.where(stiff, 1.0 / scale, 0.0)
        local = np.where(gap_rows, kappa * (1.0 + pb.shift) - pb._gap_slope if pb._gap_rows is not None else 0.0,
                         kappa * (1.0 + pb.shift - d * kappa))
        floor = 0.1 * kappa
        local = np.where(np.abs(local) < floor, np.copysign(floor, local), local)
        self.jacobi = 1.0 / local
        self.n_union = n_union = ctx.grid.mpi_comm.allreduce(int(self.union.sum()))
        if n_union:
            if self.inner_pc is None:
                from .preconditioners import SpectralPC
                self.inner_pc = SpectralPC()
            self.inner_pc.prepare(_SetView(ctx.parent, self.union))
            self.inner_active = True
        else:
            self.inner_active = False
        self.f = np.zeros(self.union.shape)
        self.z = np.zeros(self.union.shape)

    def reset(self, pc):
        """Free the set-up's arrays between solves (see ``AdhesiveMLMIPC.reset``)."""
        self.ctx = self.q_set = self.stiff = self.union = self.inv_scale = self.jacobi = None
        self.f = self.z = None

    @collective_guard
    def apply(self, pc, x, y):
        ctx = self.ctx
        full, out = ctx.full_arrays(x, y)
        a_in = full[-1]
        np.multiply(a_in, self.jacobi, out=out[-1])
        if self.inner_active:
            f = self.f
            np.multiply(a_in, self.inv_scale, out=f)   # zero off the stiff rows
            if ctx.problem.hard_wall:
                f += full[0] * self.q_set
            self.inner_pc.inner(f, self.z)
            if ctx.problem.hard_wall:
                out[0] = self.z * self.q_set
            np.copyto(out[-1], self.z, where=self.stiff)
        ctx.finish(out, y)


def minloc(comm: MPI.Comm, value: float, index: int) -> tuple[float, int]:
    """Global (min value, its index), the smallest index on ties (rank-count independent)."""
    return comm.allreduce((float(value), int(index)), op=MPI.MINLOC)
