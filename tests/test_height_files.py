"""Height input: one axis convention end to end, real heights only, files checked before a run.

Truths: an analytic, asymmetric pattern h(x, y) written through the real step-file writer
(``output.write_state``) and read back through a ``kind = "file"`` scene must come back as
h(x_i, y_j) indexed [i, j] (not transposed), on a square and a non-square grid, on any number
of ranks; refusals name the key or the file and what is accepted, and the nearest good input
is accepted.
"""
import os
import subprocess
import sys
import types
import warnings

import h5py
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, output, scenes
from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid

DX, DY = 2e-9, 3e-9


def pattern(x, y):
    """Asymmetric in x and y (h(x, y) != h(y, x) on a square grid) [m]."""
    return 1e-9 * (x / DX + 0.1 * (y / DY) ** 2)


def on_root(coll, func):
    if coll.rank == 0:
        func()
    coll.comm.Barrier()


def file_scene(path, nx, ny, dataset="heights", dx=DX, dy=DY):
    return {"geometry": {"kind": "file", "path": str(path), "dataset": dataset, "nx": nx, "ny": ny,
                         "dx": dx, "dy": dy},
            "material": {"e_star": 1e9}, "protocol": {"values": [1e-10]}}


def write_step(directory, nx, ny, stamp=True):
    """A step file of the analytic pattern through output.write_state (collective); stamped
    axes = "y,x" on the file and its datasets (by hand when the writer does not)."""
    grid = SurfaceGrid(nx, ny, DX, DY, periodic=False)
    h = surfaces.from_function(grid, pattern)
    zero = grid.create_vec(0.0)
    state = types.SimpleNamespace(pressure=zero, gap=h.copy(), displacement=zero, approach=0.0,
                                  mean_pressure=0.0, force=0.0, contact_fraction=0.0,
                                  complementarity_error=0.0, converged=True)
    path = output.write_state(str(directory), 1, grid, h, state, {"scene": "{}"})
    if grid.mpi_comm.Get_rank() == 0:
        with h5py.File(path, "a") as f:
            for obj in [f] + [f[k] for k in f]:
                if stamp and "axes" not in obj.attrs:
                    obj.attrs["axes"] = "y,x"
                if not stamp and "axes" in obj.attrs:
                    del obj.attrs["axes"]
    grid.mpi_comm.Barrier()
    return path


@pytest.mark.parametrize("nx, ny", [(12, 8), (10, 10)])
def test_step_heights_fed_back_are_not_transposed(coll, shared_tmp, nx, ny):
    path = write_step(shared_tmp, nx, ny)
    scene = scenes.validate(file_scene(path, nx, ny))
    grid = builder.build_grid(scene)
    got = grid.gather(builder.build_heights(scene, grid))
    x, y = np.meshgrid(np.arange(nx) * DX, np.arange(ny) * DY, indexing="ij")
    assert coll.max(np.abs(got - pattern(x, y)).max() / pattern(x, y).max()) <= 1e-15
    # the file keeps (ny, nx): read on one rank, its rows are y
    with h5py.File(path, "r") as f:
        assert coll.max(np.abs(f["heights"][...].T - pattern(x, y)).max()) <= 1e-24


def test_unstamped_or_wrongly_stamped_files_are_refused(coll, shared_tmp):
    nx, ny = 10, 10
    path = write_step(shared_tmp, nx, ny, stamp=False)
    coll.raises(scenes.SceneError, ["geometry.path", "axes", "y,x"], scenes.validate,
                file_scene(path, nx, ny))
    g = SurfaceGrid(nx, ny, DX, DY)
    coll.raises(GridError, ["axes", "y,x"], surfaces.from_file, g, str(path))
    odd, xy = shared_tmp / "odd.h5", shared_tmp / "xy.h5"
    data = np.arange(12 * 8, dtype=float).reshape(12, 8)

    def write():
        with h5py.File(odd, "w") as f:
            f["heights"] = data
            f["heights"].attrs["axes"] = "i,j"
        with h5py.File(xy, "w") as f:
            f.attrs["axes"] = "y,x"
            f["heights"] = data
            f["heights"].attrs["axes"] = b"x,y"     # the dataset's stamp wins over its file's

    on_root(coll, write)
    coll.raises(scenes.SceneError, ["geometry.path", "axes", "'x,y'", "'y,x'"], scenes.validate,
                file_scene(odd, 12, 8))
    g = SurfaceGrid(12, 8, DX, DY)
    assert coll.max(np.abs(g.gather(surfaces.from_file(g, str(xy))) - data).max()) == 0.0
    # stored (12, 8) as x,y does not fit an 8 x 12 grid, whatever the stamp
    coll.raises(scenes.SceneError, ["geometry.path", "(12, 8)", "(8, 12)"], scenes.validate,
                file_scene(xy, 8, 12))


def test_file_spacing_must_match_the_scene(coll, shared_tmp):
    path = write_step(shared_tmp, 12, 8)
    coll.raises(scenes.SceneError, ["geometry.path", "dx = 2e-09", "geometry.dx = 2.1e-09"],
                scenes.validate, file_scene(path, 12, 8, dx=2.1e-9))
    coll.raises(scenes.SceneError, ["dy = 3e-09", "geometry.dy = 4e-09"],
                scenes.validate, file_scene(path, 12, 8, dy=4e-9))
    g = SurfaceGrid(12, 8, DX, 4e-9)
    coll.raises(GridError, ["dy", "4e-09"], surfaces.from_file, g, str(path))
    scenes.validate(file_scene(path, 12, 8, dx=DX * (1 + 1e-12)))   # the same spacing, printed apart


