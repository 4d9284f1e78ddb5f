"""Plots of a run's outputs, with matplotlib (imported here only, and only when a plot is asked for).

``plot_run(directory)`` reads what a run wrote (``curve.csv``; with adhesion
``jumps.csv`` and ``summary.json``; ``history.csv``; the last
``step_NNNN.h5``) and saves, in the same directory:

- ``load_approach.png``: force against approach, loading and unloading steps
  marked apart (unstable and unconverged states flagged); with adhesion, each
  jump as a dashed arrow from the last state before it to the first after it,
  and the pull-off force as a dotted line; for spheres, Greenwood's alpha* and
  W* on the top and right axes.
- ``pressure_map.png``: the pressure of the last step on a diverging colour
  scale centred at zero (red compressive, blue tensile).
- ``error_vs_time.png``: the error measures of ``history.csv`` against run time.

Serial code on the files alone: ``contactpetsc run`` calls it on rank 0 after
a run when ``output.plots = true`` (or ``--plots``); ``contactpetsc plot DIR``
plots a finished run.  It draws on the Agg canvas directly: no pyplot, no
display, no change to a caller's matplotlib backend.
"""
from __future__ import annotations

import csv
import json
import os

import numpy as np

MAP_PIXELS = 2048   #: a larger field is read every k-th node for the map
BRANCH_STYLE = {"loading": dict(color="C0", marker="o"),
                "unloading": dict(color="C1", marker="s"),
                "central-gap": dict(color="C2", marker=".")}
ERRORS = ("complementarity_error", "adhesive_error", "total_error", "load_error")
JUMP_NUMBERS = ("approach_before_m", "approach_after_m", "force_before_N", "force_after_N")


def require() -> None:
    """ImportError with the remedy when matplotlib is missing (checked before a run starts)."""
    import importlib.util
    if importlib.util.find_spec("matplotlib") is None:
        raise ImportError("output.plots needs matplotlib: pip install matplotlib "
                          "(Debian: apt-get install python3-matplotlib)")


def _figure():
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=(6.4, 4.8), layout="constrained")
    FigureCanvasAgg(fig)
    return fig, fig.add_subplot()


def _prefix(values, unit: str) -> tuple[float, str]:
    """(factor, label) of the SI prefix that puts the largest |value| in [1, 1000)."""
    finite = np.abs(np.asarray(values, float))
    finite = finite[np.isfinite(finite) & (finite > 0)]
    top = finite.max() if finite.size else 1.0
    for exponent, p in ((9, "G"), (6, "M"), (3, "k"), (0, ""), (-3, "m"), (-6, "µ"), (-9, "n"), (-12, "p")):
        if top >= 10.0 ** exponent:
            return 10.0 ** exponent, p + unit
    return 1e-15, "f" + unit


def read_csv(path: str, numeric: tuple = ()) -> dict:
    """The columns of a CSV file: float arrays where every entry parses (True/False as 1/0),
    lists of strings otherwise.  A row with missing or extra entries, or a ``numeric`` column
    entry that is not a number, is a ValueError naming the file and the row."""
    with open(path, newline="") as f:
        reader = csv.DictReader(f)
        rows = list(reader)
        header = reader.fieldnames or []
    for n, r in enumerate(rows, 1):
        if None in r or any(r[c] is None for c in header):
            raise ValueError(f"{path}, row {n}: {len([c for c in header if r[c] is not None])} of {len(header)} "
                             "columns: the file is damaged (an interrupted run can leave a partial last row; "
                             "contactpetsc run --restart drops it)")
    out, words_to_numbers = {}, {"True": 1.0, "False": 0.0, "": np.nan}
    for name in header:
        words = [r[name] for r in rows]
        try:
            out[name] = np.array([words_to_numbers[w] if w in words_to_numbers else float(w)
                                  for w in words])
        except ValueError:
            if name in numeric:
                n = next(k for k, w in enumerate(words, 1) if not is_number(w))
                raise ValueError(f"{path}, row {n}: {name} = {words[n - 1]!r} is not a number: the file is "
                                 "damaged") from None
            out[name] = words
    missing = [c for c in numeric if c not in header]
    if missing:
        raise ValueError(f"{path}: no column {', '.join(missing)}")
    return out


def is_number(word: str) -> bool:
    """Whether ``word`` reads as a float (nan and inf included)."""
    try:
        float(word)
    except ValueError:
        return False
    return True


