"""The Python API examples, run as a user runs them (in a subprocess, at reduced size), checked
against closed forms and numpy: the rough example's load balance, Signorini conditions and
elastic displacement; the adhesive example's jumps and pull-off force against DMT, JKR and
Maugis-Dugdale, serially and under ``mpirun -n 2``.

Marked serial: a rank of an MPI job cannot launch examples (or mpirun) itself.
"""
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

EXAMPLES = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "examples")
ENV = dict(os.environ, OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1",
           OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1", OMPI_MCA_rmaps_base_oversubscribe="1")


def run_example(name, args, cwd, ranks=1):
    cmd = [sys.executable, os.path.join(EXAMPLES, name)] + list(args)
    if ranks > 1:
        cmd = [shutil.which("mpirun") or "mpirun", "-n", str(ranks)] + cmd
    done = subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, f"{' '.join(cmd)} failed:\n{done.stdout}\n{done.stderr}"
    return done.stdout


@pytest.mark.serial
def test_rough_api_example(tmp_path):
    out = run_example("api_rough_contact.py", ["48"], tmp_path)
    assert "SNES vinewtonrsls" in out and "(options prefix rough_)" in out and "FFT pairs" in out
    r = np.load(tmp_path / "api_rough_contact.npz")
    h, p, gap, v = r["heights"], r["pressure"], r["gap"], r["displacement"]
    n, dx, e_star = h.shape[0], float(r["dx"]), float(r["e_star"])
    # load balance: the pressures carry the prescribed nominal pressure (to what the example's
    # tolerance on the complementarity error, 1e-8 of the rms height, allows)
    assert p.mean() == pytest.approx(float(r["mean_pressure"]), rel=1e-6)
    # Signorini: p >= 0, gap >= 0, and the gap closes wherever p > 0 (to the solver's tolerance)
    rms = h.std()
    assert p.min() >= 0 and gap.min() >= -1e-8 * rms and np.abs(gap[p > 0]).max() <= 1e-6 * rms
    assert 0.01 < np.mean(p > 0) < 0.5
    # the displacement of a periodic half-space: 2 / (E* |q|) in Fourier space, mean mode zero
    f = np.fft.fftfreq(n, dx)
    q = 2 * np.pi * np.hypot(f[:, None], f[None, :])
    kernel = np.divide(2.0 / e_star, q, out=np.zeros_like(q), where=q > 0)
    v_numpy = np.fft.ifft2(kernel * np.fft.fft2(p)).real
    assert np.abs(v - v.mean() - v_numpy).max() <= 1e-10 * np.abs(v_numpy).max()
    # and the gap is h + v - delta
    assert np.abs(gap - (h + v - float(r["approach"]))).max() <= 1e-10 * rms


def derjaguin_force(radius, w, z0, approach):
    """Force [N] on a rigid sphere at apex gap -approach, Derjaguin: 2 pi R times the LJ energy
    per area w/3 (z0/z)^8 - 4w/3 (z0/z)^2 at z = gap + z0."""
    z = -approach + z0
    return 2 * np.pi * radius * (w / 3 * (z0 / z) ** 8 - 4 * w / 3 * (z0 / z) ** 2)


@pytest.mark.serial
@pytest.mark.mpirun   # launches mpirun jobs
def test_adhesive_api_example_serially_and_on_two_ranks(tmp_path):
    from contactpetsc.physics.closed_forms import maugis_pull_off_bar
    results = []
    for ranks in (1, 2):
        cwd = tmp_path / f"np{ranks}"
        cwd.mkdir()
        out = run_example("api_adhesive_mpirun.py", ["32"], cwd, ranks)
        assert f"{ranks} rank(s)" in out and "pull-off force" in out
        with open(cwd / "api_adhesive_mpirun.json") as f:
            results.append(json.load(f))
    for r in results:
        R, w, z0, mu = r["radius"], r["work_of_adhesion"], r["z0"], r["tabor"]
        assert mu == pytest.approx((R * w**2 / (r["e_star"]**2 * z0**3)) ** (1 / 3), rel=1e-12)
        points = r["points"]
        assert all(pt["converged"] and pt["stable"] for pt in points)
        # far from contact the sphere is nearly rigid: Derjaguin's force
        first = points[0]
        assert first["force"] == pytest.approx(derjaguin_force(R, w, z0, first["approach"]), rel=0.1)
        # Tabor parameter 1: a jump-on while loading, a jump-off at a smaller approach while unloading
        on, off = r["jumps"]
        assert (on["kind"], off["kind"]) == ("jump-on", "jump-off")
        assert off["approach_before"] < on["approach_before"]
        assert on["force_after"] < on["force_before"] < 0 and off["force_after"] > off["force_before"]
        # pull-off between DMT (-2 pi R w) and JKR (-1.5 pi R w), near Maugis-Dugdale (lambda = 1.16 mu)
        bar = r["pull_off_force"] / (np.pi * R * w)
        assert -2.0 < bar < -1.5
        assert bar == pytest.approx(maugis_pull_off_bar(1.16 * mu), rel=0.1)
        assert r["pull_off_force"] <= min(pt["force"] for pt in points)
    # the same path on one rank and on two
    assert results[1]["ranks"] == 2
    f1, f2 = (np.array([pt["force"] for pt in r["points"]]) for r in results)
    assert np.abs(f1 - f2).max() <= 1e-6 * np.abs(f1).max()
    assert results[1]["pull_off_force"] == pytest.approx(results[0]["pull_off_force"], rel=1e-6)
