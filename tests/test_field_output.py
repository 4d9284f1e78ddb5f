"""Field files at scale: uint8 masks, float32 fields, a selection of fields, every k-th step, one
temporal XDMF collection and lengths shown in a chosen unit.

Truths: IEEE rounding (a float32 field is the float64 result rounded to nearest, elementwise),
the masks' definitions (p > 0, p < 0), the documented rule of the written steps applied to the
run's own curve.csv and jumps.csv, the XDMF rules (a temporal collection with one Time per
written step, the approach of curve.csv), the uninterrupted run (restarts), and the run on one
rank (under mpirun).
"""
import csv
import os
from xml.etree import ElementTree

import h5py
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import runner, scenes
from scene_files import adhesive_sweep_scene as sweep, sweep_every_4th

VALUES = [5e6, 1e7, 1.5e7, 2e7, 2.5e7, 3e7, 3.5e7]


def rough(out, values=VALUES, **output):
    return scenes.validate({
        "name": "fields-rough",
        "geometry": {"kind": "self-affine", "nx": 24, "ny": 16, "dx": 1e-8, "dy": 1.5e-8, "rms_slope": 0.1,
                     "seed": 3},
        "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": list(values)},
        "output": dict(directory=str(out), **output)})


def read_rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def step_files(out):
    return sorted(int(n[5:9]) for n in os.listdir(out) if n.startswith("step_") and n.endswith(".h5"))


def collection(out):
    """(time label, [(step, time, {attribute: (HDF5 path, number type, precision, scale)})],
    spacing) of fields.xdmf, read by the XDMF rules."""
    root = ElementTree.parse(os.path.join(out, "fields.xdmf")).getroot()
    series = root.find("Domain/Grid")
    assert series.get("GridType") == "Collection" and series.get("CollectionType") == "Temporal"
    label = series.find("Information").get("Value")
    steps, spacing = [], set()
    for grid in series.findall("Grid"):
        assert grid.get("GridType") == "Uniform"
        time = float(grid.find("Time").get("Value"))
        spacing.add(tuple(float(w) for w in grid.findall("Geometry/DataItem")[1].text.split()))
        attributes, h5 = {}, set()
        for attribute in grid.findall("Attribute"):
            item, scale = attribute.find("DataItem"), 1.0
            if item.get("ItemType") == "Function":   # "<factor>*$0" of the one item inside
                factor, var = item.get("Function").split("*")
                assert var == "$0"
                scale, item = float(factor), item.find("DataItem")
            name, dataset = item.text.strip().split(":")
            h5.add(name)
            attributes[attribute.get("Name")] = (dataset, item.get("NumberType"), int(item.get("Precision")), scale)
        (name,) = h5
        steps.append((int(name[5:9]), time, attributes))
    (spacing,) = spacing
    return label, steps, spacing