def load_approach(curve: dict, jumps: dict | None = None, pull_off: float | None = None,
                  path: str | None = None, title: str = ""):
    """Force against approach from ``curve.csv`` (and ``jumps.csv``) columns; returns the Figure
    (saved to ``path``)."""
    fig, ax = _figure()
    x, y = curve["approach_m"], curve["force_N"]
    (sx, ux), (sy, uy) = _prefix(x, "m"), _prefix(np.append(y, pull_off or np.nan), "N")
    branch = curve.get("branch") or ["loading"] * len(x)
    jumps = jumps if jumps and len(jumps.get("kind", [])) else None
    used, start = set(), 0
    for i in range(1, len(x) + 1):
        if i < len(x) and branch[i] == branch[start]:
            continue
        style = BRANCH_STYLE.get(branch[start], dict(color="C4", marker="o"))
        lo = max(start - 1, 0)   # the line joins the previous branch's last state
        kind = {"loading": "jump-on", "unloading": "jump-off"}.get(branch[start])
        xs, ys = _with_jumps(x[lo:i], y[lo:i], jumps, kind, used)
        ax.plot(xs / sx, ys / sy, color=style["color"])
        ax.plot(x[start:i] / sx, y[start:i] / sy, ls="none", ms=5,
                mfc="none" if branch[start] == "unloading" else style["color"], **style)
        start = i
    for name in dict.fromkeys(branch):
        style = BRANCH_STYLE.get(name, dict(color="C4", marker="o"))
        ax.plot([], [], ms=5, mfc="none" if name == "unloading" else style["color"], label=name, **style)
    for name, mask, mark in (("unstable", curve.get("stable", np.ones_like(x)) == 0, "x"),
                             ("not converged", curve.get("converged", np.ones_like(x)) == 0, "X")):
        if np.any(mask):
            ax.plot(x[mask] / sx, y[mask] / sy, mark, color="k", ms=7, ls="none", label=name)
    for k in range(len(jumps["kind"]) if jumps else 0):
        start_pt = (jumps["approach_before_m"][k] / sx, jumps["force_before_N"][k] / sy)
        end_pt = (jumps["approach_after_m"][k] / sx, jumps["force_after_N"][k] / sy)
        ax.annotate("", xy=end_pt, xytext=start_pt,
                    arrowprops=dict(arrowstyle="->", ls="--", color="C3", lw=1.5))
        ax.annotate(jumps["kind"][k], xy=end_pt, xytext=(5, -3), textcoords="offset points",
                    color="C3", fontsize=8)
    if jumps:
        ax.plot([], [], "--", color="C3", label="jump (located by bisection)")
    if pull_off is not None and np.isfinite(pull_off):
        ax.axhline(pull_off / sy, ls=":", color="C3", label=f"pull-off {pull_off / sy:.4g} {uy}")
    ax.axhline(0.0, color="0.6", lw=0.6)
    ax.set_xlabel(f"approach δ [{ux}]")
    ax.set_ylabel(f"force F [{uy}] (compressive > 0)")
    _greenwood_axes(ax, curve, sx, sy)
    ax.legend(fontsize=8)
    ax.set_title(title or "load against approach")
    if path:
        fig.savefig(path, dpi=120)
    return fig


def _with_jumps(x, y, jumps, kind, used: set):
    """The polyline through (x, y) with each jump of ``kind`` found between two of its points
    drawn where it was located: the old branch up to the jump, a break, the new branch on.
    ``used`` collects the jumps drawn (each is drawn once)."""
    xs, ys = [x[0]], [y[0]]
    for k in range(1, len(x)):
        for j in range(len(jumps["kind"]) if jumps else 0):
            a0 = jumps["approach_before_m"][j]
            if j not in used and jumps["kind"][j] == kind and min(x[k - 1], x[k]) <= a0 <= max(x[k - 1], x[k]):
                used.add(j)
                xs += [a0, np.nan, jumps["approach_after_m"][j]]
                ys += [jumps["force_before_N"][j], np.nan, jumps["force_after_N"][j]]
        xs.append(x[k])
        ys.append(y[k])
    return np.array(xs), np.array(ys)


def _greenwood_axes(ax, curve: dict, sx: float, sy: float) -> None:
    """Top and right axes in Greenwood's alpha* = delta / z0 and W* = F / (2 pi R w) (spheres)."""
    x, y = curve["approach_m"], curve["force_N"]
    a, w = np.asarray(curve.get("alpha_star", np.nan * x)), np.asarray(curve.get("W_star", np.nan * x))
    ix, iy = np.argmax(np.where(np.isfinite(a), np.abs(x), 0)), np.argmax(np.where(np.isfinite(w), np.abs(y), 0))
    if not (np.isfinite(a[ix]) and x[ix] != 0 and np.isfinite(w[iy]) and y[iy] != 0):
        return
    fx, fy = a[ix] / x[ix] * sx, w[iy] / y[iy] * sy
    ax.secondary_xaxis("top", functions=(lambda v: v * fx, lambda v: v / fx)).set_xlabel("α* = δ / z0")
    ax.secondary_yaxis("right", functions=(lambda v: v * fy, lambda v: v / fy)).set_ylabel("W* = F / (2π R w)")


