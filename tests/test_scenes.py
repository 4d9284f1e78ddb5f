"""Scenes: validation names the key, the value and the accepted range; a run writes its outputs."""
import csv
import json
import os

import h5py

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc import protocols, scenes


def minimal(**geometry):
    g = dict(kind="sphere", radius=1e-4, nx=32, dx=5e-8)
    g.update(geometry)
    return {"geometry": g, "material": {"e_star": 50e9}, "protocol": {"values": [1e-9, 2e-9]}}


@pytest.mark.parametrize("scene, message", [
    ({"foo": 1}, "unknown key 'foo'"),
    (minimal(radiu=1.0), "unknown key geometry.radiu"),
    (minimal(dx=-1.0), "geometry.dx = -1.0: accepted range (0, inf] m"),
    (minimal(nx=1), "geometry.nx = 1: accepted range [2,"),
    (minimal(nx=32.5), "geometry.nx = 32.5: expected int"),
    (minimal(kind="cone"), "geometry.kind = 'cone': accepted values are sphere, self-affine, file"),
    (minimal(hurst=1.5, kind="self-affine", rms_slope=0.1), "geometry.hurst = 1.5: accepted range (0, 1]"),
    (minimal(kind="self-affine"), "exactly one of geometry.rms_height or geometry.rms_slope"),
    (dict(minimal(), material={"e_star": 0.0}), "material.e_star = 0.0: accepted range (0, inf] Pa"),
    (dict(minimal(), material={}), "material.e_star is required"),
    (dict(minimal(), interaction={"law": "morse"}), "interaction.law = 'morse': accepted values are none"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": 0.1}), "interaction.z0 is required"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": -0.1, "z0": 1e-9}),
     "interaction.work_of_adhesion = -0.1: accepted range"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": 0.1, "z0": 1e-9},
          solver={"method": "relaxation"}), "needs a hard-wall law"),
    (dict(minimal(), protocol={"values": []}), "protocol.values = []"),
    (dict(minimal(), protocol={"control": "force", "values": [-1.0]}), "loads must be > 0"),
    (dict(minimal(), protocol={"values": [float("nan")]}), "finite numbers"),
])
def test_bad_scenes_name_the_key(scene, message):
    with pytest.raises(scenes.SceneError) as err:
        scenes.validate(scene)
    assert message in str(err.value)


def test_defaults_are_filled_in_and_the_default_scene_is_valid():
    s = scenes.validate(minimal())
    assert s["geometry"]["ny"] == 32 and s["geometry"]["dy"] == 5e-8
    assert s["geometry"]["periodic"] is False          # a sphere is isolated by default
    assert scenes.validate(minimal(kind="self-affine", rms_slope=0.1))["geometry"]["periodic"] is True
    assert scenes.validate(scenes.DEFAULT_SCENE)["name"] == "hertz-sphere"


def test_unreadable_and_invalid_toml(tmp_path):
    with pytest.raises(scenes.SceneError, match="cannot read scene"):
        scenes.load(str(tmp_path / "missing.toml"))
    bad = tmp_path / "bad.toml"
    bad.write_text("[geometry\nnx = 3\n")
    with pytest.raises(scenes.SceneError, match="not valid TOML"):
        scenes.load(str(bad))


def _run(comm, out, values=(5e6, 1e7), restart=False):
    scene = scenes.validate({
        "name": "test-rough", "geometry": {"kind": "self-affine", "nx": 32, "ny": 24, "dx": 1e-8,
                                            "rms_slope": 0.1, "seed": 3},
        "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": list(values)},
        "solver": {"tol": 1e-10}, "output": {"directory": out}})
    return protocols.run(scene, comm=comm, restart=restart)


def test_scene_run_writes_outputs_equal_on_any_rank_count(coll, shared_tmp):
    world = os.path.join(shared_tmp, "world")
    states = _run(PETSc.COMM_WORLD, world)
    assert coll.all(all(st.converged for st in states))
    with open(os.path.join(world, "curve.csv")) as f:
        rows = list(csv.DictReader(f))
    assert [r["step"] for r in rows] == ["1", "2"]
    assert set(protocols.CURVE_COLUMNS) == set(rows[0])
    assert all(np.isfinite(float(r[c])) for r in rows for c in ("approach_m", "force_N", "fft_pairs"))
    assert all(float(r["mean_pressure_Pa"]) == pytest.approx(v, rel=1e-9) for r, v in zip(rows, [5e6, 1e7]))
    with open(os.path.join(world, "history.csv")) as f:
        assert len(list(csv.DictReader(f))) >= 2
    # the same scene on one rank: the same approaches and pressures
    alone = _run(PETSc.COMM_SELF, os.path.join(shared_tmp, f"self{PETSc.COMM_WORLD.getRank()}"))
    for a, b in zip(states, alone):
        assert coll.max(abs(a.approach - b.approach) / abs(b.approach)) <= 1e-10
        pa = a.pressure.getArray(readonly=True)
        ys = a.pressure.getOwnershipRange()
        pb = b.pressure.getArray(readonly=True)[ys[0]:ys[1]]
        assert coll.max(np.abs(pa - pb).max() / np.abs(pb).max()) <= 1e-10


