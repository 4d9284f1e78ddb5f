"""SurfaceGrid: layout, gather/scatter, coordinates, and clear collective errors."""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.grid import GridError, SurfaceGrid, check_index_range


@pytest.mark.parametrize("periodic", [True, False])
def test_vec_from_array_gather_round_trip(coll, periodic):
    """An array scattered by rows and gathered back is bit-identical, on any split (ny = 37)."""
    nx, ny = 11, 37
    g = SurfaceGrid(nx, ny, 0.5, 0.25, periodic=periodic)
    a = np.random.default_rng(7).standard_normal((nx, ny))
    v = g.vec_from_array(a)
    # local_array is indexed [i, j - ys]; the Vec holds natural order i + nx*j
    local_ok = np.array_equal(g.local_array(v, readonly=True), a[:, g.ys:g.ye])
    natural = v.getArray(readonly=True)
    ii, jj = np.meshgrid(np.arange(nx), np.arange(g.ys, g.ye), indexing="ij")
    natural_ok = np.array_equal(natural[(ii + nx * (jj - g.ys)).ravel()], a[ii, jj].ravel())
    err_all = np.max(np.abs(g.gather(v) - a))
    root = g.gather(v, root=0)
    root_ok = (root is None) if coll.rank != 0 else np.array_equal(root, a)
    assert coll.all(local_ok and natural_ok and root_ok)
    assert coll.max(err_all) == 0.0
    # the rows form a contiguous partition of 0..ny, sizes differing by at most one
    starts = [r[0] for r in g.y_ranges]
    stops = [r[1] for r in g.y_ranges]
    sizes = np.diff([0] + stops)
    assert starts[0] == 0 and stops[-1] == ny and starts[1:] == stops[:-1]
    assert sizes.max() - sizes.min() <= 1 and len(sizes) == coll.size
    assert (g.ys, g.ye) == g.y_ranges[coll.rank]


@pytest.mark.parametrize("periodic", [True, False])
@pytest.mark.parametrize("edge", ["zero", "repeat"])
@pytest.mark.parametrize("blocks", [False, True])
def test_halo_rows_are_the_neighbouring_rows_of_the_whole_array(coll, periodic, edge, blocks):
    """halo_rows gives the rows ys - 1, ye and columns xs - 1, xe of the global array: the
    wrap-around on a periodic cell, zeros or the edge repeated beyond an isolated one (the
    truth: the global array padded by numpy), on any split: slabs, or every rank a block
    along x."""
    nx, ny = 11, 17
    g = SurfaceGrid(nx, ny, 1.0, periodic=periodic, px=coll.size if blocks else 1)
    full = np.random.default_rng(3).standard_normal((ny, nx))   # rows j, columns i
    mode = "wrap" if periodic else ("constant" if edge == "zero" else "edge")
    padded = np.pad(full, 1, mode=mode)
    rows = full[g.ys:g.ye, g.xs:g.xe]
    lo, hi = np.empty(g.nx_local), np.empty(g.nx_local)
    left, right = np.empty(g.ny_local), np.empty(g.ny_local)
    g.halo_rows(rows, lo, hi, edge=edge, left=left, right=right)
    cols = slice(g.xs + 1, g.xe + 1)
    inner = slice(g.ys + 1, g.ye + 1)
    ok = (np.array_equal(lo, padded[g.ys, cols]) and np.array_equal(hi, padded[g.ye + 1, cols])
          and np.array_equal(left, padded[inner, g.xs]) and np.array_equal(right, padded[inner, g.xe + 1]))
    assert coll.all(ok)


def test_coordinates_and_sizes(coll):
    """Node (i, j) sits at (i dx, j dy); the cell is nx dx x ny dy."""
    nx, ny, dx, dy = 9, 13, 0.3, 0.7
    g = SurfaceGrid(nx, ny, dx, dy)
    x, y = g.coordinates()
    xg = np.concatenate(g.mpi_comm.allgather(x), axis=1)
    yg = np.concatenate(g.mpi_comm.allgather(y), axis=1)
    err = max(np.max(np.abs(xg - dx * np.arange(nx)[:, None])),
              np.max(np.abs(yg - dy * np.arange(ny)[None, :])))
    assert coll.max(err) <= 1e-15
    assert g.shape == (nx, ny) and g.lengths == pytest.approx((nx * dx, ny * dy), rel=1e-15)
    assert g.element_area == pytest.approx(dx * dy, rel=1e-15)
    assert coll.all(x.shape == (nx, g.ny_local))
    # dy defaults to dx
    assert SurfaceGrid(4, 4, 0.2).dy == 0.2


