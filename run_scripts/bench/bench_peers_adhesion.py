#!/usr/bin/env python3
"""Benchmark: adhesive rough contact against the peers, at equal accuracy on the same equilibrium.

The rough benchmark heights (``rough_surface.py``, periodic, E* = 1) at each of --sizes, w =
--w E* dx, range dx, and per peer the law both codes solve exactly:

* ``tamaas``: hard wall plus exponential attraction (our ``exponential``, rho = dx) against
  Tamaas' PKR on the gap with its exponential adhesion functional
  (``peers/tamaas_adhesion.py``), given the mean gap of our state (it prescribes the mean gap;
  the approach is its unknown);
* ``cm``: the full LJ curve (our ``lj``, z0 = dx) against ContactMechanics + Adhesion, L-BFGS-B
  on the energy (``peers/cm_adhesion.py``), at our approach.

At the approaches giving --areas contact (``rough_surface.calibrate``), two cases:

* ``cold``: from rest.  Ours: a fresh problem with the defaults a scene gets (nested start)
  except the tangent stiffness (``-<prefix>stiffness false``: the peers compute none); its
  stability check is timed apart (``check_cpu``, ``stability_margin``: the peers give no
  verdict).  The peers from their own start.
* ``step``: one step of a path, from the state at approach - --step x range.  Each code solves
  that state first (untimed; ContactMechanics starts from our state there, ``--initial``;
  Tamaas, which cannot be given a start, from its own solution there, whose distance to ours
  is reported), then the approach (timed).

Accuracy: ``error`` = max |g - g_ref| / range against our state polished to 1e-11 (a warm start
from it).  A peer's state within 1e-3 range of the reference is the same equilibrium;
otherwise it is reported as another state with its energy beside ours (the total energy at
the same approach: Tamaas' mean gap fixes it too, its difference to ours is reported).  Equal
accuracy: each peer runs at the tolerances of --tamaas-tol / --cm-gtol in turn until its error
is at most ours, or stops falling (then ours is the more accurate and the ratio favours the
peer), or stops at its iteration cap (the ratio a lower bound); every attempt is a line.  Times are CPU
seconds (``process_time``) of the solve alone; one rank; the peers single-threaded.

    .venv/bin/python run_scripts/bench/bench_peers_adhesion.py --sizes 1024 --peers tamaas cm
    .venv/bin/python run_scripts/bench/bench_peers_adhesion.py --sizes 2048 --peers tamaas --areas 0.05

Peers: ``run_scripts/peers/setup_peers.sh`` (two venvs under ~/.cache/contactpetsc).
"""
import argparse
import os
import sys
import tempfile
import time

import petsc4py

HERE = os.path.dirname(os.path.abspath(__file__))
CACHE = os.path.expanduser("~/.cache/contactpetsc")
ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
ap.add_argument("--sizes", type=int, nargs="+", default=[1024])
ap.add_argument("--peers", nargs="+", default=["tamaas", "cm"], choices=["tamaas", "cm"])
ap.add_argument("--areas", type=float, nargs="+", default=[0.02, 0.05, 0.10])
ap.add_argument("--cases", nargs="+", default=["cold", "step"], choices=["cold", "step"])
ap.add_argument("--w", type=float, default=0.05, help="work of adhesion / (E* dx)")
ap.add_argument("--step", type=float, default=0.1, help="the step case's approach step / range")
ap.add_argument("--tamaas-tol", type=float, nargs="+", default=[1e-8, 1e-9],
                help="Tamaas' tolerances, tried in turn until its error is at most ours")
ap.add_argument("--cm-gtol", type=float, nargs="+", default=[1e-9, 1e-10],
                help="L-BFGS-B's gtol [E*], tried in turn until its error is at most ours")
ap.add_argument("--tamaas-max-iter", type=int, default=100000,
                help="Tamaas' iteration cap: a peer stopped by it reports its error there, and the CPU "
                     "ratio is then a lower bound")
