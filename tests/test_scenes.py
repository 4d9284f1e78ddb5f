"""Scenes: validation names the key, the value and the accepted range; a run writes its outputs."""
import csv
import json
import os
import re
import subprocess
import sys
from xml.etree import ElementTree

import h5py

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, runner, scenes
from contactpetsc.app.output import LENGTH_UNITS


def minimal(**geometry):
    g = dict(kind="sphere", radius=1e-4, nx=32, dx=5e-8)
    g.update(geometry)
    return {"geometry": g, "material": {"e_star": 50e9}, "protocol": {"values": [1e-9, 2e-9]}}


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("scene, message", [
    ({"foo": 1}, "unknown key 'foo'"),
    (minimal(radiu=1.0), "unknown key geometry.radiu"),
    (minimal(dx=-1.0), "geometry.dx = -1.0: accepted range (0, inf) m"),
    (minimal(nx=1), "geometry.nx = 1: accepted range [2,"),
    (minimal(nx=32.5), "geometry.nx = 32.5: expected int"),
    (minimal(kind="cone"), "geometry.kind = 'cone': accepted values are sphere, self-affine, file"),
    (minimal(hurst=1.5, kind="self-affine", rms_slope=0.1), "geometry.hurst = 1.5: accepted range (0, 1)"),
    (minimal(kind="self-affine", radius=None), "exactly one of geometry.rms_height or geometry.rms_slope"),
    (dict(minimal(), material={"e_star": 0.0}), "material.e_star = 0.0: accepted range (0, inf) Pa"),
    (dict(minimal(), material={}), "material.e_star is required"),
    (dict(minimal(), interaction={"law": "morse"}), "interaction.law = 'morse': accepted values are none"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": 0.1}), "interaction.z0 is required"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": -0.1, "z0": 1e-9}),
     "interaction.work_of_adhesion = -0.1: accepted range"),
    (dict(minimal(), interaction={"law": "lj", "work_of_adhesion": 0.1, "z0": 1e-9, "element_integration": True},
          solver={"method": "relaxation"}), "needs the nodal rule: set interaction.element_integration = false"),
    (dict(minimal(), protocol={"values": []}), "protocol.values = []"),
    (dict(minimal(), protocol={"control": "force", "values": [-1.0]}), "loads must be > 0"),
    (dict(minimal(), protocol={"values": [float("nan")]}), "finite numbers"),
])
def test_bad_scenes_name_the_key(scene, message):
    with pytest.raises(scenes.SceneError) as err:
        scenes.validate(scene)
    assert message in str(err.value)


@pytest.mark.serial   # scene validation: no communicator
def test_defaults_are_filled_in_and_the_default_scene_is_valid():
    s = scenes.validate(minimal())
    assert s["geometry"]["ny"] == 32 and s["geometry"]["dy"] == 5e-8
    assert s["geometry"]["periodic"] is False          # a sphere is isolated by default
    assert scenes.validate(minimal(kind="self-affine", radius=None, rms_slope=0.1))["geometry"]["periodic"] is True
    assert scenes.validate(scenes.DEFAULT_SCENE)["name"] == "hertz-sphere"


@pytest.mark.serial   # scene validation: no communicator
def test_docs_scene_page_is_the_schema_and_its_example_is_valid():
    """docs/scenes.md ends with the tables generated from SCHEMA, and its TOML example validates."""
    import re
    import tomllib
    with open(os.path.join(os.path.dirname(__file__), "..", "docs", "scenes.md")) as f:
        text = f.read()
    assert text.endswith(scenes.schema_markdown()), "regenerate docs/scenes.md from schema_markdown()"
    example = tomllib.loads(re.search(r"```toml\n(.*?)```", text, re.S).group(1))
    assert scenes.validate(example)["output"]["plots"] is True


@pytest.mark.serial   # scene validation: no communicator
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
                                            "dy": 1.5e-8, "rms_slope": 0.1, "seed": 3},
        "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": list(values)},
        "solver": {"tol": 1e-10}, "output": {"directory": out}})
    return runner.run(scene, comm=comm, restart=restart)


