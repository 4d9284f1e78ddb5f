"""Block (pencil) grids: the pencil FFT against numpy, and serial == slab == pencil to round-off
for the elastic operator (periodic and isolated) and a small non-adhesive solve (spectral and
MLMI preconditioners), on every process grid px x py of the rank count; what needs whole rows
refuses block grids by name."""
import numpy as np
import pytest
from mpi4py import MPI
from petsc4py import PETSc

from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid
from contactpetsc.operators.elastic import half_space
from contactpetsc.pencil_fft import PencilRFFT
from contactpetsc.solvers import ContactProblem
from contactpetsc.solvers.transfer import can_halve, halved, prolong_bilinear

WORLD = PETSc.COMM_WORLD.tompi4py()
PX = [px for px in range(1, WORLD.Get_size() + 1) if WORLD.Get_size() % px == 0]


def _apply(grid, field):
    """K p gathered, for the global (nx, ny) pressure ``field``."""
    op = half_space(grid, 1.7, planner="estimate")
    p, v = grid.vec_from_array(field), grid.create_vec()
    op.as_mat().mult(p, v)
    return grid.gather(v)


def test_block_grid_layout(coll):
    """Blocks tile the grid in PETSc's rank order (rank = b + px a): gather round trip, the
    DMDA's own ownership ranges and the Vec offsets agree."""
    nx, ny = 14, 9
    a = np.random.default_rng(3).standard_normal((nx, ny))
    for px in PX:
        g = SurfaceGrid(nx, ny, 0.5, px=px)
        v = g.vec_from_array(a)
        (xs, xe), (ys, ye) = g.da.getRanges()
        ok = ((xs, xe, ys, ye) == (g.xs, g.xe, g.ys, g.ye) and v.getOwnershipRange()[0] == g.offset
              and np.array_equal(g.local_array(v, readonly=True), a[g.xs:g.xe, g.ys:g.ye])
              and g.rows(v).shape == g.local_shape)
        assert coll.all(ok)
        assert coll.max(np.max(np.abs(g.gather(v) - a))) == 0.0


@pytest.mark.parametrize("pad", [False, True])
def test_pencil_fft_matches_numpy(coll, pad):
    """forward == numpy's rfft2 on each rank's Fourier columns, backward(forward) = Nx Ny x
    identity; 14 x 9 (odd rows, uneven blocks) on every process grid."""
    nx, ny = 14, 9
    full = np.random.default_rng(11).standard_normal((ny, nx))   # [y, x]
    for px in PX:
        g = SurfaceGrid(nx, ny, 1.0, px=px)
        f = PencilRFFT(g.mpi_comm, nx, ny, g.x_ranges, g.y_ranges, pad=pad, planner="estimate")
        padded = np.zeros((f.Ny, f.Nx))
        padded[:ny, :nx] = full
        ref = np.fft.rfft2(padded).T[f.kx0:f.kx1]                    # [kx, ky]
        spec = f.forward(full[g.ys:g.ye, g.xs:g.xe]).copy()
        out = np.empty((g.ny_local, g.nx_local))
        f.backward(out)
        f.forward(full[g.ys:g.ye, g.xs:g.xe])
        strided = np.zeros((g.ny_local, 2 * g.nx_local))[:, ::2]     # not contiguous
        f.backward(strided)
        err_fwd = np.max(np.abs(spec - ref), initial=0.0)
        err_bwd = max(np.max(np.abs(out / (f.Nx * f.Ny) - full[g.ys:g.ye, g.xs:g.xe])),
                      np.max(np.abs(strided - out)))
        cols = sorted(g.mpi_comm.allgather((f.kx0, f.kx1)))      # tile 0..nkx, each rank some
        covered = (cols[0][0] == 0 and cols[-1][1] == f.nkx and all(a < b for a, b in cols)
                   and all(cols[i][1] == cols[i + 1][0] for i in range(len(cols) - 1)))
        assert coll.max(err_fwd) < 1e-12 and coll.max(err_bwd) < 1e-14
        assert coll.all(covered)


