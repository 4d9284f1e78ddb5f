"""Scenes' material section: E and nu instead of E*, the hardness cap and the finite layer.

Truths: E* = E / (1 - nu^2) (the definition, for a rigid counter-surface); the problem a scene
builds solves what the API solves with the same physics (a run of the scene against
``ContactProblem`` with the hardness and the layer given directly, on every rank count); each
refusal names its keys and the accepted values.
"""
import csv
import os

import h5py

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, runner, scenes
from contactpetsc.operators import Layer, PeriodicLayer
from contactpetsc.solvers import ContactProblem


def rough(**material):
    m = {"youngs_modulus": 70e9, "poisson_ratio": 0.33}
    m.update(material)
    return {"geometry": {"kind": "self-affine", "nx": 32, "dx": 2e-8, "rms_slope": 0.1,
                         "rolloff_wavelength": 3.2e-7, "seed": 2},
            "material": {k: v for k, v in m.items() if v is not None},
            "protocol": {"control": "mean_pressure", "values": [1e8, 3e8]}}


def refused(scene, *words):
    with pytest.raises(scenes.SceneError) as err:
        scenes.validate(scene)
    assert all(w in str(err.value) for w in words), str(err.value)


@pytest.mark.serial   # scene validation: no communicator
def test_youngs_modulus_and_poisson_ratio_give_e_star():
    s = scenes.validate(rough())
    assert scenes.e_star(s) == pytest.approx(70e9 / (1 - 0.33 ** 2), rel=1e-15)
    assert scenes.validate(s) == s                      # a validated scene validates again
    assert scenes.e_star(scenes.validate(rough(youngs_modulus=None, poisson_ratio=None, e_star=5e10))) == 5e10
    assert scenes.validate(rough(poisson_ratio=0.5))["material"]["poisson_ratio"] == 0.5   # incompressible


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("material, words", [
    (dict(e_star=5e10), ["exactly one of material.e_star or material.youngs_modulus", "both"]),
    (dict(youngs_modulus=None, poisson_ratio=None), ["material.e_star is required", "material.youngs_modulus"]),
    (dict(poisson_ratio=None), ["material.youngs_modulus needs material.poisson_ratio", "(-1, 0.5]"]),
    (dict(youngs_modulus=None, e_star=5e10), ["material.poisson_ratio goes with material.youngs_modulus"]),
    (dict(poisson_ratio=0.6), ["material.poisson_ratio = 0.6: accepted range (-1, 0.5]"]),
    (dict(poisson_ratio=-1.0), ["material.poisson_ratio = -1.0: accepted range (-1, 0.5]"]),
    (dict(hardness=0.0), ["material.hardness = 0.0: accepted range (0, inf) Pa"]),
    (dict(hardness=2e8), ["protocol.values: 300000000.0 Pa is not below material.hardness = 200000000.0 Pa",
                          "accepted: (0, 2e+08) Pa"]),
    (dict(layer_interface="frictionless"), ["material.layer_interface needs material.layer_thickness"]),
    (dict(layer_thickness=1e-7, layer_interface="glued"), ["material.layer_interface = 'glued'", "bonded"]),
    (dict(layer_thickness=1e-7, youngs_modulus=None, poisson_ratio=None, e_star=5e10),
     ["material.layer_interface = 'bonded' needs Poisson's ratio", "frictionless"]),
    (dict(layer_thickness=1e-300), ["material.layer_thickness = 1e-300 m: accepted range [", ", inf) m",
                                    "floating-point range"]),
])
def test_bad_material_names_the_keys(material, words):
    refused(rough(**material), *words)


@pytest.mark.serial   # scene validation: no communicator
def test_refused_combinations():
    s = rough(layer_thickness=1e-7)
    s["geometry"]["periodic"] = False
    refused(s, "material.layer_thickness = 1e-07 needs a periodic cell", "geometry.periodic")
    adhesive = rough(hardness=1e9)
    adhesive["interaction"] = {"law": "hardwall-lj", "work_of_adhesion": 0.1, "z0": 1e-9}
    adhesive["protocol"] = {"values": [1e-9]}
    refused(adhesive, "material.hardness with adhesion", "not supported")
    force = rough(hardness=1e9)
    force["protocol"] = {"control": "force", "values": [1e9 * (32 * 2e-8) ** 2]}
    refused(force, "protocol.values", "material.hardness", "window area", "N")
    # the frictionless layer needs no Poisson's ratio; adhesion on a layer is accepted
    ok = rough(youngs_modulus=None, poisson_ratio=None, e_star=5e10, layer_thickness=1e-7,
               layer_interface="frictionless")
    ok["interaction"] = {"law": "hardwall-lj", "work_of_adhesion": 0.1, "z0": 1e-9}
    ok["protocol"] = {"values": [1e-9]}
    assert scenes.layer(scenes.validate(ok)) == Layer(1e-7, "frictionless")


