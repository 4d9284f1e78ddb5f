"""Check that ParaView reads contactpetsc's field files as written.  Not a test: CI has no ParaView.

    pvpython run_scripts/checks/check_paraview.py [DIR ...]        (pvbatch works too)

For every ``step_NNNN.xdmf`` in each output directory DIR, both of ParaView's
XDMF readers (``XDMFReader``, which File > Open offers first, and
``Xdmf3ReaderS``) must give an image of nx x ny x 1 points in the x-y plane
with spacing (dx, dy) and origin 0, and every point array equal, value for
value, to its HDF5 dataset read with h5py (VTK point (i, j) = dataset[j, i]),
of the same type (float64, float32, uint8 masks).  With ``output.length_unit``
other than m (read from the step file's scene) the spacing and the length
fields (unit m) are that unit's: s * dx, s * the dataset (s = 1e6, 1e9) to
float32 round-off; ``Xdmf3ReaderS`` does not evaluate XDMF Function items, so
it leaves those fields out (reported, not a mismatch).  All of a directory's
steps opened at once must make a time series with one time per step (what
the file dialog's grouped ``step_..xdmf`` entry does), and ``fields.xdmf``
too, with the times of curve.csv (the approaches of the written steps in the
length unit when they increase, else the step numbers) and each time's arrays
its step file's.

Without DIR, two runs are made for the check in a temporary directory with
the repository's venv: a rough periodic cell with nx != ny and dx != dy on
one rank, and an adhesive Lennard-Jones sphere on two ranks (parallel HDF5),
its fields float32 every 2nd step with lengths in nm.
Prints one line per file and reader; exit status 1 on any mismatch.
``--screenshot PNG`` also renders the last directory's last step coloured by
pressure, as a user sees it (needs a display; headless: ``xvfb-run -a``);
``--warp FIELD`` with it shows the surface warped by FIELD (scale factor 1:
for runs with ``output.length_unit`` nm or um) in a 3-D view.

Debian 12: ``apt-get install --no-install-recommends paraview python3-paraview``.
"""
import csv
import glob
import json
import os
import subprocess
import sys
import tempfile

import h5py
import numpy as np
from paraview import servermanager
from paraview.simple import XDMFReader, Xdmf3ReaderS
from vtkmodules.util.numpy_support import vtk_to_numpy

HERE = os.path.dirname(os.path.abspath(__file__))
VENV = os.environ.get("CONTACTPETSC_VENV", os.path.join(HERE, "..", "..", ".venv"))

ROUGH = """name = "paraview-rough"
[geometry]
kind = "self-affine"
nx = 40
ny = 24
dx = 1e-8
dy = 1.5e-8
rms_slope = 0.1
seed = 2
[material]
e_star = 50e9
[protocol]
control = "mean_pressure"
values = [5e7, 1e8]
"""
ADHESIVE = """name = "paraview-adhesive"
[geometry]
kind = "sphere"
radius = 30e-9
nx = 56
dx = 0.5e-9
[material]
e_star = 10e9
[interaction]
law = "lj"
work_of_adhesion = 0.3
z0 = 0.3e-9
[protocol]
values = [-0.6e-9, -0.3e-9, 0.0, -0.3e-9]
refine_pull_off = false
[output]
field_precision = "float32"
field_every = 2
length_unit = "nm"
"""
SCALE = {"m": 1.0, "um": 1e6, "nm": 1e9}


