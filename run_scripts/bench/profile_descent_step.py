#!/usr/bin/env python3
"""Benchmark: where one descended path step's time goes (FFTs, our fields, PETSc's vectors).

The step of ``bench_peers_adhesion.py``'s step case: the rough benchmark heights
(``rough_surface.py``, periodic, E* = 1), the full LJ curve with w = --w E* dx and z0 = dx, the
state --step z0 below the approach giving --area contact (solved first, untimed), then the step
to that approach as a scene's path takes it (no stability check after it).  The step runs in
its own PETSc log stage; its events split its wall time into

* ``fft``: the FFTW transforms (``CPFFTForward`` + ``CPFFTBackward``);
* ``ours``: the rest of TAO's objective, gradient and Hessian callbacks and of the Hessian's and
  preconditioner's products (numpy: the law, the sums, the kernels' products);
* ``petsc_vec``: PETSc's vector operations (TAO's, its line search's and its Krylov solver's);
* ``other``: what is left (Newton's confirmation, the state's fields, Python around the calls).

    .venv/bin/python run_scripts/bench/profile_descent_step.py --size 1024 --area 0.10

Extra arguments go to PETSc (``-step_descent_...`` under the problem's prefix ``step_``).  One
JSON line; FFT pairs exact, CPU s (``process_time``) and wall s of one run;
the split in wall seconds (PETSc's event times).  One rank.
"""
import os
import sys
import time

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__, law="lj")
ap.add_argument("--area", type=float, default=0.10, help="contact fraction at the step's end")
ap.add_argument("--step", type=float, default=0.1, help="the step [z0]")
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"

CALLBACKS = ("TaoObjGradEval", "TaoHessianEval", "MatMult", "PCApply")


def main():
    PETSc.Log.begin()
    grid, h, _ = rough_surface(args.size)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    approach, = calibrate(grid, h, law, [args.area])
    opts = PETSc.Options("step_")
    if not opts.hasName("stiffness"):
        opts.setValue("stiffness", False)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="step_")
    pb.solve(approach=approach - args.step * grid.dx, raise_on_failure=False)
    pairs0 = pb.fft_pairs()
    stage = PETSc.Log.Stage("descended step")
    stage.push()
    cpu, wall = time.process_time(), time.perf_counter()
    st = pb.solve(approach=approach, raise_on_failure=False, check_stability=False)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    stage.pop()

    def seconds(name):
        return PETSc.Log.Event(name).getPerfInfo(stage)["time"]

    fft = seconds("CPFFTForward") + seconds("CPFFTBackward")
    # the Hessian's products run inside the Krylov solve, the callbacks' FFTs inside them
    ours = sum(seconds(name) for name in CALLBACKS) - fft
    vec = sum(seconds(name) for name in ("VecDot", "VecNorm", "VecScale", "VecCopy", "VecSet", "VecAXPY",
                                         "VecAYPX", "VecWAXPY", "VecMAXPY", "VecPointwiseMult"))
    emit(n=args.size, area=args.area, step=args.step, converged=st.converged, solver=st.solver,
         fft_pairs=pb.fft_pairs() - pairs0, cpu=cpu, wall=wall, descent=seconds("CPEnergyDescent"), fft=fft,
         ours=ours, petsc_vec=vec, other=wall - fft - ours - vec, vec_dots=PETSc.Log.Event("VecDot").getPerfInfo(stage)["count"],
         krylov=PETSc.Log.Event("MatMult").getPerfInfo(stage)["count"])


main()