def test_output_keys_are_checked_naming_the_accepted_fields(coll):
    def scene(**output):
        return {"geometry": {"kind": "sphere", "radius": 1e-6, "nx": 16, "dx": 1e-8},
                "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}, "output": output}
    for output, words in (
            ({"fields": ["pressure", "presure"]}, ["output.fields", "'presure'", "pressure, gap, displacement, "
                                                   "heights, contact"]),
            ({"fields": ["adhesive"]}, ["'adhesive' is not a field", "with adhesion"]),
            ({"fields": []}, ["empty list"]),
            ({"fields": ["gap", "gap"]}, ["named twice"]),
            ({"fields": "pressure"}, ["output.fields", "bool or list"]),
            ({"field_precision": "float16"}, ["output.field_precision", "float64, float32"]),
            ({"field_every": 0}, ["output.field_every", "[1, "]),
            ({"length_unit": "mm"}, ["output.length_unit", "m, um, nm"]),
            ({"fields": False, "field_every": 2}, ["output.field_every", "output.fields"])):
        with pytest.raises(scenes.SceneError) as err:
            scenes.validate(scene(**output))
        assert all(w in str(err.value) for w in words), str(err.value)
    adhesive = scene(fields=["adhesive", "gap"])
    adhesive["interaction"] = {"law": "lj", "work_of_adhesion": 0.1, "z0": 1e-9}
    assert scenes.validate(adhesive)["output"]["fields"] == ["adhesive", "gap"]


def local_rows(vec, nx):
    """This rank's rows (y) of a field Vec of the grid (x fastest), and where they start."""
    start, _ = vec.getOwnershipRange()
    return vec.getArray(readonly=True).reshape(-1, nx), start // nx


def test_float32_fields_and_uint8_masks_are_the_float64_results_rounded(coll, shared_tmp):
    """The float32 fields are the solved float64 state rounded to nearest (IEEE), elementwise;
    the masks are uint8 0/1 of p > 0; heights and the restart field (pressure) stay float64 and
    equal the state; a field selection writes those and the restart fields only.  By default
    every field is float64 but the masks."""
    full, small = shared_tmp / "f64", shared_tmp / "f32"
    runner.run(rough(full, VALUES[:2]), comm=PETSc.COMM_WORLD)
    with h5py.File(full / "step_0002.h5", "r") as f:
        assert {n: f[n].dtype for n in f} == {"pressure": np.float64, "gap": np.float64, "displacement": np.float64,
                                              "heights": np.float64, "contact": np.uint8}
    states = runner.run(rough(small, VALUES[:2], fields=["gap", "displacement", "heights", "contact"],
                              field_precision="float32"), comm=PETSc.COMM_WORLD)
    st, worst, exact = states[-1], 0.0, True
    with h5py.File(small / "step_0002.h5", "r") as f:
        assert {n: f[n].dtype for n in f} == {"pressure": np.float64, "gap": np.float32,
                                              "displacement": np.float32, "heights": np.float64,
                                              "contact": np.uint8}
        p, j0 = local_rows(st.pressure, 24)
        rows = slice(j0, j0 + p.shape[0])
        exact &= np.array_equal(f["pressure"][rows], p)
        exact &= np.array_equal(f["contact"][rows], (p > 0).astype(np.uint8))
        for name in ("gap", "displacement"):
            x64, x32 = local_rows(getattr(st, name), 24)[0], f[name][rows]
            # round to nearest: within half an ulp of float32 (at the float32 value), numpy's rounding
            ulp = np.spacing(np.abs(x32)).astype(np.float64)
            worst = max(worst, float(np.max(np.abs(x32 - x64) / ulp)))
            exact &= np.array_equal(x32, x64.astype(np.float32))
    assert coll.all(exact) and coll.max(worst) <= 0.5


def expected_steps(out, every, refine_pull_off):
    """The documented rule, applied to the run's own files: every k-th step, the last, the steps
    jumps.csv names, unconverged steps, and (sweeps refining the pull-off) each new most tensile
    stable converged state."""
    rows = read_rows(os.path.join(out, "curve.csv"))
    jumps = read_rows(os.path.join(out, "jumps.csv")) if os.path.exists(os.path.join(out, "jumps.csv")) else []
    want, best = set(), np.inf
    for r in rows:
        k = int(r["step"])
        ok = r["converged"] == "True" and r["stable"] != "False"
        if k % every == 0 or k == len(rows) or r["converged"] != "True" or any(int(j["step"]) == k for j in jumps):
            want.add(k)
        if refine_pull_off and ok and float(r["force_N"]) < best:
            want.add(k)
        if ok:
            best = min(best, float(r["force_N"]))
    return sorted(want)


def test_every_kth_step_and_the_temporal_collection(coll, shared_tmp):
    """field_every = 3 on 7 loads writes steps 3, 6 and 7 (the last); fields.xdmf lists them in
    one temporal collection whose times are curve.csv's approaches in nm, with the spacing and
    the length fields (only those) scaled to nm and the HDF5 data in metres; under mpirun, the
    files of one rank."""
    out = shared_tmp / "every"
    make = lambda out: rough(out, field_every=3, length_unit="nm", field_precision="float32")  # noqa
    runner.run(make(out), comm=PETSc.COMM_WORLD)
    rows = read_rows(out / "curve.csv")
    assert step_files(out) == [3, 6, 7] == expected_steps(out, 3, False)
    label, steps, spacing = collection(out)
    assert label == "approach [nm]"
    assert [s for s, _, _ in steps] == [3, 6, 7]
    for step, time, attributes in steps:
        assert time == pytest.approx(float(rows[step - 1]["approach_m"]) * 1e9, rel=1e-12)
        with h5py.File(out / f"step_{step:04d}.h5", "r") as f:
            assert set(attributes) == set(f)
            assert float(f.attrs["approach"]) * 1e9 == pytest.approx(time, rel=1e-12)
            for name, (dataset, number, precision, scale) in attributes.items():
                assert dataset == "/" + name and f[name].shape == (16, 24)
                assert (number, precision) == {np.dtype("f8"): ("Float", 8), np.dtype("f4"): ("Float", 4),
                                               np.dtype("u1"): ("UChar", 1)}[f[name].dtype]
                assert scale == (1e9 if f[name].attrs["unit"] == "m" else 1.0)
            assert float(f.attrs["dx"]) == 1e-8    # the data stay SI
    assert spacing == pytest.approx((1e-8 * 1e9, 1.5e-8 * 1e9, 1e-8 * 1e9), rel=1e-15)
    same_on_one_rank(coll, make, out, shared_tmp)


@pytest.mark.heavy   # an adhesive path: 1 and 2 ranks (3 oversubscribed ranks spend minutes)
@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_an_adhesive_sweep_writes_its_jumps_and_pull_off_candidates(coll, shared_tmp, adhesive_sweep):
    """Loading and unloading a sphere with field_every = 4: the written steps are the rule's
    (jump steps, the most tensile states, the last); the collection's time is the step number
    (the approach turns); the restart fields stay float64 when the others are float32; under
    mpirun, the files of one rank."""
    out = adhesive_sweep
    jumps = read_rows(out / "jumps.csv")
    assert [j["kind"] for j in jumps] == ["jump-on", "jump-off"]
    written = step_files(out)
    assert written == expected_steps(out, 4, True)
    assert {int(j["step"]) for j in jumps} <= set(written) and len(written) < 10
    label, steps, _ = collection(out)
    assert label == "step" and [(s, t) for s, t, _ in steps] == [(s, float(s)) for s in written]
    with h5py.File(out / f"step_{written[0]:04d}.h5", "r") as f:
        assert {n: f[n].dtype for n in f} == {"gap": np.float32, "contact_pressure": np.float64,
                                              "adhesive_pressure": np.float64}
    same_on_one_rank(coll, sweep_every_4th, out, shared_tmp)


def test_restart_resumes_from_the_last_step_file(coll, shared_tmp):
    """A run stopped after step 5 with field_every = 2 (files 2 and 4) resumes from step 4: step 5
    is solved again, and the path ends as the uninterrupted run's (curve, files, collection)."""
    world = PETSc.COMM_WORLD.tompi4py()
    ref, out = shared_tmp / "ref", shared_tmp / "cut"
    opts = dict(field_every=2, field_precision="float32", fields=["gap", "contact"])
    runner.run(rough(ref, **opts), comm=PETSc.COMM_WORLD)
    runner.run(rough(out, VALUES[:5], **opts), comm=PETSc.COMM_WORLD)   # its last step 5 is written
    if coll.rank == 0:   # as killed after step 5's row, before any file of it
        for name in ("step_0005.h5", "step_0005.xdmf"):
            os.remove(out / name)
    world.Barrier()
    states = runner.run(rough(out, **opts), comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 3                                    # steps 5, 6, 7
    a, b = read_rows(out / "curve.csv"), read_rows(ref / "curve.csv")
    assert [r["step"] for r in a] == [r["step"] for r in b]
    worst = max(abs(float(x["approach_m"]) - float(y["approach_m"])) / abs(float(y["approach_m"]))
                for x, y in zip(a, b))
    assert coll.max(worst) <= 1e-8
    assert step_files(out) == step_files(ref) == [2, 4, 6, 7]
    assert [s for s, _, _ in collection(out)[1]] == [2, 4, 6, 7]


def same_on_one_rank(coll, make, out, shared_tmp):
    """Under mpirun: the files written by all ranks together equal those of the same scene run
    on one rank (the datasets to the solver's tolerance, the types, the written steps, the
    collection's times)."""
    if coll.size == 1:
        return
    alone = shared_tmp / f"self{coll.rank}"
    runner.run(make(alone), comm=PETSc.COMM_SELF)
    assert step_files(out) == step_files(alone)
    worst = 0.0
    for k in step_files(out):
        with h5py.File(out / f"step_{k:04d}.h5", "r") as fa, h5py.File(alone / f"step_{k:04d}.h5", "r") as fb:
            assert {n: fa[n].dtype for n in fa} == {n: fb[n].dtype for n in fb}
            for name in fa:
                x, y = fa[name][:].astype(float), fb[name][:].astype(float)
                worst = max(worst, np.abs(x - y).max() / max(np.abs(y).max(), 1e-300))
    ta, tb = collection(out), collection(alone)
    assert ta[0] == tb[0] and [s for s, _, _ in ta[1]] == [s for s, _, _ in tb[1]]
    for (_, x, _), (_, y, _) in zip(ta[1], tb[1]):
        worst = max(worst, abs(x - y) / abs(y))
    assert coll.max(worst) <= 1e-6


# one rank: every rank finds the missing file alike (the written steps); an adhesive sweep
# restarted on two ranks to its refined pull-off is test_restart's killed adhesive sweep
@pytest.mark.serial
@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_restart_without_the_pull_off_state_file_goes_on(coll, shared_tmp, adhesive_sweep):
    """A sweep written without pull-off refinement every 4th step, restarted with the refinement
    on: its most tensile state (step 3) has no file, so the refinement starts from the new steps
    (a note) and the path completes with the uninterrupted run's curve (conftest's
    ``adhesive_sweep``: the curve is the same whatever the fields written, refined or not)."""
    ref, out = adhesive_sweep, shared_tmp / "cut"
    first = sweep(out, field_every=4)
    first["protocol"].update(values=first["protocol"]["values"][:8], refine_pull_off=False)
    runner.run(first, comm=PETSc.COMM_WORLD)
    assert 3 not in step_files(out)
    states = runner.run(sweep(out, field_every=4), comm=PETSc.COMM_WORLD, restart=True)
    assert len(states) == 2 and coll.all(all(st.converged for st in states))
    a, b = read_rows(out / "curve.csv"), read_rows(ref / "curve.csv")
    assert len(a) == len(b) == 10
    worst = max(abs(float(x["force_N"]) - float(y["force_N"])) / abs(float(y["force_N"])) for x, y in zip(a, b))
    assert coll.max(worst) <= 1e-6
