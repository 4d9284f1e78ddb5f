"""The energy descent's Python-context Mat and PC (``descent.EnergyDescent``): the scaled
energy's Hessian H = K_ii (K^-1 + diag Phi''(g)) on v = u / z0 and the compliance
preconditioner S K S / K_ii, each on TAO's inactive set by embedding.  They hold no physics
of their own: the products are ``EnergyDescent.hessian_mult`` and ``precondition``.
Also used by the energy's tangent (``energy_tangent.py``) and the spectrum benchmark.
"""
from __future__ import annotations

import numpy as np

from .reduced import python_submatrix


class Hessian:
    """Python-context Mat: H = K_ii (K^-1 + diag Phi''(g)) on v = u / z0 (the mean as the
    penalty of a hard wall, 1 on the projected-out mean of the full LJ curve).  Its
    principal sub-matrices (TAO's inactive set) embed, apply and extract rank-locally."""

    def __init__(self, descent, index=None):
        self.d, self.index = descent, index
        self.shift_value = 0.0

    def mult(self, mat, x, y):
        xa, ya = x.getArray(readonly=True), y.getArray()
        embedded(self.d, self.index, self.d.hessian_mult, xa, ya)
        if self.shift_value:
            ya += self.shift_value * xa

    def shift(self, mat, s):
        # BNLS's perturbation of an indefinite Hessian
        self.shift_value += s

    def createSubMatrix(self, mat, isrow, iscol=None, reuse=None, submat=None):
        index = isrow.getIndices()
        # a bounded TAO asks for the inactive set's matrix where no node is active (the full LJ
        # curve's gap floor, a hard wall out of contact): this rank's whole block in order, no
        # embedding
        n, offset = self.d.shape[0] * self.d.shape[1], self.d.offset
        whole = len(index) == n and (n == 0 or (isrow.isSorted() and index[0] == offset
                                                and index[-1] == offset + n - 1))
        # as np.intp: numpy gathers and scatters with its own index type a quarter faster than
        # with PETSc's 32-bit one (converted on every use)
        ctx = Hessian(self.d, None if whole else (index - self.d.offset).astype(np.intp))
        ctx.shift_value = self.shift_value
        return python_submatrix(ctx, mat)

    @property
    def n_local(self) -> int:
        return self.d.shape[0] * self.d.shape[1] if self.index is None else len(self.index)


class Compliance:
    """Python-context PC: the compliance K (the inverse of the Hessian's elastic part), on TAO's
    inactive set by embedding."""

    def __init__(self, descent):
        self.d = descent

    def apply(self, pc, x, y):
        d = self.d
        d.pc_applies += 1      # one per Krylov iteration: the descent's linear iterations
        xa, ya = x.getArray(readonly=True), y.getArray()
        embedded(d, pc.getOperators()[1].getPythonContext().index, d.precondition, xa, ya)


def embedded(descent, index, product, xa: np.ndarray, ya: np.ndarray) -> None:
    """ya = ``product`` (one of the descent's, ``product(x, y)`` on full rows, ``y`` may be
    ``x``) on the rank's inactive set ``index`` (None: every node, no embedding), xa and ya that
    set's entries.  A proper set embeds through one full array for the descent's life, the
    product in place: shared by the Hessian and the preconditioner, whose products never nest
    (every sub-matrix TAO makes had held a pair of its own)."""
    if index is None:
        product(xa.reshape(descent.shape), ya.reshape(descent.shape))
        return
    if descent._embed is None:
        descent._embed = np.zeros(descent.shape)
    full = descent._embed
    full[...] = 0.0
    full.reshape(-1)[index] = xa
    product(full, full)
    ya[:] = full.reshape(-1)[index]
