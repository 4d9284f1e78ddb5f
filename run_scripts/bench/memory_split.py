#!/usr/bin/env python3
"""Diagnosis: where an adhesive state's memory is, PETSc against numpy, per phase.

The rough benchmark case of ``bench_adhesion_path.py`` (``--law lj`` or ``exponential``, a hard
wall), one problem solved at ``--approaches`` [m] in turn with a scene's defaults (stability
check, tangent stiffness).  After each phase (each energy descent, VI Newton run, stability
check and tangent solve) and each state, in doubles per grid point: PETSc's allocations now and at their
maximum so far (``PetscMallocGetCurrentUsage`` / ``GetMaximumUsage``, which count only under
``-malloc_debug``, passed here), numpy's (``tracemalloc``: now, and the phase's peak), and the
anonymous resident size over the one before the problem.  The rest of the resident size is
freed memory the heap kept (``malloc_trim`` returns it; the high-water mark keeps it).

    .venv/bin/python run_scripts/bench/memory_split.py --size 1024 --law exponential

One rank; tracemalloc slows the Python around the solver: times are not measured.
"""
import argparse
import ctypes
import os
import sys
import tracemalloc

import petsc4py

HERE = os.path.dirname(os.path.abspath(__file__))
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--size", type=int, default=1024)
ap.add_argument("--law", default="lj", choices=("lj", "exponential"))
ap.add_argument("--approaches", type=float, nargs="+", default=[2.4e-4, 6.1e-4],
                help="approaches [m] in turn (the 1 %% and 2 %% states of the 1024^2 path)")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0], "-malloc_debug"] + petsc_args)

from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers import descent, newton, predictor, stability  # noqa: E402
from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from bench_args import emit  # noqa: E402
from rough_surface import adhesive_law, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def petsc_library():
    """The PETSc shared library this process loaded (its path from /proc/self/maps)."""
    with open("/proc/self/maps") as f:
        paths = {line.split()[-1] for line in f if "libpetsc" in line}
    return ctypes.CDLL(sorted(paths)[0])


def anonymous_kb():
    with open("/proc/self/smaps_rollup") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("Anonymous:"))


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid, name=args.law)
    lib = petsc_library()
    per_point = 8.0 * n * n

    def petsc_usage():
        now, peak = ctypes.c_double(), ctypes.c_double()
        lib.PetscMallocGetCurrentUsage(ctypes.byref(now))
        lib.PetscMallocGetMaximumUsage(ctypes.byref(peak))
        return now.value / per_point, peak.value / per_point

    tracemalloc.start()
    anon0 = anonymous_kb()

    def report(**what):
        petsc_now, petsc_max = petsc_usage()
        numpy_now, numpy_peak = (b / per_point for b in tracemalloc.get_traced_memory())
        emit(n=n, law=args.law, **what, petsc=petsc_now, petsc_max=petsc_max, numpy=numpy_now,
             numpy_peak=numpy_peak, anonymous=(anonymous_kb() - anon0) * 1024.0 / per_point)

    def phased(cls, name):
        method = getattr(cls, name)

        def wrapped(self, *a, **k):
            tracemalloc.reset_peak()
            out = method(self, *a, **k)
            report(phase=f"{cls.__name__}.{name}")
            return out
        setattr(cls, name, wrapped)

    for cls, name in ((descent.EnergyDescent, "descend"), (newton.VINewton, "run"),
                      (stability.StabilityCheck, "margin"), (predictor.TangentPredictor, "solve")):
        phased(cls, name)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="split_")
    for k, d in enumerate(args.approaches):
        st = pb.solve(approach=d, raise_on_failure=False)
        report(state=k, approach=d, converged=st.converged, solver=st.solver, fft_pairs=st.fft_pairs)


main()
