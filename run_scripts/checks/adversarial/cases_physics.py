"""Physics cases: the rigid and the far sphere (classes 1, 3), the flat periodic cell (2, 3),
PETSc's random vector (4), the window edge (7)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np

from .harness import (
    Case, LOST, LOUD, OK, WRONG, Z0, abnormal, adhesive_sphere, api, column, flat_cell,
    judge_refusal, judge_success, read_curve, read_field, run_scene, strict_json, within, z0s)
from .truths import (hertz_force, law_peak, law_pressure, peak_approach, random_signature, rigid_force,
                     rigid_force_bounds, sphere_heights)


# --------------------------------------------------------------------------------------------
# class 1 and 3: the rigid sphere (negligible deformation) and the far sphere
def law_kwargs(scene: dict) -> dict:
    it = scene.get("interaction", {})
    return {k: it[k] for k in ("z0", "rho", "sigma0") if k in it}


def check_rigid_sphere(scene: dict, out: Path, tol: float, no_jumps=False) -> tuple[str, str]:
    """Forces and nodal pressures of every step against the law over the rigid sphere's gap."""
    g, it = scene["geometry"], scene["interaction"]
    law, w, kw = it["law"], it["work_of_adhesion"], law_kwargs(scene)
    h = sphere_heights(g["nx"], g["nx"], g["dx"], g["dx"], g["radius"])
    rows = read_curve(out)
    if len(rows) != len(scene["protocol"]["values"]):
        return LOST, f"{len(rows)} rows in curve.csv for {len(scene['protocol']['values'])} steps"
    truth = [rigid_force_bounds(h, float(r["approach_m"]), g["dx"], g["dx"], law, w, **kw) for r in rows]
    scale = max(abs(t) for t in np.ravel(truth))
    errors = {f"F step {r['step']}": max(lo - float(r["force_N"]), float(r["force_N"]) - hi, 0.0) / scale
              for r, (lo, hi) in zip(rows, truth)}
    peak = law_peak(law, w, **kw)
    for r in rows:
        # the law at the step's own gap (self-consistency), and that gap against the rigid
        # sphere's (negligible deformation): a steep repulsive law amplifies a 1e-4 z0 gap
        # change, so the nodal pressures are not compared with the rigid gap's directly
        path = out / f"step_{int(r['step']):04d}.h5"
        p, gap = read_field(path), read_field(path, "gap")
        errors[f"p(g) step {r['step']}"] = float(np.max(np.abs(p - law_pressure(law, gap, w, **kw)))) / peak
        rigid_gap = h - float(r["approach_m"])
        errors[f"gap/z0 step {r['step']}"] = float(np.max(np.abs(gap - rigid_gap))) / Z0
    verdict, detail = within(errors, tol,
                             "rigid-sphere F (rel. max|F|), nodal p - p(g) (rel. peak), gap (z0)")
    if no_jumps and verdict == OK:
        summary = strict_json(out / "summary.json")
        with open(out / "jumps.csv") as f:
            n_jumps = sum(1 for _ in f) - 1
        if n_jumps or summary.get("jumps"):
            return WRONG, f"{n_jumps} jump(s) in jumps.csv of a sphere never within 10 z0"
        if summary.get("pull_off_force_N") is not None:
            return WRONG, f"pull-off {summary['pull_off_force_N']:.3e} N reported for a far sphere"
        detail += "; no jumps, no pull-off"
    return verdict, detail


def rigid_sphere_case(name, w, e_star, law="lj", values=None, ranks=1, tol=1e-3, klass="1",
                      no_jumps=False, **interaction) -> Case:
    scene = adhesive_sphere(w=w, law=law, e_star=e_star, values=values, **interaction)
    ratio = w / (e_star * Z0)

    def run(d):
        res = run_scene(d, scene, ranks=ranks)
        return judge_success(res, lambda: check_rigid_sphere(scene, d / "out", tol, no_jumps))
    what = "far sphere (min gap 10 z0)" if no_jumps else "rigid sphere"
    return Case(name, klass, f"{law} sphere, w = {w:g} J/m^2, E* = {e_star:g} Pa (w/E*z0 = {ratio:.0e}), "
                f"{ranks} rank(s)",
                f"{what}: F = sum p(h-delta) dxdy, p = p(g) at every node, g = h - delta, "
                f"all within {tol:g}" +
                ("; no jumps, pull-off null" if no_jumps else ""), run, ranks)


