"""The total potential energy of an adhesive state against a conservation law: along an
equilibrium path under approach control d(energy)/d(approach) = force (the envelope theorem:
the energy is stationary in the fields), so the energy's change between two approaches is the
integral of the force.  Units: E* = z0 = 1 (Greenwood's)."""
import numpy as np
import pytest

from adhesive_setup import sphere_problem


@pytest.mark.parametrize("law", ["lj", "hardwall-lj"])
def test_energy_change_is_the_work_of_the_force(coll, law):
    """Tabor 1 sphere pressed from first touch to one z0 in steps of 0.1 z0 (adhered, stable,
    in contact): the energy's change equals Simpson's integral of the force to 1e-5, while the
    trapezoid rule's O(h^2) error is visible (over 1e-5); the energy falls as the sphere is
    pressed into adhesion."""
    pb = sphere_problem(1.0, law=law, n=32, dx=1.0, radius=50.0, prefix=f"energy_{law.replace('-', '_')}_",
                        stability_check=False)
    h = 0.1
    states = [pb.solve(approach=a) for a in np.round(np.arange(0.0, 1.0 + 1e-9, h), 12)]
    energy = np.array([st.energy for st in states])
    force = np.array([st.force for st in states])
    assert all(st.converged for st in states)
    change = energy[-1] - energy[0]
    simpson = h / 3 * (force[0] + force[-1] + 4 * force[1:-1:2].sum() + 2 * force[2:-1:2].sum())
    trapezoid = h * (force.sum() - 0.5 * (force[0] + force[-1]))
    assert coll.max(abs(change / simpson - 1)) <= 1e-5
    assert coll.max(-abs(change / trapezoid - 1)) < -1e-5
    assert change < 0
    pb.destroy()


@pytest.mark.filterwarnings("ignore::contactpetsc.physics.resolution.UnderResolvedWarning")
def test_curve_csv_energy_is_the_work_of_its_forces(coll, shared_tmp):
    """A scene's curve.csv: energy_J changes along the loading branch by Simpson's integral of
    its force_N column over the approach (to 1e-4 of the change), in SI units."""
    import csv
    from contactpetsc.app import runner, scenes
    z0 = 0.3e-9
    values = [z0 * k / 10 for k in range(11)]
    scene = dict(name="energy", geometry=dict(kind="sphere", radius=15e-9, nx=32, dx=z0),
                 material=dict(e_star=10e9), interaction=dict(law="lj", work_of_adhesion=0.3, z0=z0),
                 protocol=dict(control="approach", values=values, refine_pull_off=False),
                 output=dict(fields=False))
    out = shared_tmp / "energy"
    runner.run(scenes.validate(scene), output=str(out))
    with open(out / "curve.csv") as f:
        rows = list(csv.DictReader(f))
    energy = np.array([float(r["energy_J"]) for r in rows])
    force = np.array([float(r["force_N"]) for r in rows])
    h = values[1] - values[0]
    simpson = h / 3 * (force[0] + force[-1] + 4 * force[1:-1:2].sum() + 2 * force[2:-1:2].sum())
    change = energy[-1] - energy[0]
    assert all(r["converged"] == "True" for r in rows)
    assert coll.max(abs(change / simpson - 1)) <= 1e-4