def test_scene_run_writes_outputs_equal_on_any_rank_count(coll, shared_tmp):
    world = os.path.join(shared_tmp, "world")
    states = _run(PETSc.COMM_WORLD, world)
    assert coll.all(all(st.converged for st in states))
    with open(os.path.join(world, "curve.csv")) as f:
        rows = list(csv.DictReader(f))
    assert [r["step"] for r in rows] == ["1", "2"]
    assert set(runner.CURVE_COLUMNS) == set(rows[0])
    assert all(np.isfinite(float(r[c])) for r in rows for c in ("approach_m", "force_N", "fft_pairs"))
    assert all(float(r["mean_pressure_Pa"]) == pytest.approx(v, rel=1e-9) for r, v in zip(rows, [5e6, 1e7]))
    with open(os.path.join(world, "history.csv")) as f:
        assert len(list(csv.DictReader(f))) >= 2
    # the same scene on one rank: the same approaches, and the last state's pressures (a run
    # keeps only the last state's fields; the step files' are compared below)
    alone = _run(PETSc.COMM_SELF, os.path.join(shared_tmp, f"self{PETSc.COMM_WORLD.getRank()}"))
    for a, b in zip(states, alone):
        assert coll.max(abs(a.approach - b.approach) / abs(b.approach)) <= 1e-10
    a, b = states[-1], alone[-1]
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
            assert "doi:10.1016/j.ijsolstr.2014.03.033" in a.attrs["citation"]
            for k in a:
                x, y = a[k][:], b[k][:]
                assert np.all(np.isfinite(x))
                worst = max(worst, np.abs(x - y).max() / max(np.abs(y).max(), 1e-300))
            # the contact mask is the set p > 0, and the gap vanishes there
            assert np.array_equal(a["contact"][:] > 0, a["pressure"][:] > 0)
        check_xdmf(os.path.join(world, f"step_{step:04d}.xdmf"), nx=32, ny=24, dx=1e-8, dy=1.5e-8)
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


XDMF_TYPES = {np.dtype("f8"): ("Float", "8"), np.dtype("f4"): ("Float", "4"), np.dtype("u1"): ("UChar", "1")}


def check_xdmf(path, nx, ny, dx, dy, scale=1.0, precision="float64"):
    """The XDMF sidecar read by its schema's rules (axes listed slowest first: z, y, x), not by
    our writer: a one-node-thick ny x nx mesh of spacing (dx, dy) shown in a length unit of
    ``scale`` per metre, every attribute a dataset of the step's HDF5 file with ny x nx values
    of its type (masks uint8; doubles, or floats with ``precision`` float32), the lengths (unit m)
    shown through a Function item ``<scale>*$0``, and every dataset listed."""
    root = ElementTree.parse(path).getroot()
    grid = root.find("Domain/Grid")
    topology, geometry = grid.find("Topology"), grid.find("Geometry")
    assert topology.get("TopologyType") == "3DCoRectMesh"
    assert [int(w) for w in topology.get("Dimensions").split()] == [1, ny, nx]
    assert geometry.get("GeometryType") == "ORIGIN_DXDYDZ"
    origin, spacing = ([float(w) for w in item.text.split()] for item in geometry.findall("DataItem"))
    assert origin == [0.0, 0.0, 0.0] and spacing[1:] == pytest.approx([dy * scale, dx * scale], rel=1e-15)
    names = set()
    floats = {np.dtype("f8")} | ({np.dtype("f4")} if precision == "float32" else set())
    with h5py.File(os.path.join(os.path.dirname(path), os.path.basename(path)[:-5] + ".h5"), "r") as f:
        for attribute in grid.findall("Attribute"):
            item = attribute.find("DataItem")
            if item.get("ItemType") == "Function":
                assert float(item.get("Function").split("*$0")[0]) == scale != 1.0
                item = item.find("DataItem")
            file_name, dataset = item.text.strip().split(":")
            assert file_name == os.path.basename(path)[:-5] + ".h5" and item.get("Format") == "HDF"
            assert np.prod([int(w) for w in item.get("Dimensions").split()]) == nx * ny
            assert f[dataset].shape == (ny, nx)
            unit = f[dataset].attrs["unit"]
            assert f[dataset].dtype == np.uint8 if unit == "1" else f[dataset].dtype in floats
            assert (item.get("NumberType"), item.get("Precision")) == XDMF_TYPES[f[dataset].dtype]
            assert (attribute.find("DataItem").get("ItemType") == "Function") == (unit == "m" and scale != 1.0)
            names.add(attribute.get("Name"))
        assert names == set(f)