@pytest.mark.parametrize("dtype, word", [(complex, "complex"), (bool, "boolean")])
def test_complex_and_boolean_heights_are_refused(coll, shared_tmp, dtype, word):
    nx, ny = 6, 7
    g = SurfaceGrid(nx, ny, DX, DY)
    bad = (np.ones((nx, ny)) * 1e-9).astype(dtype)
    coll.raises(GridError, [np.dtype(dtype).name, word, "real"], surfaces.from_array, g, bad)
    npy, h5 = shared_tmp / "bad.npy", shared_tmp / "bad.h5"

    def write():
        np.save(npy, bad)
        with h5py.File(h5, "w") as f:
            f["heights"] = bad

    on_root(coll, write)
    for path in (npy, h5):
        coll.raises(scenes.SceneError, ["geometry.path", np.dtype(dtype).name, "real"],
                    scenes.validate, file_scene(path, nx, ny))
        coll.raises(GridError, [np.dtype(dtype).name, word], surfaces.from_file, g, str(path))
    # the nearest good input: the same values as floats
    good = bad.real.astype(float) if dtype is complex else bad.astype(float)
    assert coll.max(np.abs(g.gather(surfaces.from_array(g, good)) - good).max()) == 0.0


def test_integer_heights_are_read_with_a_warning(coll, shared_tmp):
    nx, ny = 6, 7
    g = SurfaceGrid(nx, ny, DX, DY)
    ints = np.arange(nx * ny).reshape(nx, ny)
    with pytest.warns(surfaces.HeightDtypeWarning, match="int64"):
        v = surfaces.from_array(g, ints)
    assert coll.max(np.abs(g.gather(v) - ints).max()) == 0.0
    npy = shared_tmp / "ints.npy"
    on_root(coll, lambda: np.save(npy, ints.astype(np.int32)))
    with pytest.warns(surfaces.HeightDtypeWarning, match="int32"):
        v = surfaces.from_file(g, str(npy))
    assert coll.max(np.abs(g.gather(v) - ints).max()) == 0.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        surfaces.from_array(g, ints.astype(np.float32))   # floats of any precision: no warning


def test_empty_and_truncated_npy_name_the_cause(coll, shared_tmp):
    nx, ny = 6, 7
    empty, text, cut = shared_tmp / "empty.npy", shared_tmp / "text.npy", shared_tmp / "cut.npy"

    def write():
        empty.write_bytes(b"")
        text.write_text("1 2 3\n")
        np.save(cut, np.ones((nx, ny)))
        cut.write_bytes(cut.read_bytes()[:-8])

    on_root(coll, write)
    g = SurfaceGrid(nx, ny, DX, DY)
    for path in (empty, text):
        coll.raises(GridError, [path.name, "empty or not a .npy file"], surfaces.from_file, g, str(path))
        coll.raises(scenes.SceneError, ["geometry.path", "empty or not a .npy file"], scenes.validate,
                    file_scene(path, nx, ny))
    coll.raises(scenes.SceneError, ["geometry.path", "truncated"], scenes.validate, file_scene(cut, nx, ny))


def test_scene_file_checks_cover_missing_files_datasets_and_shapes(coll, shared_tmp):
    nx, ny = 6, 7
    h5 = shared_tmp / "h.h5"
    on_root(coll, lambda: h5py.File(h5, "w").create_dataset("elevation", data=np.ones((nx, ny))))
    coll.raises(scenes.SceneError, ["geometry.path", "missing.npy"], scenes.validate,
                file_scene(shared_tmp / "missing.npy", nx, ny))
    coll.raises(scenes.SceneError, ["geometry.path", "'heights'", "geometry.dataset", "elevation"],
                scenes.validate, file_scene(h5, nx, ny))
    coll.raises(scenes.SceneError, ["geometry.path", "(6, 7)", "(7, 6)"], scenes.validate,
                file_scene(h5, ny, nx, dataset="elevation"))
    coll.raises(scenes.SceneError, ["geometry.path", "'.tif'", ".npy", ".x3p"], scenes.validate,
                file_scene(shared_tmp / "h.tif", nx, ny))
    assert scenes.validate(file_scene(h5, nx, ny, dataset="elevation"))["geometry"]["nx"] == nx


@pytest.mark.serial
def test_dry_run_checks_the_height_file(tmp_path):
    """`contactpetsc run --dry-run` refuses a scene whose height file does not fit, and plans
    one whose file fits."""
    nx, ny = 12, 8
    np.save(tmp_path / "good.npy", np.ones((nx, ny)))
    np.save(tmp_path / "wrong.npy", np.ones((ny, nx)))
    env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(os.path.abspath(__file__))),
               OMP_NUM_THREADS="1")
    for name, code, words in (("good", 0, ["SurfaceGrid(12 x 8"]),
                              ("wrong", 1, ["geometry.path", "(8, 12)", "(12, 8)"])):
        scene = tmp_path / f"{name}.toml"
        scene.write_text(f'[geometry]\nkind = "file"\npath = "{tmp_path / name}.npy"\nnx = {nx}\n'
                         f'ny = {ny}\ndx = 1e-9\n[material]\ne_star = 1e9\n[protocol]\nvalues = [1e-10]\n')
        run = subprocess.run([sys.executable, "-m", "contactpetsc", "run", str(scene), "--dry-run"],
                             capture_output=True, text=True, env=env, timeout=120)
        assert run.returncode == code, run.stdout + run.stderr
        assert all(w in run.stdout + run.stderr for w in words), run.stdout + run.stderr
