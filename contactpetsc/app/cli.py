"""Command line: ``contactpetsc run [SCENE] [PETSc options]``, ``contactpetsc plot DIR``,
``contactpetsc info [--check]``, ``contactpetsc import SRC DST`` (a measured topography to a
height file; runs without PETSc), ``contactpetsc --version``.

This is an entry point: it calls ``petsc4py.init(sys.argv)`` before anything
imports PETSc, so every PETSc option on the command line reaches the options
database (``-contact_snes_monitor``, ``-log_view``, ...).

Without a scene file, ``run`` solves the built-in default scene
(``scenes.DEFAULT_SCENE``): a smooth sphere (R = 100 um, E* = 50 GPa, the
reference paper's material) pressed onto an isolated elastic half-space,
swept through five approaches in displacement control with warm starts,
each state compared with Hertz.  PETSc options that nothing used by the
end of a run (misspelt, or for a solver the scene does not run) are listed in
a warning; ``-options_left`` also works as in any PETSc program.  ``-help`` lists the
package's own options of the scene's problem as well as PETSc's.

Exit status (docs/outputs.md):

- 0: every step converged;
- 3: some step did not converge (an adhesive run stops there; ``--restart`` continues it);
- 1: an error: bad input (scene, files), a refused output directory (locked, another
  run's files, a restart of another problem), an I/O failure (a full disk), a PETSc failure;
- 2: a usage error (unknown command or argument).
"""
from __future__ import annotations

import argparse
import sys

def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="contactpetsc",
        description="Contact of rough elastic surfaces with matrix-free PETSc solvers. "
                    "PETSc options (e.g. -contact_snes_monitor, -log_view) may follow.")
    p.add_argument("--version", action="store_true", help="print versions and exit")
    sub = p.add_subparsers(dest="command")
    run = sub.add_parser("run", help="run a scene (default: the built-in Hertz sphere)")
    run.add_argument("scene", nargs="?", help="scene file (TOML, see docs/scenes.md)")
    run.add_argument("--output", default=None,
                     help="output directory (default: the scene's output.directory)")
    run.add_argument("--restart", action="store_true",
                     help="keep the steps already in the output directory (the same scene's physics) "
                          "and resume after the last")
    run.add_argument("--overwrite", action="store_true",
                     help="remove another run's files from the output directory (curve.csv, history.csv, "
                          "jumps.csv, summary.json, scene.json, atom_forces.csv, step files, fields.xdmf, plots) first")
    run.add_argument("--dry-run", action="store_true",
                     help="print the plan (grid, decomposition, solver, memory, outputs) and exit")
    run.add_argument("--plots", action="store_true",
                     help="also save the plots (load_approach.png, contact_area.png, mean_gap.png, ...: "
                          "docs/outputs.md; as output.plots = true; needs matplotlib)")
    info = sub.add_parser("info", help="print the stack (PETSc, petsc4py, MPI, FFTW, h5py, index size, "
                          "parallel HDF5, ranks); under mpirun too")
    info.add_argument("--check", action="store_true",
                      help="also solve a small Hertz sphere on the ranks of the job, write its step files "
                           "to a temporary directory and compare the forces with Hertz")
    plot = sub.add_parser("plot", help="save the plots of a finished run's output directory")
    plot.add_argument("directory", help="a run's output directory (with curve.csv)")
    plot.add_argument("--step", type=int, default=None,
                      help="the step whose pressure map and distributions are plotted (default: the scene's "
                           "output.plot_step, else the step at the largest approach)")
    from ..topography.convert import add_arguments
    add_arguments(sub.add_parser("import", help="convert a measured topography to a height file for a "
                                                "kind = \"file\" scene (no PETSc needed)"))
    return p


#: PETSc options that PETSc consumes at initialisation (not kept in the options database), with
#: the number of words that follow them (docs/scenes.md, "Command line")
CONSUMED = {"options_file": 1, "options_file_yaml": 1, "options_string_yaml": 1, "prefix_push": 1,
            "prefix_pop": 0}


