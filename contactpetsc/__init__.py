"""contactpetsc: adhesive contact of rough elastic surfaces with matrix-free PETSc solvers.

Layout (one job per module):

- ``grid``        distributed surface grid (a 2-D DMDA split along y)
- ``fft``         slab-decomposed real FFT (pyfftw + MPI all-to-all transposes)
- ``operators``   elastic half-space operators (Python-context PETSc Mats)
- ``surfaces``    height fields: arrays, files, generators

The library never calls ``petsc4py.init``: an entry point (``contactpetsc.cli``
or the user's script) does, before the first ``from petsc4py import PETSc``.
"""

__version__ = "0.1.0"
