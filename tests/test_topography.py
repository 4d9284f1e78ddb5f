"""Measured topographies: each reader against a file the test writes from the format's published
specification, and kind = "file" scenes that take their grid from the file.

Truths: an analytic, asymmetric pattern h(x_i, y_j) on a non-square grid (nx != ny) with
dx != dy, written by each format's rules (text lines are y; .gsf float32 rows of XRes after
one to four NULs; .x3p x fastest in bindata/data.bin with CZ's increment and offset; .sur int32
lines after the 512-byte header and its comment zone, z = value dz + z offset) must come back
indexed [i, j] (x first) in metres with the file's spacing; a plane (a quadric) is removed
exactly by mean-plane (curvature) detrending, and a mean-plane fit equals numpy's least
squares on the whole map, on any number of ranks.
"""
import hashlib
import os
import struct
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from petsc4py import PETSc

from contactpetsc import topography
from contactpetsc.app import builder, scenes
from contactpetsc.topography import FormatError, convert, read_topography
from contactpetsc.geometry import surfaces
from contactpetsc.grid import SurfaceGrid

NX, NY = 7, 5
DX, DY = 2.0, 3.0      # in the file's lateral unit


def pattern(i, j):
    """Heights in the file's unit at node (i, j): asymmetric, h(i, j) != h(j, i)."""
    return 3.0 * i + 0.5 * j ** 2 - 7.0


def grid_pattern():
    i, j = np.meshgrid(np.arange(NX), np.arange(NY), indexing="ij")
    return pattern(i, j)          # (NX, NY), [x, y]


def check(topo, unit_m, lateral_m, rtol=1e-12):
    """The map read is the pattern in m, indexed [x, y], with the file's spacing in m."""
    assert topo.shape == (NX, NY) and topo.heights.shape == (NX, NY)
    ref = grid_pattern() * unit_m
    assert np.abs(topo.heights - ref).max() <= rtol * np.abs(ref).max()
    assert topo.dx == pytest.approx(DX * lateral_m, rel=rtol) and topo.dy == pytest.approx(DY * lateral_m, rel=rtol)


def on_root(coll, func):
    if coll.rank == 0:
        func()
    coll.comm.Barrier()


# -- writers, from the formats' specifications -------------------------------------------------
def write_matrix(path, header=True):
    """Gwyddion's ASCII data matrix export: one line per y, columns along x, comment header."""
    lines = ["# Channel: Height", f"# Width: {NX * DX} um", f"# Height: {NY * DY} um",
             "# Value units: nm"] if header else []
    lines += [" ".join(repr(float(v)) for v in row) for row in grid_pattern().T]
    path.write_text("\n".join(lines) + "\n")


def write_gsf(path, title):
    text = (f"Gwyddion Simple Field 1.0\nXRes = {NX}\nYRes = {NY}\nXReal = {NX * DX * 1e-6}\n"
            f"YReal = {NY * DY * 1e-6}\nXYUnits = m\nZUnits = nm\nTitle = {title}\n").encode()
    pad = 4 - len(text) % 4                      # one to four NULs, data aligned to 4
    values = grid_pattern().T.astype("<f4")      # rows of XRes values, one row per y
    path.write_bytes(text + b"\0" * pad + values.tobytes())
    return pad


X3P_XML = """<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
 <Record1><Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType>
  <Axes>
   <CX><AxisType>I</AxisType><DataType>D</DataType><Increment>{dx}</Increment><Offset>0</Offset></CX>
   <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>{dy}</Increment><Offset>0</Offset></CY>
   <CZ><AxisType>A</AxisType><DataType>{ztype}</DataType>{zscale}</CZ>
  </Axes></Record1>
 <Record2><Date>2026-01-01T00:00:00</Date><Creator>contactpetsc tests</Creator></Record2>
 <Record3><MatrixDimension><SizeX>{nx}</SizeX><SizeY>{ny}</SizeY><SizeZ>1</SizeZ></MatrixDimension>
  <DataLink><PointDataLink>bindata/data.bin</PointDataLink>
   <MD5ChecksumPointData>{md5}</MD5ChecksumPointData>{valid}</DataLink></Record3>
 <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>
"""