FAR = z0s(-30, -25, -20, -15, -12, -10, -12, -15, -20, -25, -30)


def api_weak_adhesion_case(w, ranks) -> Case:
    code = f"""
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc.geometry import surfaces
        from contactpetsc.physics.interactions import make_law
        from contactpetsc.solvers.adhesive import AdhesiveProblem
        grid = SurfaceGrid(32, 32, {Z0!r}, periodic=False)
        problem = AdhesiveProblem(grid, surfaces.sphere(grid, 30e-9), 1e10,
                                  make_law("lj", work_of_adhesion={w!r}, z0={Z0!r}))
        out = []
        for m in (-3, -2, -1, -0.5, 0.0, -1, -3):
            st = problem.solve(approach=m * {Z0!r})
            out.append([st.approach, st.force, bool(st.converged)])
        report({{"states": out}})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code), ranks)

        def check():
            if rep is None:
                return WRONG, "no result printed"
            h = sphere_heights(32, 32, Z0, Z0, 30e-9)
            truth = [rigid_force(h, a, Z0, Z0, "lj", w) for a, _, _ in rep["states"]]
            scale = max(map(abs, truth))
            errors = {f"approach {a / Z0:+.1f} z0": abs(f - t) / scale
                      for (a, f, _), t in zip(rep["states"], truth)}
            if not all(c for *_, c in rep["states"]):
                return LOUD, "some states not converged"
            return within(errors, 1e-3, "API AdhesiveProblem.solve force vs rigid sphere")
        return judge_success(res, check)
    return Case(f"api-weak-adhesion-w{w:g}-np{ranks}", "1", f"AdhesiveProblem.solve, lj, w = {w:g}, "
                f"E* = 1e10, {ranks} rank(s)", "rigid-sphere force within 1e-3", run, ranks)


# --------------------------------------------------------------------------------------------
# class 2 and 3: the flat periodic cell
def flat_case(name, w=0.1, law="lj", values=None, e_star=None, refine=True, ranks=1, klass="2",
              check_forces=True, no_jumps=False, tol=1e-3, method="newton", **interaction) -> Case:
    scene = flat_cell(w=w, law=law, values=values, e_star=e_star, **interaction)
    scene["protocol"]["refine_pull_off"] = refine
    if method != "newton":
        scene["solver"] = {"method": method}
    kw = law_kwargs(scene)
    n = scene["geometry"]["nx"]
    area = (n * Z0) ** 2
    peak = law_peak(law, w, **kw)

    def check(out: Path):
        rows = read_curve(out)
        approaches = column(rows, "approach_m")
        truth = area * law_pressure(law, -approaches, w, **kw)
        errors = {}
        if check_forces:
            errors.update({f"F step {r['step']}": abs(float(r["force_N"]) - t) / (area * peak)
                           for r, t in zip(rows, truth)})
        summary = strict_json(out / "summary.json")
        unloading = [t for r, t in zip(rows, truth) if r["branch"] == "unloading"]
        expected = -area * peak if refine else min(unloading or truth)
        pull = summary.get("pull_off_force_N")
        if law != "dugdale" and max(approaches) < peak_approach(law, **kw) - 1e-9 * Z0:
            # the path turned before the law's peak: the force still fell with the approach
            # there, so no pull-off was reached
            if pull is not None:
                return WRONG, f"pull-off {pull:.4e} N reported for a path that turned short of the peak"
            verdict, detail = within(errors, tol, "flat cell F = A p(-delta), turned short of the peak")
            return verdict, detail + ("; no pull-off reported" if verdict == OK else "")
        if pull is None:
            return WRONG, f"no pull-off reported; expected {expected:.4e} N"
        errors["pull-off"] = abs(pull - expected) / (area * peak)
        verdict, detail = within(errors, tol, f"flat cell F = A p(-delta), pull-off {expected:.4e} N "
                                              f"(reported {pull:.4e})")
        if no_jumps and verdict == OK and summary.get("jumps"):
            return WRONG, f"{len(summary['jumps'])} jump(s) on a smooth flat-cell branch"
        return verdict, detail

    def run(d):
        res = run_scene(d, scene, ranks=ranks)
        return judge_success(res, lambda: check(d / "out"))
    return Case(name, klass, f"flat periodic cell 32^2, {law}, w = {w:g}, E* = "
                f"{scene['material']['e_star']:.2g}, refine_pull_off = {refine}, {method}, {ranks} rank(s)",
                ("pull-off -A x peak" if refine else "pull-off = most tensile sampled unloading state")
                + (", F = A p(-delta) each step" if check_forces else "")
                + (", no jumps" if no_jumps else ""), run, ranks)


def random_vector_case(name, scene, args=(), ranks=1) -> Case:
    def run(d):
        res = run_scene(d, scene, *args, ranks=ranks)
        bad = abnormal(res)
        if bad:
            return bad
        out = d / "out"
        if not (out / "curve.csv").exists():
            return judge_refusal(res, ["tol"])
        rows = read_curve(out)
        for r in rows:
            f = out / f"step_{int(r['step']):04d}.h5"
            if f.exists() and random_signature(read_field(f)):
                return WRONG, (f"step {r['step']} ({r['reason']}, exit {res.rc}): pressure is "
                               "PETSc's random vector (uniform in [0, 1))")
        failed = [r for r in rows if r["converged"] != "True"]
        if res.rc == 0 and not failed:
            return OK, "every step converged; no random data"
        if failed and res.rc == 3:
            return OK, f"{len(failed)} step(s) marked not converged ({failed[0]['reason']}), no random data"
        return WRONG, f"exit {res.rc} but converged flags {[r['converged'] for r in rows]}"
    return Case(name, "4", f"Signorini SNES driven to a line-search/local-min failure "
                f"({' '.join(args) or 'solver.tol'}), {ranks} rank(s)",
                "no step file with p uniform in [0,1); failed steps flagged, exit 3", run, ranks)


def api_random_vector_case() -> Case:
    code = """
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc.geometry import surfaces
        from contactpetsc.solvers import ContactProblem
        grid = SurfaceGrid(32, 32, 2e-9, periodic=False)
        problem = ContactProblem(grid, surfaces.sphere(grid, 1e-6), 1e9, tol=1e-18)
        st = problem.solve(approach=1e-9, raise_on_failure=False)
        p = grid.gather(st.pressure)
        report({"converged": bool(st.converged), "reason": str(st.reason), "p": p.ravel().tolist()})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code))

        def check():
            if rep is None:
                return WRONG, "no result"
            if random_signature(np.array(rep["p"])):
                return WRONG, f"state.pressure is PETSc's random vector ({rep['reason']})"
            return OK, f"converged={rep['converged']} ({rep['reason']}), pressure not random"
        return judge_success(res, check)
    return Case("api-random-vector", "4", "ContactProblem(tol=1e-18).solve(raise_on_failure=False)",
                "state.pressure is the best iterate, not uniform [0,1) noise", run)


