"""Robustness: extreme cases converge against an independent truth or fail with a clear
reason; bad input is reported on every rank, naming the field and the accepted range; outputs
survive failures.

The stiff and extreme cases are the most telling rows of ``run_scripts/checks/stability_matrix.py``,
run in-process on every rank (the matrix itself runs each case in a process of its own).
Truths: Maugis-Dugdale / DMT pull-off, Hertz as w -> 0, the Derjaguin force of a detached
sphere, Westergaard's full contact of a wavy surface, the law itself on a flat cell.
"""
import csv
import importlib.util
import os
import warnings

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc.app import builder, output, runner, scenes
from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid
from contactpetsc.operators.elastic import half_space
from contactpetsc.physics.interactions import make_law
from contactpetsc.physics.resolution import (RESOLUTION_NODES, UnderResolvedWarning, adhesive_zone_length,
                                             check_resolution)
from contactpetsc.solvers import ContactProblem
from contactpetsc.solvers.adhesive import AdhesiveProblem

_spec = importlib.util.spec_from_file_location(
    "stability_matrix", os.path.join(os.path.dirname(__file__), "..", "run_scripts", "checks", "stability_matrix.py"))
matrix = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(matrix)


# -- the stability matrix, reduced ------------------------------------------------------------------
@pytest.mark.parametrize("name", ["tabor-0.01-lj", "tabor-0.1-hardwall-lj", "w-tiny-hardwall-lj",
                                  "beyond-pull-off-displacement", "full-contact-signorini",
                                  "near-zero-load-signorini",
                                  "full-contact-lj-flat", "rough-0-lj"])
def test_extreme_case_converges_to_the_truth(coll, name):
    """DMT pull-off at mu = 0.01 (and Maugis-Dugdale at 0.1, hard wall), Hertz at w = 1e-8 E* z0,
    the Derjaguin force of a sphere pulled 6 z0 beyond pull-off (detached: no contact at all),
    Westergaard's full contact, a force of 1e-9 E* per node, the law p(-delta) on a flat cell."""
    r = matrix.run_case(name)
    assert coll.all(r["converged"]), r["reason"]
    assert coll.max(abs(r["rel_diff"])) <= r["truth_tol"], (r["truth_kind"], r["value"], r["truth"])
    assert not r["under_resolved"]
    if name.startswith("beyond-pull-off"):
        assert coll.all(r["detached"] and r["end_contact_fraction"] == 0.0)
    if name.startswith("full-contact-signorini"):
        assert coll.all(r["end_contact_fraction"] == 1.0)


@pytest.mark.parametrize("name", ["beyond-pull-off-force", "full-contact-hardwall-overpressed"])
def test_case_without_equilibrium_fails_with_a_clear_reason(coll, name):
    """Load control beyond the pull-off force; a periodic hard wall pressed beyond its mean height
    (the mean gap would be negative): no equilibrium exists, the state says so, on every rank."""
    r = matrix.run_case(name)
    assert coll.all(not r["converged"] and r.get("clear_reason", False)), r["reason"]
    reasons = PETSc.COMM_WORLD.tompi4py().allgather(r["reason"])
    assert len(set(reasons)) == 1 and reasons[0]


def test_the_same_problem_in_si_units_converges_as_in_greenwood_units(coll):
    """Units must not matter: a sphere (R = 100 z0, mu = 0.02, hard-wall LJ) loaded in steps of
    z0/4 in Greenwood's units (E* = z0 = 1) and in SI (E* = 1 TPa, z0 = 0.3 nm) gives the same
    forces (scaled by E* z0^2) with Newton alone, in as many iterations give or take a few."""
    runs = []
    for k, (e_star, z0) in enumerate(((1.0, 1.0), (1e12, 0.3e-9))):
        prefix = f"units{k}_"
        grid = SurfaceGrid(48, 48, z0, periodic=False)
        pb = AdhesiveProblem(grid, surfaces.sphere(grid, 100 * z0), e_star,
                             make_law("hardwall-lj", work_of_adhesion=3.333e-4 * e_star * z0, z0=z0), prefix=prefix)
        sts = [pb.solve(approach=d * z0, raise_on_failure=False, fallback=False) for d in (-0.25, 0.0, 0.25, 0.5)]
        runs.append(([st.force / (e_star * z0 ** 2) for st in sts], sum(st.newton_iterations for st in sts),
                     all(st.converged for st in sts)))
    (f1, n1, ok1), (f2, n2, ok2) = runs
    assert coll.all(ok1 and ok2), runs
    assert coll.max(np.abs(np.array(f1) - f2).max() / np.abs(f1).max()) <= 1e-6
    assert n2 <= n1 + 4, (n1, n2)