def write_x3p(path, ztype, increment=None, offset=None, invalid=None):
    """Heights pattern * 1e-6 m; integer types store (h - offset) / increment."""
    z = grid_pattern() * 1e-6
    if increment is not None:
        z = np.rint((z - offset) / increment)
    data = z.T.astype({"D": "<f8", "F": "<f4", "L": "<i4", "I": "<i2"}[ztype]).tobytes()   # x fastest
    zscale = "" if increment is None else f"<Increment>{increment!r}</Increment><Offset>{offset!r}</Offset>"
    valid, members = "", {"bindata/data.bin": data}
    if invalid is not None:
        bits = np.ones(NX * NY, np.uint8)
        bits[invalid[0] + NX * invalid[1]] = 0
        members["bindata/valid.bin"] = np.packbits(bits, bitorder="little").tobytes()
        valid = "<ValidPointsLink>bindata/valid.bin</ValidPointsLink>"
    xml = X3P_XML.format(dx=DX * 1e-6, dy=DY * 1e-6, ztype=ztype, zscale=zscale, nx=NX, ny=NY,
                         md5=hashlib.md5(data).hexdigest(), valid=valid)
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("main.xml", xml)
        for name, content in members.items():
            archive.writestr(name, content)


def write_sur(path, dz=0.5, z0=1.25, comment=b"a comment"):
    """Heights (value dz + z0) nm with value = 2 pattern; steps in um (written as µm, latin-1)."""
    header = bytearray(512)
    struct.pack_into("<12s", header, 0, b"DIGITAL SURF")
    struct.pack_into("<hhhh", header, 12, 0, 1, 1, 2)          # PC format, 1 object, version, surface
    struct.pack_into("<h", header, 98, 32)                      # bits per point
    values = np.rint(2 * grid_pattern()).astype("<i4")
    struct.pack_into("<iiiii", header, 100, int(values.min()), int(values.max()), NX, NY, NX * NY)
    struct.pack_into("<fff", header, 120, DX, DY, dz)
    for offset, text in ((132, "X"), (148, "Y"), (164, "Z"), (180, "µm"), (196, "µm"), (212, "nm"),
                         (228, "µm"), (244, "µm"), (260, "nm")):   # axis names, step and length units
        struct.pack_into("<16s", header, offset, text.encode("latin-1"))
    struct.pack_into("<fff", header, 276, 1.0, 1.0, 1.0)        # unit ratios
    struct.pack_into("<hh", header, 334, len(comment), 0)
    struct.pack_into("<f", header, 474, z0)
    path.write_bytes(bytes(header) + comment + values.T.tobytes())   # lines of NX points, one per y
    return values * dz + z0


def gwy_object(name, components):
    """A serialized object: type name, uint32 size, then (name, type character, value) items."""
    body = b""
    for key, (kind, value) in components.items():
        body += key.encode() + b"\0" + kind.encode()
        if kind == "i":
            body += struct.pack("<i", value)
        elif kind == "d":
            body += struct.pack("<d", value)
        elif kind == "s":
            body += value.encode() + b"\0"
        elif kind == "o":
            body += value
        elif kind == "D":
            body += struct.pack("<I", len(value)) + np.asarray(value, "<f8").tobytes()
    return name.encode() + b"\0" + struct.pack("<I", len(body)) + body


