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
