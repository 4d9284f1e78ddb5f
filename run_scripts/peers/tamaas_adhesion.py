#!/usr/bin/env python3
"""Peer runner: periodic adhesive contact, hard wall plus exponential attraction, with Tamaas'
PolonskyKeerRey solver on the gap (Rey, Anciaux & Molinari's constrained CG with an adhesion
functional).

Run with the peer venv's interpreter (see setup_peers.sh), e.g.::

    ~/.cache/contactpetsc/peer-venv/bin/python run_scripts/peers/tamaas_adhesion.py \
        --surface h.npy --dx 0.001 --e-star 1 --w 5e-5 --rho 0.001 \
        --mean-gaps 0.0023,0.0021 [--tol 1e-7] [--max-iter 100000] [--save-fields DIR]

One JSON line per mean gap on stdout, in the order given; each solve starts from the previous
one's state (Tamaas keeps its primal field between solves), the first from Tamaas' own start.

Problem solved (our, i.e. contactpetsc's, convention and our ``exponential`` law)
-----------------------------------------------------------------------------
Periodic n x n cell of side L = n dx, composite heights h (input .npy), gap
g = h + v - delta >= 0 with v = K p, K^(q) = 2 / (E* |q|) (q != 0), K^(0) = 0, and the
pressure p = q + a(g): q >= 0 the hard wall's contact pressure (q g = 0) and
a(g) = -(w / rho) exp(-g / rho) the exponential attraction, the stationary point of
1/2 <p, K p> dA + sum Phi(g) dA with Phi(g) = -w exp(-g / rho).

Mapping to Tamaas 2.9.0
-----------------------
* Model ``basic_2d`` of size [L, L] with ``E = E*``, ``nu = 0`` (E_star = E*); its Westergaard
  operator is our periodic K (``tamaas_signorini.py`` checks it mode by mode).
* ``surface = -h`` and Tamaas' gap is ``displacement - surface`` (as in
  ``tamaas_signorini.py``), so g = U + h with U Tamaas' displacement, v = U - mean(U) and
  delta = -mean(U).
* ``PolonskyKeerRey(model, surface, tol, gap, gap)``: the primal variable is the gap and its
  mean is prescribed (``solve(mean_gap)``); the approach is the unknown.  Under approach
  control our state at delta has mean gap mean(h) - delta, so the two problems have the same
  solutions.
* ``ExponentialAdhesionFunctional`` with ``rho = rho`` and ``surface_energy = w``: the energy
  -w exp(-g / rho), our law exactly.  On the 128^2 benchmark heights (w = 0.05 E* dx,
  rho = dx, 5.7 % contact) Tamaas' gap field equals our 1e-11 solution to 4.8e-12 rho.
* ``tol`` is Tamaas' own error measure; on that case its gap error against the reference was
  0.05-0.07 x tol (tol 1e-5 ... 1e-8).
* Iterations are read from Tamaas' log (fd 2, captured outside the timed region; printed
  every ``dump_freq`` iterations and after the loop).  ``fft_pairs`` = 2 x iterations + 1 as
  for the non-adhesive PKR (``tamaas_signorini.py``, counted there with gdb; the adhesion
  functional adds no operator application, not counted here).
* Timed: ``time`` is wall seconds and ``cpu`` process CPU seconds of ``solve`` alone.  The
  wheel's backend is sequential (one thread).

Fields saved with --save-fields DIR: ``tamaas_<i>.npz`` (gap, pressure, delta) per mean gap.
"""
import argparse
import json
import os
import sys

import numpy as np
import tamaas as tm

from tamaas_log import solve_logged


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--surface", required=True, help=".npy (n, n) heights h, our convention")
    ap.add_argument("--dx", type=float, required=True, help="grid spacing [m]")
    ap.add_argument("--e-star", type=float, required=True, help="effective modulus E* [Pa]")
    ap.add_argument("--w", type=float, required=True, help="work of adhesion [J/m^2]")
    ap.add_argument("--rho", type=float, required=True, help="decay length [m]")
    ap.add_argument("--mean-gaps", required=True, help="comma-separated mean gaps [m], solved in turn")
    ap.add_argument("--tol", type=float, default=1e-7, help="Tamaas' tolerance (its own error measure)")
    ap.add_argument("--max-iter", type=int, default=100000)
    ap.add_argument("--save-fields", default=None, metavar="DIR")
    args = ap.parse_args(argv)
    h = np.load(args.surface)
    n = h.shape[0]
    if h.shape != (n, n):
        ap.error(f"--surface must be square, got {h.shape}")
    for name in ("dx", "e_star", "w", "rho", "tol"):
        if not getattr(args, name) > 0:
            ap.error(f"--{name.replace('_', '-')} must be > 0, got {getattr(args, name)!r}")
    L = n * args.dx
    tm.set_log_level(tm.LogLevel.info)  # the iteration count is read from the log
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [L, L], [n, n])
    model.E, model.nu = args.e_star, 0.0
    surface = np.ascontiguousarray(-h)
    solver = tm.PolonskyKeerRey(model, surface, args.tol, tm.PolonskyKeerRey.gap, tm.PolonskyKeerRey.gap)
    solver.max_iter = args.max_iter
    adhesion = tm.ExponentialAdhesionFunctional(surface)
    adhesion.parameters = {"rho": args.rho, "surface_energy": args.w}
    solver.addFunctionalTerm(adhesion)
    for i, mean_gap in enumerate(float(s) for s in args.mean_gaps.split(",")):
        err, iterations, t, c, _ = solve_logged(solver, mean_gap)
        U = np.array(model.displacement, dtype=np.float64, copy=True).reshape(n, n)
        p = np.array(model.traction, dtype=np.float64, copy=True).reshape(n, n)
        gap, delta = U - surface, -float(U.mean())
        row = {"solver": "tamaas-pkr-adhesion", "n": n, "mean_gap": mean_gap, "time": t, "cpu": c,
               "iterations": iterations,
               "fft_pairs": 2 * iterations + 1 if iterations is not None else None,
               "tamaas_error": err, "converged": bool(err <= args.tol), "tol": args.tol,
               "delta": delta, "gap_min": float(gap.min()), "mean_pressure": float(p.mean()),
               "contact_fraction": float(np.mean(gap <= 0.0)), "tamaas_version": tm.__version__}
        if args.save_fields:
            np.savez(os.path.join(args.save_fields, f"tamaas_{i}.npz"), gap=gap, pressure=p, delta=delta)
        print(json.dumps(row), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