def write_gwy(path):
    """Two channels: 0 'Amplitude' (zeros), 1 'Height' (the pattern in nm, rows of xres values
    one per y), lengths in um."""
    def field(values, zunit):
        return gwy_object("GwyDataField", {
            "xres": ("i", NX), "yres": ("i", NY), "xreal": ("d", NX * DX), "yreal": ("d", NY * DY),
            "si_unit_xy": ("o", gwy_object("GwySIUnit", {"unitstr": ("s", "µm")})),
            "si_unit_z": ("o", gwy_object("GwySIUnit", {"unitstr": ("s", zunit)})),
            "data": ("D", values.T.ravel())})
    container = gwy_object("GwyContainer", {
        "/0/data": ("o", field(np.zeros((NX, NY)), "V")), "/0/data/title": ("s", "Amplitude"),
        "/1/data": ("o", field(grid_pattern(), "nm")), "/1/data/title": ("s", "Height"),
        "/1/base/palette": ("s", "Gray")})
    path.write_bytes(b"GWYP" + container)


# -- readers -------------------------------------------------------------------------------------
@pytest.mark.serial
def test_text_matrix_lines_are_y_and_the_header_gives_extent_and_unit(tmp_path):
    path = tmp_path / "scan.txt"
    write_matrix(path)
    topo = read_topography(str(path))
    check(topo, 1e-9, 1e-6)
    assert topo.format == "text" and topo.unit_stated and topo.height_unit == "nm"
    with pytest.raises(ValueError, match="states its heights in 'nm', not 'um'"):
        read_topography(str(path), height_unit="um")
    write_matrix(path, header=False)
    topo = read_topography(str(path), height_unit="um")
    assert topo.dx is None and not topo.unit_stated
    assert np.abs(topo.heights - grid_pattern() * 1e-6).max() == 0.0
    path.write_text("1 2 3\n4 5\n")
    with pytest.raises(FormatError, match="different lengths"):
        read_topography(str(path))
    path.write_text("0 0 1\n0 1 2\n1 0 3\n1 1 4\n")       # x y z points on a full grid: a point list
    topo = read_topography(str(path))
    assert topo.format == "xyz" and np.array_equal(topo.heights, [[1.0, 2.0], [3.0, 4.0]])
    path.write_text("0 0 1\n0 1 2\n1 0 3\n1 3 4\n")       # off a full grid: neither
    with pytest.raises(FormatError, match="not an x y z point list"):
        read_topography(str(path))


@pytest.mark.serial
def test_xyz_points_in_any_order_make_the_grid(tmp_path):
    i, j = np.meshgrid(np.arange(NX), np.arange(NY), indexing="ij")
    rows = np.column_stack([10 + i.ravel() * DX, -4 + j.ravel() * DY, pattern(i, j).ravel()])
    rows = rows[np.random.default_rng(0).permutation(len(rows))]
    path = tmp_path / "scan.xyz"
    path.write_text("\n".join(f"{x:.6g}\t{y:.6g}\t{float(z)!r}" for x, y, z in rows) + "\n")
    check(read_topography(str(path), height_unit="um"), 1e-6, 1e-6)
    path.write_text("\n".join(f"{x:.6g} {y:.6g} {float(z)!r}" for x, y, z in rows[1:]) + "\n")
    with pytest.raises(FormatError, match="1 of the 7 x 5 grid points are missing"):
        read_topography(str(path))


@pytest.mark.serial
def test_gsf_with_every_padding_length(tmp_path):
    pads = set()
    for k in range(4):
        path = tmp_path / f"scan{k}.gsf"
        pads.add(write_gsf(path, "t" * k))
        check(read_topography(str(path)), 1e-9, 1e-6, rtol=1e-7)   # float32 data
    assert pads == {1, 2, 3, 4}
    path.write_bytes(path.read_bytes()[:-4])
    with pytest.raises(FormatError, match="data bytes"):
        read_topography(str(path))


@pytest.mark.serial
@pytest.mark.parametrize("ztype, increment, offset", [("D", None, None), ("F", None, None),
                                                      ("L", 1e-8, -2e-6), ("I", 5e-7, 1e-6)])
def test_x3p_float_and_scaled_integer_heights(tmp_path, ztype, increment, offset):
    path = tmp_path / "scan.x3p"
    write_x3p(path, ztype, increment, offset)
    topo = read_topography(str(path))
    check(topo, 1e-6, 1e-6, rtol=1e-7 if ztype == "F" else 1e-12)
    assert topo.unit_stated and topo.metadata["Record2/Creator"] == "contactpetsc tests"