@pytest.mark.parametrize("periodic", [True, False])
def test_operator_serial_slab_pencil(coll, periodic):
    """K p on one rank == on slabs == on every block grid of the rank count, to round-off."""
    nx, ny = 16, 12
    field = np.random.default_rng(5).standard_normal((nx, ny))
    serial = _apply(SurfaceGrid(nx, ny, 0.3, 0.2, periodic=periodic, comm=MPI.COMM_SELF), field)
    scale = np.max(np.abs(serial))
    for px in PX:
        got = _apply(SurfaceGrid(nx, ny, 0.3, 0.2, periodic=periodic, px=px), field)
        assert coll.max(np.max(np.abs(got - serial)) / scale) < 1e-14


@pytest.mark.parametrize("periodic, preconditioner", [(True, "spectral"), (False, "spectral"),
                                                     (True, "mlmi")])
def test_solve_serial_slab_pencil(coll, periodic, preconditioner):
    """A rough contact solved with nested iteration (and MLMI's levels): the same Newton
    count, FFT pairs and pressure (to round-off) on one rank, on slabs and on every block grid."""
    def solve(comm, px):
        g = SurfaceGrid(32, 32, 1 / 32, periodic=periodic, comm=comm, px=px, row_alignment=4)
        h = surfaces.self_affine(g, hurst=0.8, rms_slope=0.1, seed=3)
        st = ContactProblem(g, h, 1.0, tol=1e-10, preconditioner=preconditioner,
                            prefix="pencil_").solve(mean_pressure=0.01)
        return g.gather(st.pressure), st.newton_iterations, st.fft_pairs, st.converged

    p0, newton0, pairs0, ok0 = solve(MPI.COMM_SELF, 1)
    assert coll.all(ok0)
    for px in PX:
        p, newton, pairs, ok = solve(None, px)
        assert coll.all(ok and newton == newton0 and pairs == pairs0)
        assert coll.max(np.max(np.abs(p - p0)) / np.max(p0)) < 1e-12


def test_block_grids_refused_where_rows_are_needed(coll):
    """Bilinear prolongation and file input need whole rows: a GridError naming them."""
    if WORLD.Get_size() < 2:
        pytest.skip("a block grid needs >= 2 ranks")
    g = SurfaceGrid(16, 16, 1.0, px=WORLD.Get_size(), row_alignment=2)
    coarse = halved(g)
    coll.raises(GridError, ["bilinear", "grid_px"], prolong_bilinear,
                np.zeros(coarse.local_shape), coarse)
    coll.raises(GridError, ["file", "grid_px"], surfaces.from_file, g, "missing.npy")


def test_process_grid_checked(coll):
    """grid_px not dividing the ranks, or a process grid too large for the grid: GridError."""
    coll.raises(GridError, ["grid_px", "divisor"], SurfaceGrid, 16, 16, 1.0, px=WORLD.Get_size() + 1)
    if WORLD.Get_size() == 4:   # 2 x 2: the first y-block's one row cannot feed 2 x transforms
        coll.raises(GridError, ["process grid", "rows per y-block"], SurfaceGrid, 16, 4, 1.0, px=2,
                    y_ownership=[1, 3])


@pytest.mark.parametrize("px", PX)
def test_every_coarse_grid_can_halve_admits_has_its_fft(coll, px):
    """Halving as far as ``can_halve`` allows (4 rows per y-block, 4 columns per x-block):
    every coarse grid gets an operator, i.e. its FFT has a line for every rank (on 4 ranks
    the slab hierarchy of a 16 x 16 grid used to reach 4 x 4, 3 Fourier columns for 4 ranks)."""
    n = 4 * WORLD.Get_size()
    g = SurfaceGrid(n, n, 1.0, px=px, row_alignment=2)
    levels = [g]
    while can_halve(levels[-1]):
        levels.append(halved(levels[-1]))
    ops = [half_space(level, 1.0, planner="estimate") for level in levels]
    assert coll.all(len(ops) == len(levels) >= 1)
