"""Matrix-free Jacobian of the contact VI and its reduced (inactive-set) version.

The unknown is the nodal pressure p [Pa]; the residual is the gap
F(p) = h + K p - delta [m], so the Jacobian is K itself.  SNES VINEWTONRSLS
asks the Jacobian for its sub-matrix on the inactive set through
``createSubMatrix``; the reduced Mat keeps the local positions of the
inactive nodes, which is also what the preconditioners need.
"""
from __future__ import annotations

import weakref

import numpy as np
from petsc4py import PETSc

from ..collective import collective_guard
from ..lifetime import destroy_at_exit


class PreconditionerData:
    """Data of one problem that its preconditioners share (Newton, tangent, stability and
    PTC solves each have their own PC object): built once, by the first PC that needs it."""

    def __init__(self):
        self.spectral_pairs = None       #: the spectral PC's kernel in the operator's pair layout
        self.mlmi_levels = None          #: the MLMI hierarchy (grids and operators)
        self.mlmi_mean_stiffness = None  #: stiffness of the lowest mode [Pa/m]
        self.full_pair = None            #: (input, output) of the reduced Jacobians and their PCs
        self.full_owner = None           #: (weak reference to) the reduced context whose set the input is zero off
        self.mlmi_work = None            #: the adhesive cycle's work arrays, per level
        self.stability_cycle = None      #: the stability check's adhesive cycle (``stability_pc.AdhesiveCyclePreconditioner``)

    def release(self) -> None:
        """Free the stability cycle's set-up: an adhesive problem's memory between solves, whose
        Jacobian then starts new data (the non-adhesive problem keeps its hierarchy)."""
        if self.stability_cycle is not None:
            self.stability_cycle.release()

    def claim_full_arrays(self, owner, shape) -> tuple[np.ndarray, np.ndarray]:
        """The full (input, output) arrays of one problem's reduced products and
        preconditioners, its input zero off ``owner``'s set (zeroed when another reduced
        context used it last, or made).  SNES VI makes a reduced Mat at every Newton step, the
        tangent, load-control and PTC solves their own, and a Mat mult or PC apply never
        overlaps another one: one pair serves all of them."""
        if self.full_pair is None or self.full_pair[0].shape != shape:
            self.full_pair, self.full_owner = (np.zeros(shape), np.zeros(shape)), None
        if self.full_owner is None or self.full_owner() is not owner:
            self.full_pair[0].fill(0.0)
            self.full_owner = weakref.ref(owner)
        return self.full_pair


def view_context(viewer, lines) -> None:
    """Print ``lines`` on an ASCII viewer (indented like PETSc's own objects); others ignore them."""
    if viewer is None or viewer.getType() != "ascii":
        return
    for line in lines:
        viewer.printfASCII(f"  {line}\n")


class ContactJacobian:
    """Python-context Mat on the grid's Vecs: J p = K p."""

    def __init__(self, op, prefix: str):
        self.op, self.prefix = op, prefix
        self.pc_data = PreconditionerData()

    def view(self, mat, viewer=None):
        grid = self.op.grid
        view_context(viewer, [f"contactpetsc ContactJacobian: J = K on a {grid.nx} x {grid.ny} "
                              f"{'periodic' if grid.periodic else 'isolated'} grid, E* = {self.op.e_star:g} Pa",
                              f"  kernel self-influence K_ii = {self.op.self_influence:g} m/Pa"])

    @collective_guard
    def mult(self, mat, x, y):
        grid = self.op.grid
        self.op.apply(grid.rows(x, readonly=True), grid.rows(y))

    @collective_guard
    def getDiagonal(self, mat, d):
        d.set(self.op.self_influence)

    @collective_guard
    def createSubMatrix(self, mat, isrow, iscol=None, reuse=None, submat=None):
        return python_submatrix(ReducedJacobian(self, isrow), mat)


class InactiveSet:
    """Local positions ``idx`` of a reduced Vec's entries in a full local array, with the
    copies between the two, once or twice per Krylov iteration.  The set's trailing run of
    consecutive positions is copied as a slice, much faster than an indexed gather: with a
    hard wall every adhesive pressure is inactive (the whole second block), with the full LJ
    curve every unknown."""

    def __init__(self, index_set: PETSc.IS, offset: int, full_size: int):
        self.idx = (index_set.getIndices() - offset).astype(np.intp)
        self.n_local = n = self.idx.size
        # the indices are sorted and unique (SNES VI's inactive set): the run is where
        # consecutive indices stop differing by one, counted from the end
        breaks = np.flatnonzero(np.diff(self.idx) != 1)
        self.head = int(breaks[-1]) + 1 if breaks.size else 0
        self.scattered = self.idx[:self.head]
        self.run = slice(int(self.idx[self.head]), int(self.idx[-1]) + 1) if n else slice(0, 0)
        self.everything = n == full_size   # (sorted and unique: the whole array, one run)

    def to_full(self, x: PETSc.Vec, out: np.ndarray) -> np.ndarray:
        """Scatter a reduced Vec into a full local array (entries outside the set untouched)."""
        flat, src = out.reshape(-1), x.getArray(readonly=True)
        flat[self.scattered] = src[:self.head]
        flat[self.run] = src[self.head:]
        return out

    def from_full(self, full: np.ndarray, y: PETSc.Vec) -> None:
        """Gather the set's entries of a full local array into a reduced Vec."""
        flat, dst = full.reshape(-1), y.getArray()
        # no temporary; mode "clip" (the positions are in range by construction): numpy's default
        # "raise" gathers into a copy of ``out`` first, twice the time
        np.take(flat, self.scattered, out=dst[:self.head], mode="clip")
        dst[self.head:] = flat[self.run]