@pytest.mark.serial
def test_x3p_invalid_points_and_damage_are_refused(tmp_path):
    path = tmp_path / "scan.x3p"
    write_x3p(path, "D", invalid=(3, 2))
    with pytest.raises(FormatError, match="1 of the 7 x 5 points are not measured"):
        read_topography(str(path))
    write_x3p(path, "D")
    with zipfile.ZipFile(path) as z:
        members = {n: z.read(n) for n in z.namelist()}
    members["bindata/data.bin"] = members["bindata/data.bin"][:-8] + b"\0" * 8
    with zipfile.ZipFile(path, "w") as z:
        for n, c in members.items():
            z.writestr(n, c)
    with pytest.raises(FormatError, match="MD5"):
        read_topography(str(path))


@pytest.mark.serial
def test_sur_integer_lines_after_header_and_comment(tmp_path):
    path = tmp_path / "scan.sur"
    ref = write_sur(path)
    topo = read_topography(str(path))
    assert topo.shape == (NX, NY) and topo.format == "sur" and topo.height_unit == "nm"
    assert np.abs(topo.heights - ref * 1e-9).max() <= 1e-15 * np.abs(ref).max()
    assert topo.dx == pytest.approx(DX * 1e-6, rel=1e-7) and topo.dy == pytest.approx(DY * 1e-6, rel=1e-7)
    path.write_bytes(path.read_bytes()[:600])
    with pytest.raises(FormatError, match="truncated"):
        read_topography(str(path))


@pytest.mark.serial
def test_gwy_channels_by_title(tmp_path):
    path = tmp_path / "scan.gwy"
    write_gwy(path)
    topo = read_topography(str(path), dataset="Height")
    check(topo, 1e-9, 1e-6)
    assert topo.metadata["channel"] == "Height" and topo.height_unit == "nm"
    with pytest.raises(ValueError, match="in 'V', not a length.*'Amplitude'"):   # default: the first
        read_topography(str(path))
    with pytest.raises(KeyError, match="'Phase'.*Amplitude"):
        read_topography(str(path), dataset="Phase")
    path.write_bytes(path.read_bytes()[:-16])
    with pytest.raises(FormatError, match="beyond the file's end"):
        read_topography(str(path), dataset="Height")


@pytest.mark.serial
def test_the_reader_and_the_converter_run_without_mpi_or_petsc(tmp_path):
    """contactpetsc.topography and `contactpetsc import` with petsc4py and mpi4py unimportable:
    the converter's environment (SurfaceTopography's venv) has neither."""
    src = tmp_path / "scan.txt"
    write_matrix(src)
    code = f"""
import sys
class Block:
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in ('petsc4py', 'mpi4py'):
            raise ImportError('blocked: ' + name)
sys.meta_path.insert(0, Block())
from contactpetsc.app.cli import main
sys.exit(main(['import', {str(src)!r}, {str(tmp_path / 'scan.npy')!r}]))
"""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                          env=dict(os.environ, PYTHONPATH=root))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "wrote" in done.stdout and "7 x 5 nodes" in done.stdout
    topo = read_topography(str(tmp_path / "scan.npy"))      # heights and spacing from the sidecar
    check(topo, 1e-9, 1e-6)
    assert topo.unit_stated and topo.metadata["source"] == "scan.txt"


# -- scenes --------------------------------------------------------------------------------------
def file_scene(path, **geometry):
    return {"geometry": {"kind": "file", "path": str(path), **geometry},
            "material": {"e_star": 1e9}, "protocol": {"values": [1e-10]}}


