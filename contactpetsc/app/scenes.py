"""Scenes: what to solve, as a TOML file or a dict, validated against ``SCHEMA``.

SI units throughout.  Every key is checked: unknown keys, wrong types and
values outside the accepted range raise ``SceneError`` naming the key, the
value and what is accepted; so do keys that contradict each other or that the
geometry kind or interaction law would ignore, loads too small to be more than
round-off, and a ``kind = "file"`` scene's height file (checked from its
metadata, so a dry run checks it too).  The built-in default scene (``DEFAULT_SCENE``)
is a scene like any other.  Sections and keys are documented in
docs/scenes.md (generated from ``SCHEMA`` by ``schema_markdown``).  The interaction
section is derived from the law registry (``physics.interactions.LAWS``): its law choices and
each law's parameters, required and refused, come from the laws' own declarations.
"""
from __future__ import annotations

import math
import os
import tomllib

from ..operators.layer import INTERFACES
from ..physics.interactions import LAWS, WORK_OF_ADHESION, adhesive_laws, relaxation_laws
from ..topography import DETREND, FILLS, FORMATS, HEIGHT_UNITS, HEIGHTS_ARE
from ..topography.detrend import check_size
from .scene_files import read_height_file
from .scene_material import check_hardness, check_material, e_star, layer  # noqa: F401 (e_star, layer: API)
from .scene_values import (LOAD_RESOLUTION, NONNEG, POISSON, POS, TOL, SceneError,  # noqa: F401 (API)
                           check_value, kind_name, range_text)


def _k(kind, default, unit, doc, rng=None, choices=None):
    return dict(kind=kind, default=default, unit=unit, doc=doc, range=rng, choices=choices)


