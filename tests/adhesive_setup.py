"""The adhesive sphere of the adhesion tests in Greenwood's units (E* = z0 = 1)."""
import numpy as np

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import sphere

R = 1000.0


def energy_moved(state, law, grid, step):
    """The total energy [J] of the state ``state`` (an ``AdhesiveState``) moved by an approach
    ``step`` [m]: the same displacement and pressure, every gap ``step`` smaller (the start of a
    descent at the new approach)."""
    from contactpetsc.physics.traction import AdhesiveTraction
    rows = grid.rows
    return grid.element_area * grid.mpi_comm.allreduce(
        0.5 * float(np.sum(rows(state.pressure, readonly=True) * rows(state.displacement, readonly=True)))
        + float(np.sum(AdhesiveTraction(law, grid).energy(rows(state.gap, readonly=True) - step))))


def work_for(mu, radius=R):
    """w giving Tabor parameter mu with E* = z0 = 1."""
    return np.sqrt(mu ** 3 / radius)


def sphere_problem(mu, law="hardwall-lj", n=64, dx=2.0, comm=None, radius=R, **kw):
    grid = SurfaceGrid(n, n, dx, periodic=False, comm=comm)
    return AdhesiveProblem(grid, sphere(grid, radius), 1.0,
                           make_law(law, work_of_adhesion=work_for(mu, radius), z0=1.0), **kw)


#: the adhesive sphere example (examples/scenes/adhesive_sphere.toml) in these units: Tabor
#: parameter 1, R = 100 z0 on 96 x 96 nodes of z0 (the window holds the LJ tail: a gap of 11.5 z0
#: at its edge), and its loading in steps of z0 / 4 from -2.5 z0, past its jump-on, to 0
EXAMPLE_RADIUS = 100.0
EXAMPLE_LOADING = np.arange(-2.5, 0.01, 0.25)


def example_sphere():
    return sphere_problem(1.0, law="lj", n=96, dx=1.0, radius=EXAMPLE_RADIUS)


def shifted_sphere_forces(radius, law, dx, n, element, path, shifts, prefix, raise_on_failure=True):
    """(forces [N], all converged) of an elastic sphere (E* = 1) whose apex sits (0.5 s, 0.37 s) dx
    off the grid's centre node, for each s in ``shifts``: a fresh problem per position, solved
    along the approaches ``path`` [m]; the force at the last one."""
    import warnings
    from contactpetsc.geometry.surfaces import from_function
    out, conv = [], True
    for k, s in enumerate(shifts):
        grid = SurfaceGrid(n, n, dx, periodic=False)
        x0, y0 = (n // 2 + 0.5 * s) * dx, (n // 2 + 0.37 * s) * dx
        h = from_function(grid, lambda x, y: ((x - x0) ** 2 + (y - y0) ** 2) / (2 * radius))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            pb = AdhesiveProblem(grid, h, 1.0, law, element_integration=element, stability_check=False,
                                 prefix=f"{prefix}{k}_")
        for a in path:
            st = pb.solve(approach=a, raise_on_failure=raise_on_failure)
            conv = conv and st.converged
        out.append(st.force)
    return np.array(out), conv