def test_a_text_matrix_scene_takes_its_grid_from_the_file(coll, shared_tmp):
    path = shared_tmp / "scan.txt"
    on_root(coll, lambda: write_matrix(path))
    g = scenes.validate(file_scene(path))["geometry"]
    assert (g["nx"], g["ny"], g["format"], g["height_unit"], g["periodic"]) == (NX, NY, "text", "nm", False)
    assert g["dx"] == pytest.approx(DX * 1e-6, rel=1e-15) and g["dy"] == pytest.approx(DY * 1e-6, rel=1e-15)
    assert scenes.validate(scenes.validate(file_scene(path)))["geometry"] == g   # validates again
    for geometry, words in (({"nx": NY, "ny": NX}, ["geometry.path", "(7, 5)", "geometry.nx", "(5, 7)"]),
                            ({"dx": 2.5e-6}, ["the file's dx = 2e-06", "geometry.dx = 2.5e-06"]),
                            ({"height_unit": "um"}, ["geometry.height_unit = 'um'", "'nm'"]),
                            ({"dataset": "h"}, ["geometry.dataset", "HDF5 and .gwy files only"]),
                            ({"format": "gsf"}, ["geometry.path", "Gwyddion Simple Field"]),
                            ({"detrend": "plane"}, ["geometry.detrend = 'plane'", "mean-plane"])):
        coll.raises(scenes.SceneError, words, scenes.validate, file_scene(path, **geometry))
    bare = shared_tmp / "bare.txt"
    on_root(coll, lambda: write_matrix(bare, header=False))
    coll.raises(scenes.SceneError, ["geometry.dx is required", "bare.txt"], scenes.validate, file_scene(bare))
    g = scenes.validate(file_scene(bare, dx=1e-9, height_unit="A"))["geometry"]
    assert (g["dy"], g["height_unit"]) == (1e-9, "A")


def test_a_map_too_small_for_its_fit_is_refused_naming_the_size_and_the_minimum(coll, shared_tmp):
    """A quadric has 6 coefficients and u^2, v^2 need 3 distinct values each: a 3 x 2 map
    cannot be fitted (its normal equations are singular); a mean plane can."""
    path = shared_tmp / "small.txt"
    on_root(coll, lambda: path.write_text("# Width: 3 um\n# Height: 2 um\n# Value units: nm\n1 2 3\n4 5 7\n"))
    words = ["geometry.detrend = 'curvature'", "at least 3 nodes along each axis", "this map is 3 x 2",
             "accepted for it: none, mean-plane"]
    coll.raises(scenes.SceneError, words, scenes.validate, file_scene(path, detrend="curvature"))
    assert scenes.validate(file_scene(path, detrend="mean-plane"))["geometry"]["nx"] == 3
    grid = SurfaceGrid(3, 2, 1e-6, periodic=False, comm=PETSc.COMM_SELF)   # 2 rows: one rank each
    h = surfaces.from_array(grid, np.array([[1.0, 4.0], [2.0, 5.0], [3.0, 7.0]]))
    coll.raises(ValueError, words[1:], surfaces.detrended, grid, h, "curvature")


@pytest.mark.parametrize("detrend", ["none", "mean-plane", "curvature"])
def test_heights_of_a_file_scene_are_detrended_and_shifted(coll, shared_tmp, detrend):
    """On any number of ranks, the file's heights z being the surface (peaks up): none -> the
    gap max(z) - z; mean-plane -> the same after numpy's least-squares plane is removed from z;
    curvature -> a quadric (the pattern) removed to round-off."""
    path = shared_tmp / "scan.txt"
    on_root(coll, lambda: write_matrix(path))
    scene = scenes.validate(file_scene(path, detrend=detrend))
    grid = builder.build_grid(scene)
    got = grid.gather(builder.build_heights(scene, grid))
    h = grid_pattern() * 1e-9
    if detrend == "mean-plane":
        i, j = np.meshgrid(np.arange(NX), np.arange(NY), indexing="ij")
        a = np.column_stack([np.ones(h.size), i.ravel(), j.ravel()])
        h = h - (a @ np.linalg.lstsq(a, h.ravel(), rcond=None)[0]).reshape(h.shape)
    if detrend == "curvature":
        assert coll.max(np.abs(got).max()) <= 1e-14 * np.abs(h).max()
        return
    ref = h.max() - h
    assert coll.max(np.abs(got - ref).max()) <= 1e-13 * ref.max() and coll.max(got.min()) == 0.0