_SCHEMA = {
    "name": _k(str, "scene", "", "label used in outputs"),
    "geometry": {
        "kind": _k(str, "sphere", "", "composite surface", choices=("sphere", "self-affine", "file", "tip")),
        "nx": _k(int, 128, "", "nodes along x (kind = file: the file's)", (2, 2**31 - 1, True, True)),
        "ny": _k(int, None, "", "nodes along y (default nx; kind = file: the file's)", (2, 2**31 - 1, True, True)),
        "dx": _k(float, None, "m", "grid spacing along x (required; kind = file: unless the file gives it)", POS),
        "dy": _k(float, None, "m", "grid spacing along y (default dx)", POS),
        "periodic": _k(bool, None, "", "periodic cell (default: true for self-affine; for a file, what the "
                       "file says, else false: an isolated window, zero-padded, not tapered)"),
        "radius": _k(float, None, "m", "sphere or tip radius (kind = sphere, tip)", POS),
        "tip": _k(str, "bent-commensurate", "", "atomic tip of Luan & Robbins (kind = tip; docs/studies.md)",
                  choices=("bent-commensurate", "bent-incommensurate", "amorphous", "stepped")),
        "atom_spacing": _k(float, None, "m", "nearest-neighbour atom spacing d (kind = tip)", POS),
        "atom_radius": _k(float, None, "m", "hard-sphere atom radius (kind = tip; default d / 2)", POS),
        "hurst": _k(float, 0.8, "", "Hurst exponent (self-affine)", (0.0, 1.0, False, False)),
        "rms_height": _k(float, None, "m", "rms height (self-affine; or rms_slope)", NONNEG),
        "rms_slope": _k(float, None, "", "rms slope (self-affine; or rms_height)", NONNEG),
        "rolloff_wavelength": _k(float, None, "m", "roll-off wavelength (default: cell size; above the "
                                 "short cut-off)", POS),
        "short_cutoff_wavelength": _k(float, None, "m", "short cut-off (default: 2 max(dx, dy); below "
                                      "the cell size)", POS),
        "seed": _k(int, 0, "", "random seed (self-affine, amorphous tip)", (0, 2**63 - 1, True, True)),
        "path": _k(str, None, "", "height file (kind = file; docs/topography.md): .npy or HDF5 (real "
                  "heights, shape (nx, ny); an HDF5 dataset or file with attribute axes = \"y,x\" is stored "
                  "(ny, nx), as step_NNNN.h5), a text matrix (lines are y, columns x), .xyz points, Gwyddion "
                  ".gsf or .gwy, ISO 25178 .x3p, Digital Surf .sur; nx, ny and, where the file gives them, dx, "
                  "dy are read from it (keys given must agree); its heights are the surface, peaks up, unless it or "
                  "heights_are says gap"),
        "dataset": _k(str, "heights", "", "HDF5 dataset name, or .gwy channel title (default: its first "
                      "channel) (kind = file)"),
        "format": _k(str, None, "", "height file format (kind = file; default: by the file's extension)",
                     choices=tuple(FORMATS)),
        "height_unit": _k(str, None, "", "unit of the file's heights (and of .xyz x, y) when the file states "
                          "none (kind = file; default m)", choices=tuple(HEIGHT_UNITS)),
        "detrend": _k(str, "none", "", "least-squares trend subtracted from the file's heights before the "
                      "min h = 0 shift (kind = file)", choices=DETREND),
        "heights_are": _k(str, None, "", "what the file's heights are (kind = file): surface (the sample's "
                          "surface, peaks up: the gap is h = max(z) - z, the highest point touches first) or "
                          "gap (a composite gap: the lowest point touches first); default: the file's stamp "
                          "(contactpetsc's step files say gap), else surface", choices=HEIGHTS_ARE),
        "fill": _k(str, "none", "", "points the file marks not measured (NaN): none refuses the file, "
                   "harmonic fills them by Laplace's equation with the measured points as boundary values "
                   "(kind = file; docs/topography.md)", choices=FILLS),
    },
    "material": {
        "e_star": _k(float, None, "Pa", "effective modulus E*, 1/E* = (1-nu1^2)/E1 + (1-nu2^2)/E2 (or "
                     "youngs_modulus and poisson_ratio)", POS),
        "youngs_modulus": _k(float, None, "Pa", "Young's modulus E of the elastic body against a rigid one "
                             "(with poisson_ratio; E* = E / (1 - nu^2)), instead of e_star", POS),
        "poisson_ratio": _k(float, None, "", "Poisson's ratio nu of the elastic body (with youngs_modulus)",
                            POISSON),
        "hardness": _k(float, None, "Pa", "hardness H: no node carries more pressure (perfectly plastic "
                       "asperities; default none; without adhesion; docs/formulation.md)", POS),
        "layer_thickness": _k(float, None, "m", "the elastic body is a layer of this thickness on a rigid base "
                              "(periodic cells; default: a half-space); thinner than f(2 pi t / L) = 1e-100 "
                              "(about 1e-107 L, incompressible bonded 1e-41 L) refused with the cell's range", POS),
        "layer_interface": _k(str, None, "", "the layer's contact with its base: bonded (no slip; the default "
                              "with a layer; needs poisson_ratio) or frictionless", choices=INTERFACES),
    },
    "interaction": {   # law choices and law parameters: filled in from the registry (schema())
        "law": _k(str, "none", "", "interaction law (docs/formulation.md; the registered laws are listed "
                  "below these tables)", choices=()),
        "work_of_adhesion": _k(float, 0.0, WORK_OF_ADHESION.unit, "w; 0 means no adhesion (and is the only "
                               "value for law none)", NONNEG),
        "element_integration": _k(bool, False, "", "the paper's element-integrated adhesion (Fig. 3) "
                                  "instead of nodal sampling"),
    },
    "protocol": {
        "control": _k(str, "approach", "", "what the values prescribe; with adhesion: approach "
                      "(loading where the values rise, unloading where they fall) or central_gap (the gap "
                      "at the lowest node, Greenwood's device for the full S-curve of a sphere)",
                      choices=("approach", "mean_pressure", "force", "central_gap")),
        "values": _k(list, None, "m, Pa or N", "the sequence of approaches, gaps or loads, solved in order "
                     "with warm starts (required)"),
        "refine_pull_off": _k(bool, True, "", "adhesive sweeps: refine the most tensile force by golden "
                              "section (solves on its branch: Newton, or relaxation with solver.method = "
                              "relaxation)"),
        "jump_refinement": _k(int, 6, "", "adhesive sweeps: bisections locating each jump", (0, 40, True, True)),
        "substeps": _k(int, 3, "", "adhesive sweeps: halvings of a step that fails, tried from the last "
                       "converged state (0: none)", (0, 20, True, True)),
        "max_step": _k(float, None, "z0", "adhesive sweeps under approach control (not the relaxation): the "
                       "longest step in approach, in units of the law's range (z0, rho or w / sigma0); a longer "
                       "step of the values is taken in equal sub-steps, so that the states are those of the "
                       "quasi-static path and not of the step (0: the values' own steps; default: 0 where "
                       "protocol.agreement checks the steps by the energy descent's increments, else 0.1)", NONNEG),
        "agreement": _k(float, None, "z0", "adhesive sweeps under approach control (not the relaxation): check "
                        "each (sub-)step against the quasi-static limit, to this largest gap difference (in units "
                        "of the law's range): under the energy descent (the default on periodic grids with "
                        "the nodal rule) the step descended as the descent's options say (whole by default) is "
                        "compared with it descended in 4, then 16, ... increments "
                        "until two agree; otherwise with its four quarters, dividing it into them, each checked "
                        "in turn, until they agree; the curve's solver column gives the verdict (0: no check; "
                        "default: 1e-3 under the energy descent, else 0)", NONNEG),
        "agreement_increment": _k(float, None, "z0", "adhesive sweeps with protocol.agreement under the energy "
                                  "descent: the longest increment the check starts from (its probe), in units of the "
                                  "law's range; the candidates take 4 and 16 times as many (0: the descent's own, "
                                  "-adhesion_descent_max_step; default: 0.25 where the check runs under the "
                                  "descent, else 0)", NONNEG),
        "agreement_levels": _k(int, 2, "", "adhesive sweeps with protocol.agreement: refinements at most (4^this "
                               "increments; or divisions into quarters, whose last are taken unchecked)",
                               (1, 10, True, True)),
    },
    "solver": {
        "method": _k(str, "newton", "", "with adhesion: SNES VI Newton, or the reference paper's MLMI "
                     "relaxation (eq. 7 for hard-wall laws, eq. 8 for lj with the nodal rule)",
                     choices=("newton", "relaxation")),
        "preconditioner": _k(str, "auto", "", "reduced-system preconditioner; auto: with adhesion chosen "
                             "per grid from its snap number (docs/formulation.md), without adhesion spectral",
                             choices=("auto", "spectral", "mlmi", "none")),
        "tol": _k(float, None, "", "error tolerance: complementarity error relative to the rms height "
                  "(default 1e-10); with adhesion, the errors in z0 (default 1e-8; relaxation: E_Total, 1e-4)", TOL),
        "options": _k(dict, {}, "", "further PETSc options under the solver's prefix (contact_, or "
                      "adhesion_ with adhesion), e.g. {snes_monitor = \"\", ksp_type = \"cg\"}"),
    },
    "output": {
        "directory": _k(str, "contactpetsc-output", "", "where curve.csv, history.csv and the fields go"),
        "fields": _k((bool, list), True, "", "write step_NNNN.h5 and step_NNNN.xdmf (ParaView) per step, "
                     "and fields.xdmf (all written steps as a time series): true (every field), false "
                     "(none; no restart), or a list of field names (pressure, gap, displacement, heights, "
                     "contact; with adhesion contact_pressure, adhesive_pressure, adhesive); the fields a "
                     "restart resumes from are always written (docs/outputs.md)"),
        "field_precision": _k(str, "float64", "", "the float fields of step files (masks are uint8; "
                              "heights and the restart fields stay float64)", choices=("float64", "float32")),
        "field_every": _k(int, 1, "", "write the fields of every k-th step, and of the last step, jumps, "
                          "unconverged steps and each new most tensile stable state (docs/outputs.md)",
                          (1, 2**31 - 1, True, True)),
        "length_unit": _k(str, "m", "", "the length unit ParaView shows (XDMF geometry, approach as time, "
                          "gap, displacement, heights); the HDF5 data stay in metres", choices=("m", "um", "nm")),
        "plots": _k(bool, False, "", "save the plots (needs matplotlib; docs/outputs.md): load_approach.png "
                    "(jumps, pull-off, closed forms on spheres), contact_area.png and mean_gap.png (rough "
                    "surfaces, periodic or a window, and periodic cells; two loaded steps or more), pressure_map.png "
                    "and histograms.png (the plotted step), psd.png (rough surfaces), error_vs_time.png"),
        "plot_step": _k(int, None, "", "the step whose pressure map and distributions are plotted "
                        "(default: the step at the largest approach, the most pressed)", (1, 2**31 - 1, True, True)),
        "atom_forces": _k(bool, False, "", "write atom_forces.csv: the force on each atom of a tip "
                          "(nodal pressure over its footprint) at every step (kind = tip)"),
    },
}

