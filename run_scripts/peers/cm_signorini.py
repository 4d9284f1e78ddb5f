#!/usr/bin/env python3
"""Peer runner: periodic frictionless non-adhesive contact with ContactMechanics' bound-constrained CG.

Run with the ContactMechanics peer venv (see setup_peers.sh), e.g.::

    ~/.cache/contactpetsc/peer-venv-cm/bin/python run_scripts/peers/cm_signorini.py \
        h.npy --length 1.0 --estar 1.0 --mean-pressure 0.005 --tol 1e-8 --out res.npz

The same problem and command line as ``tamaas_signorini.py``: for a periodic
square cell of side L sampled on an n x n grid (pixel size dx = L/n), in our
(contactpetsc) convention

    gap = h + v - delta >= 0,   p >= 0,   p * gap = 0,   mean(p) = P,
    v = K p,  K^(q) = 2 / (E* |q|)  (q != 0),  K^(0) = 0,

with h the composite separation (input .npy, index [i, j] = (x_i, y_j)), p the
compressive pressure, delta the approach (an unknown of the load-controlled
problem) and E* the effective modulus.

Algorithm (ContactMechanics 1.8.3, NuMPI 0.18.1)
------------------------------------------------
NuMPI's ``CCGWithoutRestart.constrained_conjugate_gradients``: the bound-
constrained conjugate gradient of Bugnicourt et al., Tribol. Lett. 66, 29
(2018) (Polak-Ribiere directions, no restart when the active set changes),
on ContactMechanics' *dual* objective (the pixel forces are the unknowns,
``NonSmoothContactSystem.dual_objective`` and ``dual_hessian_product``, whose
gradient is the gap) with ``mean_val`` prescribing the mean pixel force.
This is how ContactMechanics' own tests solve a periodic contact at a
prescribed mean force (``test/test_numpi_ccgs.py::test_using_dual_obj``:
``CCGWithoutRestart.constrained_conjugate_gradients(system.dual_objective(
offset, gradient=True), system.dual_hessian_product, init_pressure,
mean_val=mean_val, gtol=gtol)``); ``dual_minimize_proxy`` wraps the same
call (its default solver ``ccg-without-restart``) but offers only a fixed
offset.  With ``mean_val`` the residual is projected onto zero mean over the
free (p > 0) nodes each iteration, so the offset drops out (we pass 0) and
the multiplier of the mean constraint is the approach.  ContactMechanics'
older ``ConstrainedConjugateGradients`` (``minimize_proxy(external_force=)``)
is Polonsky-Keer with restarts, the algorithm of Tamaas' PKR peer, with
Tamaas' count of operator evaluations on the benchmark surface and more than
this one; so is NuMPI's ``CCGWithRestart`` (docs/performance.md).

Mapping
-------
* Units: the peer runs in reduced units (length dx, pressure E*): heights
  h/dx, pixel force p/E* (pixel area 1), so that NuMPI's absolute
  tolerances (the mean projection's bisection stops at |Phi| < 1e-14 after
  bracketing from [-1, 1]) act on numbers of order one at every n: in
  physical units (pixel forces P dx^2, tiny) the same solver took several
  times the iterations on the benchmark surface, or stalled (cause not
  analysed).  The problem is scale-invariant; fields are scaled
  back before output.
* Substrate: ``PeriodicFFTElasticHalfSpace((n, n), young=1, physical_sizes=
  (n, n))``; with poisson = 0 ``young`` is the contact modulus, and its
  Green's function 1 / (pi E* |k|), k = 1/wavelength, is our 2 / (E* |q|)
  (checked on one Fourier mode at start-up: ``kernel_check``).  Its q = 0
  entry (``stiffness_q0``, default the lowest non-zero stiffness) only adds
  a constant to the displacement, which the mean projection removes.
* Surface: the peer's gap (dual gradient) is ``disp - heights - offset``
  with ``disp = K p``; ``heights = -h/dx`` makes it our gap up to a constant.
* Start: the uniform pressure P (feasible, the prescribed mean).
* Tolerance: ``gtol = --tol * std(h) / dx``: the solver stops when the
  largest projected residual (the gap minus its free-node mean on free
  nodes, a negative gap on bound nodes) is below --tol of the rms height,
  close to our complementarity measure.
* Approach: the solver does not return the multiplier; it is recomputed as
  the same free-node mean from the returned pressure,
  delta = mean_{p > 0}(h + v), with v = K p of zero mean (one operator
  evaluation after the timed solve, not counted).

``negative_curvature_steps``: iterations where NuMPI warned that the
Hessian is negative along its direction (alpha < 0; its warnings go to
stderr).  Counts: ``fft_pairs`` = every ``evaluate_disp`` / ``evaluate_force`` of the
substrate during the solve (wrapped and counted; each is one forward and one
inverse FFT): one gradient per iteration plus one Hessian product, and the
first gradient, so 2 x iterations + 1.  ``cm_error`` = the solver's own
measure (max |projected residual| of the last iteration) / std(h).  Times:
``solve`` only.  OPENBLAS / OMP / MKL threads default to 1 (set before numpy
is imported); muGrid's FFT engine (PocketFFT) is serial.

Output: one JSON line on stdout; fields pressure, gap, displacement, h, delta
in ``--out``.
"""
import contextlib
import io
import json
import os
import sys
import time

