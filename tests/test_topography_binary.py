"""The binary height readers (.sur, .x3p, .gwy, .gsf, .npy/HDF5 metadata), points not measured
and their harmonic fill, and `contactpetsc import --reader auto`.

Truths, all independent of contactpetsc's output: SurfaceTopography 1.27.1's reading of the
real instrument files (tests/data/topography-samples/reference.json: grid, sizes, unit,
heights at nodes that fix the orientation, the count not measured); Gwyddion's specification
for chip.gsf (its header and the float32 rows it lays out after the header); the formats'
layouts for the hand-made files, each broken in one field, which must be refused fast with
the field (or member, key, attribute) named; and a discrete harmonic function
a + b x + c y + d (x^2 - y^2) + e x y, which the harmonic fill must rebuild in its holes.
"""
import importlib.util
import json
import os
import struct
import time
import warnings
import zipfile
import zlib

import h5py
import numpy as np
import pytest

from contactpetsc.app import scenes
from contactpetsc.geometry import surfaces
from contactpetsc.grid import GridError, SurfaceGrid
from contactpetsc.topography import FormatError, convert, read_topography
from contactpetsc.topography.fill import harmonic
from test_topography import NX, NY, grid_pattern, write_sur, write_x3p, gwy_object

SAMPLES = os.path.join(os.path.dirname(__file__), "data", "topography-samples")
with open(os.path.join(SAMPLES, "reference.json")) as _f:
    REFERENCE = json.load(_f)
