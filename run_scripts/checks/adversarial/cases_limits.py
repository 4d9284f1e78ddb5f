"""Limits and messages: the finite layer at any thickness, `contactpetsc plot` on damaged and
failed runs, round-off heights (a detrended plane), maps too small for their fit, fields of
another communicator, and the measured-surface inputs (heights that are the sample's surface,
the harmonic fill, text files, a height file rewritten under a restart).

Truths: the half-space run (a layer much thicker than the cell), the uniform pressure of a
flat periodic cell (p = the load), Hertz for a cap written as the sample's surface, the exact
plane a harmonic fill gives inside a plane (a harmonic function), and the messages naming the
key or file."""
from __future__ import annotations

import json

import numpy as np

from .cases_input import (GOOD_CURVE_HEAD, api_refusal_case, cli_refusal_case, npy, raw_file,
                          refuse_or_match_case)
from .harness import (Case, LOUD, OK, WRONG, cli, judge_refusal, judge_success, merged, message, read_curve,
                      read_field, run_scene, within)
from .truths import hertz_force

DX = 1e-8


def layer_cell(out="out", **material) -> dict:
    """A periodic rough cell on a frictionless layer (E* alone), load control."""
    return {"name": "sweep-layer",
            "geometry": {"kind": "self-affine", "nx": 32, "dx": DX, "rms_slope": 0.1, "seed": 3},
            "material": {"e_star": 5e10, **material},
            "protocol": {"control": "mean_pressure", "values": [1e7, 5e7]},
            "output": {"directory": out}}


def with_layer(thickness):
    def edit(scene):
        scene["material"].update(layer_thickness=thickness, layer_interface="frictionless")
        return scene
    return edit


def file_scene(fname, out="out", values=(1e6,), control="mean_pressure", **geometry) -> dict:
    g = {"kind": "file", "path": fname, "dx": DX, "periodic": True, **geometry}
    return {"name": "sweep-measured", "geometry": g, "material": {"e_star": 1e9},
            "protocol": {"control": control, "values": list(values)}, "output": {"directory": out}}


def plane(nx=16, ny=16, holes=()) -> np.ndarray:
    """A tilted plane [m], indexed [i, j] (the .npy's (nx, ny)); ``holes``: nodes set to NaN."""
    i, j = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    z = 1e-7 + 0.3 * DX * i - 0.1 * DX * j
    for node in holes:
        z[node] = np.nan
    return z


def uniform_pressure(load):
    def accept(d, res):
        if res.rc != 0:
            return LOUD, f"exit {res.rc}: {message(res)}"
        p = read_field(d / "out/step_0001.h5")
        err = float(np.abs(p / load - 1).max())
        return (OK if err <= 1e-8 else WRONG), f"max |p / load - 1| = {err:.1e} (a flat periodic cell)"
    return accept


# --------------------------------------------------------------------------------------------
# `contactpetsc plot` on damaged files and a failed first step
GOOD_ROW = "1,loading,1e-9,2e-8,1e5,0.1\n"
SCENE_JSON = json.dumps({"name": "p", "geometry": {"kind": "sphere", "periodic": False},
                         "protocol": {"values": [1e-9]}, "output": {}})


def plot_files_case(name, files: dict, names, plots=False) -> Case:
    """``contactpetsc plot`` on a directory holding ``files`` (name -> text or bytes): refused
    naming one of ``names`` and no traceback, or with ``plots`` drawn (exit 0)."""
    def run(d):
        (d / "out").mkdir()
        for fname, content in files.items():
            path = d / "out" / fname
            path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
        res = cli(d, "plot", "out")
        if plots:
            return judge_success(res, lambda: (OK, "plotted: " + ", ".join(
                ln.rsplit("/", 1)[-1] for ln in res.out.splitlines() if ln.startswith("wrote"))))
        return judge_refusal(res, list(names))
    return Case(name, "plot", f"contactpetsc plot: {name}",
                "plots drawn" if plots else f"exit 1 naming {names[0]!r}, no traceback", run)


