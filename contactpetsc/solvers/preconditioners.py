"""Preconditioners for the reduced (inactive-set) contact Jacobian K_II, as Python-context PCs.

Both approximate K_II^-1 on the inactive set I by an operator M acting on
full grid arrays that vanish outside I.  Select with
``-<prefix>pc_type python -<prefix>pc_python_type contactpetsc.solvers.SpectralPC``
(or ``contactpetsc.solvers.MLMIPC``; ``pc_registry.py``), or with the problem's shortcut
``-<prefix>preconditioner spectral|mlmi|none``.
"""
from __future__ import annotations

import numpy as np

from ..collective import collective_guard
from .reduced import view_context


class ReducedPreconditioner:
    """Base class: subclasses implement ``prepare(ctx)`` and ``inner(f, out)`` (M on full arrays).

    The full arrays are those of the reduced operator's products (``ctx.full_arrays``: the
    problem's shared pair, or the reduced Vecs' own arrays where I is everything), so the
    set-up of each Newton step allocates no grid-sized buffer.
    """

    _data = None   # the PreconditionerData this PC was initialised with

    @collective_guard
    def setUp(self, pc):
        _, P = pc.getOperators()
        ctx = P.getPythonContext()
        self.ctx = ctx
        self.prepare(ctx)

    def prepare(self, ctx) -> None:
        """``initialize`` once per problem, then ``update`` to the operator's set (also what an
        outer PC or solver calls for an inner use on a set view)."""
        if self._data is not ctx.parent.pc_data:
            self._data = ctx.parent.pc_data
            self.initialize(ctx)
        self.update(ctx)

    def view(self, pc, viewer=None):
        view_context(viewer, self.describe())

    @collective_guard
    def apply(self, pc, x, y):
        f, z = self.ctx.full_arrays(x, y)
        self.inner(f, z)
        self.ctx.finish(z, y)

    # -- to implement ----------------------------------------------------------
    def initialize(self, ctx) -> None:
        """What does not change with the set (kernels, levels, options)."""
        raise NotImplementedError

    def update(self, ctx) -> None:
        """What follows the set ``ctx.mask`` of the operator now in use."""
        raise NotImplementedError

    def describe(self) -> list[str]:
        """Lines of ``view``."""
        return [f"contactpetsc {type(self).__name__}"]

    def inner(self, f: np.ndarray, out: np.ndarray) -> np.ndarray:
        raise NotImplementedError


class SpectralPC(ReducedPreconditioner):
    """M = R_I K^-1 R_I^T: the Fourier-space inverse of the full operator, restricted to I.

    On a periodic cell K^-1 = E*|q|/2 vanishes at q = 0; M uses the value of
    the smallest non-zero |q| there instead, so that it stays positive definite
    (the mean pressure on I is not in K's null space once I is a proper subset).
    One FFT pair per application.
    """

    def initialize(self, ctx):
        op = self.op = ctx.op
        data = ctx.parent.pc_data
        if data.spectral_pairs is None:
            inv = np.array(op.inverse_kernel, copy=True)
            inv[inv == 0] = op.lowest_mode_stiffness() / (op.fft.Nx * op.fft.Ny)
            data.spectral_pairs = op.as_pairs(inv)
        self.pairs = data.spectral_pairs

    def update(self, ctx):
        self.mask = ctx.mask

    def describe(self):
        g = self.op.grid
        n = g.mpi_comm.allreduce(int(self.mask.sum())) if getattr(self, "mask", None) is not None else 0
        return [f"contactpetsc SpectralPC: M = R_I K^-1 R_I^T (Fourier inverse of K on a {g.nx} x {g.ny} grid)",
                f"  set I: {n} nodes; one FFT pair per application"]

    def inner(self, f, out):
        self.op.convolve(self.pairs, f, out)
        out *= self.mask
        return out