def test_fields_hdf5_and_xdmf_equal_on_any_rank_count(coll, shared_tmp):
    import h5py
    world = os.path.join(shared_tmp, "world")
    _run(PETSc.COMM_WORLD, world)
    alone = os.path.join(shared_tmp, f"self{PETSc.COMM_WORLD.getRank()}")
    _run(PETSc.COMM_SELF, alone)
    worst = 0.0
    for step in (1, 2):
        with h5py.File(os.path.join(world, f"step_{step:04d}.h5"), "r") as a, \
                h5py.File(os.path.join(alone, f"step_{step:04d}.h5"), "r") as b:
            assert set(a) == {"pressure", "gap", "displacement", "heights", "contact"}
            assert a["pressure"].shape == (24, 32) and a["pressure"].attrs["unit"] == "Pa"
            assert "test-rough" in a.attrs["scene"] and "PETSc" in a.attrs["versions"]
            for k in a:
                x, y = a[k][:], b[k][:]
                assert np.all(np.isfinite(x))
                worst = max(worst, np.abs(x - y).max() / max(np.abs(y).max(), 1e-300))
            # the contact mask is the set p > 0, and the gap vanishes there
            assert np.array_equal(a["contact"][:] > 0, a["pressure"][:] > 0)
        xdmf = open(os.path.join(world, f"step_{step:04d}.xdmf")).read()
        assert f"step_{step:04d}.h5:/pressure" in xdmf and 'Dimensions="24 32"' in xdmf
    assert not [f for f in os.listdir(world) if f.endswith(".tmp")]
    assert coll.max(worst) <= 1e-10


def test_interrupted_sweep_resumes_after_its_last_step(coll, shared_tmp):
    full = _run(PETSc.COMM_WORLD, os.path.join(shared_tmp, "full"))
    cut = os.path.join(shared_tmp, "cut")
    _run(PETSc.COMM_WORLD, cut, values=(5e6,))            # a sweep stopped after step 1
    resumed = _run(PETSc.COMM_WORLD, cut, restart=True)     # the whole sweep, restarted
    assert len(resumed) == 1                                # only step 2 was solved again
    with open(os.path.join(cut, "curve.csv")) as f:
        rows = list(csv.DictReader(f))
    assert [r["step"] for r in rows] == ["1", "2"]
    a, b = resumed[0], full[1]
    assert coll.all(a.converged)
    assert coll.max(abs(a.approach - b.approach) / abs(b.approach)) <= 1e-8
    pa, pb = a.pressure.getArray(readonly=True), b.pressure.getArray(readonly=True)
    assert coll.max(np.abs(pa - pb).max() / np.abs(pb).max()) <= 1e-8


EXAMPLES = sorted(os.path.join(os.path.dirname(__file__), "..", "examples", "scenes", f)
                  for f in os.listdir(os.path.join(os.path.dirname(__file__), "..", "examples", "scenes"))
                  if f.endswith(".toml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=os.path.basename)
def test_example_scenes_run_at_reduced_size(coll, shared_tmp, path):
    """Every example scene, on a 32 x 32 grid of the same physical size, converges and writes its files."""
    scene = scenes.load(path)
    g = scene["geometry"]
    g["dx"], g["dy"] = g["dx"] * g["nx"] / 32, g["dy"] * g["ny"] / 32
    g["nx"] = g["ny"] = 32
    out = os.path.join(shared_tmp, os.path.basename(path))
    states = protocols.run(scene, output=out, comm=PETSc.COMM_WORLD)
    assert coll.all(all(st.converged for st in states))
    if scenes.adhesive(scene):
        # adhesion: every state is stable, tensile somewhere on the path, and a pull-off is reported
        assert coll.all(all(np.isfinite(st.force) and st.stable for st in states))
        assert min(st.force for st in states) < 0
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        assert summary["pull_off_force_N"] <= min(st.force for st in states) + 1e-30
        with open(os.path.join(out, "curve.csv")) as f:
            header = next(csv.reader(f))
        assert {"adhesive_force_N", "adhesive_load_ratio", "W_star", "stable"} <= set(header)
        with h5py.File(os.path.join(out, "step_0001.h5"), "r") as f:
            assert {"contact_pressure", "adhesive_pressure", "adhesive"} <= set(f)
    else:
        assert coll.all(all(np.isfinite(st.force) and st.force > 0 for st in states))
    n = len(scene["protocol"]["values"])
    for name in ["curve.csv", "history.csv"] + [f"step_{k:04d}.h5" for k in range(1, n + 1)]:
        assert os.path.exists(os.path.join(out, name)), name


def _run_adhesive(comm, out, values, restart=False):
    scene = scenes.validate({
        "name": "test-adhesive", "geometry": {"kind": "sphere", "radius": 30e-9, "nx": 32, "dx": 0.3e-9},
        "material": {"e_star": 10e9},
        "interaction": {"law": "lj", "work_of_adhesion": 0.1, "z0": 0.3e-9},
        "protocol": {"control": "approach", "values": list(values), "refine_pull_off": False},
        "output": {"directory": out}})
    return protocols.run(scene, comm=comm, restart=restart)


def test_interrupted_adhesive_sweep_resumes_from_both_pressures(coll, shared_tmp):
    values = (-0.3e-9, 0.0, 0.3e-9)
    full = _run_adhesive(PETSc.COMM_WORLD, os.path.join(shared_tmp, "afull"), values)
    cut = os.path.join(shared_tmp, "acut")
    _run_adhesive(PETSc.COMM_WORLD, cut, values[:2])
    resumed = _run_adhesive(PETSc.COMM_WORLD, cut, values, restart=True)
    assert len(resumed) == 1
    a, b = resumed[0], full[2]
    assert coll.all(a.converged and a.stable)
    pa, pb = a.pressure.getArray(readonly=True), b.pressure.getArray(readonly=True)
    assert coll.max(np.abs(pa - pb).max() / np.abs(pb).max()) <= 1e-6
    with open(os.path.join(cut, "summary.json")) as f:
        assert json.load(f)["steps"] == 3
