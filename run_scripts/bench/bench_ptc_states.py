#!/usr/bin/env python3
"""Benchmark: where the pseudo-transient continuation (PTC) fallback's FFT pairs go, on the
states of the rough adhesive load-unload path (``bench_adhesion_path.py``'s case and approaches).

Two modes:

``--mode path`` runs the path's first ``--stop-after`` states as ``bench_adhesion_path.py``
does (Newton, the coarse-grid predictor, PTC where Newton fails or stalls) and writes each
converged state's adhesive pressure to ``--save`` (npz, one array per state).

``--mode ptc`` reads such a file and, for each saved state k below the last, runs PTC alone
from it to the approach of state k + 1 (Newton's steps switched off, ``-path_max_it 0``; no
predictor, no coarse level): the fallback's cost from a fixed start, free of the branch a
stalled Newton wandered to.

Per state one JSON line: FFT pairs, Newton steps, PTC steps, the Krylov iterations of each
PTC step, the shift at each PTC step, contact fraction, converged, stable.  The pair counts
are exact and machine-independent, and runs repeat (the measured FFTW plans are stored,
docs/formulation.md, "Plans that repeat from run to run").

    .venv/bin/python run_scripts/bench/bench_ptc_states.py --size 512 --stop-after 5 --save /tmp/s512.npz
    .venv/bin/python run_scripts/bench/bench_ptc_states.py --size 512 --mode ptc --load /tmp/s512.npz
        [-path_ptc_<option> ...]

One rank.
"""
import argparse
import os
import sys

import petsc4py

from bench_args import emit

HERE = os.path.dirname(os.path.abspath(__file__))
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--size", type=int, default=512)
ap.add_argument("--mode", choices=("path", "ptc"), default="path")
ap.add_argument("--states", type=int, default=10, help="path mode: states on the whole path (its approaches)")
ap.add_argument("--stop-after", type=int, default=None, help="path mode: run only the first states")
ap.add_argument("--areas", type=float, nargs=2, default=[0.01, 0.10])
ap.add_argument("--calibrate-max-n", type=int, default=256)
ap.add_argument("--save", default=None, help="path mode: npz file of the converged states")
ap.add_argument("--load", default=None, help="ptc mode: npz file written by path mode")
ap.add_argument("--only", type=int, nargs="*", default=None, help="ptc mode: the target states to run")
args, petsc_args = ap.parse_known_args()
if args.mode == "ptc" and not args.load:
    ap.error("--mode ptc needs --load, the states file of a path run (--save)")
if args.mode == "ptc":
    petsc_args += ["-path_max_it", "0", "-path_predictor", "false", "-path_fmg", "false"]
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from rough_surface import adhesive_law, calibrate, path_approaches, rough_surface  # noqa: E402


class Traced(AdhesiveProblem):
    """The solver with its PTC shift recorded at every Jacobian."""

    shifts: list = []

    def _jacobian(self, snes, x, J, P):
        super()._jacobian(snes, x, J, P)
        if self.shift and self.grid.nx == args.size:
            Traced.shifts.append(self.shift)


def solve_traced(pb, approach):
    rec0 = len(pb.history)
    Traced.shifts = []
    st = pb.solve(approach=approach, raise_on_failure=False)
    recs = pb.history.records[rec0:]
    solves = sorted({r.solve for r in recs})
    ptc = "+ptc" in st.solver
    steps = {s: [r for r in recs if r.solve == s] for s in solves}
    ptc_recs = steps[solves[-1]] if ptc and solves else []
    lin = [b.linear_iterations - a.linear_iterations for a, b in zip(ptc_recs, ptc_recs[1:])]
    newton = sum(len(v) - 1 for s, v in steps.items() if not (ptc and s == solves[-1]))
    ptc_pairs = ptc_recs[-1].fft_pairs - ptc_recs[0].fft_pairs if ptc_recs else 0.0
    return st, dict(fft_pairs=st.fft_pairs, newton=newton, ptc_steps=max(len(ptc_recs) - 1, 0),
                    ptc_pairs=ptc_pairs, ptc_krylov=lin,
                    shift=[float(f"{s:.3g}") for s in Traced.shifts],
                    error=[float(f"{max(r.complementarity_error, r.adhesive_error):.2g}") for r in ptc_recs],
                    pressure_error=[float(f"{r.pressure_error:.2g}") for r in ptc_recs],
                    contact_fraction=st.contact_fraction, converged=st.converged, stable=st.stable,
                    solver=st.solver, reason=st.reason if not st.converged else "")


def main():
    n = args.size
    grid, h, _ = rough_surface(n)
    law = adhesive_law(grid)
    if args.mode == "ptc":
        # the path's own approaches, as saved with its states (no calibration anew)
        data = np.load(args.load)
        approaches = list(data["approaches"])
    else:
        ends = calibrate(grid, h, law, args.areas, max_n=args.calibrate_max_n)
        if ends is None:
            emit(n=n, solver="calibration", converged=False,
                 message="the calibration sweep converged at fewer than two approaches")
            return
        approaches = path_approaches(ends[0], ends[1], args.states)
    opts = PETSc.Options("path_")
    if not opts.hasName("stiffness"):
        opts.setValue("stiffness", False)
    pb = Traced(grid, h, 1.0, law, prefix="path_")
    if args.mode == "path":
        saved = {}
        for k, d in enumerate(approaches[:args.stop_after]):
            st, row = solve_traced(pb, float(d))
            emit(n=n, state=k, approach=float(d), **row)
            if st.converged and st.stable is not False:
                saved[f"s{k}"] = np.asarray(pb.blocks(pb._x, readonly=True)[-1]).copy()
        if args.save:
            np.savez(args.save, approaches=np.array(approaches), **saved)
        return
    a = grid.create_vec()
    total = 0.0
    for k in range(len(approaches) - 1):
        if f"s{k}" not in data or (args.only and k + 1 not in args.only):
            continue
        grid.rows(a)[...] = data[f"s{k}"]
        pb.warm_start(None, a, float(approaches[k]))
        st, row = solve_traced(pb, float(approaches[k + 1]))
        total += row["fft_pairs"]
        emit(n=n, state=k + 1, start=k, approach=float(approaches[k + 1]), **row)
    emit(n=n, summary=True, fft_pairs_total=total)


main()