def law_keys(law: str) -> tuple:
    """The ``interaction`` keys a registered law takes besides work_of_adhesion."""
    return tuple(p.name for p in LAWS[law].parameters if p.name != WORK_OF_ADHESION.name)


def _law_section() -> dict:
    """The interaction section with the registered laws: their names as the law's choices and
    each parameter as a key (its doc naming the laws that take it)."""
    static = _SCHEMA["interaction"]
    section = {"law": dict(static["law"], choices=tuple(LAWS)), "work_of_adhesion": static["work_of_adhesion"]}
    for name, cls in LAWS.items():
        for p in cls.parameters[1:]:
            if p.name not in section:
                users = [n for n in LAWS if p.name in law_keys(n)]
                section[p.name] = _k(float, None, p.unit, f"{p.doc} ({', '.join(users)})", p.range)
    section["element_integration"] = static["element_integration"]
    return section


def schema() -> dict:
    """The scene schema with the laws registered now (``SCHEMA`` is this, read on access)."""
    return dict(_SCHEMA, interaction=_law_section())


def __getattr__(name):
    if name == "SCHEMA":
        return schema()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


DEFAULT_SCENE = {
    "name": "hertz-sphere",
    "geometry": {"kind": "sphere", "radius": 100e-6, "nx": 128, "dx": 5e-8},
    "material": {"e_star": 50e9},
    "protocol": {"control": "approach", "values": [(k / 5) ** 2 * 1e-8 for k in range(1, 6)]},
}