# --------------------------------------------------------------------------------------------
# class 7: window edge
WINDOW_WORDS = ("window", "edge")


def window_case(name, scene, expect_warning: bool, hertz_tol=None) -> Case:
    def run(d):
        res = run_scene(d, scene)

        def check():
            warned = any(w in ln.lower() and "%" in ln or w in ln.lower() and "fraction" in ln.lower()
                         for ln in res.text.splitlines() for w in WINDOW_WORDS)
            if hertz_tol is not None:
                rows = read_curve(d / "out")
                g = scene["geometry"]
                errors = {f"step {r['step']}": abs(float(r["force_N"]) / hertz_force(
                    scene["material"]["e_star"], g["radius"], float(r["approach_m"])) - 1)
                    for r in rows}
                verdict, detail = within(errors, hertz_tol, "F / F_Hertz - 1")
                if verdict != OK:
                    return verdict, detail
            if expect_warning and not warned:
                return WRONG, "zone reaches the window edge: no warning with the fraction in the log"
            return OK, "window-edge warning with the fraction" if warned else "no warning needed"
        return judge_success(res, check, allow_rc=(0, 3))
    return Case(name, "7", scene["name"] + f": {scene['geometry']['nx']}^2, dx = "
                f"{scene['geometry']['dx']:g}", ("a window-edge warning with the fraction in the log"
                                                 if expect_warning else "")
                + (f"; F within {hertz_tol:g} of Hertz" if hertz_tol else ""), run)
