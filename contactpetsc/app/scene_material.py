"""Scene material checks and the quantities derived from the material section: E*, the
elastic layer, and the hardness cap (SI units)."""
from __future__ import annotations

from .scene_values import POISSON, SceneError, range_text


def e_star(scene: dict) -> float:
    """E* [Pa] of a validated scene: material.e_star, or E / (1 - nu^2) from youngs_modulus and
    poisson_ratio (the elastic body against a rigid one)."""
    m = scene["material"]
    if m["e_star"] is not None:
        return m["e_star"]
    return m["youngs_modulus"] / (1.0 - m["poisson_ratio"] ** 2)


def layer(scene: dict):
    """The scene's ``operators.Layer`` (material.layer_thickness), or None for a half-space."""
    from ..operators.layer import Layer
    m = scene["material"]
    if m["layer_thickness"] is None:
        return None
    return Layer(m["layer_thickness"], m["layer_interface"], m["poisson_ratio"])


def check_material(out: dict, given: set) -> None:
    m = out["material"]
    if m["e_star"] is None and m["youngs_modulus"] is None:
        raise SceneError("material.e_star is required (or material.youngs_modulus with material.poisson_ratio)")
    if m["e_star"] is not None and m["youngs_modulus"] is not None:
        raise SceneError("give exactly one of material.e_star or material.youngs_modulus (with "
                         "material.poisson_ratio): both are given")
    if m["youngs_modulus"] is not None and m["poisson_ratio"] is None:
        raise SceneError(f"material.youngs_modulus needs material.poisson_ratio, in {range_text(POISSON)}")
    if m["e_star"] is not None and m["poisson_ratio"] is not None:
        raise SceneError("material.poisson_ratio goes with material.youngs_modulus, not with material.e_star "
                         "(E* = E / (1 - nu^2)); give youngs_modulus and poisson_ratio instead of e_star")
    if m["layer_thickness"] is None:
        if "layer_interface" in given:
            raise SceneError("material.layer_interface needs material.layer_thickness (a layer on a rigid base)")
        return
    m["layer_interface"] = m["layer_interface"] or "bonded"
    if not out["geometry"]["periodic"]:
        raise SceneError(f"material.layer_thickness = {m['layer_thickness']!r} needs a periodic cell "
                         f"(geometry.periodic = true): the layer's kernel is a Fourier kernel")
    if m["layer_interface"] == "bonded" and m["poisson_ratio"] is None:
        raise SceneError("material.layer_interface = 'bonded' needs Poisson's ratio: give material.youngs_modulus "
                         "and material.poisson_ratio instead of material.e_star (or layer_interface = "
                         "'frictionless', which does not depend on it)")
    from ..operators.layer import check_thickness
    g = out["geometry"]
    try:
        check_thickness(layer(out), (g["nx"] * g["dx"], g["ny"] * g["dy"]), "material.layer_thickness")
    except ValueError as e:
        raise SceneError(str(e)) from None


def check_hardness(out: dict, adhesive: bool) -> None:
    """A hardness is an upper bound of the non-adhesive problem; a load must stay below it."""
    hardness = out["material"]["hardness"]
    if hardness is None:
        return
    if adhesive:
        raise SceneError("material.hardness with adhesion (interaction.law and interaction.work_of_adhesion > 0) "
                         "is not supported: the hardness caps the pressure of the non-adhesive problem")
    control, values, g = out["protocol"]["control"], out["protocol"]["values"], out["geometry"]
    if control in ("mean_pressure", "force"):
        high, unit = ((hardness, "Pa") if control == "mean_pressure"
                      else (hardness * g["nx"] * g["dx"] * g["ny"] * g["dy"], "N"))
        above = [v for v in values if v >= high]
        if above:
            raise SceneError(f"protocol.values: {above[0]!r} {unit} is not below material.hardness = {hardness!r} Pa"
                             + (" times the window area nx dx ny dy" if control == "force" else "")
                             + f" (no node carries more than H); accepted: (0, {high:.6g}) {unit}")
