"""The software stack under contactpetsc: what it is, and the checks that speak before a solve.

A cluster user brings their own PETSc (a module, a source build, conda), their own MPI and
their own h5py; a mismatch between them otherwise shows up as a crash deep in a solve or, worse,
after the first step of a long run.  ``check_petsc`` runs once when the first module that uses
PETSc is imported (``contactpetsc.grid``); ``check_parallel_output`` runs before the first solve
of a run that writes fields on several ranks; ``describe`` is what ``contactpetsc info`` prints
(docs/install.md).
"""
from __future__ import annotations

import os

#: the reference paper and this code, as printed by ``--version`` and stored in every HDF5 file
#: (CITATION.cff holds the same, for citation tools)
CITATION = ("contactpetsc (matrix-free PETSc solvers for adhesive rough contact), after "
            "S. Medina and D. Dini, A numerical model for the deterministic analysis of adhesive rough "
            "contacts down to the nano-scale, International Journal of Solids and Structures 51 (2014) "
            "2620-2632, doi:10.1016/j.ijsolstr.2014.03.033")

#: environment variables by which MPI launchers tell a process the job's size
#: (SLURM_NTASKS is not one: it is the allocation's, set for a process started without srun too)
_LAUNCHER_SIZE = ("OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE", "MPI_LOCALNRANKS")


class StackError(RuntimeError):
    """The installed packages do not fit together (raised identically on every rank)."""


def _major_minor(version: str) -> tuple[int, int]:
    parts = version.split(".")
    return int(parts[0]), int("".join(c for c in parts[1] if c.isdigit()) or 0)


def check_petsc(petsc4py_version: str | None = None, petsc_version: tuple | None = None,
                scalar=None, real=None) -> None:
    """Refuse a petsc4py that does not match the PETSc library it loaded, and a PETSc whose
    scalars are not real double precision (the solvers' arrays are float64).

    The arguments default to the running stack; tests pass others.  The index size is
    reported (``describe``), not refused: 32-bit indices refuse a too large grid by itself
    (``grid.check_index_range``).
    """
    import numpy as np
    import petsc4py
    from petsc4py import PETSc
    p4 = petsc4py_version or petsc4py.__version__
    lib = petsc_version or PETSc.Sys.getVersion()
    if _major_minor(p4) != tuple(lib[:2]):
        raise StackError(
            f"petsc4py {p4} is running against the PETSc library {'.'.join(map(str, lib))}: they must "
            f"have the same major.minor version; install the petsc4py of your PETSc "
            f"(pip install --no-cache-dir petsc4py=={lib[0]}.{lib[1]}.* with PETSC_DIR and PETSC_ARCH "
            f"set, docs/install.md) or load the PETSc module petsc4py was built for")
    scalar = np.dtype(scalar if scalar is not None else PETSc.ScalarType)
    real = np.dtype(real if real is not None else PETSc.RealType)
    if scalar.kind == "c" or real != np.float64:
        raise StackError(
            f"PETSc was configured with {scalar.name} scalars ({real.name} reals); contactpetsc needs "
            f"real double precision: load a PETSc built with --with-scalar-type=real --with-precision=double "
            f"(the default; Debian: python3-petsc4py-real, not -complex)")


def launcher_size(environ=None) -> int | None:
    """The number of processes the MPI launcher started (mpirun, srun), from its environment;
    None when no launcher is seen."""
    environ = os.environ if environ is None else environ
    for key in _LAUNCHER_SIZE:
        if environ.get(key, "").isdigit():
            return int(environ[key])
    return None


