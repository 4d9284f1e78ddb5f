"""The scene builder: one translation of a scene into grid, law, heights and problem, with one
resolution check by one criterion (docs/robustness.md, "The resolution criterion").

Independent truth: the criterion's closed-form zone length (the sphere term sqrt(2 R z0) on a
sphere), counted warnings, and the law's parameters as the scene states them.
"""
import warnings

import numpy as np
import pytest

from contactpetsc.app import builder, scenes
from contactpetsc.physics.resolution import RESOLUTION_NODES, UnderResolvedWarning

UNDER_RESOLVED = {"geometry": {"kind": "sphere", "radius": 20.0, "nx": 16, "dx": 1.0},
                  "material": {"e_star": 1.0}, "protocol": {"values": [0.0]},
                  "interaction": {"law": "hardwall-lj", "work_of_adhesion": 0.028, "z0": 0.25}}


def test_a_scene_is_checked_for_resolution_once_with_the_sphere_criterion(coll):
    """Both the cohesive length (pi/4) E* w / sigma_max^2 and the sphere's sqrt(2 R z0) are below
    4 dx here (the solver's own check would warn too): one warning all the same, naming both,
    and the nodes per zone are the smaller length over dx."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scenes.validate(UNDER_RESOLVED)
        law = builder.build_law(scene)
        nodes = builder.resolution_nodes(scene, law)
        grid = builder.build_grid(scene)
        problem, relax = builder.build_problem(scene, grid, builder.build_heights(scene, grid), law)
    under = [w for w in caught if issubclass(w.category, UnderResolvedWarning)]
    assert len(under) == 1, [str(w.message) for w in under]
    sigma_max = 16 * 0.028 / (9 * np.sqrt(3) * 0.25)
    zone = min(np.pi / 4 * 0.028 / sigma_max ** 2, np.sqrt(2 * 20.0 * 0.25))
    assert nodes == pytest.approx(zone / 1.0, rel=1e-12) and nodes < RESOLUTION_NODES
    assert "sphere 3.16 m" in str(under[0].message)
    assert relax is None and problem.law is law
    assert (law.name, law.work_of_adhesion, law.z0) == ("hardwall-lj", 0.028, 0.25)


def test_no_law_and_no_check_without_adhesion():
    scene = scenes.validate(dict(UNDER_RESOLVED, interaction={"law": "none"}))
    assert builder.build_law(scene) is None and builder.resolution_nodes(scene, None) is None
