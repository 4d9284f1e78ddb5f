"""A new interaction law is one class: defined and registered here, it is accepted by the scene
schema with its own parameters (required, refused for other laws, range-checked), listed in the
generated docs, named where a hard-wall law is needed, and solved through the scene runner on a
tiny adhesive sphere.

Independent truths: the Derjaguin force 2 pi R Phi(g0) on a nearly rigid sphere at apex gap g0
(a constant traction over the disc where the gap is below the law's range), and the built-in
Maugis-Dugdale law, which is the same physics written by other code.  Units: z0 = 1, E* = 1.
"""
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import runner, scenes
from contactpetsc.physics.interactions import LAWS, WORK_OF_ADHESION, InteractionLaw, Parameter, register_law


class ConstantTraction(InteractionLaw):
    """A toy cohesive law: hard wall and the traction -w/delta_c up to the range delta_c."""

    name = "toy-cohesive"
    parameters = (WORK_OF_ADHESION, Parameter("cohesive_range", "m", "toy cohesive range delta_c"))
    summary = "toy constant-traction cohesive law (tests/test_law_registry.py)"

    def __init__(self, work_of_adhesion, cohesive_range):
        self.work_of_adhesion, self.cohesive_range = float(work_of_adhesion), float(cohesive_range)
        self.sigma = self.work_of_adhesion / self.cohesive_range

    def length_scale(self):
        return self.cohesive_range

    @property
    def peak_attraction(self):
        return self.sigma

    def pressure(self, gap):
        return np.where(np.asarray(gap, dtype=float) < self.cohesive_range, -self.sigma, 0.0)

    def derivative(self, gap):
        return np.zeros_like(np.asarray(gap, dtype=float))

    def energy(self, gap):
        g = np.maximum(np.asarray(gap, dtype=float), 0.0)
        return np.where(g < self.cohesive_range, -self.work_of_adhesion + self.sigma * g, 0.0)


@pytest.fixture
def toy_law():
    register_law(ConstantTraction)
    try:
        yield ConstantTraction
    finally:
        LAWS.pop(ConstantTraction.name)


def scene(out=None, **interaction):
    s = {"name": "toy", "geometry": {"kind": "sphere", "radius": 100.0, "nx": 64, "dx": 0.5},
         "material": {"e_star": 1.0}, "interaction": interaction,
         "protocol": {"control": "approach", "values": [-0.5, -0.2], "refine_pull_off": False},
         "output": {"fields": False}}
    if out is not None:
        s["output"]["directory"] = str(out)
    return s


def test_the_schema_takes_a_registered_law_with_its_parameters(toy_law):
    spec = scenes.schema()["interaction"]
    assert "toy-cohesive" in spec["law"]["choices"]
    assert spec["cohesive_range"]["unit"] == "m" and "(toy-cohesive)" in spec["cohesive_range"]["doc"]
    md = scenes.schema_markdown()
    assert "`interaction.cohesive_range`" in md and "| `toy-cohesive` |" in md
    valid = scenes.validate(scene(law="toy-cohesive", work_of_adhesion=1e-3, cohesive_range=1.0))
    assert scenes.adhesive(valid) and valid["interaction"]["cohesive_range"] == 1.0
    for bad, message in [
        (dict(law="toy-cohesive", work_of_adhesion=1e-3),
         "interaction.cohesive_range is required for interaction.law = toy-cohesive"),
        (dict(law="toy-cohesive", work_of_adhesion=1e-3, cohesive_range=1.0, z0=1.0),
         "interaction.z0 is not used by interaction.law = 'toy-cohesive'"),
        (dict(law="lj", work_of_adhesion=1e-3, z0=1.0, cohesive_range=1.0),
         "only by law = toy-cohesive"),
        (dict(law="toy-cohesive", work_of_adhesion=1e-3, cohesive_range=-1.0),
         "interaction.cohesive_range = -1.0: accepted range (0, inf) m"),
    ]:
        with pytest.raises(scenes.SceneError, match=message.replace("(", r"\(").replace(")", r"\)")):
            scenes.validate(scene(**bad))


def test_an_unregistered_law_and_its_keys_are_refused():
    assert "toy-cohesive" not in LAWS
    with pytest.raises(scenes.SceneError, match="unknown key interaction.cohesive_range"):
        scenes.validate(scene(law="dugdale", work_of_adhesion=1e-3, sigma0=1e-3, cohesive_range=1.0))
    with pytest.raises(scenes.SceneError, match="accepted values are none, hardwall-lj"):
        scenes.validate(scene(law="toy-cohesive", work_of_adhesion=1e-3))


def test_the_relaxation_refusals_come_from_the_registry(toy_law):
    # independent truth: the toy law's class declares hard_wall = True (InteractionLaw's default),
    # its soft variant neither a wall nor a repulsive branch
    from types import SimpleNamespace

    from contactpetsc.solvers.factory import describe_solver
    from contactpetsc.solvers.relaxation import RelaxationSolver

    class SoftToy(ConstantTraction):
        name = "toy-soft"
        hard_wall = False

    assert toy_law.hard_wall
    register_law(SoftToy)
    try:
        soft = SoftToy(1e-3, 1.0)
        with pytest.raises(ValueError,
                           match=r"hard wall or a repulsive branch \(.*toy-cohesive.*\), got law 'toy-soft'"):
            describe_solver(soft, method="relaxation")
        with pytest.raises(ValueError, match=r"hard wall or a repulsive branch \(.*lj.*\); law 'toy-soft'"):
            RelaxationSolver(SimpleNamespace(hard_wall=False, law=soft))
        with pytest.raises(scenes.SceneError, match=r"hard wall or a repulsive branch \(.*toy-cohesive.*\)"):
            scenes.validate(dict(scene(law="toy-soft", work_of_adhesion=1e-3, cohesive_range=1.0),
                                 solver={"method": "relaxation"}))
    finally:
        LAWS.pop(SoftToy.name)


def test_a_registered_law_refuses_a_clashing_parameter():
    class Clash(ConstantTraction):
        name = "toy-clash"
        parameters = (WORK_OF_ADHESION, Parameter("z0", "Pa", "not a length"))
    with pytest.raises(ValueError, match="parameter 'z0' differs from law 'hardwall-lj'"):
        register_law(Clash)
    assert "toy-clash" not in LAWS


def test_a_registered_law_solves_a_tiny_adhesive_sphere(coll, shared_tmp, toy_law):
    """Apex gaps 0.5 and 0.2 on a stiff sphere (w / (E* delta_c) = 1e-4): the force is Derjaguin's
    2 pi R Phi(g0) (nodal sampling of the disc, 2 %) and the built-in Dugdale law's (1e-8)."""
    w, rng = 1e-4, 1.0
    toy = runner.run(scenes.validate(scene(shared_tmp / "toy", law="toy-cohesive", work_of_adhesion=w,
                                           cohesive_range=rng)), comm=PETSc.COMM_WORLD)
    ref = runner.run(scenes.validate(scene(shared_tmp / "dugdale", law="dugdale", work_of_adhesion=w,
                                           sigma0=w / rng)), comm=PETSc.COMM_WORLD)
    assert len(toy) == 2 and coll.all(all(st.converged for st in toy + ref))
    for st, dug in zip(toy, ref):
        derjaguin = 2 * np.pi * 100.0 * float(ConstantTraction(w, rng).energy(-st.approach))
        assert coll.max(abs(st.force / derjaguin - 1)) < 0.02, (st.approach, st.force, derjaguin)
        assert coll.max(abs(st.force - dug.force)) <= 1e-8 * abs(dug.force)