def test_too_few_rows_for_the_ranks(coll):
    """ny < number of ranks: a GridError on every rank, before any collective call."""
    class FakeMPI:  # a communicator that claims 4 ranks, only its size is consulted
        def Get_size(self):
            return 4

    class FakeComm(PETSc.Comm):
        def tompi4py(self):
            return FakeMPI()

    coll.raises(GridError, ["4 MPI ranks", "ny = 3"], SurfaceGrid, 8, 3, 1.0,
                comm=FakeComm(PETSc.COMM_SELF))
    if coll.size >= 3:  # the real thing: 2 rows on COMM_WORLD
        coll.raises(GridError, ["ranks", "ny = 2"], SurfaceGrid, 8, 2, 1.0)


@pytest.mark.parametrize("kw", [dict(dx=0.0), dict(dx=-1.0), dict(dx=float("nan")),
                                dict(dx=float("inf")), dict(dx=1.0, dy=0.0), dict(dx=1.0, dy=-2.0)])
def test_non_positive_spacing(coll, kw):
    name = "dy" if "dy" in kw else "dx"
    coll.raises(GridError, [name, "> 0"], SurfaceGrid, 8, 8, **kw)


@pytest.mark.parametrize("nx, ny, bad", [(1, 8, "nx"), (0, 8, "nx"), (-3, 8, "nx"),
                                         (2.5, 8, "nx"), (8, 1, "ny")])
def test_too_few_nodes(coll, nx, ny, bad):
    coll.raises(GridError, [bad, ">= 2"], SurfaceGrid, nx, ny, 1.0)


def test_index_range_check(coll):
    """Problems beyond PETSc's index type fail early and say what to do (no huge allocation)."""
    bits = 8 * np.dtype(PETSc.IntType).itemsize
    check_index_range(2 ** (bits - 1) - 1)  # the largest representable size passes
    coll.raises(GridError, "64-bit indices", check_index_range, 2 ** (bits - 1))
    if bits == 32:
        coll.raises(GridError, ["64-bit indices", "2147483648"], check_index_range, 2 ** 31)


def test_row_alignment_and_explicit_ownership(coll):
    """row_alignment: every rank starts on a multiple of it (when there are enough blocks);
    y_ownership: the requested rows per rank; either way the data round-trips exactly."""
    nx, ny = 5, 37
    a = np.random.default_rng(1).standard_normal((nx, ny))
    g = SurfaceGrid(nx, ny, 1.0, row_alignment=4)
    assert all(start % 4 == 0 for start, _ in g.y_ranges) and g.y_ranges[-1][1] == ny
    own = [ny - 2 * (coll.size - 1)] + [2] * (coll.size - 1)      # a deliberately lopsided split
    h = SurfaceGrid(nx, ny, 1.0, y_ownership=own)
    assert [e - s for s, e in h.y_ranges] == own
    errs = [np.max(np.abs(grid.gather(grid.vec_from_array(a)) - a)) for grid in (g, h)]
    assert coll.max(errs) == 0.0
    bad_splits = [[ny + 2 - coll.size] + [1] * (coll.size - 1),    # one row too many
                  [ny - coll.size] + [1] * coll.size]                # one rank too many
    if coll.size > 1:
        bad_splits.append([ny] + [0] * (coll.size - 1))              # ranks without rows
    for bad in bad_splits:
        coll.raises(GridError, "y_ownership", SurfaceGrid, nx, ny, 1.0, y_ownership=bad)


def test_layout_is_the_dmda_layout(coll):
    """The rows computed up front (the DMDA is created at first use) are the DMDA's."""
    g = SurfaceGrid(5, 37, 1.0, row_alignment=4)
    assert g._da is None                       # sizes and rows need no PETSc allocation
    (xs, xe), (ys, ye) = g.da.getRanges()
    ly = g.da.getOwnershipRanges()[1]
    assert coll.all((xs, xe, ys, ye) == (0, 5, g.ys, g.ye))
    assert coll.all(list(np.cumsum(ly)) == [e for _, e in g.y_ranges])
    assert coll.all(g.create_vec().getLocalSize() == 5 * g.ny_local)


def test_check_vec_refuses_a_field_of_another_grid(coll):
    """16 x 12 and 12 x 16 grids have fields of one size (and, on 2 ranks, one local size):
    only the DMDA's sizes tell them apart."""
    from contactpetsc.geometry import surfaces
    g, other = SurfaceGrid(12, 16, 1.0), SurfaceGrid(16, 12, 1.0)
    v = other.create_vec(1.0)
    coll.raises(GridError, ["heights", "16 x 12", "(nx, ny) = (12, 16)"], g.check_vec, v, "heights")
    for call in (lambda: surfaces.rms_height(g, v), lambda: surfaces.scale_to_rms(g, v, 1.0),
                 lambda: surfaces.composite(g, g.create_vec(0.0), v),
                 lambda: surfaces.rough_sphere(g, 100.0, v)):
        coll.raises(GridError, "16 x 12", call)
    assert g.check_vec(g.create_vec(), "heights") is not None
    assert g.check_vec(g.create_vec().duplicate(), "heights") is not None
    plain = PETSc.Vec().createMPI((12 * g.ny_local, 12 * 16), comm=g.comm)   # no DMDA: sizes only
    assert g.check_vec(plain) is plain
    short = PETSc.Vec().createMPI(12 * 15, comm=g.comm)
    coll.raises(GridError, ["180 entries", "(12, 16)"], g.check_vec, short, "roughness")
    coll.raises(GridError, ["PETSc Vec", "ndarray"], g.check_vec, np.zeros((12, 16)), "roughness")


