"""Distributed surface grid: a 2-D PETSc DMDA, by default decomposed along y only.

A surface field f(x_i, y_j) on an nx x ny grid is stored in PETSc's natural
order, index i + nx*j, so each rank owns whole rows j in [ys, ye).  That is a
slab decomposition: the rows of one rank are one contiguous block of memory,
which the FFT (``contactpetsc.fft``) transforms along x without communication.

Block (pencil) grids.  With ``px`` > 1 ranks along x the ranks form a px x py
process grid (rank = b + px a for x-block b and y-block a, PETSc's order) and
rank (a, b) owns the block [xs, xe) x [ys, ye); its part of a Vec is that block,
(ny_loc, nx_loc) in C order.  The elastic operator transforms it with
``contactpetsc.pencil_fft``.  Chosen with ``px`` or the option ``-grid_px``
(docs/performance.md says when blocks pay).  The non-adhesive solve (spectral
or MLMI preconditioner) runs on block grids; what needs whole rows refuses
them (``require_slabs``).

User-facing arrays are indexed [i, j] = [x, y] with shape (nx, ny), as in
contact.engineering; ``local_array`` returns the rank's part as an (nx_loc, ny_loc)
view of the Vec (Fortran order), ``rows`` the same memory as (ny_loc, nx_loc).
"""
from __future__ import annotations

import math
import resource

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

from .stack import check_petsc

check_petsc()   # a petsc4py of another PETSc, or complex scalars, refused before any use


class GridError(ValueError):
    """Invalid grid parameters (raised identically on every rank)."""


#: the grid's own objects were destroyed by its user (PETSc would dereference a null handle)
DESTROYED_DA = ("the grid's DMDA was destroyed (grid.da.destroy()) while the grid is still in use: "
                "build a new SurfaceGrid (and its fields and problems), or destroy the DMDA after the last solve")


def check_index_range(n_unknowns: int, what: str = "grid") -> None:
    """Fail early if ``n_unknowns`` exceeds PETSc's index type (32-bit by default on Debian)."""
    bits = 8 * np.dtype(PETSc.IntType).itemsize
    limit = 2 ** (bits - 1) - 1
    if n_unknowns > limit:
        raise GridError(
            f"{what}: {n_unknowns} unknowns exceed the {bits}-bit PETSc index limit "
            f"({limit}); use a smaller grid or a PETSc built with 64-bit indices (docs/install.md: "
            f"INDEX_BITS=64 bash run_scripts/setup_petsc_stack.sh, a site's 64-bit PETSc module, or "
            f"Debian's python3-petsc4py-64-real with PETSC_DIR=/usr/lib/petscdir/petsc64)")


def available_memory(comm) -> float:
    """Bytes of memory one rank of ``comm`` can still allocate (inf when unknown); the same on
    every rank: the node's available memory shared by the ranks on that node, or what the
    address-space limit (ulimit -v) leaves, whichever is smaller, minimised over the ranks."""
    avail = math.inf
    try:
        with open("/proc/meminfo") as f:
            info = dict(line.split(":", 1) for line in f)
        avail = 1024.0 * float(info["MemAvailable"].split()[0])
        node = comm.Split_type(MPI.COMM_TYPE_SHARED)
        avail /= node.Get_size()
        node.Free()
    except (OSError, KeyError, ValueError, IndexError):
        pass
    limit = resource.getrlimit(resource.RLIMIT_AS)[0]
    if limit != resource.RLIM_INFINITY:
        try:
            with open("/proc/self/statm") as f:
                used = float(f.read().split()[0]) * resource.getpagesize()
        except (OSError, ValueError, IndexError):
            used = 0.0
        avail = min(avail, max(limit - used, 0.0))
    return comm.allreduce(avail, op=MPI.MIN)


#: rows per rank are multiples of this by default: four rank-local halvings
ROW_ALIGNMENT = 16