def reduced(path, n=32, **output):
    """An example scene on an n x n grid of the same physical size (a height file's on its own)."""
    scene = scenes.load(path)
    g = scene["geometry"]
    if g["kind"] == "file":
        scene["output"].update(output)
        return scene
    g["dx"], g["dy"] = g["dx"] * g["nx"] / n, g["dy"] * g["ny"] / n
    g["nx"] = g["ny"] = n
    scene["output"].update(output)
    return scene


def read_curve(out):
    with open(os.path.join(out, "curve.csv")) as f:
        return list(csv.DictReader(f))


#: example paths long enough to be checked on 1 and 2 ranks only (the suite's time on 3)
# adhesive paths and the area-load search: checked on 1 and 2 ranks (heavy)
LONG_EXAMPLES = ("rough_adhesive_cell.toml", "adhesive_sphere.toml", "atomic_tip.toml", "rough_area_load.toml")
#: examples checked on one rank: on two, their scene (a self-affine elastic cell under mean pressures, the
#: spectral preconditioner) is rough_periodic's, and rough_large_outputs' field files (float32, every k-th
#: step, lengths in nm) are test_field_output's
ONE_RANK_EXAMPLES = ("bench_rough.toml", "rough_large_outputs.toml")


def _marks(path):
    return pytest.mark.heavy if path.endswith(LONG_EXAMPLES) else (
        pytest.mark.serial if path.endswith(ONE_RANK_EXAMPLES) else ())


