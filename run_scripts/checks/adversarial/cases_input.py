"""Input cases: questionable input (class 5), axes end to end (6), messages of the CLI and
the API."""
from __future__ import annotations

import json
import textwrap
from pathlib import Path
from typing import Callable

import numpy as np

from .harness import (
    Case, LOUD, OK, UNCLEAR, WRONG, abnormal, api, cli, column, judge_refusal, judge_success,
    merged, message, read_curve, read_field, rough_cell, run_scene, within)


# --------------------------------------------------------------------------------------------
# class 5: questionable input
def same_forces(ref: Path, out: Path, tol: float) -> tuple[str, str]:
    """Forces of the steps ``out`` says converged against the reference run's; a run that
    stopped early is a loud failure if what it kept is right."""
    a, b = read_curve(ref), read_curve(out)
    b = [r for r in b if r["converged"] == "True"]
    if len(b) > len(a):
        return WRONG, f"{len(b)} steps against {len(a)} of the reference run"
    fa, fb = column(a[:len(b)], "force_N"), column(b, "force_N")
    scale = float(np.max(np.abs(column(a, "force_N")))) or 1.0
    errors = {f"step {i + 1}": abs(x - y) / scale for i, (x, y) in enumerate(zip(fa, fb))}
    verdict, detail = within(errors, tol, "converged steps' forces against a default run")
    if verdict == OK and len(b) < len(a):
        return LOUD, f"stopped: {len(b)} of {len(a)} steps converged ({detail})"
    return verdict, detail


def refuse_or_match_case(name, klass, description, scene, names, tol=1e-3, args=(),
                         edit=None) -> Case:
    """Questionable settings: refused naming one of ``names``, or the reference run's answer."""
    def run(d):
        ref = merged(scene, output={"directory": "ref"})
        res = run_scene(d, ref, name="ref.toml")
        if res.rc != 0:
            return LOUD, f"reference run failed: {message(res)}"
        bad_scene = edit(json.loads(json.dumps(scene))) if edit else scene
        res = run_scene(d, bad_scene, *args)
        return judge_refusal(res, names, accept=lambda: same_forces(d / "ref", d / "out", tol))
    return Case(name, klass, description, f"refused naming {names[0]!r}, or the default run's forces "
                f"within {tol:g}", run)


def load_case(name, scene) -> Case:
    """Subnormal or huge loads: refused naming protocol.values, or the load met."""
    def run(d):
        res = run_scene(d, scene)

        def accept():
            rows = read_curve(d / "out")
            control = scene["protocol"]["control"]
            col = "force_N" if control == "force" else "mean_pressure_Pa"
            errors = {f"step {r['step']}": abs(float(r[col]) - t) / abs(t)
                      for r, t in zip(rows, scene["protocol"]["values"])}
            if res.rc == 3:
                return OK, "not converged, exit 3 (a loud failure)"
            return within(errors, 1e-6, f"reported {col} against the prescribed load")
        return judge_refusal(res, ["values", "load", "pressure", "force"], accept=accept)
    vals = scene["protocol"]["values"]
    return Case(name, "5", f"{scene['protocol']['control']} = {vals}",
                "refused naming the load, or the load met to 1e-6 (or exit 3)", run)


def height_file_case(name, klass, make: Callable[[Path], str], nx=16, ny=16, accept=None,
                     dry_run=False, names=None, forbidden=(), periodic=True) -> Case:
    """A height file written by ``make(dir) -> file name`` fed to kind = "file"."""
    def run(d):
        fname = make(d)
        scene = {"name": "sweep-file",
                 "geometry": {"kind": "file", "path": fname, "nx": nx, "ny": ny, "dx": 1e-8,
                              "periodic": periodic},
                 "material": {"e_star": 1e9},
                 "protocol": {"control": "approach", "values": [1e-10]},
                 "output": {"directory": "out"}}
        res = run_scene(d, scene, *(["--dry-run"] if dry_run else []))
        return judge_refusal(res, names or [fname, "geometry.path", "heights"],
                             accept=(lambda: accept(d, res)) if accept else None, forbidden=forbidden)
    what = "--dry-run" if dry_run else "run"
    return Case(name, klass, f"{what} with a height file: {name}",
                f"refused naming the file{' (no ' + forbidden[0] + ')' if forbidden else ''}"
                + (", or read correctly" if accept else ""), run)


def npy(arr, fname="h.npy"):
    def make(d):
        np.save(d / fname, arr)
        return fname
    return make


def raw_file(data: bytes, fname):
    def make(d):
        (d / fname).write_bytes(data)
        return fname
    return make