ap.add_argument("--cm-maxiter", type=int, default=100000, help="L-BFGS-B's iteration cap (as --tamaas-max-iter)")
ap.add_argument("--tamaas-python", default=os.path.join(CACHE, "peer-venv", "bin", "python"))
ap.add_argument("--cm-python", default=os.path.join(CACHE, "peer-venv-cm", "bin", "python"))
args, petsc_args = ap.parse_known_args()
petsc4py.init([sys.argv[0]] + petsc_args)

import numpy as np  # noqa: E402
from petsc4py import PETSc  # noqa: E402

from contactpetsc.solvers.adhesive import AdhesiveProblem  # noqa: E402

sys.path.insert(0, HERE)
from bench_args import emit  # noqa: E402
from peer_runs import PEERS, cm_adhesion_command, json_rows  # noqa: E402
from rough_surface import adhesive_law, calibrate, rough_surface  # noqa: E402

assert PETSc.COMM_WORLD.getSize() == 1, "one rank"
SAME = 1e-3   # [range]: a peer's state this close to the reference is the same equilibrium
LAW = {"tamaas": "exponential", "cm": "lj"}


def fields(grid, st):
    return {k: grid.gather(getattr(st, k), root=0) for k in ("gap", "pressure", "displacement")}


def energy(law, h, approach, gap, pressure, dA):
    """Total energy [J] at the approach: 1/2 sum p v dA + sum Phi(g) dA, v = g - h + delta."""
    v = gap - h + approach
    return float(0.5 * np.sum(pressure * v) * dA + np.sum(law.energy(gap)) * dA)


def ours(grid, h, law, approaches, tag):
    """Our states at ``approaches`` in turn on one fresh problem: [(state, its gathered fields)],
    the CPU s of the last solve, and of its stability check (made after it, timed apart: the
    peers give no verdict; the solve is the one a scene's would be where the state is stable,
    which the margin says)."""
    opts = PETSc.Options(f"{tag}_")
    if not opts.hasName("stiffness"):
        opts.setValue("stiffness", False)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix=f"{tag}_")
    out = []
    for d in approaches:
        c = time.process_time()
        st = pb.solve(approach=d, raise_on_failure=False, check_stability=d != approaches[-1])
        cpu = time.process_time() - c
        out.append((st, fields(grid, st)))
    c = time.process_time()
    margin = pb.stability_check.margin()
    return out, cpu, (time.process_time() - c, margin, pb.stability_check.settled)


def polished(grid, h, law, st):
    """Our state ``st`` solved again to 1e-11 from itself: the reference of its equilibrium."""
    ref = AdhesiveProblem(grid, h, 1.0, law, prefix="ref_", tol=1e-11, stability_check=False)
    ref.warm_start(st.contact_pressure, st.adhesive_pressure, st.approach)
    return ref.solve(approach=st.approach, raise_on_failure=False)


def run(cmd):
    rows, err = json_rows(cmd)
    if not rows:
        raise RuntimeError(f"peer failed: {' '.join(cmd[:2])}\n{err}")
    return rows


def tamaas(tmp, n, dx, w, gaps, tol):
    cmd = [args.tamaas_python, os.path.join(PEERS, "tamaas_adhesion.py"), "--surface",
           os.path.join(tmp, "h.npy"), "--dx", repr(dx), "--e-star", "1", "--w", repr(w), "--rho", repr(dx),
           "--mean-gaps", ",".join(repr(g) for g in gaps), "--tol", repr(tol), "--save-fields", tmp,
           "--max-iter", str(args.tamaas_max_iter)]
    rows = run(cmd)
    return rows, [(f["gap"], f["pressure"]) for f in (np.load(os.path.join(tmp, f"tamaas_{i}.npz"))
                                                      for i in range(len(rows)))]


