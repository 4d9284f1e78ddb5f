#!/usr/bin/env python3
"""Peer runner: periodic adhesive (Lennard-Jones-type) contact with
ContactMechanics + Adhesion (contact.engineering).

Run with the ContactMechanics peer venv (see setup_peers.sh), e.g.::

    ~/.cache/contactpetsc/peer-venv-cm/bin/python run_scripts/peers/cm_adhesion.py \
        --surface h.npy --dx 1 --e-star 1 --w 0.05 --z0 1 --potential vdw82 \
        --offsets -2.4,-1.1,-0.45 [--gtol 1e-6] [--maxiter 100000] \
        [--maxcor 10] [--core 0.5] [--save-fields DIR]

One JSON line per offset is printed on stdout (nothing else goes to stdout).
Negative offsets may be written "--offsets -1,-0.5" or "--offsets=-1,-0.5".

Problem solved (our, i.e. contactpetsc, convention)
---------------------------------------------------
Periodic nx x ny grid, spacing dx, composite heights h (input .npy, index
[i, j] = (x_i, y_j)), approach delta (the values given by ``--offsets``),
zero-mean elastic displacement v (periodic half-space, v^(q) = 2/(E*|q|) p^(q)
for q != 0, v^(0) = 0), gap and atomic separation

    g = h + v - delta,        z = g + z0,

pressure positive when compressive, no hard wall.  The state is the
stationary point of  (1/2) <v, K^-1 v> + sum_nodes dx^2 Phi(z)  over
zero-mean v, i.e.  K^-1 v = p_law(z) - mean(p_law(z)),  and the mean
pressure (load per area) is mean(p_law(z)).

Interaction laws (both: minimum at z = z0 with Phi(z0) = -w)
-------------------------------------------------------------
``--potential vdw82`` (our ``lj`` law, exact):
    Phi(z) = (w/3) [(z0/z)^8 - 4 (z0/z)^2]
    p(z)   = -Phi'(z) = 8w/(3 z0) [(z0/z)^9 - (z0/z)^3]
  Adhesion class ``VDW82(c_sr, hamaker)`` (Adhesion/Interactions/VdW82.py:101)
  evaluates  V(r) = -hamaker/(12 pi r^2) + c_sr/r^8 ; we set
    c_sr = w z0^8 / 3,   hamaker = 16 pi w z0^2
  (this is exactly Adhesion's own helper ``Lj82(w, z0)``, VdW82.py:134-135,
  which we call); then VDW82.r_min = z0 and V(z0) = -w.
``--potential lj93``:
    Phi(z) = (w/2) (z0/z)^9 - (3w/2) (z0/z)^3
    p(z)   = -Phi'(z) = 9w/(2 z0) [(z0/z)^10 - (z0/z)^4]
  Adhesion class ``LJ93(epsilon, sigma)`` (Adhesion/Interactions/LJ93.py:119)
  evaluates  V(r) = epsilon [ (2/15) (sigma/r)^9 - (sigma/r)^3 ] with the
  minimum at r_min = sigma (2/5)^(1/6) and V(r_min) = -epsilon sqrt(10)/3;
  we set
    sigma = z0 (5/2)^(1/6),   epsilon = 3 w / sqrt(10)
  so that r_min = z0 and V(z0) = -w (checked at start-up, see
  ``law_check`` below).

Both laws are wrapped in Adhesion's ``LinearCorePotential``
(``potential.linearize_core(r_ti)``, Adhesion/Interactions/Cutoff.py), with
r_ti = ``--core`` * z0 (default 0.5, Adhesion's own default r_min/2): for
r < r_ti the energy is continued linearly (constant repulsive pressure).
This only keeps the energy finite when L-BFGS line-search trial points
overshoot to z <= 0 (no bounds can be used, see "zero-mean" below); the
output reports ``core_nodes`` = number of nodes with z < r_ti in the final
state.  If it is 0 the final state is a stationary point of the exact law
(the energies coincide in a neighbourhood); if > 0 the result is NOT a
solution of the pure law and ``converged`` is forced to false (the message
says why).  ``--core 0`` disables the wrapper (raw singular potential).

Mapping to ContactMechanics/Adhesion (ContactMechanics 1.8.3, Adhesion 0.93)
-------------------------------------------------------------------------
* Units: the peer is run in reduced units (length dx, pressure E*, energy
  per area E* dx): h~ = h/dx, z0~ = z0/dx, w~ = w/(E* dx), delta~ = delta/dx.
  Every field is scaled back before output.  So ``--gtol`` is in units of E*
  (see below).  The problem is scale-invariant, so this is exact.
* Substrate: ``PeriodicFFTElasticHalfSpace((nx, ny), young=1, physical_sizes
  =(nx, ny))``.  With the default poisson=0, ``contact_modulus = young /
  (1 - poisson^2) = young`` (FFTElasticHalfSpace.py:272-274), i.e. ``young``
  is E*.  Its stiffness is pi E* |k| with k = 1/wavelength
  (FFTElasticHalfSpace.py:519-521) = E* |q| / 2 with q = 2 pi k: the same
  kernel as ours.  Its q = 0 stiffness (stiffness_q0) never matters here
  because the displacement is kept at zero mean (below).
* Topography: the peer's gap (SystemBase.compute_gap,
  ContactMechanics/Systems.py:123-135) is  gap = u - (heights + offset),
  with u = K p (p = compressive interaction pressure, see Adhesion
  System/Systems.py:233-277: force per pixel = -V'(gap) dx^2 balances
  -substrate.force = K u dx^2).  The peer's ``gap`` is the argument r of the
  potential, i.e. our z.  With u = v:
      z = h + v - delta + z0  =  v - (heights + offset)
  => heights = -h  (SurfaceTopography ``Topography(-h, ...)``, periodic)
     offset  = delta - z0      (reported as ``offset_cm``, physical units).
* Zero-mean displacement (our delta is measured to the mean plane of the
  deformed surface).  The peer's ``minimize_proxy`` minimises over all u,
  including its mean, which is then held by the artificial q = 0 spring
  (stiffness_q0, default = lowest non-zero stiffness), so its "offset"
  would not be our delta (delta_eff = offset + z0 - mean(u), solution-
  dependent).  We therefore reproduce ``SystemBase.minimize_proxy``
  (ContactMechanics/Systems.py:248-338: scipy.optimize.minimize(
  system.objective(offset, gradient=True), method='L-BFGS-B', jac=True),
  then ``system.evaluate`` as in ``_update_state``) with one change: the
  objective is evaluated at u = x - mean(x) and its gradient is projected,
  g -> g - mean(g) (the chain rule of that re-parametrisation).  Starting
  from a zero-mean x0 all L-BFGS iterates stay zero-mean, so this is
  L-BFGS-B on the zero-mean subspace with the peer's energy and gradient.
  No bounds are passed (a box cannot be combined with the projection), hence
  the linear core above.  The Fourier-space / preconditioned objectives of
  Adhesion (``preconditioned_objective``, ``objective_k_float``) are not
  usable with this version: they need muFFT's half-complex FFT, which the
  muGrid FFTEngine shipped here lacks (Adhesion System/Systems.py:79 guard;
  ``system.stiffness_k`` is never created).
* Solver options: ``gtol`` = L-BFGS-B's projected-gradient tolerance.  The
  gradient is the out-of-balance force per pixel; in the reduced units it is
  the pressure residual r = K^-1 v - (p_law - mean p_law) in units of E*
  (max_i |r_i| <= gtol E* at convergence).  ``ftol = 0`` (as in Adhesion's
  examples, so only gtol / maxiter / line-search failure stop it),
  ``maxcor`` (default 10), ``maxiter`` and ``maxfun = 2 maxiter + 100``.
  ``converged`` = scipy's ``success`` (and core_nodes == 0 and a finite
  state); ``message`` = scipy's message; ``iterations`` = ``nit``;
  ``nfev`` = number of energy+gradient evaluations (one FFT pair each:
  substrate.evaluate_force = fft + ifft; the energy reuses that force);
  ``fft_pairs`` = nfev + 1 (the final ``system.evaluate``).
  Caveat: with ftol = 0 scipy still stops with success=True and "CONVERGENCE:
  RELATIVE REDUCTION OF F <= FACTR*EPSMCH" when the energy no longer
  decreases at all in double precision, possibly before gtol is met.  Hence
  also ``residual_max`` = max|r| / E* (= L-BFGS-B's projected-gradient norm
  in reduced units, recomputed with numpy) and ``gtol_reached`` =
  residual_max <= gtol.
* Warm start: each offset starts from the previous offset's displacement
  (the first one from v = 0, or from ``--initial``: our zero-mean displacement v [m] of a
  state, e.g. the previous state of a path).  Offsets are solved in the order given.
* Timing: ``time`` is perf_counter and ``cpu`` process_time around objective creation + minimize + final
  ``system.evaluate``; excludes imports, system set-up, and the
  post-processing below.  OPENBLAS_NUM_THREADS / OMP_NUM_THREADS /
  MKL_NUM_THREADS default to 1 (set before numpy is imported; an explicit
  environment value wins; reported as ``blas_threads``): L-BFGS-B's many
  small BLAS calls are much slower with several OpenBLAS threads on a
  loaded machine.  The FFTs (muGrid FFTEngine, PocketFFT backend) are
  serial.

Reported quantities (our units and signs)
-----------------------------------------
* ``mean_pressure`` = net interaction force / area
  = system.compute_normal_force() / area = mean(p_law(z)), compressive > 0.
* ``contact_fraction`` = fraction of nodes with z < z0 (our g < 0).  For both
  laws p_law(z) > 0 exactly when z < z0, so this is also the fraction of
  nodes with repulsive pressure (``repulsive_fraction``, from the peer's
  interaction force, is reported too; they can differ only for nodes with
  z == z0 to round-off).
* ``error`` = K_ii * max_i |r_i| / z0 with r = K^-1 v - (p_law(z) -
  mean(p_law(z))) computed with numpy from the returned displacement
  (independent of the peer: our kernel, our law, our gap), and K_ii =
  (1/N) sum_{q != 0} 2/(E* |q|) (self-influence of one node, ~1.12 dx/E* for
  large n).  ``error_kind`` names it.  ``error_rel`` = max|r| / max|p_law|.
* ``law_check``: max relative difference between the peer's interaction
  pressure and our p_law at the final state (checks the parameter mapping).
* ``z_min``, ``core_nodes`` (with ``--core 0``: nodes with z <= 0),
  ``mean_disp`` (should be ~0), ``gap_identity_err`` = max|g - (h + v -
  delta)| (should be round-off), ``nfev``.

With ``--save-fields DIR``: DIR/cm_{delta!r}_gap.npy and
DIR/cm_{delta!r}_pressure.npy (``repr`` of the float approach, e.g.
cm_-1.1_gap.npy): our g and p_law(z) (compressive > 0), plain float64
(nx, ny) arrays -- no pickles, so that any numpy reads them (the peer venv
has numpy 2, ours Debian's 1.24).  The gap path is reported as ``fields``.
Use one DIR per potential.
"""
import argparse
import json
import math
import os
import sys
import time
import warnings

