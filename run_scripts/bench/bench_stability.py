#!/usr/bin/env python3
"""Benchmark: the stability check's methods on the states of the rough benchmark's path.

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1), a law with w = --w E* dx and
range dx, the 10-state load-unload path of ``bench_fallback.py`` (approaches from 1 % to 10 %
contact and back), solved once with warm starts and a scene's defaults (the check on, so that an
unstable state goes to the fallback and the path's states are the stable ones a scene reaches;
its own margin is not reported).  At each state the margin
1 - lambda_max of the stability pencil (``solvers/stability.py``) by

* ``lobpcg``: LOBPCG on the pencil A x = lambda (K^-1)_NN x, preconditioned by K (periodic grids;
  ``-<prefix>stability_preconditioner compliance``);
* ``lobpcg-mlmi``: the same, preconditioned by an adhesive multilevel cycle on the Hessian's
  pressure form (``-<prefix>stability_preconditioner mlmi``, where ``auto`` takes it: the
  exponential law);
* ``lobpcg-multigrid``: preconditioned by a displacement-form V-cycle on the Hessian
  (``multigrid``, where ``auto`` takes it: the LJ laws);
* ``lanczos``: Lanczos on A S, S the clamped compliance (a CG on the contact set per step where
  there are contact nodes);
* ``reference``: LOBPCG to a residual of ``--reference-tol`` (1e-7; at most
  ``--reference-steps``, 3000, iterations; preconditioned by ``--reference``, K unless given);

each at the code's default steps, with its FFT pairs (exact), CPU s (``process_time``), whether
it settled, and its margin's difference to the reference.  First line: the non-adhesive solve on
the same heights (the benchmark's mean pressure 0.005 E*), the unit of the ratios.  One JSON line
per state and method.

    .venv/bin/python run_scripts/bench/bench_stability.py --size 256 --law exponential
    .venv/bin/python run_scripts/bench/bench_stability.py --size 256 --law lj --w 0.2
    .venv/bin/python run_scripts/bench/bench_stability.py --size 1024 --law exponential \
        --methods lobpcg lobpcg-mlmi --reference mlmi
    .venv/bin/python run_scripts/bench/bench_stability.py --size 256 --law lj --w 0.2 \
        --methods lanczos lobpcg lobpcg-multigrid --reference multigrid

One rank.
"""
import os
import sys

import petsc4py

from bench_args import emit, rough_parser, timed_margin

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__)
ap.add_argument("--states", type=int, default=10, help="states of the load-unload path")
METHODS = ["lobpcg", "lobpcg-mlmi", "lobpcg-multigrid", "lanczos"]
ap.add_argument("--methods", nargs="+", default=METHODS, choices=METHODS)
ap.add_argument("--reference-tol", type=float, default=1e-7, help="the reference LOBPCG's residual tolerance")
ap.add_argument("--reference-steps", type=int, default=3000, help="the reference LOBPCG's iteration cap")
ap.add_argument("--reference", default="compliance", choices=["compliance", "mlmi", "multigrid"],
                help="the reference LOBPCG's preconditioner")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.options import code_default  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, load_unload_path, non_adhesive_unit, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def margin(pb, method, **kw):
    if method.startswith("lobpcg"):
        method, kw = "lobpcg", dict({"preconditioner": method.partition("-")[2] or "compliance"}, **kw)
    return timed_margin(pb, method, **kw)


def main():
    grid, h, _ = rough_surface(args.size)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    pairs_unit, cpu = non_adhesive_unit(grid, h)
    emit(kind="non-adhesive", size=args.size, fft_pairs=pairs_unit, cpu_s=cpu)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="stab_")
    steps = code_default("adhesion", "stability_steps")
    for k, a in enumerate(load_unload_path(grid, h, law, args.states)):
        st = pb.solve(approach=a, raise_on_failure=False)
        ref = margin(pb, "lobpcg", steps=args.reference_steps, residual_tol=args.reference_tol,
                     preconditioner=args.reference)
        for method in args.methods:
            m, settled, pairs, cpu = margin(pb, method, steps=steps)
            emit(kind="state", law=args.law, w=args.w, size=args.size, state=k, approach=a,
                 converged=st.converged, contact_fraction=st.contact_fraction, method=method,
                 margin=m, settled=settled, fft_pairs=pairs, ratio=pairs / pairs_unit, cpu_s=cpu,
                 reference=ref[0], reference_settled=ref[1], error=m - ref[0])


if __name__ == "__main__":
    main()
