"""The results researchers publish: the mean gap of curve.csv against closed forms and the
step files, the closed forms drawn over sphere curves, the power spectrum of a generated
surface against its Hurst exponent, and the plots (drawn only when asked)."""
import csv
import json
import os
import subprocess
import sys

import h5py
import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import plots, runner, scenes
from contactpetsc.physics import closed_forms as cf


def rough(out, nx=32, values=(2e6, 1e7, 5e7), **output):
    return scenes.validate({
        "name": "rough-plots", "geometry": {"kind": "self-affine", "nx": nx, "dx": 1e-8, "rms_slope": 0.1,
                                            "hurst": 0.7, "seed": 5},
        "material": {"e_star": 1e9}, "protocol": {"control": "mean_pressure", "values": list(values)},
        "output": dict({"directory": str(out)}, **output)})


def read_rows(path):
    with open(path) as f:
        return list(csv.DictReader(f))


# -- closed forms ----------------------------------------------------------------------------
@pytest.mark.serial   # closed forms: no communicator
def test_jkr_and_dmt_curves_have_their_known_points():
    """JKR: pull-off -1.5 pi R w at A^(3/2) = sqrt(6)/2, zero load at a0^2 = 3 R delta0
    (A = 6^(1/3), Delta = 6^(2/3) / 3); DMT: pull-off -2 pi R w at delta = 0."""
    a = np.linspace(0.05, 3.0, 200001)
    delta, load = cf.jkr_curve(a)
    assert load.min() == pytest.approx(-1.5, rel=1e-8)
    assert a[np.argmin(load)] == pytest.approx((np.sqrt(6) / 2) ** (2 / 3), rel=1e-4)
    d0, p0 = cf.jkr_curve(6 ** (1 / 3))
    assert p0 == pytest.approx(0.0, abs=1e-12) and d0 == pytest.approx(6 ** (2 / 3) / 3, rel=1e-12)
    assert cf.dmt_curve(0.0) == (0.0, -2.0)


@pytest.mark.serial   # closed forms: no communicator
@pytest.mark.parametrize("lam, limit", [(1e3, cf.jkr_curve), (1e-6, cf.dmt_curve)])
def test_maugis_approach_tends_to_jkr_and_dmt(lam, limit):
    """Maugis-Dugdale (A, Delta, P_bar) on the JKR curve for large lambda and on DMT for small,
    compared at the same contact radius A in [0.8, 2] (DMT is approached as sqrt(lambda))."""
    a, delta, load = cf.maugis_approach(lam, 1.0 + np.logspace(-12, 6, 200001))
    keep = (a > 0.8) & (a < 2.0)
    d_ref, p_ref = limit(a[keep])
    assert np.max(np.abs(delta[keep] - d_ref)) < 2e-2 and np.max(np.abs(load[keep] - p_ref)) < 2e-2


@pytest.mark.serial   # closed forms: no communicator
def test_maugis_units_and_lambda_of_the_lennard_jones_law():
    """lambda = 2 sigma0 (R / (pi w K^2))^(1/3) with sigma0 the LJ peak 16 w / (9 sqrt 3 z0) is
    1.157 mu (Johnson & Greenwood 1997); the units put a JKR pull-off at -1.5 pi R w."""
    from contactpetsc.physics.interactions import make_law, tabor_parameter
    e_star, r, w, z0 = 10e9, 30e-9, 0.3, 0.3e-9
    law = make_law("lj", work_of_adhesion=w, z0=z0)
    assert cf.maugis_lambda(e_star, r, w, law.peak_attraction) / tabor_parameter(r, w, e_star, z0) == \
        pytest.approx(1.157, abs=1e-3)
    d_unit, f_unit = cf.maugis_units(e_star, r, w)
    assert f_unit == pytest.approx(np.pi * w * r)
    # Delta = A^2 is Hertz's delta = a^2 / R with a = A (pi w R^2 / K)^(1/3)
    a = 1.7 * (np.pi * w * r * r / (4 * e_star / 3)) ** (1 / 3)
    assert 1.7 ** 2 * d_unit == pytest.approx(a * a / r, rel=1e-12)
    assert cf.KAPPA_PERSSON == pytest.approx(1.5958, abs=1e-4) and cf.KAPPA_BGT == pytest.approx(2.5066, abs=1e-4)