def cm(tmp, n, dx, w, approaches, gtol, initial=None):
    start = None
    if initial is not None:
        start = os.path.join(tmp, "v0.npy")
        np.save(start, initial)
    rows = run(cm_adhesion_command(args.cm_python, os.path.join(tmp, "h.npy"), dx, w, dx, "vdw82", approaches,
                                   tmp, args.cm_maxiter, gtol=gtol, initial=start))
    return rows, [(np.load(os.path.join(tmp, f"cm_{a!r}_gap.npy")), np.load(os.path.join(tmp, f"cm_{a!r}_pressure.npy")))
                  for a in approaches]


def compare(peer, n, grid, h, law, case, area, states, cpu, check, ref):
    """One code against the other at one approach (the last of ``states``, from ``ours``; the
    step case's start before it): our row, then the peer's attempts."""
    dx, hg = grid.dx, grid.gather(h, root=0)
    rf = fields(grid, ref)
    err = lambda g: float(np.abs(g - rf["gap"]).max()) / dx   # noqa: E731
    st, mine = states[-1]
    start = states[0][1] if case == "step" else None
    e_ours = energy(law, hg, st.approach, mine["gap"], mine["pressure"], dx * dx)
    base = dict(peer=peer, n=n, law=law.name, case=case, area=area, approach=st.approach)
    emit(**base, solver=f"contactpetsc ({st.solver})", cpu=cpu, fft_pairs=st.fft_pairs, error=err(mine["gap"]),
         converged=st.converged, check_cpu=check[0], stability_margin=check[1], settled=check[2],
         contact_fraction=st.contact_fraction, energy=e_ours)
    with tempfile.TemporaryDirectory() as tmp:
        np.save(os.path.join(tmp, "h.npy"), hg)
        last = float("inf")
        for tol in (args.tamaas_tol if peer == "tamaas" else args.cm_gtol):
            if peer == "tamaas":
                gaps = ([float(start["gap"].mean())] if start is not None else []) + [float(mine["gap"].mean())]
                rows, gp = tamaas(tmp, n, dx, law.work_of_adhesion, gaps, tol)
                g = [f[0] for f in gp]
                # the same mean gap is the same approach (v has zero mean): energies compare
                extra = dict(approach_difference=(rows[-1]["delta"] - st.approach) / dx,
                             energy=energy(law, hg, rows[-1]["delta"], gp[-1][0], gp[-1][1], dx * dx))
                if start is not None:
                    extra["start_error"] = float(np.abs(g[0] - start["gap"]).max()) / dx
            else:
                v0 = start["displacement"] if start is not None else None
                rows, gp = cm(tmp, n, dx, law.work_of_adhesion, [st.approach], tol, v0)
                g = [gp[-1][0]]
                extra = dict(energy=energy(law, hg, st.approach, gp[-1][0], gp[-1][1], dx * dx),
                             own_error=rows[-1].get("error"))
            e = err(g[-1])
            emit(**base, solver=rows[-1]["solver"] if peer == "tamaas" else "cm+adhesion", tol=tol,
                 cpu=rows[-1]["cpu"], fft_pairs=rows[-1]["fft_pairs"], error=e, converged=rows[-1]["converged"],
                 same_state=e < SAME, cpu_ratio=rows[-1]["cpu"] / cpu, **extra)
            if not rows[-1]["converged"]:
                break   # stopped by its cap: the ratio is a lower bound
            if e <= err(mine["gap"]) or e >= SAME or e > 0.5 * last:
                break   # equal accuracy, another state, or the peer's accuracy stalls (L-BFGS-B
                # stops where the energy no longer falls in double precision)
            last = e


def main():
    for n in args.sizes:
        grid, h, _ = rough_surface(n)
        for peer in args.peers:
            law = adhesive_law(grid, args.w, 1.0, name=LAW[peer])
            approaches = calibrate(grid, h, law, args.areas)
            for area, d in zip(args.areas, approaches):
                for case in args.cases:
                    path = [d - args.step * grid.dx, d] if case == "step" else [d]
                    states, cpu, check = ours(grid, h, law, path, f"{peer}{case}{n}")
                    ref = polished(grid, h, law, states[-1][0])
                    compare(peer, n, grid, h, law, case, area, states, cpu, check, ref)


main()