def make_runs(root: str) -> list:
    # pvpython is an MPI singleton: its OMPI_/PMIX_ variables would tie mpirun to it
    env = {k: v for k, v in os.environ.items() if not k.startswith(("OMPI_", "PMIX_", "OPAL_"))}
    env.update(OMP_NUM_THREADS="1", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    dirs = []
    for name, text, ranks in (("rough", ROUGH, 1), ("adhesive", ADHESIVE, 2)):
        scene, out = os.path.join(root, f"{name}.toml"), os.path.join(root, name)
        with open(scene, "w") as f:
            f.write(text)
        cmd = ["mpirun", "-n", str(ranks), os.path.join(VENV, "bin", "contactpetsc"), "run", scene,
               "--output", out]
        print(f"running {' '.join(cmd)}")
        subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
        dirs.append(out)
    return dirs


def step_data(h5: str) -> tuple:
    """({dataset: values as ParaView should show them}, dx, dy, scale, {names of scaled lengths})."""
    with h5py.File(h5, "r") as f:
        unit = json.loads(f.attrs["scene"]).get("output", {}).get("length_unit", "m")
        scale = SCALE[unit]
        names = [name for name in f if isinstance(f[name], h5py.Dataset)]   # not the coarse_levels group
        lengths = {name for name in names if f[name].attrs["unit"] == "m" and scale != 1.0}
        data = {name: f[name][:] * (scale if name in lengths else 1) for name in names}
        return data, float(f.attrs["dx"]), float(f.attrs["dy"]), scale, lengths


def compare(image, h5: str, label: str) -> list:
    """Mismatches between a VTK image and the step file ``h5``."""
    data, dx, dy, scale, lengths = step_data(h5)
    ny, nx = next(iter(data.values())).shape
    bad = []
    if tuple(image.GetDimensions()) != (nx, ny, 1):
        bad.append(f"dimensions {image.GetDimensions()} != {(nx, ny, 1)}")
    if not np.allclose(image.GetSpacing()[:2], (dx * scale, dy * scale), rtol=1e-15, atol=0):
        bad.append(f"spacing {image.GetSpacing()} != ({dx * scale}, {dy * scale})")
    if tuple(image.GetOrigin()) != (0.0, 0.0, 0.0):
        bad.append(f"origin {image.GetOrigin()}")
    points = image.GetPointData()
    names = {points.GetArrayName(k) for k in range(points.GetNumberOfArrays())}
    # Xdmf3ReaderS skips XDMF Function items (the lengths in another unit): a known limit
    want = set(data) - (lengths if label == "Xdmf3ReaderS" else set())
    if names != want:
        bad.append(f"arrays {sorted(names)} != datasets {sorted(want)}")
    for name in sorted(names & want):
        values = vtk_to_numpy(points.GetArray(name)).reshape(ny, nx)   # VTK: x fastest
        if name in lengths:   # s * $0 evaluated by the reader in the dataset's precision
            ok = np.allclose(values, data[name], rtol=4 * np.finfo(values.dtype).eps, atol=0)
        else:
            ok = np.array_equal(values, data[name]) and values.dtype == data[name].dtype
        if not ok:
            bad.append(f"{name} ({values.dtype}) differs by {np.abs(values - data[name]).max():.3e}")
    print(f"{os.path.basename(h5)} {label}: {nx} x {ny} points, spacing "
          f"({image.GetSpacing()[0]:.6g}, {image.GetSpacing()[1]:.6g}), arrays {', '.join(sorted(names))}"
          + (f" (lengths x {scale:g}" + (", Function items skipped)" if label == "Xdmf3ReaderS" else ")")
             if lengths else "") + ": " + ("OK" if not bad else "; ".join(bad)))
    return [f"{h5} ({label}): {b}" for b in bad]


READERS = (("XDMFReader", lambda path: XDMFReader(FileNames=[path])),
           ("Xdmf3ReaderS", lambda path: Xdmf3ReaderS(FileName=[path])))


def first_image(reader):
    image = servermanager.Fetch(reader)
    return image.GetBlock(0) if image.IsA("vtkMultiBlockDataSet") else image


def check_file(xdmf: str) -> list:
    """Mismatches between what ParaView reads from ``xdmf`` and the HDF5 file beside it."""
    errors = []
    for label, make in READERS:
        reader = make(xdmf)
        reader.UpdatePipeline()
        errors += compare(first_image(reader), xdmf[:-5] + ".h5", label)
    return errors


def check_collection(directory: str) -> list:
    """fields.xdmf: one time per written step, the times of curve.csv, each time's arrays its
    step file's, with both readers."""
    path = os.path.join(directory, "fields.xdmf")
    steps = sorted(int(os.path.basename(p)[5:-3]) for p in glob.glob(os.path.join(directory, "step_*.h5")))
    with open(os.path.join(directory, "curve.csv")) as f:
        approach = {int(r["step"]): float(r["approach_m"]) for r in csv.DictReader(f)}
    scale = step_data(os.path.join(directory, f"step_{steps[0]:04d}.h5"))[3]
    wanted = [approach[k] * scale for k in steps]
    if not all(b > a for a, b in zip(wanted, wanted[1:])):
        wanted = [float(k) for k in steps]
    errors = []
    for label, make in READERS:
        reader = make(path)
        reader.UpdatePipelineInformation()
        times = list(reader.TimestepValues)
        print(f"{path} {label}: {len(times)} times for {len(steps)} step files")
        if len(times) != len(steps) or not np.allclose(times, wanted, rtol=1e-12, atol=0):
            errors.append(f"{path} ({label}): times {times} != {wanted}")
            continue
        for time, step in zip(times, steps):
            reader.UpdatePipeline(time)
            errors += compare(first_image(reader), os.path.join(directory, f"step_{step:04d}.h5"),
                              label)
    return errors


def check_directory(directory: str) -> list:
    files = sorted(glob.glob(os.path.join(directory, "step_*.xdmf")))
    if not files:
        return [f"{directory}: no step_NNNN.xdmf files"]
    errors = [e for xdmf in files for e in check_file(xdmf)]
    series = XDMFReader(FileNames=files)
    series.UpdatePipelineInformation()
    times = list(series.TimestepValues) if len(files) > 1 else [0]
    print(f"{directory}: {len(files)} steps opened together, {len(times)} time steps")
    if len(times) != len(files):
        errors.append(f"{directory}: {len(files)} steps read as {len(times)} time steps")
    return errors + check_collection(directory)


def screenshot(xdmf: str, png: str, warp: str | None = None) -> None:
    """What a user sees: the step coloured by pressure on a range centred at zero, flat or warped
    by ``warp`` with factor 1 (needs a display: ``xvfb-run -a pvpython ...`` on a headless
    machine)."""
    from paraview.simple import ColorBy, GetActiveViewOrCreate, GetColorTransferFunction, \
        ResetCamera, SaveScreenshot, Show, WarpByScalar
    reader = XDMFReader(FileNames=[xdmf])
    view = GetActiveViewOrCreate("RenderView")
    source = reader if warp is None else WarpByScalar(Input=reader, Scalars=["POINTS", warp], ScaleFactor=1.0)
    shown = Show(source, view)
    ColorBy(shown, ("POINTS", "pressure"))
    lut = GetColorTransferFunction("pressure")
    lut.ApplyPreset("Cool to Warm", True)
    top = max(abs(v) for v in reader.PointData["pressure"].GetRange())
    lut.RescaleTransferFunction(-top, top)
    shown.SetScalarBarVisibility(view, True)
    if warp is None:
        view.InteractionMode = "2D"
    else:   # an oblique view from below the x axis
        bounds = servermanager.Fetch(source).GetBounds()
        centre = [(bounds[0] + bounds[1]) / 2, (bounds[2] + bounds[3]) / 2, (bounds[4] + bounds[5]) / 2]
        size = bounds[1] - bounds[0]
        view.CameraPosition = [centre[0] + 0.2 * size, centre[1] - 1.3 * size, centre[2] + 0.9 * size]
        view.CameraFocalPoint = centre
        view.CameraViewUp = [0, 0, 1]
    ResetCamera()
    SaveScreenshot(png, view, ImageResolution=[700, 560])
    print(f"wrote {png} ({os.path.basename(xdmf)} as ParaView shows it)")


def main(args) -> int:
    print(f"ParaView {servermanager.vtkSMProxyManager.GetParaViewSourceVersion()}")
    png = warp = None
    if "--screenshot" in args:
        k = args.index("--screenshot")
        png, args = args[k + 1], args[:k] + args[k + 2:]
    if "--warp" in args:
        k = args.index("--warp")
        warp, args = args[k + 1], args[:k] + args[k + 2:]
    with tempfile.TemporaryDirectory(prefix="contactpetsc-paraview-") as tmp:
        dirs = args or make_runs(tmp)
        errors = [e for d in dirs for e in check_directory(d)]
        if png:
            screenshot(sorted(glob.glob(os.path.join(dirs[-1], "step_*.xdmf")))[-1], png, warp)
    for e in errors:
        print(f"MISMATCH {e}")
    print("ParaView reads every step as written" if not errors else f"{len(errors)} mismatches")
    return 1 if errors else 0


if __name__ == "__main__":
    status = main(sys.argv[1:])
    sys.stdout.flush()
    os._exit(status)   # skip the render window's teardown, which fails under Xvfb (GLXBadContext)