def _without_petsc_options(words, petsc_options: dict) -> list:
    """The command-line words minus PETSc options and their values (as PETSc parsed them)."""
    out, i = [], 0
    while i < len(words):
        w = words[i]
        if w.startswith("-") and not w.startswith("--") and w[1:] in CONSUMED:
            i += 1 + CONSUMED[w[1:]]
            continue
        if w.startswith("-") and not w.startswith("--") and w[1:] in petsc_options:
            value = petsc_options[w[1:]]
            i += 2 if (value and i + 1 < len(words) and words[i + 1] == str(value)) else 1
            continue
        out.append(w)
        i += 1
    return out


def unused_options() -> list[str]:
    """PETSc options set but not used so far (PetscOptionsLeftGet), as ``-name [value]``.

    petsc4py 3.18 has no wrapper for it: called through ctypes in the library petsc4py links;
    an empty list when that is not possible (``-options_left`` then still reports them at exit).
    """
    import ctypes

    from petsc4py import PETSc
    try:
        fn = ctypes.CDLL(PETSc.__file__).PetscOptionsLeftGet
        restore = ctypes.CDLL(PETSc.__file__).PetscOptionsLeftRestore
    except (OSError, AttributeError):
        return []
    n = (ctypes.c_int64 if PETSc.IntType(0).itemsize == 8 else ctypes.c_int)(0)
    names, values = ctypes.POINTER(ctypes.c_char_p)(), ctypes.POINTER(ctypes.c_char_p)()
    if fn(None, ctypes.byref(n), ctypes.byref(names), ctypes.byref(values)) != 0:
        return []
    out = [f"-{names[i].decode()}" + (f" {values[i].decode()}" if values[i] else "") for i in range(n.value)]
    restore(None, ctypes.byref(n), ctypes.byref(names), ctypes.byref(values))
    return out


def _forget_own_words(opts, words) -> None:
    """Remove this command's own ``--words`` (argparse's) from PETSc's options database: PETSc
    stores them as options too, and newer PETSc lists unused options at exit."""
    for word in words:
        if word.startswith("--") and len(word) > 2:
            opts.delValue(word.split("=", 1)[0])


def main(argv=None) -> int:
    argv = sys.argv if argv is None else [sys.argv[0]] + list(argv)
    if argv[1:2] == ["import"]:   # before PETSc: it runs where petsc4py is not installed
        from ..topography.convert import main as import_main
        return import_main(argv[2:])
    import petsc4py
    petsc4py.init(argv)
    from petsc4py import PETSc
    args = _parser().parse_args(_without_petsc_options(argv[1:], PETSc.Options().getAll()))
    _forget_own_words(PETSc.Options(), argv[1:])
    if args.command not in ("run", "plot", "info") and not args.version:
        _parser().print_help()
        return 2
    comm = PETSc.COMM_WORLD.tompi4py()
    try:
        from mpi4py import MPI

        from ..stack import check_mpi, launcher_size
        check_mpi(comm.Get_size(), MPI.COMM_WORLD.Get_size(), launcher_size())
    except Exception as exc:  # noqa: BLE001 - every rank says it: they do not share a job
        sys.stderr.write(f"contactpetsc: error: {exc}\n")
        return 1
    if args.version or args.command == "info":
        return _info(args.version, getattr(args, "check", False), comm)
    if args.command == "plot":
        return _plot(args.directory, comm, args.step)
    try:
        from . import runner, scenes
        scene = scenes.load(args.scene) if args.scene else scenes.validate(scenes.DEFAULT_SCENE)
        scene["output"]["plots"] |= args.plots
        _print_options_help(scene)
        if args.restart and args.overwrite:
            raise ValueError("--restart keeps the run in the output directory, --overwrite removes it: "
                             "give one of them")
        states = runner.run(scene, output=args.output, dry_run=args.dry_run, restart=args.restart,
                            overwrite=args.overwrite)
        unused = [] if args.dry_run else unused_options()
        if unused and comm.Get_rank() == 0:
            sys.stderr.write("contactpetsc: warning: PETSc options nobody used (misspelt, or for a solver "
                             f"this scene does not run): {', '.join(unused)}\n")
        return 0 if all(st.converged for st in states) else 3
    except Exception as exc:  # noqa: BLE001 - reported, then the whole job ends
        if isinstance(exc, PETSc.Error):
            from ..collective import petsc_error_message
            exc = f"{petsc_error_message(exc)}; rerun with -log_trace or -info for PETSc's own account"
        sys.stderr.write(f"contactpetsc [rank {comm.Get_rank()}]: error: {exc}\n")
        sys.stderr.flush()
        if comm.Get_size() > 1:
            comm.Abort(1)  # one rank's error must not leave the others waiting in a collective
        return 1