def test_check_vec_names_the_communicators_of_a_field_of_another_one(coll):
    """A COMM_WORLD field given to a COMM_SELF grid of the same size (and the reverse): on
    several ranks the message says the communicators differ and gives both sizes; on one rank
    they are the same group and the field is accepted."""
    world, alone = SurfaceGrid(16, 16, 1.0), SurfaceGrid(16, 16, 1.0, comm=PETSc.COMM_SELF)
    pairs = ((alone, world.create_vec(1.0), coll.size, 1), (world, alone.create_vec(1.0), 1, coll.size))
    for grid, vec, ranks, here in pairs:
        if coll.size == 1:
            assert grid.check_vec(vec, "heights") is vec
        else:
            coll.raises(GridError, [f"heights lives on a communicator of {ranks} rank(s)",
                                    f"16 x 16 grid on one of {here}", "communicators differ"],
                        grid.check_vec, vec, "heights")


def test_a_grid_too_big_for_memory_is_refused_in_its_terms(coll, monkeypatch):
    """Before PETSc allocates (its error would be a bare code): the grid size, the memory
    needed and available per rank, the scene keys."""
    import contactpetsc.grid as grid_module
    g = SurfaceGrid(512, 512, 1.0)
    monkeypatch.setattr(grid_module, "available_memory", lambda comm: 2.0 ** 20)
    coll.raises(GridError, ["512 x 512 grid (geometry.nx x geometry.ny)", "GiB per rank",
                            "0.00 GiB can be allocated"], g.create_vec)
    from contactpetsc.geometry import surfaces, tips     # the builders that allocate before any Vec
    coll.raises(GridError, "geometry.nx x geometry.ny", surfaces.self_affine, g, hurst=0.8, seed=0,
                rms_height=1.0)
    coll.raises(GridError, "geometry.nx x geometry.ny", tips.make_tip, "amorphous", g, 1e4, 1.0)
    monkeypatch.setattr(grid_module, "available_memory", lambda comm: 2.0 ** 30)
    assert coll.all(g.create_vec().getSize() == 512 * 512)


def test_available_memory_is_positive_and_rank_independent(coll):
    from contactpetsc.grid import available_memory
    avail = available_memory(PETSc.COMM_WORLD.tompi4py())
    assert avail > 0
    assert coll.max(avail) == -coll.max(-avail)


@pytest.mark.serial
def test_dry_run_of_a_huge_grid_allocates_nothing_and_a_run_says_why_it_cannot(tmp_path):
    """46000^2 nodes (within 32-bit indices) under an 8 GB address-space limit: the dry run
    prints the plan; the run stops before PETSc with the grid size and memory per rank."""
    import os
    import resource
    import subprocess
    import sys
    scene = tmp_path / "huge.toml"
    scene.write_text('[geometry]\nkind = "sphere"\nradius = 1e-3\nnx = 46000\ndx = 1e-8\n'
                     '[material]\ne_star = 1e9\n[protocol]\nvalues = [1e-9]\n')
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
               OMP_NUM_THREADS="1")

    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (8 * 2**30, 8 * 2**30))

    def run(*extra):
        return subprocess.run([sys.executable, "-m", "contactpetsc", "run", str(scene),
                               "--output", str(tmp_path / "out"), *extra], capture_output=True,
                              text=True, env=env, timeout=300, preexec_fn=limit)

    dry = run("--dry-run")
    assert dry.returncode == 0 and "SurfaceGrid(46000 x 46000" in dry.stdout, dry.stdout + dry.stderr
    real = run()
    assert real.returncode == 1, real.stdout + real.stderr
    assert "46000 x 46000 grid (geometry.nx x geometry.ny)" in real.stderr, real.stderr
    assert "GiB per rank" in real.stderr and "error code" not in real.stderr, real.stderr


@pytest.mark.parametrize("n", [32, 48, 64, 96])
def test_default_split_keeps_the_levels_of_one_rank(coll, n):
    """The default split lets the multilevel solver halve an n x n grid down to 8 rows as often on
    this rank count as on one rank (truth: the same grid on COMM_SELF); the rows stay balanced
    to within the alignment."""
    from contactpetsc.solvers.transfer import can_halve, halved

    def halvings(g):
        k = 0
        while can_halve(g) and g.ny // 2 >= 8:
            g, k = halved(g), k + 1
        return k

    g = SurfaceGrid(n, n, 1.0)
    one = SurfaceGrid(n, n, 1.0, comm=PETSc.COMM_SELF)
    sizes = [e - s for s, e in g.y_ranges]
    assert coll.all(halvings(g) == halvings(one))
    assert max(sizes) - min(sizes) <= 16