def aligned_split(n: int, parts: int, alignment: int = 1) -> list[int]:
    """Rows per rank: balanced blocks of ``alignment`` rows (the remainder to the last rank).

    Where there are fewer blocks than ranks the blocks are halved until each rank gets one
    (an alignment of 2^k keeps k halvings of the grid rank-local, so a small grid on an
    odd rank count still has its coarse levels), down to a plain balanced split.
    """
    if int(alignment) != alignment or alignment < 1:
        raise GridError(f"row_alignment must be an integer >= 1, got {alignment!r}")
    alignment = int(alignment)
    while alignment > 1 and n // alignment < parts:
        alignment = alignment // 2 if alignment % 2 == 0 else 1
    blocks = n // alignment
    base, extra = divmod(blocks, parts)
    rows = [alignment * (base + (1 if r < extra else 0)) for r in range(parts)]
    rows[-1] += n - sum(rows)
    return rows


def block_grid_fits(nx: int, ny: int, px: int, py: int, rows=None) -> bool:
    """Whether a px x py process grid can carry an nx x ny grid and its pencil FFT: every
    rank >= 1 column, every y-block (``rows`` per block, default balanced) >= px rows (one
    row per rank in the x transform) and every x-block of Fourier columns (of the unpadded
    transform) >= py columns."""
    from .fft import split_range
    nkx = nx // 2 + 1
    rows = [ny // py] if rows is None else rows
    return (nx >= px and ny >= py and min(rows) >= px
            and min(b - a for a, b in split_range(nkx, px)) >= py)


class SurfaceGrid:
    """Uniform nx x ny surface grid of spacing (dx, dy) in metres, distributed along y
    (or in px x py blocks).

    Parameters
    ----------
    nx, ny : int
        Number of nodes (elements) along x and y, each >= 2.
    dx, dy : float
        Grid spacing [m] (> 0).  ``dy`` defaults to ``dx``.
    periodic : bool
        True: a periodic cell of size nx*dx x ny*dy.  False: an isolated
        (non-periodic) window of an infinite half-space.
    comm : PETSc.Comm or mpi4py communicator, optional
        Defaults to PETSc.COMM_WORLD.
    stencil_width : int
        Ghost width of the DMDA (1 serves the 4-neighbour stencils).
    row_alignment : int
        Make every rank's first row (and, on a block grid, first column) a multiple
        of this where the grid has enough rows (a power of two lets the multilevel
        solver and the nested iteration halve the grid with rank-local transfers, so
        their levels are the same on any rank count).  Default: the largest power of
        two dividing the size, at most ``ROW_ALIGNMENT`` (a size it does not divide
        would leave the remainder to the last rank, and could not be halved anyway).
    y_ownership : sequence of int, optional
        Rows per y-block of ranks, overriding the balanced split (coarse grids use it).
    px : int, optional
        Ranks along x (a divisor of the rank count): 1 is the slab split, > 1 a block
        grid.  Default: the option ``-grid_px`` (on more than one rank), else 1.
    x_ownership : sequence of int, optional
        Columns per x-block of ranks (block grids; coarse grids use it).
    """

    def __init__(self, nx: int, ny: int, dx: float, dy: float | None = None, *,
                 periodic: bool = True, comm=None, stencil_width: int = 1,
                 row_alignment: int | None = None, y_ownership=None, px: int | None = None,
                 x_ownership=None):
        dy = dx if dy is None else dy
        for name, n in (("nx", nx), ("ny", ny)):
            if int(n) != n or n < 2:
                raise GridError(f"{name} must be an integer >= 2, got {n!r}")
        for name, d in (("dx", dx), ("dy", dy)):
            if not (np.isfinite(d) and d > 0):
                raise GridError(f"{name} (grid spacing, m) must be finite and > 0, got {d!r}")
        self.nx, self.ny = int(nx), int(ny)
        self.dx, self.dy = float(dx), float(dy)
        self.periodic = bool(periodic)
        check_index_range(self.nx * self.ny,
                          f"a {self.nx} x {self.ny} grid (geometry.nx x geometry.ny)")

        comm = PETSc.COMM_WORLD if comm is None else comm
        if not isinstance(comm, PETSc.Comm):
            comm = PETSc.Comm(comm)
        self.comm = comm
        self.mpi_comm = comm.tompi4py()
        size = self.mpi_comm.Get_size()
        if px is None and x_ownership is not None:
            px = len(x_ownership)
        if px is None:   # one rank has no blocks: the option is for the job's grids
            px = PETSc.Options().getInt("grid_px", 1) if size > 1 else 1
        if int(px) != px or px < 1 or size % px:
            raise GridError(f"grid_px (ranks along x) must be a divisor of the {size} MPI ranks, got {px!r}")
        self.px, self.py = int(px), size // int(px)
        if size > self.ny:
            # every 1-D transform along x is one whole row: no layout of the 2-D FFT
            # (slabs or blocks) gives work to more ranks than there are rows
            raise GridError(
                f"{size} MPI ranks but only ny = {self.ny} grid rows (geometry.ny): the FFT transforms "
                f"whole rows, so use at most {self.ny} ranks")
        def split(n, parts):
            a = min(ROW_ALIGNMENT, n & -n) if row_alignment is None else row_alignment
            return aligned_split(n, parts, a)

        if y_ownership is None:
            y_ownership = split(self.ny, self.py)
        if x_ownership is None:
            x_ownership = split(self.nx, self.px)
        self.y_ranges = self._ranges(y_ownership, self.py, self.ny, "y_ownership", "row")
        self.x_ranges = self._ranges(x_ownership, self.px, self.nx, "x_ownership", "column")
        if self.px > 1 and not block_grid_fits(self.nx, self.ny, self.px, self.py,
                                               [b - a for a, b in self.y_ranges]):
            raise GridError(
                f"a {self.px} x {self.py} process grid (grid_px = {self.px}) does not fit a "
                f"{self.nx} x {self.ny} grid: the pencil FFT needs >= {self.px} rows per y-block "
                f"and >= {self.py} Fourier columns per x-block")
        rank = self.mpi_comm.Get_rank()
        self.xs, self.xe = self.x_ranges[rank % self.px]
        self.ys, self.ye = self.y_ranges[rank // self.px]
        self._stencil_width = int(stencil_width)
        self._da = None

    @staticmethod
    def _ranges(ownership, parts: int, n: int, name: str, what: str) -> list[tuple[int, int]]:
        counts = [int(r) for r in ownership]
        if len(counts) != parts or sum(counts) != n or min(counts) < 1:
            raise GridError(f"{name} {counts} must give >= 1 {what} to each of {parts} blocks of ranks, "
                            f"{n} {what}s in all")
        starts = np.concatenate([[0], np.cumsum(counts)])
        return [(int(starts[r]), int(starts[r + 1])) for r in range(parts)]

    def require_slabs(self, what: str) -> None:
        """GridError unless the grid is split along y only (``what`` needs whole rows)."""
        if self.px > 1:
            raise GridError(
                f"{what} needs a grid split along y only (whole rows per rank), but this grid is "
                f"split over a {self.px} x {self.py} process grid (grid_px = {self.px}); run with "
                f"-grid_px 1 and at most ny = {self.ny} ranks")

    @property
    def da(self) -> PETSc.DMDA:
        """The grid's DMDA, created at first use (collective: every rank must ask for it).

        A plan or a dry run that only needs the sizes and the decomposition never
        allocates PETSc's index maps (about 5 PETSc integers per node).
        """
        if self._da is not None and self._da.handle == 0:
            raise GridError(DESTROYED_DA)
        if self._da is None:
            self.check_memory()
            bt = PETSc.DM.BoundaryType.PERIODIC if self.periodic else PETSc.DM.BoundaryType.NONE
            rows = tuple(b - a for a, b in self.y_ranges)
            cols = tuple(b - a for a, b in self.x_ranges)
            da = PETSc.DMDA().create(
                dim=2, dof=1, sizes=(self.nx, self.ny), proc_sizes=(len(cols), len(rows)),
                ownership_ranges=(cols, rows),
                boundary_type=(bt, bt), stencil_type=PETSc.DMDA.StencilType.STAR,
                stencil_width=self._stencil_width, comm=self.comm, setup=False)
            da.setUp()
            self._da = da
        return self._da

    def check_memory(self, need: float | None = None, what: str = "PETSc's index maps and one field") -> None:
        """GridError (on every rank) when ``need`` bytes per rank cannot be allocated.

        Default ``need``: the DMDA's index maps (about 5 PETSc integers per node) and one
        field, what the first Vec of the grid costs.  Called before the DMDA is created, so
        a grid too big for the machine is refused in the user's terms, not by PETSc's
        allocator.  Collective.
        """
        if need is None:
            sw = self._stencil_width
            rows = max(b - a for a, b in self.y_ranges)
            cols = max(b - a for a, b in self.x_ranges)
            need = ((cols + 2 * sw) * (rows + 2 * sw) * 5 * np.dtype(PETSc.IntType).itemsize
                    + 8 * cols * rows)
        need = self.mpi_comm.allreduce(float(need), op=MPI.MAX)
        avail = available_memory(self.mpi_comm)
        if need > avail:
            raise GridError(
                f"a {self.nx} x {self.ny} grid (geometry.nx x geometry.ny) on "
                f"{self.mpi_comm.Get_size()} rank(s) needs {need / 2**30:.2f} GiB per rank for "
                f"{what}, but only {avail / 2**30:.2f} GiB can be allocated per rank; use more "
                f"ranks on more nodes or a smaller grid")

    # -- sizes -------------------------------------------------------------
    @property
    def shape(self) -> tuple[int, int]:
        return (self.nx, self.ny)

    @property
    def ny_local(self) -> int:
        return self.ye - self.ys

    @property
    def nx_local(self) -> int:
        return self.xe - self.xs

    @property
    def local_shape(self) -> tuple[int, int]:
        """(ny_loc, nx_loc): the shape of ``rows``."""
        return (self.ny_local, self.nx_local)

    @property
    def n_local(self) -> int:
        return self.nx_local * self.ny_local

    @property
    def offset(self) -> int:
        """Global index of the rank's first Vec entry (PETSc's order: rank by rank)."""
        rank = self.mpi_comm.Get_rank()
        sizes = [(xe - xs) * (ye - ys) for ys, ye in self.y_ranges for xs, xe in self.x_ranges]
        return int(sum(sizes[:rank]))

    @property
    def lengths(self) -> tuple[float, float]:
        """Physical size of the grid [m]: (nx*dx, ny*dy)."""
        return (self.nx * self.dx, self.ny * self.dy)

    @property
    def element_area(self) -> float:
        return self.dx * self.dy

    # -- vectors -------------------------------------------------------------
    def create_vec(self, value: float | None = None) -> PETSc.Vec:
        v = self.da.createGlobalVec()
        if value is not None:
            v.set(value)
        return v

    def check_vec(self, vec: PETSc.Vec, name: str = "vec") -> PETSc.Vec:
        """``vec`` if it is a field of this grid, else GridError naming both shapes, or both
        communicators' sizes where they differ (collective).

        Checks the global size, this rank's rows and, when ``vec`` belongs to a DMDA,
        the DMDA's sizes: a 16 x 12 grid's field has the size of a 12 x 16 grid's,
        but its rows are not this grid's rows.
        """
        if not isinstance(vec, PETSc.Vec):
            raise GridError(f"{name} must be a PETSc Vec (PETSc.Vec) of the {self.nx} x {self.ny} grid "
                            f"(grid.create_vec or grid.vec_from_array), got {type(vec).__name__}")
        # a destroyed object has a null handle, and PETSc dereferences it (SEGV): refused first
        verdict, shape = (1 if self._da is not None and self._da.handle == 0 else 2 if vec.handle == 0 else 0), None
        ranks, here = (vec.getComm().getSize() if not verdict else 0), self.mpi_comm.Get_size()
        if not verdict and ranks != here:
            verdict = 4
        if not verdict:
            dm = vec.query("__PETSc_dm")
            if isinstance(dm, PETSc.DMDA) and dm.getDim() == 2 and dm.getDof() == 1:
                shape = tuple(int(n) for n in dm.getSizes())  # PETSc lists x first: (nx, ny)
            fits = (vec.getSize() == self.nx * self.ny and vec.getLocalSize() == self.n_local
                    and (shape is None or shape == self.shape))
            verdict = 0 if fits else 3
        verdict = self.mpi_comm.allreduce(verdict, op=MPI.MAX)
        if verdict == 1:
            raise GridError(DESTROYED_DA)
        if verdict == 2:
            raise GridError(f"{name} was destroyed ({name}.destroy()) while it is still in use: destroy PETSc "
                            f"objects only after their last use, or make {name} again on this grid")
        if verdict == 4:
            ranks = self.mpi_comm.allreduce(ranks, op=MPI.MAX)
            raise GridError(f"{name} lives on a communicator of {ranks} rank(s), this {self.nx} x {self.ny} grid on "
                            f"one of {here}: the communicators differ (a field of a COMM_WORLD grid given to a "
                            f"COMM_SELF one, or the reverse); make it on the grid's (grid.create_vec or "
                            f"grid.vec_from_array)")
        if verdict == 3:
            got = (f"a field of a {shape[0]} x {shape[1]} grid" if shape is not None
                   else f"a Vec of {vec.getSize()} entries ({vec.getSize()} values)")
            raise GridError(f"{name} is {got}, this grid is {self.nx} x {self.ny}: (nx, ny) = "
                            f"({self.nx}, {self.ny}) ({self.nx * self.ny} nodes, split by rows along y)")
        return vec

    def rows(self, vec: PETSc.Vec, readonly: bool = False) -> np.ndarray:
        """The rank's part of ``vec`` as a C-ordered (ny_loc, nx_loc) view (row j = one y)."""
        a = vec.getArray(readonly=readonly)
        return a.reshape(self.ny_local, self.nx_local)

    def local_array(self, vec: PETSc.Vec, readonly: bool = False) -> np.ndarray:
        """The rank's part of ``vec`` as an (nx_loc, ny_loc) view indexed [i - xs, j - ys]."""
        return self.rows(vec, readonly).T

    def coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """Local node coordinates (x, y) [m], each of shape (nx_loc, ny_loc); node (i, j) at (i dx, j dy)."""
        x = np.arange(self.xs, self.xe) * self.dx
        y = np.arange(self.ys, self.ye) * self.dy
        return np.meshgrid(x, y, indexing="ij")

    def vec_from_array(self, array: np.ndarray, name: str = "array") -> PETSc.Vec:
        """A Vec holding the global (nx, ny) ``array``; each rank copies only its block."""
        array = np.asarray(array)
        if array.shape != self.shape:
            raise GridError(f"{name} has shape {array.shape}, the grid needs (nx, ny) = {self.shape}")
        v = self.create_vec()
        self.local_array(v)[...] = array[self.xs:self.xe, self.ys:self.ye]
        return v

    def halo_rows(self, rows: np.ndarray, lo: np.ndarray, hi: np.ndarray, *,
                  edge: str = "zero", left: np.ndarray | None = None,
                  right: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Fill ``lo`` with row ys - 1 and ``hi`` with row ye of a (ny_loc, nx_loc) array, and
        ``left``/``right`` (if given) with columns xs - 1 and xe.

        Rows and columns come from the neighbouring ranks (periodic wrap-around on a periodic
        grid), point to point.  Beyond an isolated grid's edge: zeros
        (``edge="zero"``) or the edge row (column) repeated (``edge="repeat"``).
        Collective; ``lo`` and ``hi`` are caller-owned buffers of length nx_loc, ``left`` and
        ``right`` of length ny_loc.
        """
        if edge not in ("zero", "repeat"):
            raise ValueError(f"edge must be 'zero' or 'repeat', got {edge!r}")
        if self.px == self.py == 1:
            # one rank owns the whole grid: its own edges are the halo (the ghost exchange
            # through two work Vecs costs as much as the multilevel smoother's arithmetic)
            wrap = self.periodic
            lo[...] = rows[-1] if wrap else (0.0 if edge == "zero" else rows[0])
            hi[...] = rows[0] if wrap else (0.0 if edge == "zero" else rows[-1])
            if left is not None:
                left[...] = rows[:, -1] if wrap else (0.0 if edge == "zero" else rows[:, 0])
            if right is not None:
                right[...] = rows[:, 0] if wrap else (0.0 if edge == "zero" else rows[:, -1])
            return lo, hi
        # point to point with the four neighbouring blocks (rank = b + px a; periodic: wrapped):
        # edge rows and columns only, where the DMDA's ghost exchange took two grid-sized Vecs
        comm = self.mpi_comm
        rank = comm.Get_rank()
        b, a = rank % self.px, rank // self.px

        def neighbour(db: int, da: int) -> int:
            bb, aa = b + db, a + da
            if self.periodic:
                return bb % self.px + self.px * (aa % self.py)
            return bb + self.px * aa if (0 <= bb < self.px and 0 <= aa < self.py) else MPI.PROC_NULL

        def exchange(first, last, before, after, db, da, tag):
            # ``before`` gets the previous block's last line, ``after`` the next block's first
            prev, nxt = neighbour(-db, -da), neighbour(db, da)
            comm.Sendrecv(np.ascontiguousarray(last), dest=nxt, sendtag=tag, recvbuf=before, source=prev, recvtag=tag)
            comm.Sendrecv(np.ascontiguousarray(first), dest=prev, sendtag=tag + 1, recvbuf=after, source=nxt,
                          recvtag=tag + 1)
            if prev == MPI.PROC_NULL:
                before[...] = 0.0 if edge == "zero" else first
            if nxt == MPI.PROC_NULL:
                after[...] = 0.0 if edge == "zero" else last

        exchange(rows[0], rows[-1], lo, hi, 0, 1, 7301)
        if left is not None or right is not None:
            left = np.empty(rows.shape[0]) if left is None else left
            right = np.empty(rows.shape[0]) if right is None else right
            exchange(rows[:, 0], rows[:, -1], left, right, 1, 0, 7303)
        return lo, hi

    def gather(self, vec: PETSc.Vec, root: int | None = None) -> np.ndarray | None:
        """The global (nx, ny) array of ``vec`` on every rank (root=None) or on ``root`` only."""
        rows = np.ascontiguousarray(self.rows(vec, readonly=True))
        if root is None:
            parts = self.mpi_comm.allgather(rows)
        else:
            parts = self.mpi_comm.gather(rows, root=root)
            if parts is None:
                return None
        bands = [np.concatenate(parts[a * self.px:(a + 1) * self.px], axis=1) for a in range(self.py)]
        return np.concatenate(bands, axis=0).T.copy()

    def __repr__(self) -> str:
        kind = "periodic" if self.periodic else "isolated"
        split = f", {self.px} x {self.py} blocks" if self.px > 1 else ""
        return (f"SurfaceGrid({self.nx} x {self.ny}, dx={self.dx:g} m, dy={self.dy:g} m, {kind}, "
                f"{self.mpi_comm.Get_size()} rank(s){split})")
