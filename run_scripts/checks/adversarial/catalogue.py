"""The catalogue: every case of the sweep with its parameters, in the order they run."""
from __future__ import annotations

import math

import numpy as np

from .cases_input import (
    GOOD_CURVE_HEAD, api_from_step_file_case, api_refusal_case, axes_stamp_case, cli_refusal_case,
    h5, height_file_case, load_case, npy, plot_case, raw_file, refuse_or_match_case,
    round_trip_case, stamped_input_case, warn_ok)
from .cases_limits import limit_cases
from .cases_physics import (
    FAR, api_random_vector_case, api_weak_adhesion_case, flat_case, random_vector_case,
    rigid_sphere_case, window_case)
from .cases_runs import (
    _restart_finished, bookkeeping_case, budget_restart_case, changed_physics_case, concurrent_case,
    corrupted_restart_case, disk_full_case, dry_run_untouched_case, fresh_directory_case,
    kill_restart_case, old_directory_case, restart_allowed_case, summary_case)
from .harness import (
    Case, LOUD, OK, UNCLEAR, WRONG, Z0, adhesive_sphere, column, hertz_scene, jump_sphere, merged,
    message, read_curve, read_field, rough_cell, z0s)


# --------------------------------------------------------------------------------------------
# the cases
def all_cases() -> list[Case]:
    cases: list[Case] = []
    add = cases.append
    # 1: weak to strong adhesion against the rigid sphere, w / E* z0 <= 3e-8: the sphere's own
    # deformation moves its force off the rigid one in proportion to w / E* z0, by less than
    # the 1e-3 tolerance only in this range
    for w, e in [(1e-12, 1e10), (1e-9, 1e10), (1e-8, 1e10), (1e-7, 1e10), (1e-6, 1e11),
                 (1e-3, 1e14), (1.0, 1e17), (1e3, 1e20)]:
        add(rigid_sphere_case(f"weak-lj-w{w:g}", w, e))
    add(rigid_sphere_case("weak-lj-w1e-9-np2", 1e-9, 1e10, ranks=2))
    add(rigid_sphere_case("weak-hardwall-w1e-8", 1e-8, 1e10, law="hardwall-lj",
                          values=z0s(-3, -2, -1, -0.5, -0.1, -0.5, -2)))
    add(rigid_sphere_case("weak-exponential-w1e-9", 1e-9, 1e10, law="exponential", rho=Z0,
                          values=z0s(-3, -2, -1, -0.5, -0.1, -0.5, -2)))
    add(rigid_sphere_case("weak-dugdale-w1e-9", 1e-9, 1e10, law="dugdale", sigma0=1e-9 / Z0,
                          values=z0s(-2.13, -1.07, -0.47, -0.21, -0.47, -1.07)))
    add(api_weak_adhesion_case(1e-10, 1))
    add(api_weak_adhesion_case(1e-8, 2))
    # 2: pull-off on the flat periodic cell
    add(flat_case("flat-lj-w0.1", 0.1))
    add(flat_case("flat-lj-w1e-6", 1e-6))
    add(flat_case("flat-lj-w10", 10.0))
    add(flat_case("flat-lj-coarse-steps", 0.1, values=z0s(-2, -1.3, -0.6, 0, -0.37, -0.74, -1.11, -1.48)))
    add(flat_case("flat-lj-loading-only", 0.1, values=z0s(-2, -1, -0.5, -0.3, -0.1, 0)))
    add(flat_case("flat-lj-soft", 0.1, e_star=1e10, check_forces=False))
    add(flat_case("flat-lj-no-refine", 0.1, refine=False))
    add(flat_case("flat-hardwall-lj", 0.1, law="hardwall-lj",
                  values=z0s(-2, -1, -0.5, -0.02, -0.1, -0.15, -0.19, -0.23, -0.3, -0.6)))
    add(flat_case("flat-exponential-no-refine", 0.1, law="exponential", rho=Z0, refine=False,
                  values=z0s(-2, -1, -0.3, -0.05, -0.3, -1, -2)))
    add(flat_case("flat-dugdale-no-refine", 0.1, law="dugdale", sigma0=0.1 / Z0, refine=False,
                  values=z0s(-2, -1.5, -0.7, -0.3, -0.7, -1.5)))
    add(flat_case("flat-lj-np2", 0.1, ranks=2))
    # the paper's relaxation: its pull-off refined by relaxation solves
    add(flat_case("flat-lj-relaxation", 0.1, method="relaxation"))
    add(flat_case("flat-lj-relaxation-coarse-steps", 0.1, method="relaxation",
                  values=z0s(-2, -1.3, -0.6, 0, -0.37, -0.74, -1.11, -1.48)))
    add(flat_case("flat-hardwall-lj-relaxation", 0.1, law="hardwall-lj", method="relaxation",
                  values=z0s(-2, -1, -0.5, -0.02, -0.1, -0.15, -0.19, -0.23, -0.3, -0.6)))
    add(flat_case("flat-lj-relaxation-np2", 0.1, method="relaxation", ranks=2))
    # 3: no jumps where the force is smooth
    add(rigid_sphere_case("far-sphere-lj-w0.05", 0.05, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-lj-w0.3", 0.3, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-hardwall", 0.3, 1e10, law="hardwall-lj", values=FAR, klass="3",
                          no_jumps=True, tol=1e-2))
    add(rigid_sphere_case("far-sphere-fine-steps", 0.05, 1e10, klass="3", no_jumps=True, tol=1e-2,
                          values=z0s(*np.arange(-20, -9.9, 0.5), *np.arange(-10.5, -20.1, -0.5))))
    add(rigid_sphere_case("far-sphere-np2", 0.3, 1e10, values=FAR, klass="3", no_jumps=True, tol=1e-2,
                          ranks=2))
    add(flat_case("flat-tail-smooth", 0.1, klass="3", no_jumps=True, tol=1e-2, refine=False,
                  values=z0s(-3, -2.5, -2, -1.5, -1, -0.6, -0.4, -0.6, -1, -1.5, -2, -3)))
    add(flat_case("flat-through-peak-smooth", 0.1, klass="3", no_jumps=True, tol=1e-2,
                  values=z0s(*np.arange(-1.5, 0.01, 0.1), *np.arange(-0.1, -1.51, -0.1))))
    # 4: the random vector
    hertz = hertz_scene(nx=32, dx=4e-9)
    add(random_vector_case("random-vector-option-tol", hertz, ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-scene-tol", merged(hertz, solver={"tol": 1e-18})))
    add(random_vector_case("random-vector-rough-load", rough_cell(), ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-force-control",
                           merged(hertz, protocol={"control": "force", "values": [1e-8, 3e-8]}),
                           ("-contact_tol", "1e-18")))
    add(random_vector_case("random-vector-np2", hertz, ("-contact_tol", "1e-18"), ranks=2))
    add(api_random_vector_case())
    # 5: questionable input
    big = hertz_scene(nx=64, dx=4e-9, values=(1e-9, 2e-9))
    add(refuse_or_match_case("tol-1e300-signorini", "5", "solver.tol = 1e300 (Signorini)", big, ["tol"],
                             edit=lambda s: merged(s, solver={"tol": 1e300})))
    add(refuse_or_match_case("tol-1e300-adhesive", "5", "solver.tol = 1e300 (adhesive)", jump_sphere(),
                             ["tol"], edit=lambda s: merged(s, solver={"tol": 1e300})))
    add(refuse_or_match_case("tol-0.5-adhesive", "5", "solver.tol = 0.5 z0 (adhesive)", jump_sphere(),
                             ["tol"], tol=1e-2, edit=lambda s: merged(s, solver={"tol": 0.5})))
    add(refuse_or_match_case("option-tol-1e300", "5", "-contact_tol 1e300 on the command line", big,
                             ["tol"], args=("-contact_tol", "1e300")))
    add(refuse_or_match_case("option-adhesion-tol-1e10", "5", "-adhesion_tol 1e10 on the command line",
                             jump_sphere(), ["tol"], args=("-adhesion_tol", "1e10")))
    add(load_case("subnormal-mean-pressure", rough_cell(values=[1e-310])))
    add(load_case("subnormal-force", merged(big, protocol={"control": "force", "values": [5e-320]})))
    add(load_case("huge-mean-pressure-1e300", rough_cell(values=[1e300])))
    sq = np.full((16, 16), 1e-9)
    sq[3, 5] = 0.0
    add(height_file_case("heights-complex", "5", npy(sq.astype(complex) + 1e-10j),
                         names=["complex", "h.npy", "dtype"]))
    add(height_file_case("heights-bool", "5", npy(sq > 0), names=["bool", "h.npy", "dtype"]))
    add(height_file_case("heights-int", "5", npy((sq * 1e9).astype(np.int64)),
                         names=["int", "h.npy", "dtype"], accept=warn_ok(["int", "dtype"])))
    add(height_file_case("heights-nan", "5", npy(np.where(sq > 0, sq, np.nan)), names=["nan", "h.npy"]))
    add(height_file_case("heights-wrong-shape-16x12", "5", npy(np.zeros((16, 12))), nx=12, ny=16,
                         names=["shape", "h.npy"]))
    add(height_file_case("heights-truncated-npy", "5",
                         lambda d: (np.save(d / "t.npy", sq), (d / "t.npy").write_bytes(
                             (d / "t.npy").read_bytes()[:900]), "t.npy")[-1], names=["t.npy"]))
    add(api_refusal_case("api-vec-of-other-grid", "5", """
        def misuse():
            other = SurfaceGrid(16, 12, 1e-8, periodic=True)
            ContactProblem(grid, surfaces.sphere(other, 1e-6), 1e9).solve(approach=1e-9)
        """, ["grid", "shape", "size", "16"]))
    add(api_refusal_case("api-vec-of-other-grid-adhesive", "5", """
        def misuse():
            other = SurfaceGrid(16, 12, 1e-8, periodic=True)
            law = make_law("lj", work_of_adhesion=0.1, z0=3e-10)
            AdhesiveProblem(grid, surfaces.sphere(other, 1e-6), 1e10, law).solve(approach=0.0)
        """, ["grid", "shape", "size", "16"]))
    add(api_refusal_case("api-from-array-transposed", "5", """
        def misuse():
            surfaces.from_array(grid, np.zeros((16, 12)))
        """, ["shape", "(12, 16)", "nx"]))
    add(api_refusal_case("api-from-array-complex", "5", """
        def misuse():
            surfaces.from_array(grid, np.zeros((12, 16), complex))
        """, ["complex", "dtype"]))
    lawless = merged(big, interaction={"law": "none", "work_of_adhesion": 0.1})
    add(cli_refusal_case("w-with-law-none", "5", lawless, ["work_of_adhesion"],
                         accept=warn_ok(["work_of_adhesion"])))
    add(cli_refusal_case("sigma0-with-law-lj", "5", adhesive_sphere(sigma0=1e9), ["sigma0"],
                         accept=warn_ok(["sigma0"])))
    add(corrupted_restart_case("restart-truncated-last-step", "last-h5"))
    add(corrupted_restart_case("restart-truncated-earlier-step", "early-h5"))
    add(corrupted_restart_case("restart-short-curve-row", "short-row"))
    add(corrupted_restart_case("restart-garbage-curve-value", "garbage"))
    # 6: axes
    add(round_trip_case(32, 32))
    add(round_trip_case(32, 16))
    add(round_trip_case(16, 32, dy=2e-8))
    add(round_trip_case(32, 32, ranks=2))
    add(axes_stamp_case())
    add(stamped_input_case("heights-h5-stamped-yx", "yx", "y,x"))
    add(stamped_input_case("heights-h5-stamped-xy", "xy", "x,y"))
    add(api_from_step_file_case())
    # 7: the window edge
    # the minimal scene of an earlier docs/scenes.md: the contact radius reaches 86 % of the
    # half-window, inside it (Hertz holds, nothing to warn of); one more nanometre reaches the edge
    add(window_case("old-minimal-scene", hertz_scene(), expect_warning=False, hertz_tol=0.01))
    add(window_case("hertz-zone-at-edge", merged(hertz_scene(values=(3e-9, 4.5e-9)), name="hertz-edge"),
                    expect_warning=True))
    add(window_case("hertz-big-window", merged(hertz_scene(dx=4e-9, values=(0.5e-9, 1e-9, 2e-9)),
                                               name="hertz-big-window"), False, hertz_tol=0.03))
    add(window_case("adhesive-zone-at-edge", adhesive_sphere(w=0.05), expect_warning=True))
    add(window_case("hertz-force-control-small-window",
                    merged(hertz_scene(), protocol={"control": "force", "values": [1e-7, 4e-7]}),
                    expect_warning=True))
    # 8: kill and restart
    add(kill_restart_case("kill-after-jump-on", jump_sphere(), [(5, "self")]))
    add(kill_restart_case("kill-while-unloading", jump_sphere(), [(12, "self")]))
    add(kill_restart_case("kill-after-jump-off", jump_sphere(), [(17, "self")]))
    add(kill_restart_case("kill-in-pull-off-refinement", jump_sphere(), [(19, "refine")]))
    add(kill_restart_case("kill-twice", jump_sphere(), [(4, "self"), (10, "self")]))
    add(kill_restart_case("sigterm-after-jump-on", jump_sphere(), [(6, "term")]))
    add(kill_restart_case("kill-np2-all-ranks", jump_sphere(), [(6, "all")], ranks=2))
    add(kill_restart_case("kill-np2-one-rank", jump_sphere(), [(6, "self")], ranks=2, kill_rank=1))
    add(kill_restart_case("kill-np1-restart-np2", jump_sphere(), [(6, "self")], restart_ranks=2))
    tip = {"name": "sweep-tip",
           "geometry": {"kind": "tip", "tip": "bent-commensurate", "radius": 30e-9,
                        "atom_spacing": 0.3367e-9, "nx": 48, "dx": 0.17e-9},
           "material": {"e_star": 100e9},
           "interaction": {"law": "lj", "work_of_adhesion": 0.1, "z0": 0.2147e-9},
           "protocol": {"control": "approach",
                        "values": [k * 1e-10 for k in (-6, -4, -2, 0, 2, 0, -2, -4, -6)]},
           "output": {"directory": "out", "atom_forces": True}}
    add(kill_restart_case("kill-tip-atom-forces", tip, [(4, "self")], step=2e-10))
    add(kill_restart_case("kill-signorini", merged(big, protocol={"values": [1e-9, 1.5e-9, 2e-9, 2.5e-9]}),
                          [(2, "self")]))
    add(budget_restart_case("budget-stop-restart", jump_sphere(), 0.3))
    add(Case("restart-finished-run", "8", "--restart of a finished run (nothing left to do)",
             "outputs unchanged: jumps and pull-off kept", _restart_finished))
    # 9: restart with other physics
    for key, value in [("material.e_star", 2e10), ("interaction.work_of_adhesion", 0.1),
                       ("interaction.z0", 0.25e-9), ("interaction.law", "hardwall-lj"),
                       ("geometry.dx", 0.25e-9), ("geometry.nx", 40),
                       ("protocol.values", z0s(-3, -2.2, -1.4, -0.6, 0.2, 1, 0.2, -0.6, -1.4, -3)),
                       ("protocol.control", "central_gap")]:
        add(changed_physics_case(key, value))
    add(changed_physics_case("geometry.seed", 4, base=rough_cell(), kill_rows=0))
    add(changed_physics_case("protocol.control", "force", base=merged(
        big, protocol={"control": "approach", "values": [1e-9, 2e-9]}), kill_rows=0, suffix="-signorini"))
    add(restart_allowed_case("restart-plots-toggled", {"output": {"plots": True}}))
    add(restart_allowed_case("restart-on-2-ranks", {}, ranks=2))
    # 10: the output directory
    add(concurrent_case("concurrent-two-scenes"))
    add(concurrent_case("concurrent-same-scene", same=True))
    add(concurrent_case("concurrent-np1-and-np2", ranks=(1, 2)))
    add(old_directory_case("new-run-into-old-directory"))
    add(old_directory_case("overwrite-old-directory", flags=("--overwrite",), expect="run"))
    add(old_directory_case("new-run-beside-user-file", plant="notes.txt"))
    add(fresh_directory_case("empty-existing-directory", lambda d: (d / "out").mkdir()))
    add(dry_run_untouched_case())
    # 11: full disk
    add(disk_full_case("disk-full-step-file", hertz_scene(nx=64, dx=4e-9), 20_000))
    add(disk_full_case("disk-full-history", merged(hertz_scene(nx=32, dx=8e-9, values=[1e-9 * (1 + k / 20)
                                                                                   for k in range(40)]),
                                                   output={"fields": False}), 6_000))
    add(disk_full_case("disk-full-adhesive", jump_sphere(), 50_000))
    add(disk_full_case("disk-full-np2", hertz_scene(nx=64, dx=4e-9), 20_000, ranks=2))
    # 12: bookkeeping
    add(bookkeeping_case())
    # 13: summary.json
    add(summary_case("summary-jump-keys", jump_sphere()))
    add(summary_case("summary-jump-keys-np2", jump_sphere(), ranks=2))
    add(summary_case("summary-stopped-at-step-1", jump_sphere(), ("-adhesion_time_budget", "1e-9"),
                     rc=(3,)))
    add(summary_case("summary-far-sphere", adhesive_sphere(values=FAR)))
    add(summary_case("summary-relaxation", merged(adhesive_sphere(law="hardwall-lj", values=z0s(
        -3, -2, -1, -0.5, -1, -2)), solver={"method": "relaxation"})))
    # messages
    flat_none = {"name": "flat-signorini",
                 "geometry": {"kind": "self-affine", "nx": 32, "dx": 1e-8, "rms_height": 0.0},
                 "material": {"e_star": 1e9}, "protocol": {"control": "approach", "values": [-1e-9]},
                 "output": {"directory": "out"}}
    add(cli_refusal_case("flat-signorini-separated", "msg", flat_none, ["rms_height", "flat"],
                         forbidden=("length_scale",), accept=_zero_force))
    add(cli_refusal_case("flat-signorini-load", "msg", merged(flat_none, protocol={
        "control": "mean_pressure", "values": [1e6]}), ["rms_height", "flat"],
        forbidden=("length_scale",), accept=_uniform_load))
    add(cli_refusal_case("dry-run-huge-grid", "msg", merged(big, geometry={"nx": 60000}),
                         ["nx", "64-bit", "index"], args=("--dry-run",), forbidden=("error code",)))
    add(height_file_case("empty-npy", "msg", npy(np.zeros(0)), forbidden=("pickle",)))
    add(height_file_case("zero-byte-npy", "msg", raw_file(b"", "h.npy"), forbidden=("pickle",)))
    add(height_file_case("h5-missing-dataset", "msg", h5(sq, dataset="z"), names=["heights", "h.h5"]))
    add(height_file_case("dry-run-missing-file", "msg", lambda d: "nowhere.npy", dry_run=True))
    add(height_file_case("dry-run-wrong-shape", "msg", npy(np.zeros((8, 8))), dry_run=True))
    add(plot_case("plot-short-row", GOOD_CURVE_HEAD + "1,loading,1e-9,2e-8,1e5,0.1\n2,loading,2e-9\n"))
    add(plot_case("plot-garbage-value", GOOD_CURVE_HEAD + "1,loading,1e-9,abc,1e5,0.1\n"))
    add(plot_case("plot-no-curve", None))
    rough = rough_cell()
    add(cli_refusal_case("hurst-1-dry-run", "msg", merged(rough, geometry={"hurst": 1.0}), ["hurst"],
                         args=("--dry-run",)))
    add(cli_refusal_case("hurst-1-run", "msg", merged(rough, geometry={"hurst": 1.0}), ["hurst"]))
    for key, table in [("dx", "geometry"), ("e_star", "material")]:
        add(cli_refusal_case(f"{key}-inf-range-text", "msg", merged(big, **{table: {key: math.inf}}),
                             [key], forbidden=("inf]",)))
    add(cli_refusal_case("steps-1-0-message", "msg", jump_sphere(), ["step"],
                         args=("-adhesion_time_budget", "1e-9"), forbidden=("1-0 of",),
                         accept=lambda d, res: (UNCLEAR, "says 'steps 1-0'") if "1-0 of" in res.text
                         else (OK, f"exit {res.rc}, no 'steps 1-0'")))
    add(cli_refusal_case("tol-nan", "msg", merged(big, solver={"tol": math.nan}), ["tol"]))
    add(cli_refusal_case("values-nan", "msg", merged(big, protocol={"values": [1e-9, math.nan]}),
                         ["values"]))
    add(cli_refusal_case("scene-missing", "msg", ["run", "no-such-scene.toml"], ["no-such-scene.toml"]))
    add(cli_refusal_case("scene-bad-toml", "msg", ["run", "bad.toml"], ["bad.toml", "line"],
                         prepare=lambda d: (d / "bad.toml").write_text("[geometry\nnx = 3\n")))
    add(api_refusal_case("api-negative-w", "msg", """
        def misuse():
            make_law("lj", work_of_adhesion=-1.0, z0=3e-10)
        """, ["work_of_adhesion"]))
    add(api_refusal_case("api-nan-approach-np2", "msg", """
        def misuse():
            ContactProblem(grid, surfaces.sphere(grid, 1e-6), 1e9).solve(approach=float("nan"))
        """, ["approach"], ranks=2))
    # limits and messages: the layer at any thickness, plot on damaged runs, round-off heights,
    # small maps, communicators, measured surfaces
    cases += limit_cases()
    return cases


def _zero_force(d, res):
    if res.rc != 0:
        return LOUD, f"exit {res.rc}: {message(res)}"
    f = column(read_curve(d / "out"), "force_N")
    return (OK, "separated flat cell: F = 0") if np.all(f == 0) else (WRONG, f"F = {f} for a gap of 1 nm")


def _uniform_load(d, res):
    if res.rc != 0:
        return LOUD, f"exit {res.rc}: {message(res)}"
    p = read_field(d / "out/step_0001.h5")
    return (OK, "uniform pressure 1 MPa") if np.allclose(p, 1e6, rtol=1e-6) else (
        WRONG, f"pressure {p.min():.3g}..{p.max():.3g} Pa, expected 1e6 everywhere")
