"""The adhesive sphere of the adhesion tests in Greenwood's units (E* = z0 = 1)."""
import numpy as np

from contactpetsc.grid import SurfaceGrid
from contactpetsc.physics.interactions import make_law
from contactpetsc.solvers.adhesive import AdhesiveProblem
from contactpetsc.geometry.surfaces import sphere

R = 1000.0


def work_for(mu, radius=R):
    """w giving Tabor parameter mu with E* = z0 = 1."""
    return np.sqrt(mu ** 3 / radius)


def sphere_problem(mu, law="hardwall-lj", n=64, dx=2.0, comm=None, radius=R, **kw):
    grid = SurfaceGrid(n, n, dx, periodic=False, comm=comm)
    return AdhesiveProblem(grid, sphere(grid, radius), 1.0,
                           make_law(law, work_of_adhesion=work_for(mu, radius), z0=1.0), **kw)
