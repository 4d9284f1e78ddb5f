"""Scenes shared by the tests: a rough periodic cell under load and the adhesive sphere example
on a short path as scene files (for the tests that run the command line), and the adhesive
sphere example on 48 x 48 nodes as a validated scene (conftest's ``adhesive_sweep``)."""
import os
import textwrap

SCENES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "scenes")


def rough_scene(path, out, nx=32, values=(5e6, 1e7), ny=None):
    path.write_text(textwrap.dedent(f"""
        [geometry]
        kind = "self-affine"
        nx = {nx}
        {f"ny = {ny}" if ny else ""}
        dx = 1e-8
        rms_slope = 0.1
        seed = 3
        [material]
        e_star = 1e9
        [protocol]
        control = "mean_pressure"
        values = {list(values)}
        [output]
        directory = "{out}"
    """))
    return str(path)


def adhesive_sphere_scene(path, out):
    """The adhesive sphere example (examples/scenes/adhesive_sphere.toml: Tabor parameter 1, its
    96 x 96 grid) on a shorter path: loaded in steps of z0 / 2 past its jump-on (-489 pm) to 0,
    unloaded past its jump-off (-522 pm), each jump located by 3 bisections -- a jump-on, the
    most tensile state (step 3), a jump-off and the pull-off refinement in 10 steps."""
    import tomllib
    with open(os.path.join(SCENES, "adhesive_sphere.toml"), "rb") as f:
        scene = tomllib.load(f)
    g, law = scene["geometry"], scene["interaction"]
    values = [-0.6e-9, -0.45e-9, -0.3e-9, -0.15e-9, 0.0, -0.15e-9, -0.3e-9, -0.45e-9, -0.6e-9, -0.75e-9]
    path.write_text(textwrap.dedent(f"""
        name = "{scene['name']}-short"
        [geometry]
        kind = "sphere"
        radius = {g['radius']!r}
        nx = {g['nx']}
        dx = {g['dx']!r}
        [material]
        e_star = {scene['material']['e_star']!r}
        [interaction]
        law = "{law['law']}"
        work_of_adhesion = {law['work_of_adhesion']!r}
        z0 = {law['z0']!r}
        [protocol]
        control = "approach"
        values = {values!r}
        jump_refinement = 3
        [output]
        directory = "{out}"
    """))
    return str(path)


def adhesive_sweep_scene(out, **output):
    """The adhesive sphere example (Tabor parameter 1) on 48 x 48 nodes, loaded past its jump-on
    (-489 pm) to +0 and unloaded past its jump-off (-522 pm), in steps of z0 / 2."""
    from contactpetsc.app import scenes
    scene = scenes.load(os.path.join(SCENES, "adhesive_sphere.toml"))
    g = scene["geometry"]
    g["dx"] = g["dy"] = g["dx"] * g["nx"] / 48
    g["nx"] = g["ny"] = 48
    scene["protocol"].update(values=[-0.6e-9, -0.45e-9, -0.3e-9, -0.15e-9, 0.0, -0.15e-9, -0.3e-9, -0.45e-9,
                                     -0.6e-9, -0.75e-9], jump_refinement=3)
    scene["output"].update(directory=str(out), **output)
    return scenes.validate(scene)


def sweep_every_4th(out):
    """``adhesive_sweep_scene`` writing every 4th step's gap in float32, lengths shown in nm."""
    return adhesive_sweep_scene(out, field_every=4, field_precision="float32", fields=["gap"], length_unit="nm")
