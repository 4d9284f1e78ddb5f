"""Which side of a measured map is pressed: its heights are the surface, peaks up.

Truths: a flat film with one bump, pressed a little, touches at the bump's apex and nowhere
else; a sparse field of identical spherical particles on a flat film (a strongly skewed
surface), placed symmetrically in an isolated window, shares a load equally among its
particles, so its contact area is N pi a^2 with Hertz's a = (3 F R / 4 N E*)^(1/3); a step
file's heights (a gap, stamped so) fed back are pressed from the same side as in the run that
wrote them.  Files are written as an instrument writes them: the sample's surface, peaks up.
"""
import numpy as np
import pytest

from contactpetsc.app import builder, scenes
from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid
from contactpetsc.solvers import ContactProblem

E_STAR = 10e9


def write_matrix(path, z, dx):
    """A Gwyddion ASCII export of the surface z[i, j] = z(x_i, y_j) [m], lines are y."""
    nx, ny = z.shape
    with open(path, "w") as f:
        f.write(f"# Channel: Height\n# Width: {nx * dx:.17g} m\n# Height: {ny * dx:.17g} m\n"
                "# Value units: m\n")
        for line in z.T:
            f.write(" ".join(f"{v:.17g}" for v in line) + "\n")


def shared_file(coll, shared_tmp, name, z, dx):
    path = shared_tmp / name
    if coll.rank == 0:
        write_matrix(path, z, dx)
    coll.comm.Barrier()
    return str(path)


def test_a_bump_touches_at_its_apex_only(coll, shared_tmp):
    n, dx = 48, 1e-9
    x, y = np.meshgrid(np.arange(n) * dx, np.arange(n) * dx, indexing="ij")
    apex = (30, 17)                                       # off-centre: a flip would move it
    r2 = (x - apex[0] * dx) ** 2 + (y - apex[1] * dx) ** 2
    z = 2e-9 + 10e-9 * np.exp(-r2 / (2 * (4 * dx) ** 2))  # a film at 2 nm, a 10 nm bump
    path = shared_file(coll, shared_tmp, "bump.txt", z, dx)
    scene = scenes.validate({"geometry": {"kind": "file", "path": path},
                             "material": {"e_star": E_STAR}, "protocol": {"values": [1e-9]}})
    assert scene["geometry"]["heights_are"] == "surface"
    grid = builder.build_grid(scene)
    h = grid.gather(builder.build_heights(scene, grid))
    assert coll.max(np.abs(h - (z.max() - z)).max()) <= 1e-24
    assert coll.all(np.unravel_index(np.argmin(h), h.shape) == apex)
    state = ContactProblem(grid, builder.build_heights(scene, grid), E_STAR).solve(approach=1e-9)
    p = grid.gather(state.pressure)
    touching = np.argwhere(p > 0)
    assert coll.all(len(touching) > 0)
    # every node in contact lies on the bump's cap, within the 1 nm it was pressed
    assert coll.all(np.all(z[p > 0] >= z.max() - 1e-9))
    assert coll.all(np.all(np.hypot(*(touching - apex).T) <= 4))
    assert coll.all(state.contact_fraction < 0.02)


def particles_on_film(n, dx, radius, cap, centres):
    """Spherical caps of ``radius``, ``cap`` high, on a flat film at z = 0 [m]."""
    x, y = np.meshgrid(np.arange(n) * dx, np.arange(n) * dx, indexing="ij")
    z = np.zeros((n, n))
    for cx, cy in centres:
        r2 = (x - cx * dx) ** 2 + (y - cy * dx) ** 2
        z = np.maximum(z, np.sqrt(np.maximum(radius ** 2 - r2, 0.0)) - (radius - cap))
    return z


def test_particles_on_a_film_share_the_load_as_hertz_says(coll, shared_tmp):
    # 4 identical particles on the corners of a square centred in the window: by symmetry each
    # carries F / 4, and each contact is Hertz's (the others' displacement is nearly uniform
    # over it); with the map upside down the film's wide flat would touch instead
    n, dx, radius, cap = 128, 1e-9, 40e-9, 3e-9
    centres = [(32, 32), (32, 95), (95, 32), (95, 95)]
    z = particles_on_film(n, dx, radius, cap, centres)
    skew = np.mean((z - z.mean()) ** 3) / z.std() ** 3
    assert skew > 2                                        # strongly skewed: peaks up
    path = shared_file(coll, shared_tmp, "particles.txt", z, dx)
    grid = SurfaceGrid(n, n, dx, periodic=False)
    h = surfaces.from_topography(grid, path)
    a = 8 * dx                                             # Hertz radius of each contact
    force = 4 * 4 * E_STAR * a ** 3 / (3 * radius)
    state = ContactProblem(grid, h, E_STAR).solve(force=force)
    p = grid.gather(state.pressure)
    area = np.count_nonzero(p > 0) * dx * dx
    assert coll.max(abs(area / (4 * np.pi * a ** 2) - 1)) < 0.04
    # each particle carries its quarter, and the film none
    x, y = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    for cx, cy in centres:
        near = np.hypot(x - cx, y - cy) < 20
        assert coll.max(abs(p[near].sum() * dx * dx / (force / 4) - 1)) < 1e-6
    assert coll.all(np.all(p[z == 0] == 0))


