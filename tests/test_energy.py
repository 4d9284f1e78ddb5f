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
