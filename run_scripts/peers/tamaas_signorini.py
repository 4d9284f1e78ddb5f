#!/usr/bin/env python3
"""Peer runner: periodic frictionless non-adhesive contact with Tamaas' PKR.

Run with the peer venv's interpreter (see setup_peers.sh), e.g.::

    ~/.cache/contactpetsc/peer-venv/bin/python run_scripts/peers/tamaas_signorini.py \
        h.npy --length 1.0 --estar 1.0 --mean-pressure 0.05 --tol 1e-8 --out res.npz

Solves, for a periodic square cell of side L sampled on an n x n grid
(pixel size L/n), the Signorini problem in *our* (contactpetsc) convention

    gap = h + v - delta >= 0,   p >= 0,   p * gap = 0,   mean(p) = P,
    v = K p,  K^(q) = 2 / (E* |q|)  (q != 0),  K^(0) = 0,

with h the composite separation (input .npy, nominally min(h) = 0), v the
elastic (Westergaard, periodic half-space) surface displacement produced by
the compressive pressure p, delta the rigid-body approach (an unknown of the
load-controlled problem) and E* the effective modulus.

Mapping to Tamaas (checked against tamaas 2.9.0, see report / checks below)
---------------------------------------------------------------------------
* Model: ``ModelFactory.createModel(model_type.basic_2d, [L, L], [n, n])``
  with ``model.E = E*`` and ``model.nu = 0`` so that
  ``model.E_star = E / (1 - nu^2) = E*``.  Tamaas' Westergaard Neumann
  operator is exactly u^(q) = 2 / (E_star |q|) p^(q), |q| = 2 pi |k| / L,
  with the q = 0 mode set to zero (verified numerically with
  ``model.solveNeumann`` on single Fourier modes; point-wise kernel, no
  pixel averaging).
* Surface: Tamaas' ``surface`` is the profile of the rigid indenter with
  asperities pointing *towards* the elastic body, and its gap is
  ``gap_tamaas = displacement - surface`` (contact where displacement equals
  surface up to the rigid shift).  Hence ``surface = -h``.
* After ``PolonskyKeerRey.solve(P)``: ``model.traction`` = p (>= 0, mean P)
  and ``model.displacement`` = U = K p + c, where the constant c is the rigid
  shift Tamaas chose so that min(U - surface) = 0.  Therefore
  ``gap = U - surface = U + h`` (this is what we save),
  ``v = U - mean(U)`` (K p has zero mean) and ``delta = -mean(U)``,
  so that gap = h + v - delta holds identically.  Any constant offset of h
  only shifts delta.
* Error measure (value returned by ``solve`` and by ``computeError``):
  ``err = |sum(p * g)| / (sum(p) * std(surface))``, i.e. a relative
  complementarity error: the pressure-weighted mean gap divided by the rms
  height of the surface (population std).  Tamaas iterates until
  ``err <= tolerance`` (or ``max_iter``).  The same quantity is recomputed
  here from the returned fields (``compl_rel``) as a cross-check.
* Iterations: Tamaas logs (stderr, level info) the iteration index every
  ``dump_freq`` (=100) iterations and once more after the loop with the last
  index n; iterations = n + 1 on convergence, n when max_iter stopped it.  We capture fd 2 during the solve and
  parse it (the redirection is outside the timed region).
* FFT count: each PKR iteration applies the Westergaard operator twice
  (gradient u = K p, and K t for the critical step along the conjugate
  direction t), and one more application follows the loop to refresh the
  gap.  Each application is one real-to-complex plus one complex-to-real
  FFT.  So ``fft_pairs = 2 * iterations + 1``; verified by counting
  fftw_execute_dft_r2c / _c2r calls with gdb breakpoints for tamaas 2.9.0
  (e.g. 45 iterations -> 91 r2c + 91 c2r).
* The wheel's backend is "cpp" (sequential, FFTW statically linked,
  no threads, no MPI).

Output: one JSON line on stdout; fields p, gap, v, h, delta in ``--out``.
"""
import json
import sys

import numpy as np
import tamaas as tm

import signorini_cli
from tamaas_log import solve_logged


def _westergaard_np(p, length, estar):
    """Independent numpy evaluation of v = K p (for the kernel cross-check)."""
    n0, n1 = p.shape
    q0 = 2 * np.pi * np.fft.fftfreq(n0, d=length / n0)
    q1 = 2 * np.pi * np.fft.rfftfreq(n1, d=length / n1)
    qn = np.hypot(q0[:, None], q1[None, :])
    qn[0, 0] = 1.0
    kern = 2.0 / (estar * qn)
    kern[0, 0] = 0.0
    return np.fft.irfft2(np.fft.rfft2(p) * kern, s=p.shape)


def main(argv=None):
    args, h = signorini_cli.parse(__doc__.split("\n")[0], "Tamaas tolerance on sum(p g)/(sum(p) std(h))", 10000,
                                  "skip the numpy kernel cross-check (one extra FFT pair)", argv)
    n = h.shape[0]
    L, estar, P = args.length, args.estar, args.mean_pressure

    tm.set_log_level(tm.LogLevel.info)  # needed to read the iteration count
    model = tm.ModelFactory.createModel(tm.model_type.basic_2d, [L, L], [n, n])
    model.E = estar
    model.nu = 0.0
    assert abs(model.E_star - estar) <= 1e-14 * abs(estar)
    surface = np.ascontiguousarray(-h)  # Tamaas surface = -(our separation)
    solver = tm.PolonskyKeerRey(model, surface, args.tol)
    solver.max_iter = args.max_iter

    err, iterations, t_solve, _, log = solve_logged(solver, P)

    p = np.array(model.traction, dtype=np.float64, copy=True).reshape(n, n)
    U = np.array(model.displacement, dtype=np.float64, copy=True).reshape(n, n)
    err_final = float(solver.computeError())
    gap = U - surface                      # = h + v - delta, min 0
    v = U - U.mean()                       # = K p (zero mean)
    delta = -float(U.mean())

    hstd = float(np.std(h))
    psum = float(p.sum())
    res = {
        "solver": "tamaas-pkr",
        "n": n,
        "time": t_solve,
        "iterations": iterations,
        "fft_pairs": (2 * iterations + 1) if iterations is not None else None,
        "tamaas_error": float(err),
        "tamaas_error_final": err_final,
        "converged": bool(err <= args.tol),
        "tol": args.tol,
        "tamaas_version": tm.__version__,
        "mean_pressure": float(p.mean()),
        "mean_pressure_rel_err": float(abs(p.mean() - P) / abs(P)) if P else None,
        "p_min": float(p.min()),
        "gap_min": float(gap.min()),
        "compl_rel": float(abs(np.sum(p * gap)) / (psum * hstd)) if psum * hstd > 0 else None,
        "contact_fraction": float(np.mean(p > 0)),
        "delta": delta,
    }
    if not args.no_check:
        v_np = _westergaard_np(p, L, estar)
        res["kernel_check"] = float(np.linalg.norm(v_np - v) / max(np.linalg.norm(v), 1e-300))
    if iterations is None:
        res["log_tail"] = log[-500:]
    if args.out:
        np.savez(args.out, pressure=p, gap=gap, displacement=v, h=h, delta=delta,
                 tamaas_displacement=U)
    print(json.dumps(res), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