@pytest.mark.parametrize("fallback", ["ptc", "relaxation"])
def test_time_budget_ends_an_unresolvable_solve_on_every_rank(coll, fallback):
    """w = 10 E* z0 on a wavy cell (snap number 13.8: every node can snap on its own, neither
    the predicted Newton step nor a fallback settles; the energy descent, the default strategy
    on this periodic grid, does): ``-<prefix>time_budget`` stops Newton and either fallback
    with the reason WALL_TIME_BUDGET on every rank, keeps the last converged state finite, and
    refuses later solves at once (without a budget the PTC fallback alone runs its 300 steps)."""
    prefix = f"budget_{fallback}_"
    opts = PETSc.Options(prefix)
    opts.setValue("time_budget", "1.0")
    opts.setValue("fallback", fallback)
    opts.setValue("strategy", "newton")
    try:
        grid = SurfaceGrid(64, 64, 1.0, periodic=True)
        h = surfaces.from_function(grid, lambda x, y: 2.0 * (1 - np.cos(2 * np.pi * x / 64.0)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UnderResolvedWarning)
            pb = AdhesiveProblem(grid, h, 1.0, make_law("hardwall-lj", work_of_adhesion=10.0, z0=1.0),
                                 prefix=prefix)
        first = pb.solve(approach=-0.5, raise_on_failure=False)
        states = [pb.solve(approach=d, raise_on_failure=False) for d in (0.0, 0.5)]
    finally:
        for key in ("time_budget", "fallback", "strategy"):
            opts.delValue(key)
    assert coll.all(first.converged or first.reason.startswith("WALL_TIME_BUDGET")), first.reason
    for st in states:
        assert coll.all(not st.converged and st.reason.startswith("WALL_TIME_BUDGET")), st.reason
        assert coll.all(np.isfinite(st.force) and np.isfinite(st.adhesive_error))
        reasons = PETSc.COMM_WORLD.tompi4py().allgather(st.reason)
        assert len(set(reasons)) == 1
    # the budget bounds the whole sequence (one Newton or relaxation step past it at most)
    assert coll.all(first.wall_time + sum(st.wall_time for st in states) < 15.0)
    assert coll.all(states[-1].newton_iterations == 0)
    with pytest.raises(Exception, match="WALL_TIME_BUDGET"):
        pb.solve(approach=1.0)


# -- the resolution criterion --------------------------------------------------------------------
@pytest.mark.serial   # closed forms and a warning: no communicator
def test_resolution_criterion_and_warning():
    """The zone length in both limits (closed forms), a warning naming the criterion below
    RESOLUTION_NODES nodes per zone, none above it."""
    law = make_law("lj", work_of_adhesion=0.1, z0=1.0)
    zl = adhesive_zone_length(law, 1.0, radius=100.0)
    sigma = 16 * 0.1 / (9 * np.sqrt(3))
    assert zl["cohesive"] == pytest.approx(np.pi / 4 * 0.1 / sigma ** 2, rel=1e-12)
    assert zl["sphere"] == pytest.approx(np.sqrt(200.0), rel=1e-12) and zl["zone"] == zl["cohesive"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert check_resolution(law, 1.0, zl["zone"] / RESOLUTION_NODES, radius=100.0) == pytest.approx(4.0)
    with pytest.warns(UnderResolvedWarning, match=r"l_zone >= 4 dx.*Refine the grid \(dx <= 1.86"):
        assert check_resolution(law, 1.0, 2.0, radius=100.0) < RESOLUTION_NODES
    # the range below the grid spacing is not by itself under-resolved: a large sphere, weak adhesion
    weak = make_law("hardwall-lj", work_of_adhesion=1e-4, z0=0.25)
    assert check_resolution(weak, 1.0, 1.0, radius=1e4) > RESOLUTION_NODES


@pytest.mark.serial   # the builder's resolution check on a scene: no communicator
def test_under_resolved_scene_warns():
    """The scene's one resolution check (the builder's, with the sphere's radius)."""
    def check(scene):
        valid = scenes.validate(scene)
        return builder.resolution_nodes(valid, builder.build_law(valid))

    scene = {"geometry": {"kind": "sphere", "radius": 20.0, "nx": 32, "dx": 1.0},
             "material": {"e_star": 1.0}, "protocol": {"values": [0.0]},
             "interaction": {"law": "hardwall-lj", "work_of_adhesion": 0.028, "z0": 0.25}}
    with pytest.warns(UnderResolvedWarning, match="spans 1.7 grid spacings"):
        check(scene)
    scene["geometry"]["dx"] = 0.25
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check(scene)


# -- bad input: the field and the accepted range, on every rank -------------------------------------
@pytest.mark.parametrize("e_star", [0.0, -1e9, float("nan"), float("inf")])
def test_non_positive_modulus(coll, e_star):
    g = SurfaceGrid(8, 8, 1e-9, periodic=False)
    h = surfaces.sphere(g, 1e-7)
    law = make_law("lj", work_of_adhesion=0.1, z0=3e-10)
    for build in (lambda: half_space(g, e_star), lambda: ContactProblem(g, h, e_star),
                  lambda: AdhesiveProblem(g, h, e_star, law)):
        coll.raises(ValueError, ["e_star", "> 0"], build)


@pytest.mark.parametrize("law, params, key, unit", [
    ("lj", dict(work_of_adhesion=0.1, z0=0.0), "z0", "m"),
    ("hardwall-lj", dict(work_of_adhesion=0.1, z0=-3e-10), "z0", "m"),
    ("lj", dict(work_of_adhesion=-0.1, z0=3e-10), "work_of_adhesion", "J/m^2"),
    ("hardwall-lj", dict(work_of_adhesion=float("nan"), z0=3e-10), "work_of_adhesion", "J/m^2"),
    ("exponential", dict(work_of_adhesion=0.1, rho=0.0), "rho", "m"),
    ("dugdale", dict(work_of_adhesion=0.1, sigma0=-1.0), "sigma0", "Pa"),
])
def test_bad_law_parameters(coll, law, params, key, unit):
    coll.raises(ValueError, [key, "accepted range (0, inf)", unit], make_law, law, **params)


@pytest.mark.serial   # scene validation: no communicator
@pytest.mark.parametrize("section, values, message", [
    ("interaction", {"law": "lj", "work_of_adhesion": 0.1, "z0": 0.0}, "interaction.z0 = 0.0: accepted range (0, inf) m"),
    ("interaction", {"law": "lj", "work_of_adhesion": 0.1, "z0": 1e-9, "range": 2}, "unknown key interaction.range"),
    ("material", {"e_star": -5.0}, "material.e_star = -5.0: accepted range (0, inf) Pa"),
    ("material", {"e_star": float("inf")}, "material.e_star = inf: accepted range"),
    ("solver", {"tol": 0.0}, "solver.tol = 0.0: accepted range (0, 0.01]"),
    ("output", {"dir": "x"}, "unknown key output.dir"),
])
def test_bad_scene_values(section, values, message):
    scene = {"geometry": {"kind": "sphere", "radius": 1e-7, "nx": 16, "dx": 1e-9},
             "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}}
    scene[section] = values
    with pytest.raises(scenes.SceneError) as err:
        scenes.validate(scene)
    assert message in str(err.value)


def test_grids_beyond_32_bit_indices_fail_before_allocating(coll):
    """65536^2 nodes: SurfaceGrid and a scene's grid both stop with the index limit, at once."""
    bits = 8 * np.dtype(PETSc.IntType).itemsize
    n = 2 ** ((bits - 1) // 2 + 1)
    coll.raises(GridError, ["64-bit indices", f"{n} x {n}"], SurfaceGrid, n, n, 1e-9)
    scene = scenes.validate({"geometry": {"kind": "sphere", "radius": 1e-6, "nx": n, "dx": 1e-9},
                             "material": {"e_star": 1e9}, "protocol": {"values": [1e-9]}})
    coll.raises(GridError, "64-bit indices", builder.build_grid, scene)


def test_truncated_hdf5_heights_and_restart_files(coll, shared_tmp):
    """A truncated HDF5 height file, and a restart whose last step file is truncated: the same
    error on every rank, naming the file."""
    import h5py
    g = SurfaceGrid(6, 9, 1.0)
    good, cut = shared_tmp / "h.h5", shared_tmp / "cut.h5"
    if coll.rank == 0:
        with h5py.File(good, "w") as f:
            f["heights"] = np.ones((6, 9))
        raw = good.read_bytes()
        cut.write_bytes(raw[: len(raw) // 2])
    PETSc.COMM_WORLD.tompi4py().Barrier()
    assert coll.max(np.abs(g.gather(surfaces.from_file(g, str(good))) - 1).max()) == 0.0
    coll.raises(GridError, ["cannot read heights", "cut.h5"], surfaces.from_file, g, str(cut))
    # restart: step 1 is listed in curve.csv, but its field file is truncated
    scene = scenes.validate({"geometry": {"kind": "self-affine", "nx": 16, "dx": 1e-8, "rms_slope": 0.1},
                             "material": {"e_star": 1e9},
                             "protocol": {"control": "mean_pressure", "values": [5e6, 1e7]},
                             "output": {"directory": str(shared_tmp / "run")}})
    runner.run(scene, comm=PETSc.COMM_WORLD)
    step = shared_tmp / "run" / "step_0002.h5"
    if coll.rank == 0:
        raw = step.read_bytes()
        step.write_bytes(raw[: len(raw) // 3])
    PETSc.COMM_WORLD.tompi4py().Barrier()
    coll.raises(RuntimeError, ["cannot restart from", "step_0002.h5"], runner.run, scene,
                comm=PETSc.COMM_WORLD, restart=True)


# -- outputs: reported before the solve, written atomically ---------------------------------------
def _scene(out, **extra):
    s = {"geometry": {"kind": "sphere", "radius": 1e-6, "nx": 16, "dx": 1e-8},
         "material": {"e_star": 1e9}, "protocol": {"values": [1e-9, 2e-9]}, "output": {"directory": out}}
    s.update(extra)
    return scenes.validate(s)


def test_unwritable_output_directory_is_reported_before_the_solve(coll, monkeypatch):
    """/proc exists but takes no files, even for root: an OSError naming the directory on every
    rank, and no solve was started."""
    solved = []
    monkeypatch.setattr(ContactProblem, "solve", lambda self, **kw: solved.append(kw))
    coll.raises(OSError, ["output directory '/proc'", "not writable"], runner.run, _scene("/proc"),
                comm=PETSc.COMM_WORLD)
    assert not solved


def test_full_output_directory_is_reported_before_the_solve(coll, shared_tmp, monkeypatch):
    """A file system with less room than the run's outputs (statvfs says 0 blocks free)."""
    class Full:
        f_bavail, f_frsize = 0, 4096
    solved = []
    monkeypatch.setattr(ContactProblem, "solve", lambda self, **kw: solved.append(kw))
    monkeypatch.setattr(os, "statvfs", lambda path: Full())
    coll.raises(OSError, ["0.0 MiB free", "2 step files of 5 fields of 16 x 16"], runner.run,
                _scene(str(shared_tmp / "full")), comm=PETSc.COMM_WORLD)
    assert not solved


@pytest.mark.serial
def test_atomic_text_write_keeps_the_old_file_on_failure(tmp_path):
    path = tmp_path / "curve.csv"
    output.write_text_atomic(str(path), "step\n1\n")
    with pytest.raises(UnicodeEncodeError):
        output.write_text_atomic(str(path), "step\n1\n2\n\udc80")    # cannot be encoded: the write fails
    assert path.read_text() == "step\n1\n" and os.listdir(tmp_path) == ["curve.csv"]
    output.write_text_atomic(str(path), "step\n1\n2\n")
    with open(path) as f:
        assert [r["step"] for r in csv.DictReader(f)] == ["1", "2"]