def pressure_map(pressure: np.ndarray, dx: float, dy: float, path: str | None = None, title: str = ""):
    """A (ny, nx) pressure field [Pa], node (i, j) at (i dx, j dy), on a diverging scale centred at
    zero; returns the Figure (saved to ``path``)."""
    fig, ax = _figure()
    ny, nx = pressure.shape
    top = float(np.nanmax(np.abs(pressure))) if pressure.size else 0.0
    top = top if top > 0 and np.isfinite(top) else 1.0
    (sp, up), (sl, ul) = _prefix([top], "Pa"), _prefix([nx * dx, ny * dy], "m")
    extent = (-0.5 * dx / sl, (nx - 0.5) * dx / sl, -0.5 * dy / sl, (ny - 0.5) * dy / sl)
    im = ax.imshow(pressure / sp, origin="lower", extent=extent, cmap="RdBu_r",
                   vmin=-top / sp, vmax=top / sp, interpolation="nearest")
    fig.colorbar(im, ax=ax, label=f"pressure p [{up}] (compressive > 0)")
    ax.set_xlabel(f"x [{ul}]")
    ax.set_ylabel(f"y [{ul}]")
    ax.set_title(title or "pressure")
    if path:
        fig.savefig(path, dpi=120)
    return fig


def error_vs_time(history: dict, path: str | None = None, title: str = ""):
    """The error columns of ``history.csv`` against wall time; returns the Figure."""
    fig, ax = _figure()
    t = history["wall_time"]
    for name in ERRORS:
        e = np.asarray(history.get(name, []), float)
        if e.size and np.any(np.isfinite(e) & (e > 0)):
            ax.semilogy(t, np.where(e > 0, e, np.nan), ".-", ms=3, lw=0.8, label=name.replace("_", " "))
    ax.set_xlabel("wall time [s]")
    ax.set_ylabel("error (adhesive runs: in z0; else relative)")
    ax.legend(fontsize=8)
    ax.set_title(title or "error against run time")
    if path:
        fig.savefig(path, dpi=120)
    return fig


def read_step(directory: str, step: int):
    """(pressure (ny, nx) read every k-th node, dx, dy, attrs) of ``step_NNNN.h5``, or None when
    the run wrote no field file of that step, or none with the pressure (output.fields)."""
    path = os.path.join(directory, f"step_{step:04d}.h5")
    if not os.path.exists(path):
        return None
    import h5py
    with h5py.File(path, "r") as f:
        if "pressure" not in f:
            return None
        dset = f["pressure"]
        k = max(1, -(-max(dset.shape) // MAP_PIXELS))
        attrs = dict(f.attrs)
        return dset[::k, ::k], k * float(attrs["dx"]), k * float(attrs["dy"]), attrs


def plot_run(directory: str, pressure: tuple | None = None) -> list[str]:
    """Save the plots of a run's output directory; returns their paths.

    ``pressure``: (field (ny, nx), dx, dy, title) of the last step, for runs without field
    files; by default it is read from the last ``step_NNNN.h5``.
    """
    curve_path = os.path.join(directory, "curve.csv")
    if not os.path.exists(curve_path):
        raise FileNotFoundError(f"no curve.csv in {directory}: not a contactpetsc output directory")
    curve = read_csv(curve_path, numeric=("step", "approach_m", "force_N"))
    if not curve:
        raise ValueError(f"{curve_path} has no steps yet")
    jumps = read_csv(os.path.join(directory, "jumps.csv"), numeric=JUMP_NUMBERS) if os.path.exists(
        os.path.join(directory, "jumps.csv")) else None
    pull_off = None
    if os.path.exists(os.path.join(directory, "summary.json")):
        with open(os.path.join(directory, "summary.json")) as f:
            pull_off = json.load(f).get("pull_off_force_N")
    step = int(curve["step"][-1])   # the run's last step (older step files may lie beside it)
    last = read_step(directory, step) if pressure is None else None
    # the scene's name, from a field file's provenance, else the directory's
    name = json.loads(last[3]["scene"])["name"] if last else os.path.basename(os.path.normpath(directory))
    written = [os.path.join(directory, "load_approach.png")]
    load_approach(curve, jumps, pull_off, written[-1], title=f"{name}: load against approach")
    if last is not None:
        field, dx, dy, attrs = last
        pressure = (field, dx, dy, f"{name}, step {step}: δ = {attrs['approach']:.4g} m, "
                                   f"F = {attrs['force']:.4g} N")
    if pressure is not None:
        written.append(os.path.join(directory, "pressure_map.png"))
        pressure_map(pressure[0], pressure[1], pressure[2], written[-1], title=pressure[3])
    if os.path.exists(os.path.join(directory, "history.csv")):
        written.append(os.path.join(directory, "error_vs_time.png"))
        error_vs_time(read_csv(os.path.join(directory, "history.csv")), written[-1],
                      title=f"{name}: error against run time")
    return written