def check_mpi(petsc_size: int, mpi4py_size: int, launched: int | None) -> None:
    """Refuse a job in which PETSc, mpi4py and the launcher disagree on the number of ranks:
    each process then runs as its own one-rank job (a Python built against another MPI than
    mpirun's) and N copies of the same run would overwrite each other's files."""
    if petsc_size != mpi4py_size:
        raise StackError(
            f"PETSc sees {petsc_size} MPI rank(s) but mpi4py sees {mpi4py_size}: petsc4py and mpi4py were "
            f"built against different MPI libraries; rebuild mpi4py with the MPI of your PETSc "
            f"(pip install --no-binary mpi4py --no-cache-dir mpi4py, with that MPI's mpicc first on PATH)")
    if launched is not None and launched > 1 and petsc_size == 1:
        raise StackError(
            f"the MPI launcher started {launched} processes but each sees a job of 1 rank: this Python's "
            f"MPI (mpi4py, petsc4py) is not the MPI of the mpirun/srun that started it; use the mpirun of "
            f"the MPI your PETSc was built with (`contactpetsc info` names it)")


def h5py_has_mpi() -> bool:
    """Whether the h5py in use was built with MPI (parallel HDF5: ``HDF5_MPI=ON``)."""
    import h5py
    return bool(h5py.get_config().mpi)


def check_parallel_output(n_ranks: int, writes_fields: bool, has_mpi: bool | None = None) -> None:
    """Refuse, before any solve, a run on several ranks that would write field files with a
    serial h5py (the first step file would fail after the first solve)."""
    if n_ranks <= 1 or not writes_fields:
        return
    if not (h5py_has_mpi() if has_mpi is None else has_mpi):
        raise StackError(
            f"this run writes step files from {n_ranks} ranks, but the h5py in use is serial (built without "
            f"MPI); install an MPI-enabled h5py (Debian: apt install python3-h5py-mpi; pip: "
            f"HDF5_MPI=ON CC=mpicc pip install --no-binary h5py --no-build-isolation --no-cache-dir h5py "
            f"against a parallel HDF5, docs/install.md), or run without fields (output.fields = false)")


def fftw_version() -> str:
    """The FFTW library pyfftw uses (its ``fftw_version`` string), or pyfftw's own version."""
    import ctypes
    import pyfftw
    try:
        lib = ctypes.CDLL(pyfftw.pyfftw.__file__)
        # ``const char fftw_version[]``: an array in the library, not a pointer
        return (ctypes.c_char * 64).in_dll(lib, "fftw_version").value.decode()
    except (OSError, ValueError, AttributeError):
        return "unknown"


def describe(comm=None) -> dict:
    """The stack as ``contactpetsc info`` prints it: versions, PETSc's configuration (index size,
    scalar type, PETSC_DIR/PETSC_ARCH), MPI, FFTW, h5py with or without parallel HDF5, and the
    number of ranks.  Collective only in that every rank may call it."""
    import h5py
    import mpi4py
    import numpy
    import petsc4py
    import pyfftw
    from mpi4py import MPI
    from petsc4py import PETSc
    from . import __version__
    config = petsc4py.get_config()
    comm = comm or PETSc.COMM_WORLD
    return {
        "contactpetsc": __version__,
        "PETSc": "%d.%d.%d" % PETSc.Sys.getVersion(),
        "PETSC_DIR": config.get("PETSC_DIR", ""),
        "PETSC_ARCH": config.get("PETSC_ARCH", "") or "(none: a prefix install)",
        "PETSc index bits": 8 * PETSc.IntType(0).itemsize,
        "PETSc scalar": numpy.dtype(PETSc.ScalarType).name,
        "petsc4py": petsc4py.__version__,
        "mpi4py": mpi4py.__version__,
        "MPI": MPI.Get_library_version().replace("\x00", "").splitlines()[0].strip(),
        "MPI ranks": comm.getSize(),
        "pyfftw": pyfftw.__version__,
        "FFTW": fftw_version(),
        "h5py": h5py.__version__,
        "HDF5": h5py.version.hdf5_version,
        "parallel HDF5": "yes" if h5py_has_mpi() else "no (serial h5py: field files on 1 rank only)",
        "numpy": numpy.__version__,
    }