def python_submatrix(ctx, mat: PETSc.Mat) -> PETSc.Mat:
    """A square Python-context Mat on ``mat``'s communicator for a reduced context with
    ``n_local`` rows on this rank (what ``createSubMatrix`` returns to SNES VI)."""
    n = mat.getComm().tompi4py().allreduce(ctx.n_local)
    sub = PETSc.Mat().createPython(((ctx.n_local, n), (ctx.n_local, n)), ctx, comm=mat.getComm())
    sub.setUp()
    return destroy_at_exit(sub)


class ReducedContext:
    """What a reduced (inactive-set) Mat context shares with its preconditioners: the set
    (``set``, an ``InactiveSet``) in full local arrays of ``shape``, and the problem's shared
    pair of them (``parent.pc_data``).  Subclasses set ``parent``, ``set``, ``n_local`` and
    ``shape``."""

    def to_full(self, x: PETSc.Vec, out: np.ndarray) -> np.ndarray:
        """Scatter a reduced Vec into a full local array (entries outside the set untouched)."""
        return self.set.to_full(x, out)

    def from_full(self, full: np.ndarray, y: PETSc.Vec) -> None:
        """Gather the set's entries of a full local array into a reduced Vec."""
        self.set.from_full(full, y)

    def full_arrays(self, x: PETSc.Vec, y: PETSc.Vec):
        """(input, output) of a product or a preconditioner as full local arrays: x and y's own
        arrays when the set is everything (the reduced Vecs are the full arrays: no copies), else
        x scattered into the problem's shared pair (``PreconditionerData.claim_full_arrays``,
        the input zero off this set) for ``finish``."""
        if self.set.everything:
            return x.getArray(readonly=True).reshape(self.shape), y.getArray().reshape(self.shape)
        full, out = self.parent.pc_data.claim_full_arrays(self, self.shape)
        self.to_full(x, full)
        return full, out

    def finish(self, out: np.ndarray, y: PETSc.Vec) -> None:
        """Gather ``full_arrays``' output into y (nothing to do when the set is everything)."""
        if not self.set.everything:
            self.from_full(out, y)


class ReducedJacobian(ReducedContext):
    """K restricted to an index set I (the VI's inactive set): K_II."""

    def __init__(self, parent: ContactJacobian, index_set: PETSc.IS):
        self.parent = parent
        self.op = parent.op
        g = self.grid = self.op.grid
        self.set = InactiveSet(index_set, g.offset, g.n_local)
        self.n_local = self.set.n_local
        self.shape = g.local_shape
        self.mask = np.zeros(self.shape, bool)
        self.mask.reshape(-1)[self.set.idx] = True
        n_set = g.mpi_comm.allreduce(self.n_local)
        # On a periodic cell K has no mean mode: with every node inactive K_II = K is
        # singular and the Newton system inconsistent (mean gap = mean h - delta).  There,
        # and only there, the mean mode gets the compliance of the lowest mode, which
        # turns the step into one that opens the gap towards partial contact.
        self.mean_compliance = 0.0
        if g.periodic and n_set == g.nx * g.ny:
            self.mean_compliance = 1.0 / self.op.lowest_mode_stiffness()

    def view(self, mat, viewer=None):
        n = self.grid.mpi_comm.allreduce(self.n_local)
        view_context(viewer, [f"contactpetsc ReducedJacobian: K_II on {n} inactive nodes of "
                              f"{self.grid.nx * self.grid.ny}"])

    @collective_guard
    def mult(self, mat, x, y):
        full, out = self.full_arrays(x, y)
        self.op.apply(full, out)
        if self.mean_compliance:
            grid = self.grid
            total = grid.mpi_comm.allreduce(float(full.sum()))
            out += self.mean_compliance * total / (grid.nx * grid.ny)
        self.finish(out, y)

    @collective_guard
    def getDiagonal(self, mat, d):
        d.set(self.op.self_influence)