METRES = {"m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9}


def sample(name):
    return os.path.join(SAMPLES, name)


def file_scene(path, **geometry):
    return {"geometry": {"kind": "file", "path": str(path), **geometry},
            "material": {"e_star": 1e9}, "protocol": {"values": [1e-10]}}


def check_against_reference(topo, name):
    """SurfaceTopography's grid, sizes and heights at the recorded nodes (1e-9 relative; NaN
    where it records a point not measured), in metres."""
    ref = REFERENCE[name]
    unit = METRES[ref["unit"]]
    assert topo.shape == tuple(ref["nb_grid_pts"])
    assert topo.shape[0] * topo.dx == pytest.approx(ref["physical_sizes"][0] * unit, rel=1e-9)
    assert topo.shape[1] * topo.dy == pytest.approx(ref["physical_sizes"][1] * unit, rel=1e-9)
    for node, value in ref["nodes"].items():
        i, j = map(int, node.split(","))
        if value is None:
            assert np.isnan(topo.heights[i, j]), node
        else:
            assert topo.heights[i, j] == pytest.approx(value * unit, rel=1e-9), node


def refused(match, func, *args, seconds=2.0, error=FormatError, **kw):
    """``func`` refuses with a message matching ``match``, within ``seconds``."""
    start = time.perf_counter()
    with pytest.raises(error, match=match):
        func(*args, **kw)
    assert time.perf_counter() - start < seconds


# -- .sur ----------------------------------------------------------------------------------------
@pytest.mark.serial
def test_sur_header_sizes_are_checked_before_a_byte_is_a_height(tmp_path):
    path = tmp_path / "scan.sur"
    write_sur(path)
    good = path.read_bytes()
    for offset, fmt, value, field in ((334, "<h", -8, "comment zone length"),     # uint16: 65528
                                      (336, "<H", 40000, "private zone length"),
                                      (116, "<I", NX * NY + 1, "total points"),
                                      (108, "<i", 0, "points per line"),
                                      (112, "<i", -3, "number of lines"),
                                      (98, "<H", 8, "bits per point"),
                                      (120, "<f", 0.0, "x spacing"),
                                      (128, "<f", float("nan"), "z spacing"),
                                      (290, "<H", 7, "inversion")):
        broken = bytearray(good)
        struct.pack_into(fmt, broken, offset, value)
        path.write_bytes(bytes(broken))
        refused(f"'{field}' \\(byte {offset}\\)", read_topography, str(path))
    # a comment zone shorter than the header says: the data would start inside the comment
    broken = bytearray(good)
    struct.pack_into("<H", broken, 334, 2)
    path.write_bytes(bytes(broken))
    refused("accounts for .*a damaged header", read_topography, str(path))
    path.write_bytes(bytes(good[:-4]))
    refused("truncated", read_topography, str(path))


@pytest.mark.serial
def test_sur_sample_reads_as_surfacetopography_and_its_unmeasured_points_are_filled_or_refused(tmp_path):
    name = "sur-2.sur"
    refused('117 of the 563 x 484 points are not measured.*geometry.fill = "harmonic".*--fill harmonic',
            read_topography, sample(name))
    with pytest.raises(scenes.SceneError, match=r"sur-2.sur.*117 of .*geometry.fill"):
        scenes.validate(file_scene(sample(name)))
    topo = read_topography(sample(name), fill="harmonic")
    measured = {k: v for k, v in REFERENCE[name]["nodes"].items() if v is not None}
    for node, value in measured.items():       # measured heights unchanged by the fill
        i, j = map(int, node.split(","))
        assert topo.heights[i, j] == pytest.approx(value * 1e-3, rel=1e-9)
    assert topo.metadata["filled_points"] == REFERENCE[name]["undefined"] == 117
    assert np.isfinite(topo.heights).all() and topo.dtype.kind == "f"
    # the filled points lie within their measured surroundings (the maximum principle)
    assert REFERENCE[name]["nodes"]["562,483"] is None
    assert 8.9e-6 <= topo.heights[562, 483] <= 1.04e-5
    g = scenes.validate(file_scene(sample(name), fill="harmonic"))["geometry"]
    assert (g["nx"], g["ny"], g["fill"]) == (563, 484, "harmonic")


@pytest.mark.serial
def test_sur_sample_unmeasured_points_are_nan_where_surfacetopography_masks_them():
    from contactpetsc.topography import sur
    topo = sur.read_sur(sample("sur-2.sur"))       # the reader: NaN before any fill
    topo.heights = topo.heights * 1e-3             # mm, as the header's step units say
    topo.dx, topo.dy = topo.dx * 1e-3, topo.dy * 1e-3
    check_against_reference(topo, "sur-2.sur")
    assert int(np.isnan(topo.heights).sum()) == REFERENCE["sur-2.sur"]["undefined"]
    assert np.nanmean(topo.heights) == pytest.approx(REFERENCE["sur-2.sur"]["mean"] * 1e-3, rel=1e-9)


# -- .x3p ----------------------------------------------------------------------------------------
def x3p_members(path):
    with zipfile.ZipFile(path) as z:
        return {n: z.read(n) for n in z.namelist()}


def write_members(path, members, compression=zipfile.ZIP_STORED):
    with zipfile.ZipFile(path, "w", compression) as z:
        for n, c in members.items():
            z.writestr(n, c)


def declare_size(path, member, size):
    """Patch the central directory's uncompressed size of ``member`` (what ZipInfo.file_size
    reads) to ``size``, leaving the data as it is: an archive that lies about a member."""
    data = bytearray(path.read_bytes())
    at = data.find(b"PK\x01\x02")
    while at >= 0:
        length = struct.unpack_from("<H", data, at + 28)[0]
        if data[at + 46:at + 46 + length] == member.encode():
            struct.pack_into("<I", data, at + 24, size)
            path.write_bytes(bytes(data))
            return
        at = data.find(b"PK\x01\x02", at + 4)
    raise AssertionError(f"no {member}")


@pytest.mark.serial
def test_x3p_members_are_sized_before_they_are_inflated(tmp_path, capsys):
    path = tmp_path / "scan.x3p"
    write_x3p(path, "D")
    members = x3p_members(path)
    need = NX * NY * 8
    # a highly compressible data member a few MB over what SizeX x SizeY x 8 bytes need
    members["bindata/data.bin"] = bytes(need + 8 * 2**20)
    write_members(path, members, zipfile.ZIP_DEFLATED)
    assert path.stat().st_size < 2**16
    refused(f"bindata/data.bin .*inflates to {need + 8 * 2**20} bytes; the map needs {need}",
            read_topography, str(path))
    with pytest.raises(scenes.SceneError, match=f"{path}.*bindata/data.bin .*the map needs {need}"):
        scenes.validate(file_scene(path))          # the --dry-run path: app/scene_files.py
    assert convert.main([str(path), str(tmp_path / "out.h5")]) == 1
    assert f"{path}" in capsys.readouterr().err
    # a directory entry that lies: 4 GiB declared (refused unread), or the expected size
    # declared for a member that inflates to more (the bounded stream stops at the lie)
    declare_size(path, "bindata/data.bin", 2**32 - 1)
    refused(f"inflates to {2**32 - 1} bytes", read_topography, str(path))
    declare_size(path, "bindata/data.bin", need)
    refused("bindata/data.bin .*(cannot be inflated|holds)", read_topography, str(path))
    write_x3p(path, "D")
    declare_size(path, "main.xml", 2**31)
    refused("main.xml .*inflates to 2147483648 bytes; at most", read_topography, str(path))


@pytest.mark.serial
def test_x3p_missing_increments_short_valid_points_and_scaled_integers(tmp_path):
    path = tmp_path / "scan.x3p"
    write_x3p(path, "D")
    members = x3p_members(path)
    xml = members["main.xml"].decode()
    for axis in ("CX", "CY"):
        start = xml.index(f"<{axis}>")
        cut = xml[:start] + xml[start:].replace(xml[start:].split("<Increment>")[1].split("</Increment>")[0], "", 1)
        members["main.xml"] = cut.replace("<Increment></Increment>", "", 1).encode()
        write_members(path, members)
        refused(f"main.xml lacks Record1/Axes/{axis}/Increment", read_topography, str(path))
    members["main.xml"] = xml.replace("<SizeX>7</SizeX>", "<SizeX>0</SizeX>").encode()
    write_members(path, members)
    refused("SizeX = '0': must be finite and > 0", read_topography, str(path))
    # one byte of valid-point bits for 35 points
    write_x3p(path, "D", invalid=(3, 2))
    members = x3p_members(path)
    members["bindata/valid.bin"] = b"\xff"
    write_members(path, members)
    refused("bindata/valid.bin .*inflates to 1 bytes; the map needs 5", read_topography, str(path))
    # integers scaled by CZ's increment are heights in m (floats): no "taken as metres" warning
    for ztype in ("L", "I"):
        write_x3p(path, ztype, 5e-7, 1e-6)
        topo = read_topography(str(path))
        assert topo.dtype.kind == "f"
        assert np.abs(topo.heights - grid_pattern() * 1e-6).max() < 1e-12
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            surfaces.check_height_dtype(topo.dtype, str(path))
    sur = tmp_path / "scan.sur"
    write_sur(sur)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        surfaces.check_height_dtype(read_topography(str(sur)).dtype, str(sur))
    with pytest.warns(surfaces.HeightDtypeWarning):      # raw integers stay warned about
        surfaces.check_height_dtype(np.dtype("<i4"), "a .npy file")


@pytest.mark.serial
def test_x3p_sample_reads_as_surfacetopography():
    topo = read_topography(sample("x3p-2.x3p"))
    check_against_reference(topo, "x3p-2.x3p")
    assert topo.dx != topo.dy and topo.metadata["not_measured"] == REFERENCE["x3p-2.x3p"]["undefined"]
    assert np.mean(topo.heights) == pytest.approx(REFERENCE["x3p-2.x3p"]["mean"], rel=1e-9)


# -- .gwy, .gsf ----------------------------------------------------------------------------------
@pytest.mark.serial
def test_gwy_nesting_and_gsf_sizes_are_bounded(tmp_path):
    path = tmp_path / "deep.gwy"
    inner = gwy_object("GwySIUnit", {"unitstr": ("s", "m")})
    for _ in range(2000):
        inner = gwy_object("GwyContainer", {"x": ("o", inner)})
    path.write_bytes(b"GWYP" + inner)
    refused("nested more than 32 deep", read_topography, str(path))
    header = "Gwyddion Simple Field 1.0\nXRes = {xres}\nYRes = 2\nXReal = {xreal}\n"
    for xres, xreal, key in ((0, 1e-6, "XRes"), (-2, 1e-6, "XRes"), (2, 0, "XReal"), (2, "nan", "XReal")):
        text = header.format(xres=xres, xreal=xreal).encode()
        path = tmp_path / "bad.gsf"
        path.write_bytes(text + b"\0" * (4 - len(text) % 4) + bytes(16))
        refused(f"header {key} = '{xres if key == 'XRes' else xreal}': must be", read_topography, str(path))


@pytest.mark.serial
def test_chip_gsf_is_read_as_gwyddion_lays_it_out():
    """SurfaceTopography cannot read it: the truth is Gwyddion's layout, checked by hand."""
    with open(sample("chip.gsf"), "rb") as f:
        raw = f.read()
    header = dict(line.split(" = ") for line in raw[:raw.index(b"\0")].decode().splitlines()[1:])
    assert (header["XRes"], header["YRes"], header["XYUnits"], header["ZUnits"]) == ("300", "300", "m", "m")
    rows = np.frombuffer(raw[-4 * 300 * 300:], "<f4").reshape(300, 300)     # a row is one y
    topo = read_topography(sample("chip.gsf"))
    assert topo.shape == (300, 300)
    assert topo.dx * 300 == pytest.approx(float(header["XReal"]), rel=1e-12)
    assert topo.dy * 300 == pytest.approx(float(header["YReal"]), rel=1e-12)
    assert np.array_equal(topo.heights, rows.T.astype(float))          # [i, j] = row j, column i
    assert np.array_equal(topo.heights.astype("<f4").astype(float), topo.heights)
    assert np.isfinite(topo.heights).all() and 0 < np.ptp(topo.heights) < 1e-4   # a chip: um


# -- .npy / HDF5 metadata ------------------------------------------------------------------------
@pytest.mark.serial
def test_periodic_and_spacing_metadata_are_parsed_strictly(tmp_path):
    h = np.arange(12.0).reshape(4, 3)
    path = str(tmp_path / "map.h5")
    for value, periodic in (("false", False), ("TRUE", True), (b"False", False), (np.bool_(True), True),
                            (0, False), (np.int64(1), True), (False, False)):
        with h5py.File(path, "w") as f:
            f.create_dataset("heights", data=h).attrs.update(periodic=value, dx=1e-9)
        assert read_topography(path, metadata_only=True).periodic is periodic, value
    for attrs, match in (({"periodic": "yes"}, "attribute periodic of 'heights' = 'yes': not a boolean"),
                         ({"periodic": 2}, "periodic .* = 2: not a boolean"),
                         ({"dx": "1e-9"}, "attribute dx of 'heights' = '1e-9': a spacing is a number > 0"),
                         ({"dx": -1e-9}, "attribute dx .* = -1e-09: a spacing"),
                         ({"dx": 1e-9, "dy": 0.0}, "attribute dy .* = 0.0: a spacing")):
        with h5py.File(path, "w") as f:
            f.create_dataset("heights", data=h).attrs.update(attrs)
        refused(match, read_topography, path, metadata_only=True)
    npy = str(tmp_path / "map.npy")
    np.save(npy, h)
    for meta, expected in (({"dx": 1e-9, "periodic": "false"}, False), ({"dx": 1e-9, "periodic": True}, True)):
        with open(npy + ".json", "w") as f:
            json.dump(meta, f)
        assert read_topography(npy).periodic is expected
    for meta, match in (({"dx": "1e-9"}, "map.npy.json: dx = '1e-9'"), ({"dx": 0}, "map.npy.json: dx = 0"),
                        ({"periodic": "nope"}, "map.npy.json: periodic = 'nope': not a boolean")):
        with open(npy + ".json", "w") as f:
            json.dump(meta, f)
        refused(match, read_topography, npy)


# -- the harmonic fill ---------------------------------------------------------------------------
def harmonic_map(nx=40, ny=31, dx=2.0, dy=3.0):
    """A discrete harmonic function on an anisotropic grid (the 5-point Laplacian with weights
    1/dx^2, 1/dy^2 of every term is 0), indexed [i, j]."""
    x, y = np.meshgrid(np.arange(nx) * dx, np.arange(ny) * dy, indexing="ij")
    return 0.3 + 0.02 * x - 0.05 * y + 1e-3 * (x ** 2 - y ** 2) + 2e-3 * x * y


def punch(h):
    """``h`` with interior holes: a blob of 9 x 7, a line, and scattered single points."""
    holey = h.copy()
    holey[5:14, 4:11] = np.nan
    holey[20, 3:28] = np.nan
    holey[[30, 33, 36], [25, 8, 17]] = np.nan
    return holey


@pytest.mark.serial
def test_harmonic_fill_rebuilds_a_harmonic_function():
    exact = harmonic_map()
    holey = punch(exact)
    filled, count = harmonic(holey, 2.0, 3.0)
    assert count == int(np.isnan(holey).sum()) == 63 + 25 + 3
    assert np.abs(filled - exact).max() <= 1e-10 * np.abs(exact).max()
    assert np.array_equal(filled[~np.isnan(holey)], exact[~np.isnan(holey)])     # measured: unchanged
    # a hole at the edge: no exact answer, but within the measured range (maximum principle)
    holey[0, :10] = np.nan
    edge, _ = harmonic(holey, 2.0, 3.0)
    assert np.nanmin(holey) <= edge[0, :10].min() and edge[0, :10].max() <= np.nanmax(holey)
    with pytest.raises(FormatError, match="no point of the map is measured"):
        harmonic(np.full((3, 3), np.nan))


def test_a_filled_map_is_the_same_field_on_any_number_of_ranks(coll, shared_tmp):
    """A .npy map (read by rows) with holes: geometry.fill = "harmonic" reads the whole map on
    each rank, fills it, then takes the rank's rows: the harmonic function, on every rank."""
    dx, dy = 2e-9, 3e-9
    exact = harmonic_map(dx=1.0, dy=1.5) * 1e-9                  # the same function, in m
    path = shared_tmp / "holes.npy"
    if coll.rank == 0:
        np.save(path, punch(exact))
        with open(str(path) + ".json", "w") as f:
            json.dump({"dx": dx, "dy": dy, "unit": "m"}, f)
    coll.comm.Barrier()
    grid = SurfaceGrid(40, 31, dx, dy, periodic=False)
    with pytest.raises(GridError, match="holes.npy.*not measured.*geometry.fill"):
        surfaces.from_file(grid, str(path))       # by rows: some rank's rows hold NaN
    info = {}
    h = surfaces.from_file(grid, str(path), fill="harmonic", info=info)
    local = grid.local_array(h, readonly=True)
    assert coll.max(np.abs(local - exact[:, grid.ys:grid.ye]).max()) <= 1e-10 * np.abs(exact).max()
    assert info["filled_points"] == 91


# -- binary files with a text extension; the import's fall-back ---------------------------------
@pytest.mark.serial
def test_a_binary_dat_is_named_and_handed_to_surfacetopography(tmp_path, capsys):
    with pytest.raises(scenes.SceneError, match="metropro-1.dat.*a binary file \\(looks like Zygo MetroPro\\)"
                                                ".*contactpetsc import"):
        scenes.validate(file_scene(sample("metropro-1.dat")))
    text = tmp_path / "matrix.dat"                  # a text matrix with a .dat name still reads
    text.write_text("# Value units: nm\n1 2 3\n4 5 6\n")
    assert read_topography(str(text)).shape == (3, 2)
    out = str(tmp_path / "m.h5")
    if importlib.util.find_spec("SurfaceTopography") is None:
        assert convert.main([sample("metropro-1.dat"), out]) == 1
        err = capsys.readouterr().err
        assert "looks like Zygo MetroPro" in err and "pip install SurfaceTopography" in err
    else:
        assert convert.main([sample("metropro-1.dat"), out]) == 0
        check_against_reference(read_topography(out), "metropro-1.dat")


def test_a_run_records_the_fill_and_the_count_filled(coll, shared_tmp):
    """geometry.fill goes into the scene stored with the run; summary.json counts the points filled."""
    from contactpetsc.app import runner
    path = shared_tmp / "holes.npy"
    if coll.rank == 0:
        np.save(path, punch(harmonic_map(dx=1.0, dy=1.0)) * 1e-9)
        with open(str(path) + ".json", "w") as f:
            json.dump({"dx": 1e-9, "dy": 1e-9, "unit": "m"}, f)
    coll.comm.Barrier()
    scene = scenes.validate(dict(file_scene(path, fill="harmonic"), protocol={"values": [1e-10]}))
    out = str(shared_tmp / "run")
    runner.run(scene, output=out)
    with open(os.path.join(out, "summary.json")) as f:
        assert json.load(f)["filled_points"] == 91
    with open(os.path.join(out, "scene.json")) as f:
        assert json.load(f)["geometry"]["fill"] == "harmonic"