@pytest.mark.parametrize("path", [pytest.param(p, marks=_marks(p)) for p in EXAMPLES], ids=os.path.basename)
def test_example_scenes_run_at_reduced_size(coll, shared_tmp, path):
    """Every example scene, on a 32 x 32 grid of the same physical size with plots on, converges
    and writes its files: CSV columns, finite fields, HDF5 and XDMF readable, the plots; under
    mpirun the same files, to the solver's tolerance, as the scene run on one rank."""
    # the plots on one rank only: rank 0 draws them from the same files whatever the rank count
    # (the other ranks idle meanwhile); under mpirun they are test_plots_results'
    # test_plots_of_a_rough_run_without_field_files and test_plots_of_a_measured_window, and
    # test_cli_progress_plots_and_plot_command's (a sphere with and without adhesion, 2 ranks)
    plots = coll.size == 1
    scene = reduced(path, plots=plots, fields=True)
    out = os.path.join(shared_tmp, os.path.basename(path))
    states = runner.run(scene, output=out, comm=PETSc.COMM_WORLD)
    assert coll.all(all(st.converged for st in states))
    values = scene["protocol"]["values"]
    rows = read_curve(out)
    assert list(rows[0]) == runner.CURVE_COLUMNS and [int(r["step"]) for r in rows] == list(
        range(1, len(values) + 1))
    # the branch of each step follows the prescribed values: loading where they rise
    assert [r["branch"] for r in rows] == ["loading"] + [
        "loading" if b >= a else "unloading" for a, b in zip(values, values[1:])]
    for r in rows:
        assert all(np.isfinite(float(r[c])) for c in ("approach_m", "force_N", "contact_fraction",
                                                      "complementarity_error", "fft_pairs", "wall_time_s"))
    if scenes.adhesive(scene):
        # adhesion: no state is unstable (the sweep checks those near folds: stability_checked),
        # tensile somewhere on the path, and a pull-off is reported
        assert coll.all(all(np.isfinite(st.force) and st.stable is not False for st in states))
        assert [r["stable"] for r in rows] == [str(st.stable) if st.stable is not None else "nan" for st in states]
        assert [r["stability_checked"] for r in rows] == [str(st.stable is not None) for st in states]
        assert min(st.force for st in states) < 0
        with open(os.path.join(out, "summary.json")) as f:
            summary = json.load(f)
        assert summary["pull_off_force_N"] <= min(st.force for st in states) + 1e-30
        check_pull_off_biases(scene, states, summary)
        with h5py.File(os.path.join(out, "step_0001.h5"), "r") as f:
            assert {"contact_pressure", "adhesive_pressure", "adhesive"} <= set(f)
            assert np.allclose(f["pressure"][:], f["contact_pressure"][:] + f["adhesive_pressure"][:])
            assert np.array_equal(f["adhesive"][:] > 0, f["pressure"][:] < 0)
        # W* = F / (2 pi R w), alpha* = delta / z0 (Greenwood), for a sphere
        g, it = scene["geometry"], scene["interaction"]
        for r in rows if g.get("radius") else ():
            assert float(r["W_star"]) == pytest.approx(
                float(r["force_N"]) / (2 * np.pi * g["radius"] * it["work_of_adhesion"]), rel=1e-12)
            assert float(r["alpha_star"]) == pytest.approx(float(r["approach_m"]) / it["z0"], rel=1e-12)
    else:
        assert coll.all(all(np.isfinite(st.force) and st.force > 0 for st in states))
    g = scene["geometry"]
    area = g["nx"] * g["dx"] * g["ny"] * g["dy"]
    written = [k for k in range(1, len(values) + 1) if os.path.exists(os.path.join(out, f"step_{k:04d}.h5"))]
    every = scene["output"]["field_every"]
    assert {k for k in range(1, len(values) + 1) if k % every == 0 or k == len(values)} <= set(written)
    for k in written:
        with h5py.File(os.path.join(out, f"step_{k:04d}.h5"), "r") as f:
            assert all(np.all(np.isfinite(f[name][:])) for name in f)
            assert float(f.attrs["approach"]) == pytest.approx(float(rows[k - 1]["approach_m"]), rel=1e-12)
            assert json.loads(f.attrs["scene"])["name"] == scene["name"] and "PETSc" in f.attrs["versions"]
            # the mean of the pressure field is the force of curve.csv over the grid's area
            assert f["pressure"][:].mean() * area == pytest.approx(float(rows[k - 1]["force_N"]), rel=1e-9)
        check_xdmf(os.path.join(out, f"step_{k:04d}.xdmf"), g["nx"], g["ny"], g["dx"], g["dy"],
                   LENGTH_UNITS[scene["output"]["length_unit"]], scene["output"]["field_precision"])
    if plots:
        check_plots(out)
    if coll.size > 1:
        alone = os.path.join(shared_tmp, f"self{coll.rank}")
        runner.run(reduced(path, fields=True), output=alone, comm=PETSc.COMM_SELF)
        worst = 0.0
        for a, b in zip(rows, read_curve(alone)):
            for c in ("approach_m", "force_N"):
                worst = max(worst, abs(float(a[c]) - float(b[c])) / max(abs(float(b[c])), 1e-300))
        for k in written:
            with h5py.File(os.path.join(out, f"step_{k:04d}.h5"), "r") as fa, \
                    h5py.File(os.path.join(alone, f"step_{k:04d}.h5"), "r") as fb:
                assert set(fa) == set(fb)
                for name in fa:
                    x, y = fa[name][:].astype(float), fb[name][:].astype(float)
                    worst = max(worst, np.abs(x - y).max() / max(np.abs(y).max(), 1e-300))
        assert coll.max(worst) <= 1e-6