def h5(arr, fname="h.h5", dataset="heights", **attrs):
    def make(d):
        import h5py
        with h5py.File(d / fname, "w") as f:
            f[dataset] = arr
            for k, v in attrs.items():
                f[dataset].attrs[k] = v
                f.attrs[k] = v
        return fname
    return make


def warn_ok(words):
    """Accept a run that warns with one of ``words`` in its log."""
    def accept(d, res):
        if any(w.lower() in res.text.lower() for w in words):
            return OK, "ran with a warning naming it"
        return WRONG, f"accepted without a word (no {words[0]!r} in the log)"
    return accept


# --------------------------------------------------------------------------------------------
# class 6: axes end to end
def tilted(nx, ny, dx=1e-8, dy=1e-8) -> np.ndarray:
    """An asymmetric surface [m], indexed [j, i] (row = y): any transposition shows."""
    x, y = np.arange(nx) * dx, np.arange(ny) * dy
    return 1e-3 * x[None, :] + 3e-3 * y[:, None] + 2e-10 * np.sin(x[None, :] / dx) ** 2


def round_trip_case(nx, ny, dy=1e-8, ranks=1) -> Case:
    """A self-affine run's step_0001.h5 fed back as kind = "file": the same heights and forces."""
    first = {"name": "sweep-axes",
             "geometry": {"kind": "self-affine", "nx": nx, "ny": ny, "dx": 1e-8, "dy": dy,
                          "rms_height": 1e-9, "seed": 7},
             "material": {"e_star": 1e9},
             "protocol": {"control": "mean_pressure", "values": [2e6]},
             "output": {"directory": "first"}}
    second = merged(first, geometry={"kind": "file", "path": "first/step_0001.h5",
                                     "dataset": "heights", "rms_height": None, "seed": None},
                    output={"directory": "out"})

    def run(d):
        res = run_scene(d, first, name="first.toml", ranks=ranks)
        if res.rc != 0:
            return LOUD, f"first run failed: {message(res)}"
        res = run_scene(d, second, ranks=ranks)

        def check():
            h1 = read_field(d / "first/step_0001.h5", "heights")
            h2 = read_field(d / "out/step_0001.h5", "heights")
            if h1.shape != h2.shape or not np.allclose(h1, h2, rtol=0, atol=1e-12 * np.abs(h1).max()):
                diff = np.abs(h1 - h2).max() if h1.shape == h2.shape else "shape"
                return WRONG, f"heights came back different (max diff {diff}): transposed"
            return same_forces(d / "first", d / "out", 1e-6)
        return judge_refusal(res, ["axes", "transpos", "shape"], accept=check)
    return Case(f"axes-round-trip-{nx}x{ny}{'-dxdy' if dy != 1e-8 else ''}-np{ranks}", "6",
                f"step file of a {nx}x{ny} run fed back as kind = file, {ranks} rank(s)",
                "the same heights (1e-12) and forces (1e-6), or refused naming the axes", run, ranks)


def axes_stamp_case() -> Case:
    def run(d):
        scene = rough_cell(nx=32)
        scene["geometry"]["ny"] = 16
        res = run_scene(d, scene)

        def check():
            import h5py
            with h5py.File(d / "out/step_0001.h5", "r") as f:
                stamps = [f.attrs.get("axes")] + [f[k].attrs.get("axes") for k in f.keys()]
            stamps = [s.decode() if isinstance(s, bytes) else s for s in stamps if s is not None]
            if stamps and all(s == "y,x" for s in stamps):
                return OK, f"axes = 'y,x' on the file/datasets ({len(stamps)})"
            return WRONG, f"step file not stamped with axes = 'y,x' (found {stamps})"
        return judge_success(res, check)
    return Case("axes-stamp", "6", "step file attributes after a 32x16 rough run",
                "attribute axes = 'y,x'", run)


def stamped_input_case(name, shape_order, stamp, nx=24, ny=16) -> Case:
    """A hand-written HDF5 heights file with an axes stamp: read the way it says."""
    yx = tilted(nx, ny)
    arr = yx if shape_order == "yx" else yx.T

    def accept(d, res):
        if res.rc != 0:
            return LOUD, f"exit {res.rc}: {message(res)}"
        got = read_field(d / "out/step_0001.h5", "heights")
        # the file holds the surface, peaks up (docs/topography.md): the gap is max(z) - z
        gap = yx.max() - yx
        if got.shape == gap.shape and np.allclose(got, gap, atol=1e-15 * np.abs(yx).max()):
            return OK, "heights read in the stamped order (pressed peaks up)"
        return WRONG, "heights read in the wrong order"
    make = h5(arr, **({"axes": stamp} if stamp else {}))
    return height_file_case(name, "6", make, nx=nx, ny=ny, accept=accept,
                            names=["axes", "shape", "h.h5"])


