"""Command line: ``contactpetsc run [SCENE] [PETSc options]``, ``contactpetsc --version``.

This is an entry point: it calls ``petsc4py.init(sys.argv)`` before anything
imports PETSc, so every PETSc option on the command line reaches the options
database (``-contact_snes_monitor``, ``-log_view``, ...).

Without a scene file, ``run`` solves the built-in default scene: a smooth
sphere (R = 100 um, E* = 50 GPa, the reference paper's material) pressed
onto an isolated elastic half-space, swept through five approaches in
displacement control with warm starts, each state compared with Hertz.
Scene files (TOML) are not implemented yet.
"""
from __future__ import annotations

import argparse
import os
import sys

DEFAULT_SCENE = {
    "name": "hertz-sphere",
    "radius": 100e-6,          # R [m]
    "e_star": 50e9,            # E* [Pa]
    "contact_radius": 1e-6,    # Hertz contact radius a at the deepest approach [m]
    "elements_per_radius": 20,  # a / dx
    "nodes": 128,              # n x n isolated grid
    "steps": 5,                # approaches delta_k = (k/steps)^2 a^2/R ... up to a^2/R
}


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="contactpetsc",
        description="Contact of rough elastic surfaces with matrix-free PETSc solvers. "
                    "PETSc options (e.g. -contact_snes_monitor, -log_view) may follow.")
    p.add_argument("--version", action="store_true", help="print versions and exit")
    sub = p.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a scene (default: the built-in Hertz sphere)")
    run.add_argument("scene", nargs="?", help="scene file (TOML; not implemented yet)")
    run.add_argument("--output", default="contactpetsc-output",
                     help="output directory (default: %(default)s)")
    run.add_argument("--dry-run", action="store_true",
                     help="print the plan (grid, decomposition, solver, memory) and exit")
    return p


def versions() -> dict:
    import numpy
    import mpi4py
    import pyfftw
    import h5py
    import petsc4py
    from mpi4py import MPI
    from petsc4py import PETSc
    from . import __version__
    return {
        "contactpetsc": __version__,
        "PETSc": "%d.%d.%d" % PETSc.Sys.getVersion(),
        "PETSc index bits": 8 * PETSc.IntType(0).itemsize,
        "petsc4py": petsc4py.__version__,
        "mpi4py": mpi4py.__version__,
        "MPI": MPI.Get_library_version().replace("\x00", "").splitlines()[0].strip(),
        "pyfftw": pyfftw.__version__,
        "h5py": h5py.__version__,
        "numpy": numpy.__version__,
    }


def _default_scene(output: str, dry_run: bool) -> int:
    import numpy as np
    from petsc4py import PETSc
    from .grid import SurfaceGrid
    from . import surfaces
    from .solvers import ContactProblem

    s = DEFAULT_SCENE
    R, E, a = s["radius"], s["e_star"], s["contact_radius"]
    n = s["nodes"]
    dx = a / s["elements_per_radius"]
    comm = PETSc.COMM_WORLD
    grid = SurfaceGrid(n, n, dx, periodic=False, comm=comm, row_alignment=16)
    say = PETSc.Sys.Print
    say(f"scene {s['name']}: sphere R = {R:g} m on an isolated half-space, E* = {E:g} Pa")
    say(f"  {grid}, window {n * dx:.3g} m = {n * dx / a:.1f} a")
    say(f"  decomposition: rows per rank {[b - a_ for a_, b in grid.y_ranges]}")
    # FFT buffers (padded 2n x 2n) and solver vectors: an upper estimate
    per_rank = (2 * n) * (2 * n) * 8 * 9 / comm.getSize() + n * n * 8 * 12 / comm.getSize()
    say(f"  memory estimate: {per_rank / 2**20:.1f} MiB per rank")
    if dry_run:
        say("  solver: SNES vinewtonrsls (prefix contact_), KSP cg, PC python "
            "(-contact_preconditioner spectral|mlmi|none)")
        return 0
    h = surfaces.sphere(grid, R)
    problem = ContactProblem(grid, h, E, length_scale=a * a / R)
    say(f"  {'delta [m]':>10} {'F [N]':>11} {'F/F_H':>9} {'a/a_H':>8} {'p0/p0_H':>8} "
        f"{'Newton':>6} {'CG':>5} {'FFT pairs':>9} {'error':>9}")
    rows = []
    for k in range(1, s["steps"] + 1):
        delta = (k / s["steps"]) ** 2 * a * a / R
        st = problem.solve(approach=delta)
        a_h = np.sqrt(R * delta)
        f_h = 4.0 / 3.0 * E * np.sqrt(R) * delta ** 1.5
        p0_h = 2 * E * a_h / (np.pi * R)
        # contact radius from the contact area (nodes with p > 0)
        a_num = np.sqrt(st.contact_fraction * grid.lengths[0] * grid.lengths[1] / np.pi)
        p_max = st.pressure.max()[1]
        rows.append((delta, st.force, f_h, a_num, a_h, p_max, p0_h))
        say(f"  {delta:10.3e} {st.force:11.4e} {st.force / f_h:9.5f} {a_num / a_h:8.4f} "
            f"{p_max / p0_h:8.4f} {st.newton_iterations:6d} {st.linear_iterations:5d} "
            f"{st.fft_pairs:9.0f} {st.complementarity_error:9.2e}")
    if comm.getRank() == 0:
        os.makedirs(output, exist_ok=True)
        np.savetxt(os.path.join(output, "curve.csv"), np.array(rows), delimiter=",",
                   header="approach_m,force_N,force_hertz_N,contact_radius_m,contact_radius_hertz_m,"
                          "max_pressure_Pa,max_pressure_hertz_Pa", comments="")
        problem.history.write_csv(os.path.join(output, "history.csv"))
    say(f"  wrote {output}/curve.csv and {output}/history.csv")
    return 0


def _without_petsc_options(words, petsc_options: dict) -> list:
    """The command-line words minus PETSc options and their values (as PETSc parsed them)."""
    out, i = [], 0
    while i < len(words):
        w = words[i]
        if w.startswith("-") and not w.startswith("--") and w[1:] in petsc_options:
            value = petsc_options[w[1:]]
            i += 2 if (value and i + 1 < len(words) and words[i + 1] == str(value)) else 1
            continue
        out.append(w)
        i += 1
    return out


def main(argv=None) -> int:
    argv = sys.argv if argv is None else [sys.argv[0]] + list(argv)
    import petsc4py
    petsc4py.init(argv)
    from petsc4py import PETSc
    args = _parser().parse_args(_without_petsc_options(argv[1:], PETSc.Options().getAll()))
    if args.version:
        for k, v in versions().items():
            PETSc.Sys.Print(f"{k}: {v}")
        return 0
    if args.command != "run":
        _parser().print_help()
        return 2
    comm = PETSc.COMM_WORLD.tompi4py()
    try:
        if args.scene is not None:
            raise NotImplementedError("scene files are not implemented yet; run without a scene "
                                      "for the built-in default scene")
        return _default_scene(args.output, args.dry_run)
    except Exception as exc:  # noqa: BLE001 - reported, then the whole job ends
        sys.stderr.write(f"contactpetsc [rank {comm.Get_rank()}]: error: {exc}\n")
        sys.stderr.flush()
        if comm.Get_size() > 1:
            comm.Abort(1)  # one rank's error must not leave the others waiting in a collective
        return 1


if __name__ == "__main__":
    sys.exit(main())