def plot_cases() -> list[Case]:
    good = {"curve.csv": GOOD_CURVE_HEAD + GOOD_ROW}
    failed_row = GOOD_CURVE_HEAD.strip() + ",converged\n1,loading,nan,nan,nan,nan,False\n"
    return [
        plot_files_case("plot-failed-at-step-1-no-row", {"curve.csv": GOOD_CURVE_HEAD, "scene.json": SCENE_JSON},
                        ["nothing to plot", "curve.csv"]),
        plot_files_case("plot-failed-at-step-1-row", {"curve.csv": failed_row}, [], plots=True),
        plot_files_case("plot-scene-without-sections", {"curve.csv": failed_row, "scene.json": SCENE_JSON},
                        ["scene.json"]),
        plot_files_case("plot-binary-curve", {"curve.csv": bytes(range(256)) * 8}, ["curve.csv"]),
        plot_files_case("plot-nul-curve", {"curve.csv": GOOD_CURVE_HEAD + "1,loading,1e-9,2e-8,1e5\x00\x00\n"},
                        ["curve.csv"]),
        plot_files_case("plot-damaged-summary", {**good, "summary.json": '{"pull_off'}, ["summary.json"]),
        plot_files_case("plot-summary-a-list", {**good, "summary.json": "[1, 2]"}, ["summary.json"]),
        plot_files_case("plot-damaged-scene", {**good, "scene.json": SCENE_JSON[:40]}, ["scene.json"]),
        plot_files_case("plot-scene-without-geometry", {**good, "scene.json": '{"name": "x"}'}, ["scene.json"]),
        plot_files_case("plot-damaged-step-file", {**good, "step_0001.h5": b"\x89HDF\r\n\x1a\n" + bytes(600)},
                        ["step_0001.h5"]),
        plot_files_case("plot-binary-history", {**good, "history.csv": bytes(range(256)) * 8}, ["history.csv"]),
    ]


# --------------------------------------------------------------------------------------------
def layer_cases() -> list[Case]:
    cell = layer_cell()
    lx = 32 * DX
    out = []
    for name, t in (("layer-1e300", 1e300), ("layer-1e3-cells", 1e3 * lx), ("layer-50-cells", 50 * lx)):
        case = refuse_or_match_case(name, "layer", f"material.layer_thickness = {t:g} m (cell {lx:g} m)",
                                    cell, ["layer_thickness"], tol=1e-9, edit=with_layer(t))
        case.expected = "the half-space run's forces within 1e-9 (a layer far thicker than the cell)"
        out.append(case)
    for t in (1e-300, 1e-200, 0.0, -1e-9):
        out.append(cli_refusal_case(f"layer-{t:g}", "layer", with_layer(t)(layer_cell()),
                                    ["layer_thickness"], forbidden=("error code", "nan")))
    out.append(cli_refusal_case("layer-thin-dry-run", "layer", with_layer(1e-300)(layer_cell()),
                                ["layer_thickness"], args=("--dry-run",)))
    return out


def flat_cases() -> list[Case]:
    out = []
    for periodic in (True, False):
        def run(d, periodic=periodic):
            npy(plane(), "plane.npy")(d)
            res = run_scene(d, file_scene("plane.npy", periodic=periodic, detrend="mean-plane"))
            if periodic:
                return judge_success(res, lambda: uniform_pressure(1e6)(d, res))

            def check():
                rows = read_curve(d / "out")
                p = read_field(d / "out/step_0001.h5")
                err = abs(float(np.mean(p)) / 1e6 - 1)
                full = float(rows[0]["contact_fraction"])
                return ((OK if err <= 1e-8 and full == 1.0 and p.min() > 0 else WRONG),
                        f"flat punch: mean pressure off by {err:.1e}, contact {full:g}")
            return judge_success(res, check)
        kind = "periodic" if periodic else "isolated"
        out.append(Case(f"detrended-plane-{kind}", "scale", f"a tilted plane detrended (rms ~ 1e-23 m), {kind}, "
                        "1 MPa", "converged: uniform pressure (periodic) / full-contact flat punch", run))
    return out


def detrend_cases() -> list[Case]:
    out = []
    for shape, mode, ok in (((3, 2), "curvature", False), ((2, 7), "curvature", False),
                            ((2, 2), "mean-plane", True), ((3, 3), "curvature", True)):
        name = f"detrend-{mode}-{shape[0]}x{shape[1]}"
        scene = file_scene("small.npy", detrend=mode, periodic=False)
        if ok:
            def run(d, scene=scene, shape=shape):
                npy(plane(*shape), "small.npy")(d)
                res = run_scene(d, scene)
                return judge_success(res, lambda: (OK, f"exit 0, {len(read_curve(d / 'out'))} step"), (0, 3))
            out.append(Case(name, "detrend", f"geometry.detrend = {mode} on a {shape[0]} x {shape[1]} map",
                            "runs (the smallest map its fit needs)", run))
        else:
            out.append(cli_refusal_case(name, "detrend", scene, ["geometry.detrend"],
                                        forbidden=("singular",), prepare=npy(plane(*shape), "small.npy")))
    return out


def comm_cases() -> list[Case]:
    return [
        api_refusal_case("api-world-vec-on-self-grid-np2", "comm", """
            def misuse():
                alone = SurfaceGrid(16, 16, 1e-8, comm=PETSc.COMM_SELF)
                alone.check_vec(SurfaceGrid(16, 16, 1e-8).create_vec(1.0), "heights")
            """, ["communicator"], ranks=2),
        api_refusal_case("api-self-vec-on-world-grid-np2", "comm", """
            def misuse():
                world = SurfaceGrid(16, 16, 1e-8)
                ContactProblem(world, SurfaceGrid(16, 16, 1e-8, comm=PETSc.COMM_SELF).create_vec(1.0), 1e9)
            """, ["communicator"], ranks=2),
    ]