def validate(scene: dict) -> dict:
    """A complete scene (defaults filled in) or SceneError (a height file is opened to read its
    metadata; no rank talks to another: every rank reaches the same verdict on a shared file)."""
    if not isinstance(scene, dict):
        raise SceneError("a scene is a table of sections")
    out, spec_all = {}, schema()
    for key in scene:
        if key not in spec_all:
            raise SceneError(f"unknown key {key!r}; accepted: {', '.join(spec_all)}")
    for key, spec in spec_all.items():
        if "kind" in spec and isinstance(spec["kind"], type):  # a top-level key
            out[key] = check_value(key, spec, scene.get(key, spec["default"]))
            continue
        given = scene.get(key, {})
        if not isinstance(given, dict):
            raise SceneError(f"[{key}] must be a table")
        for sub in given:
            if sub not in spec:
                raise SceneError(f"unknown key {key}.{sub}; accepted: {', '.join(spec)}")
        section = {}
        for sub, s in spec.items():
            value = given.get(sub, s["default"])
            section[sub] = None if value is None else check_value(f"{key}.{sub}", s, value)
        out[key] = section
    g = out["geometry"]
    if g["kind"] == "file":
        if g["path"] is None:
            raise SceneError("geometry.path is required for geometry.kind = file")
        read_height_file(g, {k for k, v in scene.get("geometry", {}).items() if v is not None})
    for required in ("geometry.dx", "protocol.values"):
        sec, sub = required.split(".")
        if out[sec][sub] is None:
            raise SceneError(f"{required} is required")
    g["ny"] = g["ny"] or g["nx"]
    g["dy"] = g["dy"] or g["dx"]
    if g["periodic"] is None:
        g["periodic"] = g["kind"] == "self-affine"
    _check_geometry(g, _given(scene, "geometry"))
    if g["kind"] == "file":
        try:
            check_size(g["nx"], g["ny"], g["detrend"], "geometry.detrend")
        except ValueError as e:
            raise SceneError(str(e)) from None
    check_material(out, _given(scene, "material"))
    if out["output"]["atom_forces"] and g["kind"] != "tip":
        raise SceneError("output.atom_forces needs geometry.kind = tip (forces per atom of a tip)")
    _check_interaction(out, _given(scene, "interaction"))
    _check_fields(out, _given(scene, "output"))
    _check_protocol(out)
    check_hardness(out, adhesive(out))
    steps = len(out["protocol"]["values"])
    if out["output"]["plot_step"] is not None and out["output"]["plot_step"] > steps:
        raise SceneError(f"output.plot_step = {out['output']['plot_step']}: accepted range [1, {steps}] "
                         "(the steps of protocol.values)")
    return out