def test_a_step_file_is_pressed_from_the_side_it_was_run(coll, shared_tmp):
    """The run's h (a gap, stamped heights_are = "gap") fed back gives the same h."""
    import types
    from contactpetsc.app import output
    n, dx = 16, 1e-9
    grid = SurfaceGrid(n, n, dx, periodic=False)
    h = surfaces.from_function(grid, lambda x, y: 1e-9 * ((x / dx - 3) ** 2 + 0.5 * (y / dx - 11) ** 2) / 50)
    zero = grid.create_vec(0.0)
    state = types.SimpleNamespace(pressure=zero, gap=h.copy(), displacement=zero, approach=0.0,
                                  mean_pressure=0.0, force=0.0, contact_fraction=0.0,
                                  complementarity_error=0.0, converged=True)
    path = output.write_state(str(shared_tmp), 1, grid, h, state, {"scene": "{}"})
    scene = scenes.validate({"geometry": {"kind": "file", "path": path},
                             "material": {"e_star": E_STAR}, "protocol": {"values": [1e-10]}})
    assert scene["geometry"]["heights_are"] == "gap"
    back = grid.gather(builder.build_heights(scene, grid))
    assert coll.max(np.abs(back - grid.gather(h)).max()) <= 1e-24
    # a scene that says otherwise is refused, naming the key
    with pytest.raises(scenes.SceneError, match="geometry.heights_are"):
        scenes.validate({"geometry": {"kind": "file", "path": path, "heights_are": "surface"},
                         "material": {"e_star": E_STAR}, "protocol": {"values": [1e-10]}})
    with pytest.raises(GridError, match="heights_are"):
        surfaces.from_topography(grid, path, heights_are="surface")


def test_a_file_that_holds_a_gap_is_pressed_from_its_lowest_point(coll, shared_tmp):
    n, dx = 24, 1e-9
    x, y = np.meshgrid(np.arange(n) * dx, np.arange(n) * dx, indexing="ij")
    g = 3e-9 + 1e-9 * ((x / dx - 5) ** 2 + (y / dx - 19) ** 2) / 40   # lowest at node (5, 19)
    path = shared_file(coll, shared_tmp, "gap.txt", g, dx)
    scene = scenes.validate({"geometry": {"kind": "file", "path": path, "heights_are": "gap"},
                             "material": {"e_star": E_STAR}, "protocol": {"values": [1e-10]}})
    grid = builder.build_grid(scene)
    h = grid.gather(builder.build_heights(scene, grid))
    assert coll.max(np.abs(h - (g - g.min())).max()) <= 1e-24
    surface = grid.gather(surfaces.from_topography(grid, path))
    assert coll.max(np.abs(surface - (g.max() - g)).max()) <= 1e-24


def test_an_afm_scan_gives_the_peers_contact_under_the_same_load(coll):
    """The real AFM scan matrix-3.txt (tests/data/topography-samples), detrended, under the same
    force on an isolated window, as ContactMechanics solved it reading the file itself
    (contact_reference.json, run_scripts/checks/measured_peer.py): the same contact nodes and the
    same largest pressures.  Upside down the contact is 64 % larger."""
    import json
    import os
    from contactpetsc.topography import read_topography
    samples = os.path.join(os.path.dirname(__file__), "data", "topography-samples")
    with open(os.path.join(samples, "contact_reference.json")) as f:
        ref = json.load(f)["matrix-3.txt"]
    path = os.path.join(samples, "matrix-3.txt")
    topo = read_topography(path, metadata_only=True)
    grid = SurfaceGrid(*topo.shape, topo.dx, topo.dy, periodic=False)
    h = surfaces.from_topography(grid, path, detrend="mean-plane")
    p = grid.gather(ContactProblem(grid, h, ref["estar_Pa"]).solve(force=ref["force_N"]).pressure)
    assert coll.all(np.count_nonzero(p > 0) == ref["contact_nodes"])
    for node, want in ref["largest_pressures_Pa"].items():
        i, j = map(int, node.split(","))
        assert coll.max(abs(p[i, j] / want - 1)) < 1e-6
