"""Scene values that used to pass without a word: each refusal names the key and what is accepted,
and the nearest good value passes.

Truths: the printed range itself (a bound is accepted exactly when its bracket says so), and the
generators (``surfaces.self_affine``, ``tips.make_tip``): the schema accepts exactly what they build.
"""
import math

import numpy as np
import pytest

from contactpetsc.app import scenes
from contactpetsc.geometry import surfaces, tips
from contactpetsc.grid import GridError, SurfaceGrid


def sphere(**sections):
    s = {"geometry": {"kind": "sphere", "radius": 1e-6, "nx": 16, "dx": 1e-9},
         "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}}
    for key, value in sections.items():
        s[key] = {**s.get(key, {}), **value}
    return s


def refused(scene, *words):
    with pytest.raises(scenes.SceneError) as err:
        scenes.validate(scene)
    assert all(w in str(err.value) for w in words), str(err.value)
    return str(err.value)


def ranged_keys():
    for section, spec in scenes.SCHEMA.items():
        if isinstance(spec.get("kind"), type):
            continue
        for key, s in spec.items():
            if s["range"] is not None:
                yield section, key, s


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("section, key, spec", list(ranged_keys()), ids=lambda v: v if isinstance(v, str) else "")
def test_printed_ranges_say_what_is_accepted(section, key, spec):
    """Each bound is accepted exactly when the printed range includes it ([ or ]), and a refusal
    prints that range; inf is never accepted, so no range ends in 'inf]'."""
    text = scenes.range_text(spec["range"])
    lo, hi = spec["range"][:2]
    assert not text.endswith("inf]")
    for bound, inside, included in ((lo, (hi + lo) / 2 if math.isfinite(hi) else lo + 1, text[0] == "["),
                                    (hi, (hi + lo) / 2 if math.isfinite(hi) else lo + 1, text[-1] == "]")):
        value = spec["kind"](bound) if math.isfinite(bound) else bound
        try:
            scenes.check_value(f"{section}.{key}", spec, value)
            accepted = True
        except scenes.SceneError as exc:
            accepted = False
            assert f"{section}.{key} = {value!r}: accepted range {text}" in str(exc)
        assert accepted == included, (key, bound, text)
        scenes.check_value(f"{section}.{key}", spec, spec["kind"](inside))


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("tol", [1e300, 1.0, 0.0101])
@pytest.mark.parametrize("interaction, solver", [
    ({}, {}),
    ({"law": "lj", "work_of_adhesion": 0.1, "z0": 1e-9}, {"method": "newton"}),
    ({"law": "hardwall-lj", "work_of_adhesion": 0.1, "z0": 1e-9}, {"method": "relaxation"}),
])
def test_tolerances_are_bounded(tol, interaction, solver):
    refused(sphere(interaction=interaction, solver={**solver, "tol": tol}),
            f"solver.tol = {tol!r}: accepted range (0, 0.01]")
    assert scenes.validate(sphere(interaction=interaction, solver={**solver, "tol": 1e-2}))["solver"]["tol"] == 1e-2


@pytest.mark.serial   # scene validation: no communicator
def test_adhesion_without_a_law_is_refused():
    refused(sphere(interaction={"work_of_adhesion": 0.1}), "interaction.work_of_adhesion = 0.1",
            "interaction.law = 'none'", "work_of_adhesion = 0")
    assert not scenes.adhesive(scenes.validate(sphere(interaction={"work_of_adhesion": 0.0})))
    assert scenes.adhesive(scenes.validate(sphere(interaction={"law": "lj", "work_of_adhesion": 0.1,
                                                               "z0": 1e-9})))


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("control, smallest, unit", [
    ("mean_pressure", 1e-12 * 1e9, "Pa"),                        # 1e-12 E*
    ("force", 1e-12 * 1e9 * (16 * 1e-9) ** 2, "N"),             # 1e-12 E* Lx Ly
])
def test_round_off_loads_are_refused(control, smallest, unit):
    for tiny in (5e-324, 2.2e-308, 0.99 * smallest):
        msg = refused(sphere(protocol={"control": control, "values": [2 * smallest, tiny]}),
                      "protocol.values", repr(tiny), unit)
        assert f"{smallest:.3g}" in msg
    ok = scenes.validate(sphere(protocol={"control": control, "values": [smallest, 2 * smallest]}))
    assert ok["protocol"]["values"][0] == smallest


@pytest.mark.serial   # scene validation: no communicator
def test_round_off_approaches_are_displacements_not_loads():
    """An approach through zero made by arange (4e-25 m) is a displacement of zero: accepted."""
    values = list(np.arange(-1.5, 0.01, 0.1) * 0.3e-9)
    assert 0 < abs(min(values, key=abs)) < 1e-24
    assert scenes.validate(sphere(protocol={"control": "approach", "values": values}))


@pytest.mark.parametrize("hurst", [1e-9, 0.5, 1.0 - 1e-9, 1.0, 0.0, -0.1, 1.5])
def test_hurst_accepted_by_the_scene_exactly_when_the_generator_builds_it(hurst):
    g = SurfaceGrid(16, 16, 1e-9, comm=None)
    try:
        surfaces.self_affine(g, hurst=hurst, seed=0, rms_height=1e-9)
        builds = True
    except GridError:
        builds = False
    scene = {"geometry": {"kind": "self-affine", "nx": 16, "dx": 1e-9, "hurst": hurst, "rms_height": 1e-9},
             "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}}
    if builds:
        scenes.validate(scene)
    else:
        refused(scene, f"geometry.hurst = {hurst!r}: accepted range (0, 1)")
    assert builds == (0 < hurst < 1)


def self_affine(**geometry):
    g = {"kind": "self-affine", "nx": 16, "dx": 1e-9, "rms_height": 1e-9}
    g.update(geometry)
    return {"geometry": g, "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}}


def test_self_affine_band_is_checked_as_the_generator_builds_it():
    """A short cut-off at or beyond the cell size leaves the generator no mode (it fails at run
    time): the scene refuses it; one below the roll-off is the nearest good value."""
    g = SurfaceGrid(16, 16, 1e-9, comm=None)
    cell = 16e-9
    with pytest.raises(GridError, match="empty"):
        surfaces.self_affine(g, hurst=0.8, seed=0, rms_height=1e-9, short_cutoff_wavelength=1.01 * cell)
    refused(self_affine(short_cutoff_wavelength=1.01 * cell), "geometry.short_cutoff_wavelength",
            f"accepted range (0, {cell:g}) m")
    refused(self_affine(rolloff_wavelength=4e-9, short_cutoff_wavelength=4e-9),
            "geometry.rolloff_wavelength = 4e-09", "geometry.short_cutoff_wavelength = 4e-09")
    refused(self_affine(rolloff_wavelength=1.5e-9), "geometry.rolloff_wavelength = 1.5e-09",
            "geometry.short_cutoff_wavelength = 2e-09", "default")
    refused(self_affine(rms_slope=0.1), "exactly one of geometry.rms_height or geometry.rms_slope")
    scenes.validate(self_affine(rolloff_wavelength=4.01e-9, short_cutoff_wavelength=4e-9))
    scenes.validate(self_affine(short_cutoff_wavelength=0.99 * cell))
    surfaces.self_affine(g, hurst=0.8, seed=0, rms_height=1e-9, short_cutoff_wavelength=0.99 * cell)


@pytest.mark.parametrize("kind", ["bent-commensurate", "bent-incommensurate"])
def test_tip_radius_accepted_exactly_when_the_tip_covers_the_window(kind):
    d, dx, n = 0.3367e-9, 0.085e-9, 16
    g = SurfaceGrid(n, n, dx, periodic=False, comm=None)
    need = 0.5 * n * dx + 2 * 0.5 * d * (0.94 if kind == "bent-incommensurate" else 1.0)
    for radius in (0.99 * need, 1.01 * need):
        try:
            tips.make_tip(kind, g, radius, d)
            builds = True
        except GridError:
            builds = False
        scene = {"geometry": {"kind": "tip", "tip": kind, "radius": radius, "atom_spacing": d, "nx": n,
                              "dx": dx}, "material": {"e_star": 1e9}, "protocol": {"values": [1e-10]}}
        if builds:
            scenes.validate(scene)
        else:
            refused(scene, f"geometry.radius = {radius!r}: accepted range ({need:g}, inf) m")
        assert builds == (radius > need)


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("scene, words", [
    (sphere(geometry={"hurst": 0.5}), ["geometry.hurst", "geometry.kind = 'sphere'", "self-affine"]),
    (sphere(geometry={"rms_height": 1e-9}), ["geometry.rms_height", "'sphere'"]),
    (sphere(geometry={"path": "h.npy"}), ["geometry.path", "'sphere'", "kind = file"]),
    (sphere(interaction={"law": "exponential", "work_of_adhesion": 0.1, "rho": 1e-9, "z0": 1e-9}),
     ["interaction.z0", "interaction.law = 'exponential'", "hardwall-lj, lj"]),
    (sphere(interaction={"z0": 1e-9}), ["interaction.z0", "interaction.law = 'none'"]),
    (sphere(interaction={"element_integration": True}), ["interaction.element_integration", "adhesion"]),
    (sphere(solver={"method": "relaxation"}), ["solver.method = 'relaxation'", "adhesion"]),
])
def test_keys_the_scene_would_ignore_are_refused(scene, words):
    refused(scene, *words)


@pytest.mark.serial   # scene validation: no communicator
def test_a_validated_scene_validates_again():
    for scene in (sphere(), self_affine(), scenes.DEFAULT_SCENE):
        once = scenes.validate(scene)
        assert scenes.validate(once) == once