def _given(scene: dict, section: str) -> set:
    """Keys of ``section`` set to something other than their default (a validated scene
    validates again)."""
    return {k for k, v in scene.get(section, {}).items()
            if v is not None and v != schema()[section][k]["default"]}


#: the geometry keys each kind uses (besides kind, nx, ny, dx, dy, periodic)
KIND_KEYS = {"sphere": ("radius",),
             "tip": ("radius", "tip", "atom_spacing", "atom_radius", "seed"),
             "self-affine": ("hurst", "rms_height", "rms_slope", "rolloff_wavelength",
                             "short_cutoff_wavelength", "seed"),
             "file": ("path", "dataset", "format", "height_unit", "detrend", "heights_are", "fill")}


def _check_geometry(g: dict, given: set) -> None:
    kind = g["kind"]
    for key in sorted(given):
        users = [k for k, keys in KIND_KEYS.items() if key in keys]
        if users and kind not in users:
            raise SceneError(f"geometry.{key} is not used by geometry.kind = {kind!r} (only by "
                             f"kind = {', '.join(users)})")
    for key in {"sphere": ("radius",), "tip": ("radius", "atom_spacing")}.get(kind, ()):
        if g[key] is None:
            raise SceneError(f"geometry.{key} is required for geometry.kind = {kind}")
    size = max(g["nx"] * g["dx"], g["ny"] * g["dy"])
    if kind == "self-affine":
        if (g["rms_height"] is None) == (g["rms_slope"] is None):
            raise SceneError("give exactly one of geometry.rms_height or geometry.rms_slope")
        short = g["short_cutoff_wavelength"] or 2 * max(g["dx"], g["dy"])
        rolloff = g["rolloff_wavelength"] or size
        if g["short_cutoff_wavelength"] is not None and short >= size:
            raise SceneError(f"geometry.short_cutoff_wavelength = {short!r}: accepted range (0, {size:g}) "
                             f"m (below the cell size max(nx dx, ny dy): longer cut-offs leave no modes)")
        if short >= rolloff:
            raise SceneError(f"geometry.rolloff_wavelength = {rolloff!r} m (default: the cell size) must "
                             f"exceed geometry.short_cutoff_wavelength = {short!r} m (default: 2 max(dx, "
                             f"dy)): the self-affine band between them is empty")
    if kind == "tip":
        # tips.make_tip: atoms must cover the window and 2 atom radii around it
        spacing = g["atom_spacing"] * (0.94 if g["tip"] == "bent-incommensurate" else 1.0)
        atom_radius = g["atom_radius"] or 0.5 * spacing
        need = 0.5 * size + 2 * atom_radius
        if g["radius"] <= need:
            raise SceneError(f"geometry.radius = {g['radius']!r}: accepted range ({need:g}, inf) m for "
                             f"this window (half of max(nx dx, ny dy) plus 2 atom radii): the tip must "
                             f"be wider than the grid")