for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

import signorini_cli  # noqa: E402


class CountedSubstrate:
    """Counts the substrate's operator evaluations (one FFT pair each) while ``counting``."""

    def __init__(self, substrate):
        self.calls, self.counting = 0, False
        for name in ("evaluate_disp", "evaluate_force"):
            setattr(substrate, name, self._counted(getattr(substrate, name)))

    def _counted(self, fn):
        def wrapped(*a, **kw):
            self.calls += self.counting
            return fn(*a, **kw)
        return wrapped


def kernel_check(substrate, n):
    """Relative deviation of the substrate's response to one pressure mode from 2/(E*|q|) (reduced units)."""
    x = np.arange(n)
    k1, k2 = 1, 2
    mode = np.cos(2 * np.pi * (k1 * x[:, None] + k2 * x[None, :]) / n)
    disp = substrate.evaluate_disp(-mode)
    disp -= disp.mean()
    expected = 2.0 / (2 * np.pi * np.hypot(k1, k2) / n) * mode
    return float(np.abs(disp - expected).max() / np.abs(expected).max())


def main(argv=None):
    args, h = signorini_cli.parse(__doc__.split("\n")[0], "gtol / std(h): largest projected gap residual relative to the rms height", 100000,
                                  "skip the kernel check on one Fourier mode (one extra FFT pair)", argv)
    n = h.shape[0]
    L, estar, P = args.length, args.estar, args.mean_pressure
    dx = L / n
    hstd = float(np.std(h))

    import ContactMechanics
    import NuMPI
    from ContactMechanics import PeriodicFFTElasticHalfSpace
    from ContactMechanics.Systems import NonSmoothContactSystem
    from NuMPI.Optimization import CCGWithoutRestart
    from SurfaceTopography import Topography

    substrate = PeriodicFFTElasticHalfSpace((n, n), young=1.0, physical_sizes=(n, n))
    counter = CountedSubstrate(substrate)
    system = NonSmoothContactSystem(substrate, Topography(-h / dx, physical_sizes=(n, n)))
    force0 = P / estar                     # pixel force in reduced units = p / E*

    counter.counting = True
    notes = io.StringIO()      # NuMPI prints its warnings to stdout, which carries our JSON line
    with contextlib.redirect_stdout(notes):
        t0 = time.perf_counter()
        res = CCGWithoutRestart.constrained_conjugate_gradients(
            system.dual_objective(0.0, gradient=True), system.dual_hessian_product,
            np.full((n, n), force0), mean_val=force0, gtol=args.tol * hstd / dx, maxiter=args.max_iter)
        t_solve = time.perf_counter() - t0
    counter.counting = False
    sys.stderr.write(notes.getvalue())

    p = res.x.reshape(n, n) * estar
    disp = substrate.evaluate_disp(-res.x.reshape(n, n))
    v = (disp - disp.mean()) * dx          # = K p, zero mean, physical length
    contact = p > 0
    delta = float(np.mean((h + v)[contact])) if contact.any() else float(h.min())
    gap = h + v - delta
    psum = float(p.sum())
    out = {
        "solver": "cm-ccg",
        "n": n,
        "time": t_solve,
        "iterations": int(res.nit),
        "fft_pairs": counter.calls,
        "cm_error": float(np.abs(res.jac).max() * dx / hstd),
        "converged": bool(res.success),
        "message": res.message,
        "negative_curvature_steps": notes.getvalue().count("hessian is negative"),
        "tol": args.tol,
        "cm_version": ContactMechanics.__version__,
        "numpi_version": NuMPI.__version__,
        "mean_pressure": float(p.mean()),
        "mean_pressure_rel_err": float(abs(p.mean() - P) / P),
        "p_min": float(p.min()),
        "gap_min": float(gap.min()),
        "compl_rel": float(abs(np.sum(p * gap)) / (psum * hstd)) if psum * hstd > 0 else None,
        "contact_fraction": float(np.mean(contact)),
        "delta": delta,
    }
    if not args.no_check:
        out["kernel_check"] = kernel_check(substrate, n)
    if args.out:
        np.savez(args.out, pressure=p, gap=gap, displacement=v, h=h, delta=delta)
    print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