def test_a_scene_solves_what_the_api_solves(coll, shared_tmp):
    """A plastic rough surface on a bonded layer, run as a scene, against ContactProblem with
    the same E*, hardness and layer: the same pressures, and curve.csv's plastic columns are
    the states' (rank count: whatever the test runs on)."""
    s = rough(hardness=2e9, layer_thickness=2e-7)
    s["solver"] = {"tol": 1e-10}
    s["output"] = {"directory": str(shared_tmp / "out"), "fields": ["pressure"]}
    scene = scenes.validate(s)
    states = runner.run(scene)
    grid = builder.build_grid(scene)
    h = builder.build_heights(scene, grid)
    e_star = 70e9 / (1 - 0.33 ** 2)
    api = ContactProblem(grid, h, e_star, hardness=2e9, tol=1e-10, prefix="api_scene_",
                         operator=PeriodicLayer(grid, e_star, Layer(2e-7, "bonded", 0.33)))
    with open(os.path.join(shared_tmp, "out", "curve.csv")) as f:
        rows = list(csv.DictReader(f))
    for step, (value, st, row) in enumerate(zip((1e8, 3e8), states, rows), start=1):
        ref = api.solve(mean_pressure=value)
        # each state's pressure from its step file (a run keeps only the last state's fields)
        with h5py.File(os.path.join(shared_tmp, "out", f"step_{step:04d}.h5"), "r") as f:
            p = f["pressure"][:].T
        p_ref = grid.gather(ref.pressure)
        assert coll.max(np.abs(p - p_ref).max() / p_ref.max()) <= 1e-6
        assert st.plastic_fraction > 0 and coll.max(abs(st.plastic_fraction - ref.plastic_fraction)) <= 2 / 32 ** 2
        assert float(row["plastic_fraction"]) == pytest.approx(st.plastic_fraction, rel=1e-12)
        assert float(row["plastic_volume_m3"]) == pytest.approx(st.plastic_volume, rel=1e-12)
        assert float(row["max_plastic_displacement_m"]) == pytest.approx(st.max_plastic_displacement, rel=1e-12)
    assert np.isclose(api.e_star, e_star, rtol=1e-15)


@pytest.mark.heavy   # a layer sweep through the CLI and the API: on 1 and 2 ranks
def test_an_adhesive_scene_on_a_layer_solves_what_the_api_solves(coll, shared_tmp):
    """Adhesion on a bonded layer, E and nu given: the scene's states are the API's."""
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    e, nu, t, z0 = 1e9, 0.3, 4e-9, 1e-9
    e_star = e / (1 - nu ** 2)
    w = 0.05 * e_star * z0
    scene = scenes.validate({
        "geometry": {"kind": "self-affine", "nx": 32, "dx": 1e-9, "rms_height": 1e-9, "seed": 7},
        "material": {"youngs_modulus": e, "poisson_ratio": nu, "layer_thickness": t},
        "interaction": {"law": "hardwall-lj", "work_of_adhesion": w, "z0": z0},
        "protocol": {"values": [0.5e-9, 0.8e-9], "refine_pull_off": False},
        "output": {"directory": str(shared_tmp / "adh"), "fields": False}})
    states = runner.run(scene)
    grid = builder.build_grid(scene)
    h = builder.build_heights(scene, grid)
    api = AdhesiveProblem(grid, h, e_star, make_law("hardwall-lj", work_of_adhesion=w, z0=z0),
                          operator=PeriodicLayer(grid, e_star, Layer(t, "bonded", nu)), prefix="api_adh_layer_")
    for value, st in zip((0.5e-9, 0.8e-9), states):
        ref = api.solve(approach=value)
        assert coll.all(st.converged and ref.converged)
        assert coll.max(abs(st.force - ref.force)) <= 1e-6 * abs(ref.force)
