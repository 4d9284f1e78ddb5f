"""The application: a scene file in, a run directory out (README.md, "Layout").

``scenes`` (schema and validation), ``builder`` (grid, heights, law and problem of a scene),
``runner`` (the step loop), ``steppers`` (one step of a path), ``recorder`` (what a step
writes), ``rundir`` (the locked output directory), ``output`` (HDF5/XDMF files), ``plots``
and ``cli`` (the ``contactpetsc`` command).  The library (``contactpetsc`` outside ``app``)
never imports from here.
"""