def _print_options_help(scene: dict) -> None:
    """With ``-help``: the package's own options of the scene's problem under its prefix, before
    anything is built or solved (PETSc lists its objects' options as they are set up)."""
    from ..solvers.options import print_help
    from .builder import ADHESION_PREFIX, CONTACT_PREFIX
    from .scenes import adhesive
    table, prefix = ("adhesion", ADHESION_PREFIX) if adhesive(scene) else ("contact", CONTACT_PREFIX)
    print_help(table, prefix)


def _info(version_only: bool, check: bool, comm) -> int:
    """``--version`` and ``info``: the stack, one ``key: value`` per line, and the citation;
    ``--check`` also solves a small Hertz sphere on every rank of the job, step files included."""
    from petsc4py import PETSc

    from ..stack import CITATION, describe
    stack = describe()
    if version_only:
        stack = {k: stack[k] for k in ("contactpetsc", "PETSc", "petsc4py", "PETSc index bits")}
    for k, v in stack.items():
        PETSc.Sys.Print(f"{k}: {v}")
    PETSc.Sys.Print(f"cite: {CITATION}")
    if not check:
        return 0
    import tempfile

    from ..collective import collective_call
    from . import runner, scenes
    scene = scenes.validate({**scenes.DEFAULT_SCENE, "name": "info-check",
                             "geometry": {**scenes.DEFAULT_SCENE["geometry"], "nx": 64, "dx": 1e-7}})
    rank0 = comm.Get_rank() == 0
    tmp = comm.bcast(collective_call(comm, OSError, "info --check: {error}",
                                     lambda: tempfile.mkdtemp(prefix="contactpetsc-check-") if rank0 else None))
    try:
        states = runner.run(scene, output=tmp, comm=comm)
        from ..physics.closed_forms import hertz_force
        g = scene["geometry"]
        worst = max(abs(st.force / float(hertz_force(scenes.e_star(scene), g["radius"], st.approach)) - 1)
                    for st in states)
        ok = all(st.converged for st in states) and worst < 0.05
        PETSc.Sys.Print(f"check: {'passed' if ok else 'FAILED'}: {len(states)} approaches on {comm.Get_size()} "
                        f"rank(s), step files written"
                        f"{' with MPI-IO' if comm.Get_size() > 1 else ''}, force within {100 * worst:.2f} % of Hertz")
        return 0 if ok else 1
    finally:
        comm.Barrier()
        if rank0:
            import shutil
            shutil.rmtree(tmp, ignore_errors=True)


def _plot(directory: str, comm, step: int | None = None) -> int:
    """``contactpetsc plot DIR``: the plots of a finished run, drawn on rank 0."""
    if comm.Get_rank() != 0:
        return 0
    try:
        from .plots import plot_run
        for path in plot_run(directory, step=step):
            print(f"wrote {path}")
        return 0
    except Exception as exc:  # noqa: BLE001 - a damaged file is reported, not a traceback
        sys.stderr.write(f"contactpetsc plot: error: {exc}\n")
        return 1


if __name__ == "__main__":
    sys.exit(main())
