"""The energy descent's Python-context Mat and PC (``descent.EnergyDescent``): the scaled
energy's Hessian H = K_ii (K^-1 + diag Phi''(g)) on v = u / z0 and the compliance
preconditioner S K S / K_ii, each on TAO's inactive set by embedding.  They hold no physics
of their own: the products are ``EnergyDescent.hessian_mult`` and ``precondition``.
Also used by the energy's tangent (``energy_tangent.py``) and the spectrum benchmark.
"""
from __future__ import annotations

import numpy as np

from .reduced import InactiveSet, python_submatrix


class Hessian:
    """Python-context Mat: H = K_ii (K^-1 + diag Phi''(g)) on v = u / z0 (the mean as the
    penalty of a hard wall, 1 on the projected-out mean of the full LJ curve).  Its
    principal sub-matrices (TAO's inactive set) embed, apply and extract rank-locally."""

    def __init__(self, descent, inactive: InactiveSet | None = None):
        self.d, self.inactive = descent, inactive
        self.shift_value = 0.0

    def mult(self, mat, x, y):
        embedded(self.d, self.inactive, self.d.hessian_mult, x, y)
        if self.shift_value:
            ya = y.getArray()
            ya += self.shift_value * x.getArray(readonly=True)

    def shift(self, mat, s):
        # BNLS's perturbation of an indefinite Hessian
        self.shift_value += s

    def createSubMatrix(self, mat, isrow, iscol=None, reuse=None, submat=None):
        # a bounded TAO asks for the inactive set's matrix where no node is active (the full LJ
        # curve's gap floor, a hard wall out of contact): this rank's whole block in order, no
        # embedding (TAO's inactive set is sorted and unique, as SNES VI's)
        inactive = InactiveSet(isrow, self.d.offset, self.d.shape[0] * self.d.shape[1])
        if self.d.cycle is not None:
            self.d.cycle.stale = True      # its clamped nodes are the new set's (every rank calls this)
        ctx = Hessian(self.d, None if inactive.everything else inactive)
        ctx.shift_value = self.shift_value
        return python_submatrix(ctx, mat)

    @property
    def n_local(self) -> int:
        return self.d.shape[0] * self.d.shape[1] if self.inactive is None else self.inactive.n_local


class Compliance:
    """Python-context PC: the compliance K (the inverse of the Hessian's elastic part), or the
    descent's V-cycle on the Hessian (``descent_cycle.py``), on TAO's inactive set by embedding."""

    def __init__(self, descent):
        self.d = descent

    def apply(self, pc, x, y):
        d = self.d
        d.pc_applies += 1      # one per Krylov iteration: the descent's linear iterations
        inactive = pc.getOperators()[1].getPythonContext().inactive
        if d.cycle is not None and d.cycle.on:
            d.cycle.apply(inactive, x, y)
        else:
            embedded(d, inactive, d.precondition, x, y)


def embedded(descent, inactive: InactiveSet | None, product, x, y) -> None:
    """y = ``product`` (one of the descent's, ``product(x, y)`` on full rows, ``y`` may be
    ``x``) on the rank's inactive set ``inactive`` (None: every node, no embedding), x and y
    that set's Vecs.  A proper set embeds through one full array for the descent's life, the
    product in place, with the copies of the Newton steps' reduced products
    (``reduced.InactiveSet``: the gather into y without a temporary): shared by the Hessian and
    the preconditioner, whose products never nest (every sub-matrix TAO makes had held a pair
    of its own)."""
    if inactive is None:
        product(x.getArray(readonly=True).reshape(descent.shape), y.getArray().reshape(descent.shape))
        return
    if descent._embed is None:
        descent._embed = np.zeros(descent.shape)
    full = descent._embed
    full[...] = 0.0
    inactive.to_full(x, full)
    product(full, full)
    inactive.from_full(full, y)
