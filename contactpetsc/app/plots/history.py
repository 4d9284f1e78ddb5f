"""The solver's history: the error of every iteration against run time and against FFT pairs."""
from __future__ import annotations

import numpy as np

from .common import figure, save

#: history.csv's error columns, each with its marker (the colour tells the step)
ERRORS = {"complementarity_error": "o", "adhesive_error": "^", "total_error": "s", "load_error": "x"}


def error_vs_time(history: dict, path: str | None = None, title: str = ""):
    """Two panels of the error columns of ``history.csv`` (log): against wall time and against
    the cumulative FFT pairs.  One colour per step of the path (column ``step``; the iterations
    after the last step, such as the pull-off refinement, in grey), one marker per error
    measure, each solve's iterations joined by a line; returns the Figure."""
    fig, (top, bottom) = figure(2, 1, size=(7.0, 7.0), sharey=True)
    t, pairs = np.asarray(history["wall_time"], float), np.asarray(history["fft_pairs"], float)
    step = np.asarray(history.get("step", np.full(t.shape, np.nan)), float)
    solve = np.asarray(history.get("solve", np.zeros(t.shape)), float)
    steps = np.unique(step[np.isfinite(step)])
    from matplotlib import colormaps
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import BoundaryNorm
    cmap = colormaps["viridis"]
    lo, hi = (steps.min(), steps.max()) if steps.size else (1.0, 1.0)
    norm = BoundaryNorm(np.arange(lo - 0.5, hi + 1.5), cmap.N) if hi > lo else None
    colour = (lambda k: "0.6" if not np.isfinite(k) else cmap(norm(k)) if norm else "C0")
    # the points of one solve and one step share a line: breaks at every change of either
    key = np.nan_to_num(step, nan=-1.0)
    breaks = np.flatnonzero((np.diff(solve) != 0) | (np.diff(key) != 0)) + 1
    segments = np.split(np.arange(t.size), breaks)
    colours = [colour(k) for k in step]
    from matplotlib.collections import LineCollection
    for name, marker in ERRORS.items():
        e = np.asarray(history.get(name, []), float)
        if not (e.size and np.any(np.isfinite(e) & (e > 0))):
            continue
        e = np.where(e > 0, e, np.nan)
        for ax, x in ((top, t), (bottom, pairs)):
            # one collection and one scatter per measure: cheap for runs of thousands of solves
            ax.add_collection(LineCollection([np.column_stack([x[seg], e[seg]]) for seg in segments], lw=0.7,
                                             colors=[colours[seg[0]] for seg in segments]))
            ax.scatter(x, e, s=9, marker=marker, linewidths=0.8, facecolors="none" if marker in "o^s" else None,
                       edgecolors=colours if marker in "o^s" else None, c=None if marker in "o^s" else colours)
            ax.plot([], [], marker=marker, ls="none", color="k", mfc="none", label=name.replace("_", " "))
    if np.any(np.isnan(step)) and steps.size:
        top.plot([], [], color="0.6", label="after the last step (pull-off refinement)")
    for ax, label in ((top, "wall time [s]"), (bottom, "FFT pairs (cumulative; coarse levels weighted)")):
        ax.set_yscale("log")
        ax.set_xlabel(label)
        ax.set_ylabel("error (adhesion: in z0; else relative)")
    top.legend(fontsize=8, title="marker: error measure", title_fontsize=8)
    if norm is not None:
        bar = fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=[top, bottom], label="step")
        bar.set_ticks(steps[:: max(1, steps.size // 12)])
    fig.suptitle(title or "error against run time")
    return save(fig, path)
