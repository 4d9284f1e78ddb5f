"""Bytes of one adhesive step file per output setting, measured, and projected to a larger grid.

Writes step 1 of the adhesive sphere example (``examples/scenes/adhesive_sphere.toml``) on an
n x n grid through ``output.write_state`` (the scene and versions as attributes, as a run
writes them) for each setting of ``output.fields`` and ``output.field_precision``, and for
the layout before masks were uint8 (every dataset float64).  The values do not change the
size (the datasets are contiguous, uncompressed): the state written is the undeformed one.
Prints per setting the datasets, the file size, bytes per node and the size projected to an
N x N grid (bytes per node times N^2).

    python run_scripts/bench/step_file_sizes.py [--n 512] [--project 4096] [--output DIR]
"""
from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
import types as namespace

import petsc4py

petsc4py.init(sys.argv[:1])

from petsc4py import PETSc  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SCENE = os.path.join(HERE, "..", "..", "examples", "scenes", "adhesive_sphere.toml")
SETTINGS = [   # (label, output.fields, output.field_precision)
    ("every field, float64 (the default)", True, "float64"),
    ("every field, float32", True, "float32"),
    ('["pressure", "gap", "contact", "adhesive"], float32', ["pressure", "gap", "contact", "adhesive"],
     "float32"),
    ('["gap"], float32', ["gap"], "float32"),
]


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--n", type=int, default=512)
    p.add_argument("--project", type=int, default=4096)
    p.add_argument("--output", default=None, help="directory for the files (default: a temporary one)")
    args = p.parse_args()
    from contactpetsc.app import builder, scenes
    from contactpetsc.app.output import AXES, available_fields, scene_field_types, versions, write_state
    scene = scenes.load(SCENE)
    g = scene["geometry"]
    g["dx"] = g["dy"] = g["dx"] * g["nx"] / args.n
    g["nx"] = g["ny"] = args.n
    grid = builder.build_grid(scene, PETSc.COMM_WORLD)
    h = builder.build_heights(scene, grid)
    zero = grid.create_vec(0.0)
    state = namespace.SimpleNamespace(pressure=zero, gap=h.copy(), displacement=zero, contact_pressure=zero,
                                      adhesive_pressure=zero, approach=0.0, mean_pressure=0.0, force=0.0,
                                      contact_fraction=0.0, complementarity_error=0.0, converged=True)
    out = args.output or tempfile.mkdtemp(prefix="contactpetsc-sizes-")
    os.makedirs(out, exist_ok=True)
    nodes = args.n ** 2
    before = {name: "f8" for name in available_fields(True)}
    PETSc.Sys.Print(f"adhesive step file, {args.n} x {args.n} nodes ({AXES} datasets); projected to "
                    f"{args.project} x {args.project}")
    PETSc.Sys.Print(f"| setting | datasets | {args.n}^2 file [MiB] | bytes per node | {args.project}^2 [GB] |")
    PETSc.Sys.Print("|---|---|---:|---:|---:|")
    for label, fields, precision in [("before: every field float64, masks too", None, None)] + SETTINGS:
        if fields is None:
            types = before
        else:
            scene["output"].update(fields=fields, field_precision=precision)
            types = scene_field_types(scenes.validate(scene))
        path = write_state(out, 1, grid, h, state, {"scene": scene, "versions": versions()}, types=types)
        size = os.path.getsize(path) if grid.mpi_comm.Get_rank() == 0 else 0
        per_node = size / nodes
        listed = ", ".join(f"{k} {v}" for k, v in types.items())
        PETSc.Sys.Print(f"| {label} | {listed} | {size / 2**20:.2f} | {per_node:.2f} | "
                        f"{per_node * args.project ** 2 / 1e9:.2f} |")
    if args.output is None and grid.mpi_comm.Get_rank() == 0:
        shutil.rmtree(out)


if __name__ == "__main__":
    main()