# Single-threaded BLAS unless the caller says otherwise (must precede the numpy
# import).  scipy's L-BFGS-B does many small BLAS calls; with a multi-threaded
# OpenBLAS on a loaded machine they are much slower than single-threaded.
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402


def our_law(potential, z, w, z0):
    """(Phi, p) of our laws, p = -dPhi/dz (compressive > 0)."""
    s = z0 / z
    if potential == "vdw82":
        return (w / 3.0) * (s**8 - 4.0 * s**2), (8.0 * w / (3.0 * z0)) * (s**9 - s**3)
    if potential == "lj93":
        return 0.5 * w * s**9 - 1.5 * w * s**3, (4.5 * w / z0) * (s**10 - s**4)
    raise ValueError(potential)


def make_peer_potential(potential, w, z0):
    from Adhesion.Interactions import LJ93, Lj82
    if potential == "vdw82":
        return Lj82(w, z0)  # = VDW82(c_sr=w z0^8/3, hamaker=16 pi w z0^2)
    if potential == "lj93":
        return LJ93(epsilon=3.0 * w / math.sqrt(10.0), sigma=z0 * 2.5 ** (1.0 / 6.0))
    raise ValueError(potential)


def kernel_q(nx, ny, dx, estar):
    """E*|q|/2 on the rfft grid (q = 0 entry set to 0) and K_ii."""
    qx = 2 * np.pi * np.fft.fftfreq(nx, d=dx)
    qy = 2 * np.pi * np.fft.rfftfreq(ny, d=dx)
    q = np.hypot(qx[:, None], qy[None, :])
    stiff = 0.5 * estar * q
    # K_ii = (1/N) sum over the full q grid (q != 0) of 2/(E*|q|)
    qfx = 2 * np.pi * np.fft.fftfreq(nx, d=dx)
    qfy = 2 * np.pi * np.fft.fftfreq(ny, d=dx)
    qf = np.hypot(qfx[:, None], qfy[None, :])
    qf[0, 0] = np.inf
    kii = float(np.sum(2.0 / (estar * qf)) / (nx * ny))
    return stiff, kii


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--surface", required=True, help=".npy (nx, ny) heights h (our convention)")
    ap.add_argument("--dx", type=float, required=True, help="grid spacing")
    ap.add_argument("--e-star", type=float, required=True, help="effective modulus E*")
    ap.add_argument("--w", type=float, required=True, help="work of adhesion (Phi(z0) = -w)")
    ap.add_argument("--z0", type=float, required=True, help="equilibrium distance")
    ap.add_argument("--potential", choices=("vdw82", "lj93"), required=True)
    ap.add_argument("--offsets", required=True,
                    help="comma-separated approaches delta (OUR convention)")
    ap.add_argument("--gtol", type=float, default=1e-6,
                    help="L-BFGS-B gtol = max pressure residual / E* (default 1e-6)")
    ap.add_argument("--maxiter", type=int, default=100000)
    ap.add_argument("--maxcor", type=int, default=10, help="L-BFGS memory (default 10)")
    ap.add_argument("--core", type=float, default=0.5,
                    help="linear core below r_ti = CORE*z0 (0 = raw potential; default 0.5)")
    ap.add_argument("--save-fields", default=None, metavar="DIR")
    ap.add_argument("--initial", default=None, metavar="V.npy",
                    help="start the first offset from this displacement v [m] (our convention)")
    argv = list(sys.argv[1:] if argv is None else argv)
    for i in range(len(argv) - 1):  # allow "--offsets -1.5,-1" (negative values)
        if argv[i] == "--offsets":
            argv[i:i + 2] = ["--offsets=" + argv[i + 1]]
            break
    args = ap.parse_args(argv)

    h = np.load(args.surface).astype(np.float64)
    if h.ndim != 2:
        ap.error(f"expected a 2-D height array, got shape {h.shape}")
    nx, ny = h.shape
    dx, estar, w, z0 = args.dx, args.e_star, args.w, args.z0
    offsets = [float(s) for s in args.offsets.split(",") if s.strip()]
    if args.save_fields:
        os.makedirs(args.save_fields, exist_ok=True)

    # ---- peer imports and system set-up (not timed) ----
    import scipy.optimize
    from SurfaceTopography import Topography
    from ContactMechanics import PeriodicFFTElasticHalfSpace
    from Adhesion.System import SmoothContactSystem
    import ContactMechanics
    import Adhesion

    # reduced units: length dx, pressure E*, energy/area E* dx
    hr = h / dx
    z0r = z0 / dx
    wr = w / (estar * dx)
    base = make_peer_potential(args.potential, wr, z0r)
    # check the parameter mapping: minimum at z0 with depth -w
    vmin_err = abs(base.r_min - z0r) / z0r + abs(base.v_min + wr) / wr
    if vmin_err > 1e-10:
        raise RuntimeError(f"potential mapping failed: r_min={base.r_min}, v_min={base.v_min}")
    interaction = base.linearize_core(r_ti=args.core * z0r) if args.core > 0 else base
    r_ti = args.core * z0r if args.core > 0 else 0.0

    topo = Topography(-hr, (float(nx), float(ny)), periodic=True)
    substrate = PeriodicFFTElasticHalfSpace((nx, ny), 1.0, physical_sizes=(float(nx), float(ny)))
    system = SmoothContactSystem(substrate, interaction, topo)
    stiff, kii = kernel_q(nx, ny, 1.0, 1.0)  # reduced units
    kii_phys = kii * dx / estar

    x_prev = np.zeros(nx * ny)
    if args.initial:
        v0 = np.load(args.initial).astype(np.float64)
        if v0.shape != h.shape:
            ap.error(f"--initial has shape {v0.shape}, the surface {h.shape}")
        x_prev = v0.ravel() / dx
    for delta in offsets:
        offset_r = (delta - z0) / dx  # peer offset, reduced units
        rec = {"code": "contactmechanics+adhesion", "potential": args.potential,
               "n": nx, "ny": ny, "approach": delta, "offset_cm": delta - z0,
               "w": w, "z0": z0, "e_star": estar, "dx": dx, "gtol": args.gtol,
               "maxcor": args.maxcor, "core": args.core,
               "blas_threads": os.environ.get("OPENBLAS_NUM_THREADS"),
               "versions": f"ContactMechanics {ContactMechanics.__version__}, "
                           f"Adhesion {getattr(Adhesion, '__version__', '?')}, "
                           f"scipy {scipy.__version__}"}
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)
                t0, c0 = time.perf_counter(), time.process_time()
                peer_fun = system.objective(offset_r, gradient=True)

                def fun(x):
                    u = x - x.mean()
                    e, g = peer_fun(u)
                    return e, g - g.mean()

                x0 = x_prev - x_prev.mean()
                sol = scipy.optimize.minimize(
                    fun, x0, method="L-BFGS-B", jac=True,
                    options=dict(gtol=args.gtol, ftol=0.0, maxcor=args.maxcor,
                                 maxiter=args.maxiter, maxfun=2 * args.maxiter + 100))
                u = (sol.x - sol.x.mean()).reshape(nx, ny)
                system.evaluate(u, offset_r, forces=True)  # as in _update_state
                t_solve, c_solve = time.perf_counter() - t0, time.process_time() - c0

            # ---- post-processing (not timed), our units ----
            zr = np.asarray(system.gap, dtype=np.float64)      # peer gap = z/dx
            z = zr * dx
            v = u * dx
            g = z - z0
            p_peer = np.asarray(system.interaction_force) / system.area_per_pt * estar
            _, p_law = our_law(args.potential, z, w, z0)
            # elastic pressure of the displacement (q != 0), our kernel
            p_el = np.fft.irfft2(np.fft.rfft2(u) * stiff, s=(nx, ny)) * estar
            r = p_el - (p_law - p_law.mean())
            finite = bool(np.all(np.isfinite(z)) and np.isfinite(sol.fun))
            core_nodes = int(np.sum(zr < r_ti)) if r_ti > 0 else int(np.sum(zr <= 0))
            converged = bool(sol.success) and finite and core_nodes == 0
            msg = str(sol.message)
            if core_nodes and r_ti > 0:
                msg += f" | {core_nodes} nodes inside the linear core (z < {args.core}*z0)"
            elif core_nodes:
                msg += f" | {core_nodes} nodes with z <= 0 (raw potential, --core 0)"
            if not finite:
                msg += " | non-finite state"
            gap_check = float(np.max(np.abs(g - (h + v - delta))))
            rec.update({
                "time": t_solve,
                "cpu": c_solve,
                "iterations": int(sol.nit),
                "nfev": int(sol.nfev),
                "fft_pairs": int(sol.nfev) + 1,
                "converged": converged,
                "message": msg,
                "mean_pressure": float(system.compute_normal_force()) / system.area_per_pt
                                 / (nx * ny) * estar,
                "mean_pressure_law": float(p_law.mean()),
                "contact_fraction": float(np.mean(z < z0)),
                "contact_fraction_kind": "nodes with z < z0 (g < 0) = nodes with p_law > 0",
                "repulsive_fraction": float(np.mean(p_peer > 0)),
                "error": float(kii_phys * np.max(np.abs(r)) / z0),
                "error_kind": "K_ii*max|p_el - (p_law - mean p_law)|/z0, K_ii=mean_{q!=0} 2/(E*|q|)",
                "error_rel": float(np.max(np.abs(r)) / max(np.max(np.abs(p_law)), 1e-300)),
                "residual_max": float(np.max(np.abs(r)) / estar),
                "gtol_reached": bool(np.max(np.abs(r)) / estar <= args.gtol),
                "K_ii": kii_phys,
                "law_check": float(np.max(np.abs(p_peer - p_law))
                                   / max(np.max(np.abs(p_law)), 1e-300)),
                "z_min": float(np.min(z)),
                "core_nodes": core_nodes,
                "mean_disp": float(v.mean()),
                "gap_identity_err": gap_check,
            })
            if args.save_fields:
                fn = os.path.join(args.save_fields, f"cm_{delta!r}_gap.npy")
                np.save(fn, np.asarray(g, dtype=np.float64))
                np.save(os.path.join(args.save_fields, f"cm_{delta!r}_pressure.npy"),
                        np.asarray(p_law, dtype=np.float64))
                rec["fields"] = fn
            if finite:
                x_prev = u.ravel().copy()
        except Exception as exc:  # never crash: report and go on
            rec.update({"time": None, "iterations": None, "converged": False,
                        "message": f"{type(exc).__name__}: {exc}",
                        "mean_pressure": None, "contact_fraction": None,
                        "error": None, "error_kind": None})
        print(json.dumps(rec), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
