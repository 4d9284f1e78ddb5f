"""Stability matrix: extreme, stiff and ill-posed cases; each converges or says why not.

Every case runs in its own process (``--case NAME``) under a wall-time bound
(``--timeout``, default 90 s): a case that hangs or crashes is reported as
such and the matrix goes on.  Each case prints one JSON line (parameters,
outcome, the error measures, the force against an independent truth where
one exists, the resolution warnings raised); the parent collects them and
writes a markdown table (``--markdown FILE``).

    .venv/bin/python run_scripts/checks/stability_matrix.py --markdown /tmp/matrix.md
    .venv/bin/python run_scripts/checks/stability_matrix.py --only tabor        # a subset
    .venv/bin/python run_scripts/checks/stability_matrix.py --case tabor-1-lj   # one case, in-process

Units: Greenwood's (E* = z0 = 1) unless the case says SI.  Truths: the
Maugis-Dugdale pull-off at lambda = 1.16 mu (DMT -2 pi R w at small mu),
Hertz as w -> 0, the Derjaguin force 2 pi R Phi(gap) of a detached sphere,
Westergaard's full contact of a wavy surface, the law itself on a flat cell.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import time
import warnings

import numpy as np

from contactpetsc.physics.resolution import check_resolution

HERE = os.path.abspath(__file__)


# -- helpers (run inside a case's process) -----------------------------------------------------------
BUDGET = 0.0   # [s] each adhesive problem's -<prefix>time_budget (set by --budget)


def _lib():
    from contactpetsc.geometry import surfaces
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.physics import closed_forms as maugis, interactions
    from contactpetsc.solvers.adhesive import AdhesiveProblem

    def budgeted(*args, prefix="adhesion_", **kw):
        """AdhesiveProblem under the case's wall-time budget: the solver itself ends a case
        that cannot converge, with its reason, before the harness has to kill it."""
        from petsc4py import PETSc
        opts = PETSc.Options(prefix)
        if BUDGET and not opts.hasName("time_budget"):
            opts.setValue("time_budget", repr(BUDGET))
        return AdhesiveProblem(*args, prefix=prefix, **kw)
    return surfaces, SurfaceGrid, interactions, maugis, budgeted


def _errors(states) -> dict:
    """The largest error measures over the converged states of a path [z0]."""
    conv = [s for s in states if s.converged] or states
    return {"complementarity_error": max(s.complementarity_error for s in conv),
            "adhesive_error": max(s.adhesive_error for s in conv),
            "total_error": max(s.total_error for s in conv)}


def _outcome(states, solves=None) -> dict:
    """Outcome of a path: ``states`` its steps (AdhesiveState or paths.PathPoint), ``solves`` every
    AdhesiveState behind them (with jump bisections), for iteration counts and failure reasons."""
    solves = states if solves is None else solves
    failed = [s for s in states if not s.converged]
    reason = solves[-1].reason
    if failed:
        reason = next((s.reason for s in solves if not s.converged and s.approach == failed[0].approach),
                      "not converged")
    out = {"converged": not failed, "steps": len(states), "failed_steps": len(failed),
           "newton_iterations": sum(s.newton_iterations for s in solves),
           "fallbacks": sum(s.solver.endswith(("+ptc", "+relaxation")) for s in states),
           "reason": reason, "first_failure_approach": failed[0].approach if failed else None}
    out.update(_errors(states))
    end = states[-1]
    out["end_contact_fraction"] = end.contact_fraction
    # detached: no node in repulsive contact at the end of the path
    out["detached"] = bool(end.converged and end.contact_fraction == 0.0)
    return out


def _recorded(pb) -> list:
    """Every AdhesiveState ``pb.solve`` returns from now on (appended to the returned list)."""
    solves, solve = [], pb.solve

    def recording(**kw):
        st = solve(**kw)
        solves.append(st)
        return st
    pb.solve = recording
    return solves


def _truth(value, truth, tol, what, scale=None) -> dict:
    """The relative difference from ``truth`` (from zero: |value| / scale)."""
    rel = value / truth - 1.0 if scale is None else abs(value - truth) / scale
    return {"value": value, "truth": truth, "truth_kind": what, "rel_diff": rel, "truth_tol": tol,
            "truth_ok": bool(abs(rel) <= tol)}


def _sphere(n, dx, radius, e_star, law_name, w, z0, prefix, **kw):
    surfaces, SurfaceGrid, interactions, _, AdhesiveProblem = _lib()
    grid = SurfaceGrid(n, n, dx, periodic=False)
    law = interactions.make_law(law_name, work_of_adhesion=w, z0=z0)
    check_resolution(law, e_star, dx, radius=radius)
    return AdhesiveProblem(grid, surfaces.sphere(grid, radius), e_star, law, prefix=prefix, **kw)


def _pull_off_case(mu, law_name, solver="newton", n=64, dx=1.0, radius=20.0, step=None,
                   z0=1.0, e_star=1.0):
    """Load a sphere to about its JKR pull-off force, unload past pull-off; the most tensile
    force of the path against Maugis-Dugdale (lambda = 1.16 mu)."""
    from contactpetsc.paths import sweep
    from contactpetsc.pull_off import refine_pull_off
    _, _, interactions, maugis, _ = _lib()
    w = np.sqrt(mu ** 3 * e_star ** 2 * z0 ** 3 / radius)
    pb = _sphere(n, dx, radius, e_star, law_name, w, z0, "sm_")
    # the relaxation has no pull-off refinement (it relaxes wherever it goes): finer samples
    step = step or (0.25 if solver == "newton" else 0.1) * z0 * max(1.0, mu / 2.0)
    top = max(z0, 2.0 * (np.pi * w * radius * 1.5 / (4.0 / 3.0 * e_star * np.sqrt(radius))) ** (2.0 / 3.0))
    bottom = -(2.0 + 2.0 * mu) * z0
    approaches = np.concatenate([np.arange(-z0, top + 1e-12, step), np.arange(top - step, bottom - 1e-12, -step)])
    if solver == "newton":
        solves = _recorded(pb)
        path = sweep(pb, approaches)
        states = path.points
        pull = refine_pull_off(pb, path, xtol=0.01 * step)
        jumps = [j.kind for j in path.jumps]
    else:
        from contactpetsc.solvers.relaxation import RelaxationSolver
        relax = RelaxationSolver(pb, max_cycles=3000)
        states = []
        for d in approaches:
            states.append(relax.solve(approach=float(d), raise_on_failure=False))
            if not states[-1].converged:
                break
        pull = min(s.force for s in states if s.converged) if any(s.converged for s in states) else np.nan
        jumps = []
        solves = states
    md = maugis.maugis_pull_off(radius, w, 1.16 * mu)
    out = {"mu": mu, "w_over_Ez0": w / (e_star * z0), "dx_over_z0": dx / z0, "n": n, "jumps": jumps}
    out.update(_outcome(states, solves))
    # LJ against the Dugdale law: a few per cent apart in the resolved range (docs/validation.md)
    out.update(_truth(pull, md, 0.08, "Maugis-Dugdale pull-off" + ("" if solver == "newton" else " (sampled)")))
    return out


# -- the cases -------------------------------------------------------------------------------------------
CASES = {}


def case(name, group, what, no_equilibrium=False):
    """Register a case; ``no_equilibrium``: none exists, the outcome to check is a clear reason."""
    def deco(fn):
        CASES[name] = (group, what, fn, no_equilibrium)
        return fn
    return deco


for _mu, _n, _dx in ((0.01, 64, 1.0), (0.1, 64, 1.0), (1.0, 96, 0.5), (5.0, 64, 1.0), (20.0, 64, 2.0)):
    for _law in ("lj", "hardwall-lj"):
        case(f"tabor-{_mu:g}-{_law}", "Tabor", f"sphere R = 20 z0, mu = {_mu:g}, {_law}, Newton, "
             f"{_n}^2, dx = {_dx:g} z0: load-unload, pull-off")(
            lambda mu=_mu, law=_law, n=_n, dx=_dx: _pull_off_case(mu, law, n=n, dx=dx))
for _mu, _n, _dx in ((0.01, 64, 1.0), (0.1, 64, 1.0), (1.0, 96, 0.5)):
    case(f"tabor-{_mu:g}-relaxation", "Tabor", f"as tabor-{_mu:g}-hardwall-lj, the paper's relaxation solver")(
        lambda mu=_mu, n=_n, dx=_dx: _pull_off_case(mu, "hardwall-lj", solver="relaxation", n=n, dx=dx))
case("under-resolved-z0", "resolution", "mu = 1, z0 = dx / 4 (range below the grid spacing), hardwall-lj")(
    lambda: _pull_off_case(1.0, "hardwall-lj", n=64, dx=1.0, z0=0.25, radius=20.0))


@case("w-tiny-hardwall-lj", "w/(E* z0)", "sphere, w = 1e-8 E* z0, hardwall-lj: Hertz at delta = 2 z0")
def _w_tiny(law_name="hardwall-lj"):
    _, _, _, maugis, _ = _lib()
    radius = 200.0
    pb = _sphere(64, 1.0, radius, 1.0, law_name, 1e-8, 1.0, "wt_")
    st = pb.solve(approach=2.0, raise_on_failure=False)
    out = {"w_over_Ez0": 1e-8}
    out.update(_outcome([st]))
    # a = sqrt(R delta) = 20 dx: the contact is resolved, the discrete Hertz force close to the closed form
    out.update(_truth(st.force, float(maugis.hertz_force(1.0, radius, 2.0)), 0.02, "Hertz force"))
    return out


case("w-tiny-lj", "w/(E* z0)", "as w-tiny-hardwall-lj with the full LJ curve (its wall is 1e-8 E* soft)")(
    lambda: _w_tiny("lj"))


@case("w-huge-hardwall-lj", "w/(E* z0)", "flat-ish periodic wavy cell, w = 10 E* z0, hardwall-lj, approach 0")
def _w_huge(law_name="hardwall-lj"):
    surfaces, SurfaceGrid, interactions, _, AdhesiveProblem = _lib()
    grid = SurfaceGrid(64, 64, 1.0, periodic=True)
    lam = grid.lengths[0]
    h = surfaces.from_function(grid, lambda x, y: 2.0 * (1 - np.cos(2 * np.pi * x / lam)))
    law = interactions.make_law(law_name, work_of_adhesion=10.0, z0=1.0)
    check_resolution(law, 1.0, 1.0, rms_slope=2 * np.pi * 2.0 / lam / np.sqrt(2))
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="wh_")
    states = [pb.solve(approach=d, raise_on_failure=False) for d in (-0.5, 0.0)]
    out = {"w_over_Ez0": 10.0}
    out.update(_outcome(states))
    return out


case("w-huge-lj", "w/(E* z0)", "as w-huge-hardwall-lj with the full LJ curve")(lambda: _w_huge("lj"))


def _rough(rms, law_name):
    surfaces, SurfaceGrid, interactions, _, AdhesiveProblem = _lib()
    grid = SurfaceGrid(64, 64, 1.0, periodic=True)
    if rms == 0:
        h = grid.create_vec(0.0)
        slope = None
    else:
        h = surfaces.self_affine(grid, hurst=0.8, seed=4, rms_height=rms, rolloff_wavelength=16.0)
        hs = grid.gather(h)
        slope = float(np.sqrt(np.mean(np.gradient(hs, axis=0) ** 2 + np.gradient(hs, axis=1) ** 2)))
    w = 0.05
    law = interactions.make_law(law_name, work_of_adhesion=w, z0=1.0)
    check_resolution(law, 1.0, 1.0, rms_slope=slope)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="rr_")
    # approach: the highest summit (min h = 0) touches at 0; then into the rough layer
    approaches = [-1.0, -0.5, 0.0, 0.25] if rms == 0 else list(np.array([-1.0, 0.0, 0.5, 1.0, 2.0]) * max(rms, 1.0))
    states = []
    for d in approaches:
        states.append(pb.solve(approach=float(d), raise_on_failure=False))
        if not states[-1].converged:
            break
    out = {"rms_over_z0": rms, "rms_slope": slope, "w_over_Ez0": w}
    out.update(_outcome(states))
    if rms == 0 and law_name == "lj" and states[-1].converged:
        # a flat cell: uniform gap -delta, the mean pressure is the law's pressure there, exactly
        out.update(_truth(states[-1].mean_pressure, float(law.pressure(-approaches[-1])), 1e-8,
                          "law p(-delta) on a flat cell"))
    return out


for _rms in (0.0, 1.0, 10.0, 100.0):
    for _law in ("lj", "hardwall-lj"):
        if _rms == 0 and _law == "hardwall-lj":
            continue   # a flat hard wall in a periodic cell has no contact pressure to find (see full-contact)
        case(f"rough-{_rms:g}-{_law}", "roughness", f"self-affine periodic 64^2, rms {_rms:g} z0 (roll-off 16 z0), "
             f"w = 0.05 E* z0, {_law}: approach into the rough layer")(lambda r=_rms, law=_law: _rough(r, law))


@case("near-zero-load-signorini", "loads", "sphere, no adhesion, mean pressure 1e-9 E* (one node in contact)")
def _near_zero_signorini():
    from contactpetsc.geometry import surfaces
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.solvers import ContactProblem
    grid = SurfaceGrid(64, 64, 1.0, periodic=False)
    pb = ContactProblem(grid, surfaces.sphere(grid, 100.0), 1.0, prefix="nz_")
    target = 1e-9 * 64 * 64
    st = pb.solve(force=target, raise_on_failure=False)
    return {"converged": st.converged, "reason": st.reason, "complementarity_error": st.complementarity_error,
            "newton_iterations": st.newton_iterations, "end_contact_fraction": st.contact_fraction,
            **_truth(st.force, target, 1e-6, "prescribed force")}


def _mu01_sphere(law_name, prefix):
    """(problem, R, w): a sphere R = 20 z0 at mu = 0.1 (E* = z0 = 1), 64^2 nodes, dx = z0."""
    radius = 20.0
    w = np.sqrt(0.1 ** 3 / radius)
    return _sphere(64, 1.0, radius, 1.0, law_name, w, 1.0, prefix), radius, w


@case("near-zero-load-adhesive", "loads", "sphere mu = 0.1, hardwall-lj, load control at zero net force")
def _near_zero_adhesive():
    _, _, _, maugis, _ = _lib()
    pb, radius, w = _mu01_sphere("hardwall-lj", "nza_")
    pb.solve(approach=0.5)
    st = pb.solve_force(0.0, raise_on_failure=False)
    out = _outcome([st])
    out.update(_truth(st.force, 0.0, 1e-6, "zero net force, in 2 pi R w", scale=2 * np.pi * radius * w))
    # for information: DMT (Muller et al.), the approach where the Hertz load balances the adhesive
    # force; the contact is a few nodes wide at this load, and mu = 0.1 is not quite DMT
    lo, hi = 1e-6, 5.0       # bisection: F_DMT rises with the approach
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if maugis.dmt_force(pb.law, 1.0, radius, mid)[0] < 0 else (lo, mid)
    out["approach_over_dmt"] = st.approach / (0.5 * (lo + hi))
    return out


@case("beyond-pull-off-displacement", "loads", "sphere mu = 0.1, lj: loaded, then pulled to delta = -6 z0")
def _beyond_displacement(law_name="lj"):
    _, _, _, maugis, _ = _lib()
    from contactpetsc.paths import sweep
    pb, radius, w = _mu01_sphere(law_name, "bd_")
    solves = _recorded(pb)
    path = sweep(pb, [-1.0, 0.0, 0.5, 0.0, -1.0, -2.0, -4.0, -6.0])
    st = path.points[-1]
    out = _outcome(path.points, solves)
    # detached: the law summed over the rigid sphere's gap h + 6 z0 on the same window (the
    # deformation is ~ mu^1.5 smaller); Derjaguin's 2 pi R Phi(6 z0) for the infinite plane
    grid = pb.grid
    rigid = grid.mpi_comm.allreduce(float(pb.law.pressure(grid.rows(pb.heights, readonly=True) + 6.0).sum()))
    out.update(_truth(st.force, rigid * grid.element_area, 0.01, "rigid sphere's force on the window"))
    out["over_derjaguin"] = st.force / float(maugis.dmt_force(pb.law, 1.0, radius, -6.0)[0])
    return out


case("beyond-pull-off-displacement-hw", "loads", "as beyond-pull-off-displacement with hardwall-lj")(
    lambda: _beyond_displacement("hardwall-lj"))


@case("beyond-pull-off-force", "loads", "sphere mu = 0.1, hardwall-lj: load control at 1.5 x the pull-off force",
      no_equilibrium=True)
def _beyond_force():
    _, _, _, maugis, _ = _lib()
    pb, radius, w = _mu01_sphere("hardwall-lj", "bf_")
    pb.solve(approach=0.5)
    st = pb.solve_force(1.5 * maugis.dmt_pull_off(radius, w), raise_on_failure=False)
    out = _outcome([st])
    out["clear_reason"] = "LOAD_CONTROL_UNSTABLE" in st.reason
    return out


@case("full-contact-signorini", "full contact", "wavy periodic cell, no adhesion, mean pressure 2 p* (full contact)")
def _full_signorini():
    from contactpetsc.geometry import surfaces
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.solvers import ContactProblem
    grid = SurfaceGrid(64, 32, 1.0, periodic=True)
    lam, amp = grid.lengths[0], 1.0
    h = surfaces.from_function(grid, lambda x, y: amp * (1 - np.cos(2 * np.pi * x / lam)))
    p_star = np.pi * amp / lam          # Johnson 13.3 with E* = 1: full contact from p* on
    st = ContactProblem(grid, h, 1.0, prefix="fc_").solve(mean_pressure=2 * p_star, raise_on_failure=False)
    p = grid.gather(st.pressure)
    x = np.arange(grid.nx)[:, None] * grid.dx
    exact = 2 * p_star + p_star * np.cos(2 * np.pi * x / lam)   # highest where h is lowest
    err = float(np.max(np.abs(p - exact)) / p_star)
    return {"converged": st.converged, "reason": st.reason, "complementarity_error": st.complementarity_error,
            "newton_iterations": st.newton_iterations, "end_contact_fraction": st.contact_fraction,
            "value": err, "truth": 0.0, "truth_kind": "max |p - (p_mean + p* cos)| / p* (Westergaard)",
            "rel_diff": err, "truth_tol": 1e-6, "truth_ok": err <= 1e-6}


@case("full-contact-lj-flat", "full contact", "flat periodic cell, lj, pressed 0.3 z0 into the wall")
def _full_lj():
    surfaces, SurfaceGrid, interactions, _, AdhesiveProblem = _lib()
    grid = SurfaceGrid(32, 32, 1.0, periodic=True)
    law = interactions.make_law("lj", work_of_adhesion=0.05, z0=1.0)
    pb = AdhesiveProblem(grid, grid.create_vec(0.0), 1.0, law, prefix="fl_")
    st = pb.solve(approach=0.3, raise_on_failure=False)
    out = _outcome([st])
    out.update(_truth(st.mean_pressure, float(law.pressure(-0.3)), 1e-8, "law p(-delta) on a flat cell"))
    return out


@case("full-contact-hardwall-overpressed", "full contact",
      "wavy periodic cell, hardwall-lj, approach beyond the mean height: no equilibrium exists",
      no_equilibrium=True)
def _overpressed():
    surfaces, SurfaceGrid, interactions, _, AdhesiveProblem = _lib()
    grid = SurfaceGrid(32, 32, 1.0, periodic=True)
    lam = grid.lengths[0]
    h = surfaces.from_function(grid, lambda x, y: 1 - np.cos(2 * np.pi * x / lam))
    law = interactions.make_law("hardwall-lj", work_of_adhesion=0.05, z0=1.0)
    pb = AdhesiveProblem(grid, h, 1.0, law, prefix="op_")
    # mean gap = mean h - delta (K has no mean mode): delta = 1.5 > mean h = 1 cannot keep g >= 0
    st = pb.solve(approach=1.5, raise_on_failure=False)
    out = _outcome([st])
    # a clear reason says why: the mean gap would be negative / the approach exceeds the mean height
    out["clear_reason"] = not st.converged and "mean" in st.reason
    return out


def _material(e_star, name, maxstep=None):
    """SI: a sphere R = 30 nm, z0 = 0.3 nm, w = 0.1 J/m^2 on materials of modulus E*: loaded to
    1 z0 and pulled off in steps of z0 / 4, the pull-off refined (Newton).  ``maxstep``: PETSc's
    line-search step limit (-snes_linesearch_maxstep, default 1e8 in the unknowns' units, Pa)."""
    from contactpetsc.paths import sweep
    from contactpetsc.pull_off import refine_pull_off
    from petsc4py import PETSc
    _, _, interactions, maugis, _ = _lib()
    if maxstep is not None:
        PETSc.Options(f"mat{name}_").setValue("snes_linesearch_maxstep", maxstep)
    radius, z0, w = 30e-9, 0.3e-9, 0.1
    mu = interactions.tabor_parameter(radius, w, e_star, z0)
    pb = _sphere(128, z0, radius, e_star, "hardwall-lj", w, z0, f"mat{name}_")   # window edge gap 20 z0
    solves = _recorded(pb)
    path = sweep(pb, np.concatenate([np.arange(-1.0, 1.01, 0.25), np.arange(0.75, -3.01, -0.25)]) * z0)
    pull = refine_pull_off(pb, path, xtol=0.0025 * z0)
    out = {"e_star_Pa": e_star, "mu": mu, "w_over_Ez0": w / (e_star * z0)}
    out.update(_outcome(path.points, solves))
    out.update(_truth(pull, maugis.maugis_pull_off(radius, w, 1.16 * mu), 0.08, "Maugis-Dugdale pull-off"))
    return out


case("stiff-1TPa", "materials", "SI sphere R 30 nm, w 0.1 J/m^2, z0 0.3 nm, E* = 1e12 Pa (mu 0.02)")(
    lambda: _material(1e12, "stiff"))
case("stiff-1TPa-maxstep", "materials", "as stiff-1TPa with -snes_linesearch_maxstep 1e300 (no step limit)")(
    lambda: _material(1e12, "stiffmax", maxstep="1e300"))
case("soft-1MPa", "materials", "as stiff-1TPa with E* = 1e6 Pa (mu ~ 220: JKR, under-resolved)")(
    lambda: _material(1e6, "soft"))


# -- driver ------------------------------------------------------------------------------------------
def run_case(name) -> dict:
    group, what, fn, no_equilibrium = CASES[name]
    t0 = time.perf_counter()
    caught = []

    def show(message, category, *args, **kw):
        # printed at once too: a case killed at its time bound still shows its warnings
        caught.append(message)
        print(f"{category.__name__}: {message}", file=sys.stderr, flush=True)

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        warnings.showwarning = show
        try:
            out = fn()
        except Exception as exc:  # noqa: BLE001 - a case that raises is reported, not hidden
            out = {"converged": False, "reason": f"raised {type(exc).__name__} (no state returned): {exc}"}
    out.update(case=name, group=group, what=what, no_equilibrium=no_equilibrium, time_s=time.perf_counter() - t0,
               warnings=sorted({str(m) for m in caught if "under-resolved" in str(m)}))
    out["under_resolved"] = bool(out["warnings"])
    return out


def verdict(r: dict) -> str:
    if r.get("timeout"):
        return f"TIMEOUT (> {r['timeout']:g} s)"
    if r.get("no_equilibrium"):
        ok = not r.get("converged") and r.get("clear_reason")
        return "no equilibrium, clear reason" if ok else "no equilibrium, UNCLEAR reason"
    out = "converged" if r.get("converged") else "FAILED"
    if r.get("detached"):
        out += ", detached at the end"
    if "truth_ok" in r and not r["truth_ok"]:
        out += ", OFF the truth"
    return out


def markdown(rows) -> str:
    lines = ["| case | what | outcome | reason | errors c / a / E_Total [z0] | vs truth | Newton | "
             "warn | time [s] |", "|---|---|---|---|---|---|---:|---|---:|"]
    for r in rows:
        errs = "/".join(f"{r[k]:.1e}" if isinstance(r.get(k), float) else "-"
                        for k in ("complementarity_error", "adhesive_error", "total_error"))
        truth = (f"{r['truth_kind']}: {100 * r['rel_diff']:+.2f} % (tol {100 * r['truth_tol']:g} %)"
                 if "truth_kind" in r and r["truth_kind"] and np.isfinite(r.get("rel_diff", np.nan)) else "")
        lines.append(f"| {r['case']} | {r.get('what', '')} | {verdict(r)} | {str(r.get('reason', ''))[:90]} | "
                     f"{errs} | {truth} | {r.get('newton_iterations', '')} | "
                     f"{'under-resolved' if r.get('under_resolved') else ''} | {r.get('time_s', 0):.1f} |")
    return "\n".join(lines)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--case", help="run one case in this process and print its JSON line")
    ap.add_argument("--only", default="", help="run the cases whose name contains this")
    ap.add_argument("--timeout", type=float, default=90.0, help="wall-time bound per case [s]")
    ap.add_argument("--budget", type=float, default=None,
                    help="solver wall-time budget per case [s] (-<prefix>time_budget; default: "
                         "the timeout less 15 s, leaving the harness's bound for hangs)")
    ap.add_argument("--markdown", help="write the markdown table here")
    ap.add_argument("--list", action="store_true")
    args, petsc_args = ap.parse_known_args(argv)
    if args.list:
        for name, (group, what, *_) in CASES.items():
            print(f"{name:34s} {group:12s} {what}")
        return 0
    budget = max(args.timeout - 15.0, 0.5 * args.timeout) if args.budget is None else args.budget
    if args.case:
        global BUDGET
        BUDGET = budget
        import petsc4py
        petsc4py.init([sys.argv[0]] + petsc_args)
        print(json.dumps(run_case(args.case), default=float), flush=True)
        return 0
    rows = []
    for name in CASES:
        if args.only not in name:
            continue
        t0 = time.perf_counter()
        try:
            proc = subprocess.run([sys.executable, HERE, "--case", name, "--budget", repr(budget)] + petsc_args,
                                  capture_output=True,
                                  text=True, timeout=args.timeout)
            lines = [ln for ln in proc.stdout.splitlines() if ln.startswith("{")]
            if lines:
                row = json.loads(lines[-1])
            else:
                tail = (proc.stderr.strip().splitlines() or ["no output"])[-1]
                row = {"case": name, "converged": False, "reason": f"crashed (exit {proc.returncode}): {tail}"}
        except subprocess.TimeoutExpired as exc:
            err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
            warned = sorted({ln.split(": ", 1)[1] for ln in err.splitlines() if ln.startswith("UnderResolvedWarning")})
            row = {"case": name, "converged": False, "timeout": args.timeout, "warnings": warned,
                   "under_resolved": bool(warned),
                   "reason": f"no result within the {args.timeout:g} s wall-time bound (process killed)"}
        row.setdefault("what", CASES[name][1])
        row.setdefault("no_equilibrium", CASES[name][3])
        row.setdefault("time_s", time.perf_counter() - t0)
        rows.append(row)
        print(json.dumps(row, default=float), flush=True)
    table = markdown(rows)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(f"<!-- {platform.node()} {platform.processor() or platform.machine()}, "
                    f"{os.cpu_count()} cores, {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())} -->\n")
            f.write(table + "\n")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(main())