# -- the surface's spectrum ------------------------------------------------------------------
@pytest.mark.parametrize("hurst", [0.3, 0.8])
def test_psd_of_a_generated_surface_has_the_hurst_slope(coll, hurst):
    """C(q) ~ q^(-2(1+H)) between roll-off and cut-off (fitted on log-log, the band's ends left
    out); the rms slope is the one asked for."""
    from contactpetsc.geometry.surfaces import self_affine
    from contactpetsc.grid import SurfaceGrid
    n, dx = 256, 1e-8
    grid = SurfaceGrid(n, n, dx, periodic=True, comm=PETSc.COMM_WORLD)
    h = grid.gather(self_affine(grid, hurst=hurst, seed=11, rms_slope=0.2, rolloff_wavelength=n * dx / 8,
                                short_cutoff_wavelength=4 * dx), root=None).T
    q, c = plots.radial_psd(h, dx, dx)
    q_r, q_s = 2 * np.pi / (n * dx / 8), 2 * np.pi / (4 * dx)
    band = (q > 1.5 * q_r) & (q < q_s / 1.5)
    slope = np.polyfit(np.log(q[band]), np.log(c[band]), 1)[0]
    assert coll.max(abs(slope + 2 * (1 + hurst))) < 0.15
    assert coll.max(abs(plots.rms_slope(h, dx, dx) / 0.2 - 1)) < 1e-10


# -- the mean gap ----------------------------------------------------------------------------
def test_mean_gap_of_a_hertz_contact_is_the_closed_form_over_the_window(coll, shared_tmp):
    """Over an isolated window, the mean displacement mean(g) - mean(h) + delta of a smooth sphere
    is that of Hertz's gap outside the contact (Maugis 1992; zero inside) averaged over the
    nodes: within 1 % with a contact radius of 5.7 grid spacings (measured 0.15 %)."""
    from contactpetsc.geometry.surfaces import centre
    from contactpetsc.grid import SurfaceGrid
    r_s, dx, nx, d = 1e-4, 5e-8, 32, 0.8e-9
    out = shared_tmp / "hertz"
    runner.run(scenes.validate({"geometry": {"kind": "sphere", "radius": r_s, "nx": nx, "dx": dx},
                                "material": {"e_star": 50e9}, "protocol": {"values": [d]},
                                "output": {"directory": str(out)}}), comm=PETSc.COMM_WORLD)
    row = read_rows(out / "curve.csv")[0]
    xc, yc = centre(SurfaceGrid(nx, nx, dx, periodic=False, comm=PETSc.COMM_SELF))
    x = np.arange(nx) * dx
    r = np.hypot(*np.meshgrid(x - xc, x - yc))
    a = float(cf.hertz_contact_radius(r_s, d))
    g = np.where(r > a, cf.hertz_gap_outside(r_s, a, np.maximum(r, a)), 0.0)
    h_mean = np.mean(r * r / (2 * r_s))
    v_exact, v = g.mean() - h_mean + d, float(row["mean_gap_m"]) - h_mean + d
    assert coll.max(abs(v / v_exact - 1)) < 1e-2
    assert 0 < float(row["mean_gap_error_m"]) < 1e-3 * v_exact


