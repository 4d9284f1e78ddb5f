"""Plots of a run's outputs, with matplotlib (imported only when a plot is drawn: importing this
package imports numpy alone).

``plot_run(directory)`` reads what a run wrote (``curve.csv``, ``scene.json``; with adhesion
``jumps.csv`` and ``summary.json``; ``history.csv``; the step file of the plotted step) and
saves, in the same directory (docs/outputs.md, "Plots"):

- ``load_approach.png``: force against approach, loading and unloading apart, jumps and the
  pull-off force; on smooth spheres the closed forms (Hertz; DMT, JKR, Maugis-Dugdale) and,
  with adhesion, Greenwood's alpha* and W* on the top and right axes (``curves``).
- ``contact_area.png`` and ``mean_gap.png`` (rough surfaces, self-affine or from a file, and
  periodic cells; at least two steps with load): A/A0 against p/E* with the small-load laws of
  Persson and Bush-Gibson-Thomas, and the mean gap against log p/E*; on an isolated window A0
  is the window's area nx dx ny dy and p = F / A0.
- ``pressure_map.png`` and ``histograms.png``: the pressure, and the pressure and gap
  distributions, of the plotted step: ``output.plot_step``, by default the step at the largest
  approach (``fields``), on scales that an outlier node does not set (``scales``).
- ``psd.png`` (rough surfaces: self-affine or from a file): the radially averaged power
  spectrum of the heights (``spectrum``; a non-periodic map Hann-windowed), with the
  generator's slope -2(1 + H) for a self-affine one.
- ``error_vs_time.png``: the error of every iteration against run time and FFT pairs, one colour
  per step (``history``).

Serial code on the files: ``contactpetsc run`` calls it on rank 0 after a run when
``output.plots = true`` (or ``--plots``); ``contactpetsc plot DIR`` plots a finished run.
"""
from __future__ import annotations

import os

import numpy as np

from .common import is_number, prefix, read_csv, read_json, reading, require
from .curves import BRANCH_STYLE, contact_area, load_approach, mean_gap, sphere_overlays
from .fields import histograms, pressure_map, psd
from .history import ERRORS, error_vs_time
from .scales import histogram_range, pressure_limits
from .spectrum import power_spectrum, radial_psd, rms_slope

__all__ = ["plot_run", "plot_step", "require", "read_csv", "is_number", "prefix", "load_approach",
           "contact_area", "mean_gap", "sphere_overlays", "pressure_map", "histograms", "psd",
           "radial_psd", "power_spectrum", "rms_slope", "pressure_limits", "histogram_range", "error_vs_time",
           "BRANCH_STYLE", "ERRORS", "PLOTS", "planned", "loaded_steps"]

MAP_PIXELS = 2048      #: a larger field is read every k-th node for the map and the histograms
HEIGHT_NODES = 8192    #: the heights (spectrum, rms slope) are read whole up to this many per side
JUMP_NUMBERS = ("approach_before_m", "approach_after_m", "force_before_N", "force_after_N")
#: every file ``plot_run`` may write (the run directory's own files, docs/outputs.md)
PLOTS = ("load_approach.png", "contact_area.png", "mean_gap.png", "pressure_map.png", "histograms.png",
         "psd.png", "error_vs_time.png")
ROUGH = ("self-affine", "file")   #: the geometry kinds whose heights are a rough surface
LOAD_CURVES = ("contact_area.png", "mean_gap.png")
#: what a run's scene.json holds (the validated scene)
SCENE_SECTIONS = ("name", "geometry", "material", "interaction", "protocol", "solver", "output")


def planned(scene: dict | None) -> tuple:
    """The plots a run of ``scene`` draws (those whose data it writes: ``plot_run`` leaves out a
    plot whose data a directory lacks, such as the load curves of a path with fewer than two
    loaded steps); all of them when the scene is not known.  The load curves: rough surfaces
    (periodic or an isolated window) and periodic cells, with two steps or more; the spectrum:
    rough surfaces."""
    if scene is None:
        return PLOTS
    g = scene["geometry"]
    rough = g["kind"] in ROUGH
    curves = (rough or g["periodic"]) and len(scene["protocol"]["values"]) >= 2
    return tuple(name for name in PLOTS if not (name in LOAD_CURVES and not curves
                                                or name == "psd.png" and not rough))