def test_imported_files_are_read_with_nothing_restated(coll, shared_tmp):
    """`contactpetsc import` to HDF5 (and .npy + sidecar): a scene with only the path gets the
    grid, the spacing, the unit and the heights of the source."""
    src = shared_tmp / "scan.sur"
    ref = {}
    on_root(coll, lambda: ref.update(h=write_sur(src)))
    ref = coll.comm.bcast(ref.get("h"), root=0) * 1e-9
    for name in ("scan.h5", "scan.npy"):
        dst = shared_tmp / name
        on_root(coll, lambda: convert.convert(str(src), str(dst)))
        scene = scenes.validate(file_scene(dst))
        g = scene["geometry"]
        assert (g["nx"], g["ny"], g["height_unit"], g["periodic"]) == (NX, NY, "m", False)
        assert g["dx"] == pytest.approx(DX * 1e-6, rel=1e-7) and g["dy"] == pytest.approx(DY * 1e-6, rel=1e-7)
        grid = builder.build_grid(scene)
        got = grid.gather(builder.build_heights(scene, grid))
        assert coll.max(np.abs(got - (ref.max() - ref)).max()) <= 1e-15 * np.abs(ref).max()   # peaks up


def test_a_step_file_scene_needs_only_its_path(coll, shared_tmp):
    """contactpetsc's own step files carry dx, dy, the axes stamp and their run's scene (hence
    whether its cell was periodic): nothing to restate."""
    import json

    import h5py
    def write(path, periodic):
        with h5py.File(path, "w") as f:
            f.attrs.update(axes="y,x", dx=2e-9, dy=3e-9,
                           scene=json.dumps({"geometry": {"kind": "self-affine", "periodic": periodic}}))
            f["heights"] = grid_pattern().T * 1e-9          # stored (ny, nx)
    for periodic in (True, False):
        # a file of its own per case: rank 0 must not rewrite one that other ranks still read
        path = shared_tmp / f"step_{'periodic' if periodic else 'window'}.h5"
        on_root(coll, lambda: write(path, periodic))
        g = scenes.validate(file_scene(path))["geometry"]
        assert (g["nx"], g["ny"], g["dx"], g["dy"], g["format"]) == (NX, NY, 2e-9, 3e-9, "hdf5")
        assert g["periodic"] is periodic


@pytest.mark.serial
def test_the_example_file_is_its_generator_s_map_and_dry_runs_with_nothing_restated(tmp_path):
    """examples/scenes/measured_surface.txt holds make_measured_surface.heights() [nm] to the
    0.01 nm it is printed with, [x, y] as the generator indexes it; its scene's dry run prints
    the grid read from the file."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    sys.path.insert(0, os.path.join(root, "examples", "scenes"))
    try:
        import make_measured_surface as gen
    finally:
        sys.path.pop(0)
    topo = read_topography(os.path.join(root, "examples", "scenes", "measured_surface.txt"))
    assert topo.shape == (gen.NX, gen.NY) and topo.dx == pytest.approx(gen.DX * 1e-9, rel=1e-12)
    assert np.abs(topo.heights - gen.heights() * 1e-9).max() <= 0.0051e-9
    done = subprocess.run([sys.executable, "-m", "contactpetsc", "run", "--dry-run",
                           os.path.join(root, "examples", "scenes", "measured_surface.toml")],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path,
                          env=dict(os.environ, PYTHONPATH=root, OMP_NUM_THREADS="1"))
    assert done.returncode == 0, done.stdout + done.stderr
    assert "SurfaceGrid(64 x 48, dx=5e-08 m, dy=5e-08 m, isolated" in done.stdout
    assert "detrend mean-plane" in done.stdout