def check_pull_off_biases(scene, states, summary):
    """A sphere's pull-off states the window's left-out tail (against a brute-force sum of the law
    over the gap outside the window, the sphere's at the most tensile state's approach plus the
    point-load far field F / (pi E* r)) and, on a
    grid coarser than the criterion, the sawtooth and the spacing that removes it (the LJ cohesive
    zone (pi/4) E* w / sigma_max^2 = 0.7455 E* z0^2 / w over RESOLUTION_NODES)."""
    from contactpetsc.physics.closed_forms import sphere_window_edges
    from contactpetsc.physics.resolution import RESOLUTION_NODES
    from test_grid_biases import tail_by_summation
    g, it = scene["geometry"], scene["interaction"]
    if g["kind"] != "sphere" or it["law"] not in ("lj", "hardwall-lj"):
        return
    law = builder.build_law(scene)
    z0 = it["z0"]
    at = min((st for st in states if st.stable is not False), key=lambda st: st.force).approach
    ref = tail_by_summation(law, g["radius"], at, sphere_window_edges(g["nx"], g["ny"], g["dx"], g["dy"]),
                            h=0.25 * z0, reach=400 * z0,
                            far=summary["pull_off_force_N"] / (np.pi * scenes.e_star(scene)))
    assert summary["window_tail_N"] == pytest.approx(ref, rel=2e-3)
    assert summary["window_tail_fraction"] == pytest.approx(ref / summary["pull_off_force_N"], rel=2e-3)
    zone = np.pi / 4 * 243 / 256 * scenes.e_star(scene) * z0 ** 2 / it["work_of_adhesion"]   # sigma_max = 16 w / (9 sqrt(3) z0)
    if zone / max(g["dx"], g["dy"]) < RESOLUTION_NODES:
        assert summary["sawtooth_free_dx_m"] == pytest.approx(zone / RESOLUTION_NODES, rel=1e-9)
        lo, hi = summary["sawtooth_amplitude"]
        assert lo < 0 < hi
    else:
        assert "sawtooth_amplitude" not in summary


def check_plots(out):
    """The three PNG files of output.plots exist and are images (drawn by rank 0)."""
    from matplotlib.image import imread
    for name in ("load_approach.png", "pressure_map.png", "error_vs_time.png"):
        image = imread(os.path.join(out, name))
        assert image.ndim == 3 and image.shape[0] > 100 and image.shape[1] > 100, name
        assert image[..., :3].std() > 0.05, f"{name} is blank"


def _run_adhesive(comm, out, values, restart=False):
    scene = scenes.validate({
        "name": "test-adhesive", "geometry": {"kind": "sphere", "radius": 30e-9, "nx": 32, "dx": 0.3e-9},
        "material": {"e_star": 10e9},
        "interaction": {"law": "lj", "work_of_adhesion": 0.1, "z0": 0.3e-9},
        # the values' own steps of a whole z0: the restarted step is one solve, checked
        "protocol": {"control": "approach", "values": list(values), "refine_pull_off": False, "max_step": 0.0},
        "output": {"directory": out}})
    return runner.run(scene, comm=comm, restart=restart)


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


