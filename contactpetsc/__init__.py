"""contactpetsc: adhesive contact of rough elastic surfaces with matrix-free PETSc solvers.

The public names below are imported on first use, so ``import contactpetsc`` stays cheap and
never initialises PETSc: an entry point (``contactpetsc.app.cli`` or the user's script) calls
``petsc4py.init`` before the first ``from petsc4py import PETSc`` (docs/api.md).  The module
map is in README.md, "Layout".
"""

__version__ = "0.1.0"

#: public name -> the module that defines it
_PUBLIC = {
    "SurfaceGrid": "grid",
    "sphere": "geometry.surfaces", "self_affine": "geometry.surfaces", "from_array": "geometry.surfaces",
    "from_function": "geometry.surfaces", "from_file": "geometry.surfaces", "rough_sphere": "geometry.surfaces",
    "from_topography": "geometry.surfaces", "read_topography": "topography",
    "composite": "geometry.surfaces", "scale_to_rms": "geometry.surfaces", "make_tip": "geometry.tips",
    "ContactProblem": "solvers.problem", "AdhesiveProblem": "solvers.adhesive",
    "RelaxationSolver": "solvers.relaxation", "make_problem": "solvers.factory",
    "describe_solver": "solvers.factory",
    "make_law": "physics.interactions", "tabor_parameter": "physics.interactions",
    "lj_from_atomistic": "physics.interactions", "check_resolution": "physics.resolution",
    "sweep": "paths", "refine_pull_off": "pull_off", "central_gap_path": "paths", "edge_gap_path": "paths",
    "hertz_force": "physics.closed_forms", "maugis_pull_off": "physics.closed_forms",
}

__all__ = sorted(_PUBLIC)


def __getattr__(name):
    if name in _PUBLIC:
        import importlib
        value = getattr(importlib.import_module(f".{_PUBLIC[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'contactpetsc' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