def api_from_step_file_case() -> Case:
    code = """
        from contactpetsc.grid import SurfaceGrid
        from contactpetsc.geometry import surfaces
        from contactpetsc.app import runner, scenes
        scene = scenes.validate({"geometry": {"kind": "self-affine", "nx": 32, "ny": 16, "dx": 1e-8,
                                 "rms_height": 1e-9, "seed": 5}, "material": {"e_star": 1e9},
                                 "protocol": {"control": "mean_pressure", "values": [1e6]},
                                 "output": {"directory": "apiout"}})
        runner.run(scene)
        grid = SurfaceGrid(32, 16, 1e-8, periodic=True)
        try:
            h = grid.gather(surfaces.from_file(grid, "apiout/step_0001.h5"))
            report({"read": True, "h_xy": h.tolist()})
        except Exception as exc:
            report({"read": False, "error": str(exc)})
        """

    def run(d):
        res, rep = api(d, textwrap.dedent(code))

        def check():
            if rep is None:
                return WRONG, "no result"
            if not rep["read"]:
                ok = any(w in rep["error"].lower() for w in ("axes", "shape", "step_0001"))
                return (OK if ok else UNCLEAR), f"refused: {rep['error'][:150]}"
            stored = read_field(d / "apiout/step_0001.h5", "heights")     # (ny, nx)
            h_xy = np.array(rep["h_xy"])                                     # (nx, ny)
            if h_xy.shape == stored.T.shape and np.allclose(h_xy, stored.T):
                return OK, "surfaces.from_file read the step file's (y, x) heights correctly"
            return WRONG, "surfaces.from_file read a step file transposed or scrambled"
        return judge_success(res, check)
    return Case("api-from-file-step", "6", "surfaces.from_file on a 32x16 step file",
                "heights equal to the stored ones, or refused naming the axes", run)


# --------------------------------------------------------------------------------------------
# messages
def cli_refusal_case(name, klass, scene, names, args=(), forbidden=(), prepare=None,
                     accept=None) -> Case:
    def run(d):
        if prepare:
            prepare(d)
        res = run_scene(d, scene, *args) if isinstance(scene, dict) else cli(d, *scene)
        return judge_refusal(res, names, forbidden=forbidden,
                             accept=(lambda: accept(d, res)) if accept else None)
    words = " ".join(map(str, args)) if isinstance(scene, dict) else " ".join(map(str, scene))
    return Case(name, klass, f"{words}".strip() or name, f"refused naming {names[0]!r}"
                + (f", never {forbidden[0]!r}" if forbidden else ""), run)


def plot_case(name, curve_text: str | None, names=("curve.csv",)) -> Case:
    def run(d):
        (d / "out").mkdir()
        if curve_text is not None:
            (d / "out/curve.csv").write_text(curve_text)
        return judge_refusal(cli(d, "plot", "out"), list(names))
    return Case(name, "msg", f"contactpetsc plot on {name}", "exit 1 naming curve.csv, no traceback", run)


GOOD_CURVE_HEAD = "step,branch,approach_m,force_N,mean_pressure_Pa,contact_fraction\n"


def api_refusal_case(name, klass, code, names, ranks=1) -> Case:
    """API misuse (``code`` defines misuse() on API_GRID's 12 x 16 grid): the call must raise
    on every rank with a message naming one of ``names``."""
    wrapped = textwrap.dedent(API_GRID) + textwrap.dedent(code) + textwrap.dedent("""
        try:
            misuse()
            report({"raised": False})
        except Exception as exc:
            report({"raised": True, "type": type(exc).__name__, "error": str(exc)})
        """)

    def run(d):
        res, rep = api(d, wrapped, ranks)
        bad = abnormal(res)
        if bad:
            return bad
        if rep is None:
            return UNCLEAR, f"exit {res.rc}, no report: {message(res)}"
        if not rep["raised"]:
            return WRONG, "accepted without a word"
        text = rep["error"].lower()
        hit = any(n.lower() in text for n in names)
        return (OK if hit else UNCLEAR), f"{rep['type']}: {rep['error'][:150]}"
    return Case(name, klass, f"API: {name}", f"raises naming {names[0]!r}", run, ranks)


API_GRID = """
    from contactpetsc.grid import SurfaceGrid
    from contactpetsc.geometry import surfaces
    from contactpetsc.solvers import ContactProblem
    from contactpetsc.physics.interactions import make_law
    from contactpetsc.solvers.adhesive import AdhesiveProblem
    grid = SurfaceGrid(12, 16, 1e-8, periodic=True)
    """