def test_mean_gap_column_is_the_step_files_gap_and_the_periodic_mean_plane(coll, shared_tmp):
    """curve.csv's mean_gap_m is the mean separation max(g, 0) of the step file's gap; on a periodic cell it is
    mean(h) - delta (K has no mean mode); mean_gap_error_m is the complementarity error in
    metres (relative to the rms height); history.csv labels its rows with their step."""
    out = shared_tmp / "rough"
    runner.run(rough(out), comm=PETSc.COMM_WORLD)
    rows = read_rows(out / "curve.csv")
    columns = list(rows[0])
    assert columns[columns.index("mean_gap_m") + 1] == "mean_gap_error_m"
    for k, r in enumerate(rows, 1):
        with h5py.File(out / f"step_{k:04d}.h5", "r") as f:
            gap, h = f["gap"][:], f["heights"][:]
        assert coll.max(abs(float(r["mean_gap_m"]) / np.maximum(gap, 0).mean() - 1)) < 1e-12
        expect = h.mean() - float(r["approach_m"])
        assert coll.max(abs(float(r["mean_gap_m"]) - expect) / h.std()) < 1e-12
        assert float(r["mean_gap_error_m"]) == pytest.approx(float(r["complementarity_error"]) * h.std(), rel=1e-9)
    # the gap falls as the load rises
    assert coll.all(np.all(np.diff([float(r["mean_gap_m"]) for r in rows]) < 0))
    steps = [r["step"] for r in read_rows(out / "history.csv")]
    assert coll.all(set(steps) == {"1", "2", "3"} and steps == sorted(steps))


def test_mean_gap_with_a_hardness_is_the_separation_and_the_flattened_volume_closes_it(coll, shared_tmp):
    """Under a hardness the nodes at p = H overlap (g < 0, material flattened away): the mean
    gap is the surfaces' separation mean(max(g, 0)) of the step file's gap, and volume is
    conserved on a periodic cell: mean_gap_m - plastic_volume_m3 / (nx dx ny dy) = mean(h) - delta
    (K has no mean mode), the same identity as without a hardness."""
    out, hardness = shared_tmp / "plastic", 3e7
    scene = rough(out, values=(3e6, 1.5e7))
    scene["material"]["hardness"] = hardness
    runner.run(scenes.validate(scene), comm=PETSc.COMM_WORLD)
    for k, r in enumerate(read_rows(out / "curve.csv"), 1):
        with h5py.File(out / f"step_{k:04d}.h5", "r") as f:
            gap, h = f["gap"][:], f["heights"][:]
        assert coll.all(float(r["plastic_fraction"]) > 0 and gap.min() < 0)
        separation = float(r["mean_gap_m"])
        assert coll.max(abs(separation / np.maximum(gap, 0).mean() - 1)) < 1e-12
        plastic = float(r["plastic_volume_m3"]) / (h.size * 1e-8 * 1e-8)
        expect = h.mean() - float(r["approach_m"])
        assert coll.max(abs(separation - plastic - expect) / h.std()) < 1e-10
        assert coll.all(separation > expect)