# --------------------------------------------------------------------------------------------
# measured surfaces
def cap(nx=64, radius=1e-6, dx=2e-9) -> np.ndarray:
    """A spherical cap as the sample's surface (peaks up), apex at node (nx//2, nx//2)."""
    x = (np.arange(nx) - nx // 2) * dx
    return -(x[:, None] ** 2 + x[None, :] ** 2) / (2 * radius)


def hertz_cap_case() -> Case:
    values = (1e-9, 2e-9, 3e-9)

    def run(d):
        npy(cap(), "cap.npy")(d)
        scene = file_scene("cap.npy", control="approach", values=values, periodic=False, dx=2e-9,
                           heights_are="surface")
        res = run_scene(d, scene)

        def check():
            rows = read_curve(d / "out")
            errors = {f"step {r['step']}": abs(float(r["force_N"]) / hertz_force(1e9, 1e-6, float(r["approach_m"]))
                                               - 1) for r in rows}
            return within(errors, 0.01, "F / F_Hertz - 1")
        return judge_success(res, check)
    return Case("measured-cap-surface-hertz", "measured", "a spherical cap written as the sample's surface "
                "(heights_are = surface, peaks up)", "Hertz within 1 % (the sphere scene's bound)", run)


def harmonic_plane_case() -> Case:
    """Holes in a tilted plane filled harmonically are the plane (a linear function is harmonic):
    detrended, a flat periodic cell: the uniform pressure."""
    def run(d):
        npy(plane(holes=[(5, 5), (5, 6), (6, 5), (10, 3)]), "holes.npy")(d)
        res = run_scene(d, file_scene("holes.npy", fill="harmonic", detrend="mean-plane"))
        return judge_success(res, lambda: uniform_pressure(1e6)(d, res))
    return Case("measured-harmonic-fill-of-a-plane", "measured", "4 points not measured in a tilted plane, "
                "fill = harmonic, detrend = mean-plane", "uniform pressure = the load (the fill is the plane)", run)


def rewritten_file_case() -> Case:
    def run(d):
        npy(plane() + 1e-9 * np.random.default_rng(1).standard_normal((16, 16)), "h.npy")(d)
        scene = file_scene("h.npy", values=(1e6, 2e6))
        res = run_scene(d, scene)
        if res.rc != 0:
            return LOUD, f"first run: exit {res.rc}: {message(res)}"
        npy(plane() + 1e-9 * np.random.default_rng(2).standard_normal((16, 16)), "h.npy")(d)
        return judge_refusal(run_scene(d, merged(scene, protocol={"values": [1e6, 2e6, 3e6]}), "--restart"),
                             ["h.npy"])
    return Case("measured-restart-rewritten-heights", "measured", "--restart after the height file was "
                "rewritten with other heights", "refused naming the file", run)


def measured_cases() -> list[Case]:
    sq = plane()
    out = [hertz_cap_case(), harmonic_plane_case(), rewritten_file_case()]
    for key, value in (("heights_are", "depth"), ("fill", "nearest"), ("detrend", "plane")):
        out.append(cli_refusal_case(f"measured-{key}-{value}", "measured",
                                    file_scene("h.npy", **{key: value}), [f"geometry.{key}"],
                                    prepare=npy(sq, "h.npy")))
    all_holes = np.full((16, 16), np.nan)
    out.append(cli_refusal_case("measured-fill-nothing-measured", "measured",
                                file_scene("h.npy", fill="harmonic"), ["h.npy"], prepare=npy(all_holes, "h.npy")))
    out.append(cli_refusal_case("measured-holes-without-fill", "measured", file_scene("h.npy"), ["h.npy"],
                                prepare=npy(plane(holes=[(3, 3)]), "h.npy")))
    text = "\n".join(" ".join(f"{v:.6g}" for v in row) for row in (sq * 1e9).T) + "\n"
    texts = {"line-scan": "1 2 3 4 5 6 7 8\n", "binary-txt": bytes(range(256)) * 4,
             "ragged": "1 2 3\n4 5\n6 7 8\n", "decimal-commas-mixed": "1,5 2,5\n3.5 4.5\n",
             "empty": ""}
    for name, content in texts.items():
        out.append(cli_refusal_case(f"text-{name}", "text", file_scene("h.txt", height_unit="nm"), ["h.txt"],
                                    prepare=raw_file(content if isinstance(content, bytes) else content.encode(),
                                                     "h.txt")))
    out.append(cli_refusal_case("text-plane-read", "text",
                                file_scene("h.txt", height_unit="nm", detrend="mean-plane"), ["h.txt"],
                                prepare=raw_file(text.encode(), "h.txt"), accept=uniform_pressure(1e6)))
    return out


def limit_cases() -> list[Case]:
    return layer_cases() + plot_cases() + flat_cases() + detrend_cases() + comm_cases() + measured_cases()