def _check_interaction(out: dict, given: set) -> None:
    it, law = out["interaction"], out["interaction"]["law"]
    if not LAWS[law].parameters and it["work_of_adhesion"] > 0:
        raise SceneError(f"interaction.work_of_adhesion = {it['work_of_adhesion']!r} with "
                         f"interaction.law = {law!r}: set a law ({', '.join(adhesive_laws())}) for "
                         f"adhesion, or work_of_adhesion = 0")
    for key in sorted(given - {"law", "work_of_adhesion", "element_integration"}):
        if key not in law_keys(law):
            users = [n for n in LAWS if key in law_keys(n)]
            raise SceneError(f"interaction.{key} is not used by interaction.law = {law!r} (only by "
                             f"law = {', '.join(users)})")
    if not adhesive(out):
        if it["element_integration"]:
            raise SceneError("interaction.element_integration = true needs adhesion (interaction.law "
                             "and interaction.work_of_adhesion > 0)")
        if out["solver"]["method"] == "relaxation":
            raise SceneError("solver.method = 'relaxation' is the adhesive relaxation: it needs adhesion "
                             "(interaction.law and interaction.work_of_adhesion > 0)")
        if out["protocol"]["control"] == "central_gap":
            raise SceneError("protocol.control = 'central_gap' needs adhesion (interaction.law and "
                             "interaction.work_of_adhesion > 0)")
        return
    for needed in law_keys(law):
        if it[needed] is None:
            raise SceneError(f"interaction.{needed} is required for interaction.law = {law}")
    if out["protocol"]["control"] in ("mean_pressure", "force"):
        raise SceneError(f"protocol.control = {out['protocol']['control']!r} with adhesion: load "
                         f"control is unstable on parts of adhesive paths; use approach or central_gap")
    if out["solver"]["method"] == "relaxation":
        if law not in relaxation_laws():
            raise SceneError(f"solver.method = 'relaxation' needs a law with a hard wall or a repulsive branch "
                             f"({', '.join(relaxation_laws())}); law {law!r} is solved by newton")
        if not LAWS[law].hard_wall and it["element_integration"]:
            raise SceneError(f"solver.method = 'relaxation' with interaction.law = {law!r} (eq. 8) needs the "
                             f"nodal rule: set interaction.element_integration = false, or solver.method = "
                             f"'newton'")


def _check_fields(out: dict, given: set) -> None:
    """output.fields: true, false or a non-empty list of this scene's field names, without
    repeats; the keys that shape field files only with fields."""
    from .output import available_fields
    o = out["output"]
    names = available_fields(adhesive(out))
    if isinstance(o["fields"], list):
        bad = [f for f in o["fields"] if f not in names]
        if not o["fields"] or bad or len(set(o["fields"])) != len(o["fields"]):
            why = (f"{bad[0]!r} is not a field of this scene" if bad else "an empty list" if not o["fields"]
                   else "a field named twice")
            raise SceneError(f"output.fields = {o['fields']!r}: {why}; accepted: true, false or a list of "
                             f"{', '.join(names)}" + ("" if adhesive(out) else
                                                      " (contact_pressure, adhesive_pressure, adhesive: "
                                                      "with adhesion)"))
    if o["fields"] is False:
        for key in sorted(given & {"field_precision", "field_every", "length_unit"}):
            raise SceneError(f"output.{key} shapes the field files: it needs output.fields (true or a list), "
                             f"not false")