@pytest.mark.serial
def test_plots_draw_the_data_they_are_given():
    """load_approach: each branch's markers at its own steps, the jumps as arrows between the
    located states, the pull-off line at the pull-off force; pressure_map: the field itself on a
    diverging colour scale centred at zero."""
    from contactpetsc.app import plots
    approach = np.array([-3.0, -2.0, -1.0, 0.0, -1.0, -2.0, -3.0]) * 1e-10      # m
    force = np.array([-1.0, -2.0, -9.0, -6.0, -9.5, -3.0, -1.5]) * 1e-9          # N
    branch = ["loading"] * 4 + ["unloading"] * 3
    jumps = {"kind": ["jump-on", "jump-off"], "approach_before_m": np.array([-1.5e-10, -1.6e-10]),
             "approach_after_m": np.array([-1.4e-10, -1.7e-10]),
             "force_before_N": np.array([-2.5e-9, -8.0e-9]), "force_after_N": np.array([-8.5e-9, -2.9e-9])}
    curve = {"approach_m": approach, "force_N": force, "branch": branch,
             "stable": np.ones(7), "converged": np.ones(7)}
    fig = plots.load_approach(curve, jumps, pull_off=-9.7e-9)
    ax = fig.axes[0]
    assert "[nN]" in ax.get_ylabel() and "[pm]" in ax.get_xlabel()
    markers = {line.get_color(): line for line in ax.lines if line.get_linestyle() == "None"}
    for name, idx in (("loading", slice(0, 4)), ("unloading", slice(4, 7))):
        line = markers[plots.BRANCH_STYLE[name]["color"]]
        assert np.allclose(line.get_xdata(), approach[idx] * 1e12)
        assert np.allclose(line.get_ydata(), force[idx] * 1e9)
    arrows = [a for a in ax.texts if a.arrow_patch is not None]
    assert len(arrows) == 2
    for k, arrow in enumerate(arrows):
        assert np.allclose(arrow.xy, (jumps["approach_after_m"][k] * 1e12, jumps["force_after_N"][k] * 1e9))
        assert np.allclose(arrow.xyann, (jumps["approach_before_m"][k] * 1e12, jumps["force_before_N"][k] * 1e9))
    pull = [line for line in ax.lines if line.get_linestyle() == ":"]
    assert len(pull) == 1 and np.allclose(pull[0].get_ydata(), -9.7)
    assert {"loading", "unloading", "pull-off -9.7 nN"} <= {t.get_text() for t in ax.get_legend().get_texts()}

    p = np.outer(np.linspace(-1.0, 3.0, 5), np.ones(4)) * 1e6                  # Pa, (ny, nx)
    fig = plots.pressure_map(p, 1e-9, 2e-9)
    image = fig.axes[0].images[0]
    assert image.get_cmap().name == "RdBu_r"
    assert image.norm.vmin == -image.norm.vmax == pytest.approx(-3.0)         # MPa, centred at zero
    assert np.allclose(image.get_array(), p / 1e6)
    assert image.get_extent() == pytest.approx([-0.5, 3.5, -1.0, 9.0])         # nm, x horizontal


def test_plots_need_matplotlib_before_the_run_starts(coll, shared_tmp, monkeypatch):
    import importlib.util
    find_spec = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec",
                        lambda name, *a: None if name == "matplotlib" else find_spec(name, *a))
    scene = scenes.validate(dict(minimal(), output={"plots": True}))
    out = os.path.join(shared_tmp, "no-matplotlib")
    coll.raises(ImportError, ["output.plots needs matplotlib", "pip install matplotlib"],
                runner.run, scene, output=out, comm=PETSc.COMM_WORLD)
    assert not os.path.exists(out)          # refused before anything was solved or written