def plot_step(approach, converged, requested: int | None = None) -> int:
    """The step whose fields are plotted (1, 2, ...): ``requested`` (``output.plot_step``), else
    the converged step of the largest approach (the last on ties): the most pressed state, the
    one of the largest load without adhesion; else the last step.  A requested step beyond the
    run's steps is a ValueError naming the key."""
    approach = np.asarray(approach, float)
    if requested is not None:
        if not 1 <= requested <= approach.size:
            raise ValueError(f"plot step {requested} (output.plot_step, or plot --step): the run has steps 1 "
                             f"to {approach.size}")
        return int(requested)
    ok = (np.asarray(converged, float) == 1) & np.isfinite(approach)
    if not np.any(ok):
        return int(approach.size)
    best = np.where(ok, approach, -np.inf)
    return int(np.flatnonzero(best == best.max())[-1]) + 1


def loaded_steps(curve: dict) -> int:
    """The converged steps of ``curve.csv`` that carry a compressive load (mean pressure > 0):
    the points of the load curves, which need two."""
    ok = np.asarray(curve.get("converged", np.ones(len(curve["mean_pressure_Pa"]))), float) == 1
    return int(np.count_nonzero(ok & (np.asarray(curve["mean_pressure_Pa"], float) > 0)))


def read_fields(directory: str, step: int) -> dict | None:
    """The fields of ``step_NNNN.h5``, or None when the run wrote no field file of that step, or
    none with the pressure (``output.fields``, ``output.field_every``): ``pressure``
    and ``gap`` read every k-th node (at most MAP_PIXELS per side) with their spacing ``dx``,
    ``dy``; ``heights`` whole with ``hdx``, ``hdy`` (None above HEIGHT_NODES per side);
    ``attrs``, the file's attributes."""
    path = os.path.join(directory, f"step_{step:04d}.h5")
    if not os.path.exists(path):
        return None
    import h5py
    with reading(path), h5py.File(path, "r") as f:
        if "pressure" not in f:
            return None
        attrs = dict(f.attrs)
        dx, dy = float(attrs["dx"]), float(attrs["dy"])
        shape = f["pressure"].shape
        k = max(1, -(-max(shape) // MAP_PIXELS))
        whole = max(shape) <= HEIGHT_NODES and "heights" in f
        return dict(pressure=f["pressure"][::k, ::k], gap=f["gap"][::k, ::k] if "gap" in f else None,
                    dx=k * dx, dy=k * dy, heights=f["heights"][:] if whole else None, hdx=dx, hdy=dy,
                    attrs=attrs)


def plot_run(directory: str, fields: dict | None = None, step: int | None = None) -> list[str]:
    """Save the plots of a run's output directory; returns their paths.

    ``fields``: the plotted step's ``pressure``, ``gap``, ``heights`` (ny, nx) with ``dx``, ``dy``
    (``hdx``, ``hdy`` for the heights) and its ``step``, for runs without field files; by
    default they are read from its ``step_NNNN.h5``.  ``step``: the step to plot (default
    ``output.plot_step`` of the run's scene, else the step at the largest approach).
    """
    path = lambda name: os.path.join(directory, name)  # noqa: E731
    if not os.path.exists(path("curve.csv")):
        raise FileNotFoundError(f"no curve.csv in {directory}: not a contactpetsc output directory")
    curve = read_csv(path("curve.csv"), numeric=("step", "approach_m", "force_N"))
    if not curve or not len(curve["step"]):
        raise ValueError(f"{path('curve.csv')} has no steps: the run wrote none (it failed or was stopped at "
                         "its first step; its log says why): nothing to plot")
    scene = read_json(path("scene.json")) if os.path.exists(path("scene.json")) else None
    missing = [k for k in SCENE_SECTIONS if scene is not None and k not in scene]
    if missing:
        raise ValueError(f"cannot read {path('scene.json')}: no {', '.join(missing)}: the file is damaged or "
                         "not a contactpetsc scene")
    jumps = read_csv(path("jumps.csv"), numeric=JUMP_NUMBERS) if os.path.exists(path("jumps.csv")) else None
    pull_off = None
    if os.path.exists(path("summary.json")):
        pull_off = read_json(path("summary.json")).get("pull_off_force_N")
    if fields is not None:
        chosen = fields["step"]
    else:
        requested = step if step is not None else (scene or {}).get("output", {}).get("plot_step")
        chosen = plot_step(curve["approach_m"], curve.get("converged", np.ones(len(curve["step"]))), requested)
        fields = read_fields(directory, int(curve["step"][chosen - 1]))
    name = scene["name"] if scene else os.path.basename(os.path.normpath(directory))
    written = []

    def draw(file, plot, *args, **kw):
        written.append(path(file))
        plot(*args, path=written[-1], **kw)

    try:
        _draw_all(draw, directory, curve, scene, jumps, pull_off, fields, chosen, name)
    except KeyError as exc:
        raise ValueError(f"cannot plot {directory}: no {exc} in scene.json or curve.csv (damaged, or written "
                         "by another version)") from None
    return written


def _draw_all(draw, directory, curve, scene, jumps, pull_off, fields, chosen, name) -> None:
    """``plot_run``'s drawing, each plot through ``draw``."""
    path = lambda name: os.path.join(directory, name)  # noqa: E731
    wanted = planned(scene)
    draw("load_approach.png", load_approach, curve, jumps, pull_off, title=f"{name}: load against approach",
         overlays=sphere_overlays(scene, curve["approach_m"]) if scene else [])
    g = scene["geometry"] if scene else {}
    periodic = bool(g.get("periodic", True))
    heights = fields.get("heights") if fields else None
    slope = (rms_slope(heights, fields["hdx"], fields["hdy"], periodic) if heights is not None
             else g.get("rms_slope"))
    if LOAD_CURVES[0] in wanted and scene and loaded_steps(curve) >= 2:
        from ..scenes import e_star as e_star_of   # E* or E, nu (the scene module needs PETSc)
        e_star, window = e_star_of(scene), not periodic
        draw("contact_area.png", contact_area, curve, e_star, slope, window=window,
             title=f"{name}: contact area against load")
        if np.any(np.isfinite(curve.get("mean_gap_m", np.nan))):   # not in runs of older versions
            h_rms = float(np.std(heights)) if heights is not None else g.get("rms_height")
            draw("mean_gap.png", mean_gap, curve, e_star, h_rms, window=window,
                 title=f"{name}: mean gap against load")
    if fields is not None:
        row = chosen - 1
        what = (f"{name}, step {int(curve['step'][row])}: δ = {curve['approach_m'][row]:.4g} m, "
                f"F = {curve['force_N'][row]:.4g} N")
        draw("pressure_map.png", pressure_map, fields["pressure"], fields["dx"], fields["dy"], title=what)
        if fields.get("gap") is not None:
            draw("histograms.png", histograms, fields["pressure"], fields["gap"], title=what)
    if "psd.png" in wanted and heights is not None and scene:
        generated = g["kind"] == "self-affine"
        draw("psd.png", psd, heights, fields["hdx"], fields["hdy"], bool(g.get("periodic")),
             hurst=g["hurst"] if generated else None, cutoffs=_band(g) if generated else None,
             title=f"{name}: power spectrum of the heights")
    if os.path.exists(path("history.csv")):
        draw("error_vs_time.png", error_vs_time, read_csv(path("history.csv")),
             title=f"{name}: error against run time")


def _band(g: dict) -> tuple[float, float]:
    """(q_r, q_s) [1/m] of a self-affine scene's geometry section."""
    from ...geometry.surfaces import self_affine_band
    return self_affine_band(g["nx"] * g["dx"], g["ny"] * g["dy"], g["dx"], g["dy"], g["rolloff_wavelength"],
                            g["short_cutoff_wavelength"])
