"""A rough periodic cell under load as a scene file, for the tests that run the command line."""
import textwrap


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
    import os
    import tomllib
    example = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples", "scenes",
                           "adhesive_sphere.toml")
    with open(example, "rb") as f:
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