# -- the command line, as a user runs it ---------------------------------------------------------
CLI = [sys.executable, "-m", "contactpetsc"]
ENV = dict(os.environ, OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
           OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")
PROGRESS = re.compile(r"^\s+(\d+)\s+(\S+)\s+(\S+).*\[step (\d+)/(\d+), ([\d.]+) s, ~([\d.]+) s left\]$")


def cli(args, ranks=1, cwd=None):
    cmd = (["mpirun", "-n", str(ranks)] if ranks > 1 else []) + CLI + list(args)
    done = subprocess.run(cmd, env=ENV, cwd=cwd, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{cmd}:\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.mark.serial
def test_cli_version():
    out = cli(["--version"])
    import contactpetsc
    assert f"contactpetsc: {contactpetsc.__version__}" in out
    assert "PETSc: %d.%d.%d" % PETSc.Sys.getVersion() in out


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@pytest.mark.parametrize("name, solver", [("adhesive_sphere.toml", "SNES vinewtonrsls (prefix -adhesion_"),
                                          ("rough_periodic.toml", "SNES vinewtonrsls (prefix -contact_")])
def test_cli_dry_run_prints_the_plan_on_two_ranks(tmp_path, name, solver):
    path = [p for p in EXAMPLES if p.endswith(name)][0]
    scene = scenes.load(path)
    g = scene["geometry"]
    out = cli(["run", "--dry-run", path, "--output", str(tmp_path / "out")], ranks=2)
    assert f"SurfaceGrid({g['nx']} x {g['ny']}" in out and "2 rank(s)" in out
    half = g["ny"] // 2                          # 16-row blocks: an even split of these grids
    assert f"rows per rank [{half}, {g['ny'] - half}]" in out
    assert solver in out and f"preconditioner {scene['solver']['preconditioner']}" in out
    assert re.search(r"memory estimate: \d+ MiB per rank", out)
    n = len(scene["protocol"]["values"])
    assert f"x {n} steps" in out and f"{n} x step_NNNN.h5" in out
    assert not (tmp_path / "out").exists()      # a dry run writes nothing


def write_scene(path, text):
    path.write_text(text)
    return str(path)


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
@pytest.mark.parametrize("kind", ["non-adhesive", "adhesive"])
def test_cli_progress_plots_and_plot_command(tmp_path, kind):
    """Progress on rank 0 for every step (step i of N, load, error, elapsed, time left) that
    matches curve.csv; --plots saves the plots; `contactpetsc plot DIR` redraws them."""
    scene = write_scene(tmp_path / "s.toml", (
        '[geometry]\nkind = "sphere"\nradius = 30e-9\nnx = 32\ndx = 0.6e-9\n[material]\ne_star = 10e9\n'
        + ('[interaction]\nlaw = "lj"\nwork_of_adhesion = 0.3\nz0 = 0.3e-9\n'
           '[protocol]\nvalues = [-0.6e-9, -0.3e-9, 0.0, -0.3e-9]\nrefine_pull_off = false\n'
           if kind == "adhesive" else '[protocol]\nvalues = [1e-10, 2e-10, 4e-10]\n')))
    out_dir = tmp_path / "out"
    out = cli(["run", scene, "--plots", "--output", str(out_dir)], ranks=2)
    progress = [m.groups() for m in map(PROGRESS.match, out.splitlines()) if m]
    rows = read_curve(out_dir)
    assert [int(p[0]) for p in progress] == [int(p[3]) for p in progress] == list(range(1, len(rows) + 1))
    assert {int(p[4]) for p in progress} == {len(rows)}
    elapsed = [float(p[5]) for p in progress]
    assert elapsed == sorted(elapsed) and float(progress[-1][6]) == 0.0
    for p, r in zip(progress, rows):     # approach and force as printed, to 5 digits
        assert float(p[1]) == pytest.approx(float(r["approach_m"]), rel=1e-4, abs=1e-25)
        assert float(p[2]) == pytest.approx(float(r["force_N"]), rel=1e-4)
    header = out.splitlines()[[i for i, line in enumerate(out.splitlines()) if "approach [m]" in line][0]]
    assert "force [N]" in header and "error" in header
    check_plots(out_dir)
    for png in out_dir.glob("*.png"):
        png.unlink()
    assert "wrote" in cli(["plot", str(out_dir)])
    check_plots(out_dir)


def test_atomic_tip_forces_per_atom_add_up_to_the_load(coll, shared_tmp):
    """kind = tip with output.atom_forces: the forces on the atoms (pressure over each atom's
    footprint) add up, step by step, to the net force of curve.csv (every node belongs to
    one atom when the grid spacing is below the atom radius)."""
    scene = scenes.load(next(p for p in EXAMPLES if p.endswith("atomic_tip.toml")))
    scene["geometry"]["nx"] = scene["geometry"]["ny"] = 64
    scene["protocol"]["values"] = [-0.2e-9, 0.0, 0.1e-9, -0.3e-9]
    scene["output"]["fields"] = False
    out = os.path.join(shared_tmp, "tip")
    states = runner.run(scene, output=out, comm=PETSc.COMM_WORLD)
    assert coll.all(all(st.converged for st in states))
    with open(os.path.join(out, "atom_forces.csv")) as f:
        rows = list(csv.DictReader(f))
    for st, r in zip(states, read_curve(out)):
        total = sum(float(a["force_N"]) for a in rows if float(a["approach_m"]) == st.approach)
        assert total == pytest.approx(float(r["force_N"]), rel=1e-9)