def test_restart_of_a_run_without_the_new_columns(coll, shared_tmp):
    """A run written before mean_gap_m and history's step existed continues: its rows get nan,
    the new steps their values, every history row the step column."""
    out = shared_tmp / "old"
    runner.run(rough(out, values=(2e6, 1e7)), comm=PETSc.COMM_WORLD)
    world = PETSc.COMM_WORLD.tompi4py()
    if coll.rank == 0:
        for name, drop in (("curve.csv", ("mean_gap_m", "mean_gap_error_m")), ("history.csv", ("step",))):
            rows = read_rows(out / name)
            keep = [c for c in rows[0] if c not in drop]
            with open(out / name, "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=keep, extrasaction="ignore")
                w.writeheader()
                w.writerows(rows)
    world.Barrier()
    runner.run(rough(out), comm=PETSc.COMM_WORLD, restart=True)
    rows = read_rows(out / "curve.csv")
    gaps = [float(r["mean_gap_m"]) for r in rows]
    assert coll.all(np.isnan(gaps[:2]).all() and np.isfinite(gaps[2]))
    history = read_rows(out / "history.csv")
    assert coll.all(all(None not in r for r in history) and history[-1]["step"] == "3"
                    and history[0]["step"] == "nan")


# -- the plots -------------------------------------------------------------------------------
@pytest.mark.serial
def test_plots_are_off_unless_asked_and_cost_nothing_then(tmp_path):
    """A run without plots imports no matplotlib and gathers no field (SurfaceGrid.gather
    refuses in the child process)."""
    code = f"""
import sys, petsc4py
petsc4py.init(["plots-off-check"])   # argv[0] of python -c is "-c", an option to PETSc
from contactpetsc.grid import SurfaceGrid
def refuse(*a, **k):
    raise AssertionError("a field was gathered")
SurfaceGrid.gather = refuse
from contactpetsc.app import runner, scenes
scene = scenes.validate({{"geometry": {{"kind": "self-affine", "nx": 16, "dx": 1e-8, "rms_slope": 0.1}},
    "material": {{"e_star": 1e9}}, "protocol": {{"control": "mean_pressure", "values": [1e6]}},
    "output": {{"directory": {str(tmp_path / "out")!r}, "fields": False}}}})
runner.run(scene)
print("matplotlib" in sys.modules, sorted(m for m in sys.modules if m.startswith("matplotlib"))[:3])
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, OMP_NUM_THREADS="1"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip().splitlines()[-1].startswith("False"), proc.stdout
    assert not any(name.endswith(".png") for name in os.listdir(tmp_path / "out"))


def test_plots_of_a_rough_run_without_field_files(coll, shared_tmp):
    """With plots on, a rough periodic run without field files writes every plot of a rough
    surface, from the plotted step's fields gathered to rank 0 (the plot command draws them
    from step files, below)."""
    pytest.importorskip("matplotlib")
    names = {"load_approach.png", "contact_area.png", "mean_gap.png", "pressure_map.png", "histograms.png",
             "psd.png", "error_vs_time.png"}
    out = shared_tmp / "plots"
    scene = rough(out, plots=True, fields=False, plot_step=2)
    runner.run(scene, comm=PETSc.COMM_WORLD)
    assert coll.all(names == {f for f in os.listdir(out) if f.endswith(".png")} == set(plots.planned(scene)))
    sphere = scenes.validate({"geometry": {"kind": "sphere", "radius": 1e-4, "nx": 32, "dx": 5e-8},
                              "material": {"e_star": 50e9}, "protocol": {"values": [1e-9]}})
    assert set(plots.planned(sphere)) == names - {"contact_area.png", "mean_gap.png", "psd.png"}
    from matplotlib.image import imread
    for name in names:
        image = imread(out / name)
        assert image[..., :3].std() > 0.05, f"{name} is blank"


MEASURED = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "examples", "scenes",
                        "measured_surface.toml")


def test_plots_of_a_measured_window(coll, shared_tmp):
    """examples/scenes/measured_surface.toml (a non-periodic height file, 3 loaded steps) gets
    the load curves and the spectrum as a periodic rough cell does: every planned plot is
    written and drawn, and the load curves' axes name the window's nominal area."""
    pytest.importorskip("matplotlib")
    out = shared_tmp / "measured"
    scene = scenes.load(MEASURED)
    scene["output"].update(directory=str(out), plots=True)
    runner.run(scene, comm=PETSc.COMM_WORLD)
    names = set(plots.PLOTS)
    assert coll.all(names == set(plots.planned(scene)) == {f for f in os.listdir(out) if f.endswith(".png")})
    from matplotlib.image import imread
    for name in names:
        assert imread(out / name)[..., :3].std() > 0.05, f"{name} is blank"
    curve = plots.read_csv(out / "curve.csv")
    assert plots.loaded_steps(curve) == 3
    for draw in (plots.contact_area, plots.mean_gap):
        ax = draw(curve, 10e9, 0.04, window=True).axes[0]
        assert "window's area" in ax.get_xlabel() and "F / (nx dx ny dy)" in ax.get_xlabel()
    assert "nx dx ny dy" in plots.contact_area(curve, 10e9, window=True).axes[0].get_ylabel()


@pytest.mark.serial
def test_load_curves_are_planned_for_rough_surfaces_with_two_steps():
    """Self-affine and file surfaces, periodic or an isolated window, get contact_area.png and
    mean_gap.png when the path has two steps or more (plot_run also wants two loaded ones);
    a smooth isolated sphere does not; psd.png is for rough surfaces."""
    window = rough("x")
    window["geometry"]["periodic"] = False
    assert {"contact_area.png", "mean_gap.png", "psd.png"} <= set(plots.planned(window))
    one = rough("x", values=(1e7,))
    assert "contact_area.png" not in plots.planned(one) and "psd.png" in plots.planned(one)
    assert plots.loaded_steps({"mean_pressure_Pa": np.array([0.0, 1e6, 2e6]), "converged": np.array([1, 1, 0])}) == 1


@pytest.mark.serial
def test_plot_step_is_the_most_pressed_unless_asked():
    assert plots.plot_step([1.0, 3.0, 2.0], [1, 1, 1]) == 2
    assert plots.plot_step([1.0, 3.0, 2.0], [1, 0, 1]) == 3
    assert plots.plot_step([-3.0, 1.0, 1.0, -3.0], [1, 1, 1, 1]) == 3   # loading, unloading: the last on ties
    assert plots.plot_step([1.0, 3.0, 2.0], [1, 1, 1], requested=1) == 1
    with pytest.raises(ValueError, match=r"plot step 4 \(output.plot_step, or plot --step\): the run has steps 1 to 3"):
        plots.plot_step([1.0, 3.0, 2.0], [1, 1, 1], requested=4)
    with pytest.raises(scenes.SceneError, match=r"output.plot_step = 5: accepted range \[1, 3\]"):
        rough("x", plot_step=5)


@pytest.mark.serial
def test_new_plots_draw_the_data_and_the_references_they_are_given():
    """contact_area: the data and kappa p / (E* h'rms) for both kappas; mean_gap: the column on a
    log pressure axis; histograms: densities integrating to the share of the nodes drawn;
    error_vs_time: one colour per step; the sphere overlays: Hertz, and JKR's pull-off."""
    pytest.importorskip("matplotlib")
    e_star, slope = 1e9, 0.1
    p = np.array([1e6, 1e7, 1e8])
    curve = {"mean_pressure_Pa": p, "contact_fraction": 2.0 * p / (e_star * slope), "converged": np.ones(3),
             "mean_gap_m": np.array([3e-9, 2e-9, 1e-9]), "mean_gap_error_m": np.full(3, 1e-11)}
    ax = plots.contact_area(curve, e_star, slope).axes[0]
    assert ax.get_xscale() == ax.get_yscale() == "log"
    lines = {line.get_label().split(":")[0]: line for line in ax.lines}
    assert np.allclose(lines["computed (lowest load"].get_ydata(), curve["contact_fraction"])
    for name, kappa in (("Persson", cf.KAPPA_PERSSON), ("Bush-Gibson-Thomas", cf.KAPPA_BGT)):
        x, y = lines[name].get_xdata(), lines[name].get_ydata()
        assert np.allclose(y, kappa * x / slope)
    assert "κ = 2" in lines["computed (lowest load"].get_label()
    ax = plots.mean_gap(curve, e_star).axes[0]
    assert ax.get_xscale() == "log" and np.allclose(ax.lines[0].get_ydata(), [3, 2, 1])   # nm

    pressure = np.array([[0.0, 1e6, 2e6, -1e5], [0.0, 0.0, 3e6, 1e6]])
    gap = np.array([[1e-9, 0.0, 0.0, 2e-9], [3e-9, 5e-9, 0.0, 0.0]])
    fig = plots.histograms(pressure, gap)
    for ax, share in zip(fig.axes, (5 / 8, 4 / 8)):
        patch = ax.patches[0]
        edges, values = patch.get_data()[1], patch.get_data()[0]
        assert np.sum(values * np.diff(edges)) == pytest.approx(share)

    history = {"wall_time": np.arange(6.0), "fft_pairs": np.arange(6.0) * 10, "solve": np.array([0, 0, 1, 1, 2, 2]),
               "step": np.array([1, 1, 2, 2, np.nan, np.nan]), "complementarity_error": np.logspace(0, -5, 6)}
    ax = plots.error_vs_time(history).axes[0]
    from matplotlib.collections import LineCollection
    lines, = [c for c in ax.collections if isinstance(c, LineCollection)]
    assert len(lines.get_segments()) == 3                       # one per solve
    assert len({tuple(c) for c in lines.get_colors()}) == 3     # step 1, step 2, grey after the path

    sphere = scenes.validate({"geometry": {"kind": "sphere", "radius": 1e-4, "nx": 32, "dx": 5e-8},
                              "material": {"e_star": 50e9}, "protocol": {"values": [1e-9, 2e-9]}})
    (label, d, f), = plots.sphere_overlays(sphere, np.array([1e-9, 2e-9]))
    assert label == "Hertz" and np.allclose(f, cf.hertz_force(50e9, 1e-4, d))
    adhesive = scenes.validate({"geometry": {"kind": "sphere", "radius": 30e-9, "nx": 32, "dx": 0.3e-9},
                                "material": {"e_star": 10e9},
                                "interaction": {"law": "lj", "work_of_adhesion": 0.3, "z0": 0.3e-9},
                                "protocol": {"values": [-0.9e-9, 0.3e-9]}})
    got = {label.split(",")[0]: (d, f) for label, d, f in plots.sphere_overlays(adhesive, np.array([-0.9e-9, 0.3e-9]))}
    assert set(got) == {"DMT", "JKR", "Maugis-Dugdale"}
    assert np.nanmin(got["JKR"][1]) == pytest.approx(cf.jkr_pull_off(30e-9, 0.3), rel=1e-3)
    assert np.nanmin(got["DMT"][1]) == pytest.approx(cf.dmt_pull_off(30e-9, 0.3), rel=1e-3)


@pytest.mark.serial
def test_plot_command_draws_a_chosen_step(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "run"
    runner.run(rough(out), comm=PETSc.COMM_SELF)
    env = dict(os.environ, OMP_NUM_THREADS="1")
    proc = subprocess.run([sys.executable, "-m", "contactpetsc", "plot", str(out), "--step", "1"],
                          capture_output=True, text=True, timeout=120, env=env)
    assert proc.returncode == 0, proc.stderr
    assert "contact_area.png" in proc.stdout and "psd.png" in proc.stdout
    with open(out / "scene.json") as f:
        assert json.load(f)["output"]["plot_step"] is None


def test_a_run_holds_one_states_fields_and_plots_an_earlier_step_from_them(coll, shared_tmp):
    """A run releases each state's fields before it solves the next step (a long path held every
    step's fields): only the last state it returns has them.  The most pressed step, the second
    of three (unloaded after it), is still plotted from its fields kept in memory, without a
    field file, exactly as from its step file."""
    pytest.importorskip("matplotlib")
    from matplotlib.image import imread
    values = (2e6, 5e7, 1e7)
    memory, filed = shared_tmp / "from_memory", shared_tmp / "from_file"
    states = runner.run(rough(memory, values=values, plots=True, fields=False), comm=PETSc.COMM_WORLD)
    assert [st.pressure is None for st in states] == [True, True, False]
    assert all(st.gap is None and st.displacement is None for st in states[:-1])
    assert plots.plot_step([st.approach for st in states], [1, 1, 1]) == 2
    runner.run(rough(filed, values=values, plots=True, fields=True), comm=PETSc.COMM_WORLD)
    # a contact run's files carry the pressure whatever the list, not the gap and heights the
    # plots read beside it: drawn from memory as without files
    contact_only = shared_tmp / "contact_only"
    runner.run(rough(contact_only, values=values, plots=True, fields=["contact"]), comm=PETSc.COMM_WORLD)
    for name in ("pressure_map.png", "histograms.png", "psd.png"):
        a = imread(memory / name)
        for other in (filed, contact_only):
            b = imread(other / name)
            assert coll.all(a.shape == b.shape and np.array_equal(a, b)), (name, other)