def _check_protocol(out: dict) -> None:
    """Values must be finite numbers, loads positive, and no load so small that it is round-off:
    loads below LOAD_RESOLUTION E* (mean pressure) or E* nx dx ny dy (force) would be solved to a
    relative error that means nothing.  Approaches and gaps are displacements: one of round-off
    size (an arange through zero) is solved as zero."""
    control, values = out["protocol"]["control"], out["protocol"]["values"]
    if not values or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                             and math.isfinite(v) for v in values):
        raise SceneError(f"protocol.values = {values!r}: a non-empty list of finite numbers")
    if control in ("mean_pressure", "force") and min(values) <= 0:
        raise SceneError(f"protocol.values = {values!r}: loads must be > 0 without adhesion")
    g, e_star_value = out["geometry"], e_star(out)
    smallest, unit, what = {
        "mean_pressure": (e_star_value, "Pa", "1e-12 material.e_star"),
        "force": (e_star_value * g["nx"] * g["dx"] * g["ny"] * g["dy"], "N",
                  "1e-12 material.e_star times the window area nx dx ny dy"),
    }.get(control, (0.0, "m", ""))   # an approach or gap of round-off size is just zero
    smallest *= LOAD_RESOLUTION
    tiny = [v for v in values if v != 0 and abs(v) < smallest]
    if tiny:
        raise SceneError(f"protocol.values: {tiny[0]!r} {unit} is below {what} (round-off, not a "
                         f"{control.replace('_', ' ')}); accepted: [{smallest:.3g}, inf) {unit}")


def adhesive(scene: dict) -> bool:
    """Whether a validated scene has adhesion (a law other than none and w > 0)."""
    it = scene["interaction"]
    return bool(LAWS[it["law"]].parameters) and it["work_of_adhesion"] > 0


def load(path: str) -> dict:
    """Read and validate a TOML scene file; a relative ``geometry.path`` is taken from the scene
    file's directory."""
    try:
        with open(path, "rb") as f:
            data = tomllib.load(f)
    except OSError as exc:
        raise SceneError(f"cannot read scene {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise SceneError(f"scene {path} is not valid TOML: {exc}") from None
    g = data.get("geometry")
    if isinstance(g, dict) and isinstance(g.get("path"), str) and not os.path.isabs(g["path"]):
        g["path"] = os.path.join(os.path.dirname(path), g["path"])   # next to the scene file
    return validate(data)


def schema_markdown() -> str:
    """The schema as Markdown tables, then the registered laws (docs/scenes.md)."""
    lines = []
    for key, spec in schema().items():
        items = [(key, spec)] if isinstance(spec.get("kind"), type) else \
            [(f"{key}.{sub}", s) for sub, s in spec.items()]
        lines += [f"### `{key}`", "", "| key | type | unit | default | accepted | meaning |",
                  "|---|---|---|---|---|---|"]
        for name, s in items:
            acc = ", ".join(s["choices"]) if s["choices"] else (range_text(s["range"]) if s["range"] else "")
            lines.append(f"| `{name}` | {kind_name(s['kind'])} | {s['unit']} | {s['default']!r} | {acc} | {s['doc']} |")
        lines.append("")
    lines += ["### Interaction laws", "", "| law | parameters | meaning |", "|---|---|---|"]
    for name, cls in LAWS.items():
        params = ", ".join(f"`{p.name}` [{p.unit}]" for p in cls.parameters)
        lines.append(f"| `{name}` | {params} | {cls.summary} |")
    lines.append("")
    return "\n".join(lines)
