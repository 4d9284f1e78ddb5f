#!/usr/bin/env python3
"""Benchmark: the energy descent's preconditioned Hessian at a converged rough state, per contact factor.

The rough benchmark heights (``rough_surface.py``, full LJ curve, z0 = dx, w = --w E* dx) at
the approach giving --area contact, solved with the defaults.  At that state, for each
``--factors`` f, CG on the descent's Hessian K^-1 + diag Phi''(g) preconditioned by
P = S K S (S_ii = (1 + f min(1, K_ii Phi''))^-1/2, ``descent.py``; f = 0 is K alone) solves a
random right-hand side of zero mean (as TAO's gradients are) to 1e-8: its iterations, its
converged reason and the extreme eigenvalues of P H that CG's Lanczos estimates give.  The
full LJ curve only (a hard wall's descent works on TAO's inactive set, which this does not
model).  One JSON line per factor.

    .venv/bin/python run_scripts/bench/descent_pc_spectrum.py --size 256 --area 0.02 --factors 0 1 3 10 30

One rank.
"""
import os
import sys

import petsc4py

from bench_args import emit, rough_parser

HERE = os.path.dirname(os.path.abspath(__file__))
ap = rough_parser(__doc__, law="lj")
ap.add_argument("--area", type=float, default=0.02, help="contact area of the state")
ap.add_argument("--factors", type=float, nargs="+", default=[0, 1, 3, 10, 30])
args, petsc_args = ap.parse_known_args()
if args.law != "lj":
    ap.error("--law: the full LJ curve (lj) only; a hard wall's descent works on TAO's inactive set")
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402
from contactpetsc.solvers.descent import EnergyDescent  # noqa: E402
from contactpetsc.solvers.descent_contexts import Compliance, Hessian  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"


def main():
    grid, h, _ = rough_surface(args.size)
    law = adhesive_law(grid, args.w, 1.0, name=args.law)
    approach = calibrate(grid, h, law, [args.area])[0]
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="spec_", petsc_options={"stiffness": False})
    st = pb.solve(approach=approach, raise_on_failure=False, check_stability=False)
    descent = EnergyDescent(pb)
    g = descent.at_state()
    stiff = descent.kappa * descent.curvature      # K_ii Phi''(g)
    for f in args.factors:
        descent.pc_contact_factor = f
        descent.set_curvature(g)
        H = descent.shell((grid.n_local, descent.n), Hessian(descent))
        ksp = PETSc.KSP().create(comm=grid.comm)
        ksp.setType("cg")
        ksp.setOperators(H)
        pc = ksp.getPC()
        pc.setType("python")
        pc.setPythonContext(Compliance(descent))
        ksp.setTolerances(rtol=1e-8, max_it=5000)
        ksp.setComputeEigenvalues(True)
        b, x = H.createVecs()
        rng = PETSc.Random().create(comm=grid.comm)
        rng.setSeed(1)
        b.setRandom(rng)
        b.shift(-b.sum() / b.getSize())
        ksp.solve(b, x)
        ev = np.sort(ksp.computeEigenvalues().real)
        emit(n=args.size, w=args.w, contact_fraction=st.contact_fraction, converged=st.converged,
             stiff_max=float(stiff.max()), stiff_nodes=float(np.mean(stiff > 1.0)), factor=f,
             cg_iterations=ksp.getIterationNumber(), reason=int(ksp.getConvergedReason()),
             eig_min=float(ev[0]), eig_max=float(ev[-1]), condition=float(ev[-1] / ev[0]))
        for obj in (ksp, H, b, x, rng):
            obj.destroy()


main()
