"""Plain-text height files (text matrix, x y z lists): read right or refused with the file and cause.

Truths: SurfaceTopography 1.27.1's reading of the real sample files (``reference.json`` beside
them: grid, physical sizes, unit, heights at nodes that fix the orientation), and hand-made
files whose values the tests write (a matrix line is one y: line j, column i is h(x_i, y_j)).
Units are converted here by their definitions (1 um = 1e-6 m), not by contactpetsc's table.
"""
import json
import struct
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

from contactpetsc import topography
from contactpetsc.app import scenes
from contactpetsc.topography import FormatError, TopographyUnitWarning, convert, read_topography

SAMPLES = Path(__file__).parent / "data" / "topography-samples"
REFERENCE = json.loads((SAMPLES / "reference.json").read_text())
METRES = {None: 1.0, "m": 1.0, "mm": 1e-3, "um": 1e-6, "nm": 1e-9}
#: a 4 x 3 map [nm], [i, j] = h(x_i, y_j): written as 3 lines (y) of 4 numbers (x)
MAP = np.array([[1.5, -2.0, 0.25], [3.0, 4.5, -6.0], [7.0, 0.0, 9.75], [-1.0, 2.0, 11.0]])


def matches_reference(name, topo):
    """``topo`` (heights and spacing in m) is SurfaceTopography's reading of sample ``name``."""
    ref = REFERENCE[name]
    scale = METRES[ref["unit"]]
    assert list(topo.shape) == ref["nb_grid_pts"]
    top = max(abs(v) for v in ref["nodes"].values()) * scale
    for node, value in ref["nodes"].items():
        i, j = map(int, node.split(","))
        assert topo.heights[i, j] == pytest.approx(value * scale, rel=1e-12, abs=1e-12 * top), node
    sizes = [topo.shape[0] * topo.dx, topo.shape[1] * topo.dy]
    assert sizes == pytest.approx([s * scale for s in ref["physical_sizes"]], rel=1e-12)


def matrix_lines(h, fmt="{!r}", sep=" "):
    """Lines of a text matrix of ``h`` [x, y]: one line per y."""
    return [sep.join(fmt.format(float(v)) for v in row) for row in np.asarray(h).T]


def file_scene(path, **geometry):
    return {"geometry": {"kind": "file", "path": str(path), **geometry},
            "material": {"e_star": 1e9}, "protocol": {"values": [1e-10]}}


def on_root(coll, func):
    if coll.rank == 0:
        func()
    coll.comm.Barrier()


@pytest.mark.serial
def test_line_scans_are_refused_never_read_as_maps(tmp_path):
    """xy-1.txt (SurfaceTopography: a 1-D profile of 132 points) and hand-made 1- and 2-column
    or 1-line files: refused as line scans, by extension or with the format named, and in a
    scene that gives dx."""
    assert REFERENCE["xy-1.txt"]["dim"] == 1
    xy = SAMPLES / "xy-1.txt"
    for format in (None, "text", "xyz"):
        with pytest.raises(FormatError, match=r"^xy-1.txt: 132 lines of 2 numbers: a line scan "
                                              r"\(x, z pairs\): contact needs a 2-D map"):
            read_topography(str(xy), format=format)
    with pytest.raises(scenes.SceneError, match="xy-1.txt.*line scan"):
        scenes.validate(file_scene(xy, dx=1e-6))
    for text, words in (("1\n2\n3\n4\n5\n", "single column of 5 numbers"),
                        ("1 2 3 4 5\n", "single line of 5 numbers"),
                        ("1,2\n3,4\n5,6\n7,8\n", "4 lines of 2 numbers"),
                        ("1 2 3 4\n5 6 7 8\n", "2 lines of 4 numbers")):
        path = tmp_path / "scan.csv"
        path.write_text(text)
        with pytest.raises(FormatError, match=f"^scan.csv: (a )?{words}.*line scan.*2-D map"):
            read_topography(str(path))


@pytest.mark.serial
def test_decimal_commas_are_read_and_ambiguous_separators_refused(tmp_path):
    """German-locale files: semicolons between numbers with decimal commas (Excel's CSV), or
    tabs (Gwyddion): the 4 x 3 map, not one twice as wide; points and commas mixed: refused."""
    for name, sep in (("excel.csv", ";"), ("tabs.txt", "\t")):
        path = tmp_path / name
        lines = [line.replace(".", ",") for line in matrix_lines(MAP, "{:.2f}", sep)]
        path.write_text("\n".join(lines) + "\n")
        assert "-2,00" in path.read_text()
        topo = read_topography(str(path), height_unit="nm")
        assert topo.shape == (4, 3) and np.array_equal(topo.heights, MAP * 1e-9)
    path = tmp_path / "plain.csv"                     # decimal points, comma separators: as before
    path.write_text("\n".join(matrix_lines(MAP, sep=", ")) + "\n")
    assert np.array_equal(read_topography(str(path)).heights, MAP)
    for text in ("1,5;2.5;3;4\n5;6;7;8\n9;1;2;3\n", "1,5 2,5,1 3 4\n5 6 7 8\n9 1 2 3\n"):
        path = tmp_path / "mixed.csv"
        path.write_text(text)
        with pytest.raises(FormatError, match="^mixed.csv: ambiguous decimal separator.*decimal points"):
            read_topography(str(path))


@pytest.mark.serial
@pytest.mark.parametrize("name", ["gwyddion-export-english.txt", "matrix-3.txt", "matrix-6.txt",
                                  "txt_example.txt"])
def test_gwyddion_exports_match_surfacetopography(name):
    """The Gwyddion exports, by extension and with the format named (a 3-column export is a
    matrix: its header says so)."""
    for format in (None, "text"):
        topo = read_topography(str(SAMPLES / name), format=format)
        assert topo.format == "text" and topo.unit_stated
        matches_reference(name, topo)


@pytest.mark.serial
def test_gwyddion_headers_in_other_languages_short_or_latin1(tmp_path):
    """Gwyddion's German labels (Latin-1 µm, decimal commas), a UTF-8 byte-order mark, UTF-16,
    and a short header (channel and unit only) read as the English export; a Width without its
    Height is refused with what to add."""
    english = ["# Channel: Height", "# Width: 8 µm", "# Height: 4.5 µm", "# Value units: nm"]
    german = ["# Kanal: Höhe", "# Breite: 8 µm", "# Höhe: 4,5 µm", "# Werteeinheiten: nm"]
    body = matrix_lines(MAP)
    (tmp_path / "en.txt").write_text("\n".join(english + body) + "\n", encoding="utf-8")
    (tmp_path / "de.txt").write_bytes("\n".join(german + body).encode("latin-1"))
    (tmp_path / "bom.txt").write_bytes(b"\xef\xbb\xbf" + "\n".join(english + body).encode("utf-8"))
    (tmp_path / "u16.txt").write_bytes("\n".join(english + body).encode("utf-16"))
    for name in ("en.txt", "de.txt", "bom.txt", "u16.txt"):
        topo = read_topography(str(tmp_path / name))
        assert topo.shape == (4, 3) and np.array_equal(topo.heights, MAP * 1e-9), name
        assert (topo.dx, topo.dy) == pytest.approx((2e-6, 1.5e-6), rel=1e-15)
    (tmp_path / "short.txt").write_text("\n".join([english[0], english[3]] + body) + "\n")
    topo = read_topography(str(tmp_path / "short.txt"))
    assert topo.dx is None and topo.unit_stated and np.array_equal(topo.heights, MAP * 1e-9)
    (tmp_path / "half.txt").write_text("\n".join(english[1:2] + body) + "\n")
    with pytest.raises(FormatError, match="^half.txt: .*# Width but not # Height: add '# Height:"):
        read_topography(str(tmp_path / "half.txt"))


@pytest.mark.serial
def test_instrument_header_with_pixel_size_and_height_factor(tmp_path):
    """matrix-2.txt (h= w=, pixel size, data unit = rad, height conversion factor (-> m)):
    heights = value x factor in m, dx = dy = pixel size, as SurfaceTopography reads it; a
    header whose w= or h= disagrees with the lines is refused."""
    topo = read_topography(str(SAMPLES / "matrix-2.txt"))
    matches_reference("matrix-2.txt", topo)
    assert topo.dx == topo.dy == pytest.approx(3.69862e-7, rel=1e-15)
    path = tmp_path / "cut.txt"
    path.write_text("h=4 w=4\npixel size=1e-6 m\n" + "\n".join(matrix_lines(MAP)) + "\n")
    with pytest.raises(FormatError, match="^cut.txt: the header announces h = 4 .lines., the file has 3"):
        read_topography(str(path))


def test_xyz_lists_in_a_height_unit_and_sniffed_from_txt(coll, shared_tmp):
    """An .xyz list in nm through a scene: dx, dy in m (the coordinates' unit is the heights');
    xyz-1.txt, a .txt of x y z points, reads as SurfaceTopography's 4 x 4 map, unless the
    format is named text (then it is a 3-column matrix of 16 lines)."""
    path = shared_tmp / "scan.xyz"
    i, j = np.meshgrid(np.arange(4), np.arange(3), indexing="ij")
    rows = np.column_stack([5 + 2 * i.ravel(), 3 * j.ravel(), MAP.ravel()])[::-1]   # x, y in nm
    on_root(coll, lambda: path.write_text("\n".join(" ".join(map(repr, r)) for r in rows.tolist())))
    g = scenes.validate(file_scene(path, height_unit="nm"))["geometry"]
    assert (g["nx"], g["ny"], g["format"]) == (4, 3, "xyz")
    assert (g["dx"], g["dy"]) == pytest.approx((2e-9, 3e-9), rel=1e-12)
    topo = read_topography(str(path), height_unit="um")
    assert np.array_equal(topo.heights, MAP * 1e-6) and topo.dx == pytest.approx(2e-6, rel=1e-12)
    sample = SAMPLES / "xyz-1.txt"
    topo = read_topography(str(sample))
    assert topo.format == "xyz" and not topo.unit_stated
    matches_reference("xyz-1.txt", topo)
    assert read_topography(str(sample), format="text").shape == (3, 16)
    g = scenes.validate(file_scene(sample, height_unit="um"))["geometry"]
    assert (g["nx"], g["ny"], g["format"], g["dx"]) == (4, 4, "xyz", 1e-6)
    assert scenes.validate(scenes.validate(file_scene(sample, height_unit="um")))["geometry"] == g


@pytest.mark.serial
def test_spacing_written_as_a_string_is_refused_with_the_fix(tmp_path):
    path = tmp_path / "scan.npy"
    np.save(path, MAP)
    (tmp_path / "scan.npy.json").write_text(json.dumps({"dx": "1e-9", "unit": "nm"}))
    with pytest.raises(FormatError, match="^scan.npy.json: dx = '1e-9': a spacing is a number.*without quotes"):
        read_topography(str(path))
    (tmp_path / "scan.npy.json").write_text(json.dumps({"unit": "nm"}))
    with pytest.raises(scenes.SceneError, match="geometry.dx = '1e-9': expected float.*without quotes"):
        scenes.validate(file_scene(path, dx="1e-9"))


def test_unstated_or_implausible_units_warn_with_the_figures(coll, shared_tmp):
    """A unitless text matrix in a scene: heights taken as metres (their rms given); a spacing
    of 0.3125 m: the 1.25 m extent; a file stating plausible units, or a unit given: silence.
    `contactpetsc import` warns alike, naming its options."""
    bare, nm = shared_tmp / "bare.txt", shared_tmp / "nm.txt"
    on_root(coll, lambda: (bare.write_text("\n".join(matrix_lines(MAP * 1e-9)) + "\n"),
                           nm.write_text("# Width: 4 um\n# Height: 3 um\n# Value units: nm\n"
                                         + "\n".join(matrix_lines(MAP)) + "\n")))
    rms = f"{np.std(MAP * 1e-9):.4g}"
    with pytest.warns(TopographyUnitWarning, match=f"bare.txt.*states no height unit.*taken as metres.*"
                                                   f"rms height {rms} m.*geometry.height_unit"):
        scenes.validate(file_scene(bare, dx=1e-9))
    with pytest.warns(TopographyUnitWarning, match=r"bare.txt.*1\.25 m x 0\.9375 m.*geometry.dx"):
        scenes.validate(file_scene(bare, dx=0.3125, height_unit="m"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scenes.validate(file_scene(nm))
        scenes.validate(file_scene(bare, dx=1e-9, height_unit="m"))
    dst, metres = shared_tmp / f"out{coll.rank}.npy", shared_tmp / "metres.txt"
    on_root(coll, lambda: metres.write_text("# Value units: m\n" + "\n".join(matrix_lines(MAP)) + "\n"))
    with pytest.warns(TopographyUnitWarning, match=r"^bare.txt: .*taken as metres.*--height-unit"):
        convert.convert(str(bare), str(dst), dx=1e-9)
    with pytest.warns(TopographyUnitWarning, match=r"^metres.txt: the rms height .* m is above 0.001 m"):
        convert.convert(str(metres), str(dst), dx=1e-9)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        convert.convert(str(nm), str(dst))


@pytest.mark.serial
def test_any_reader_failure_names_the_file_and_the_cause(tmp_path, monkeypatch):
    """Whatever a reader raises becomes a FormatError starting with the file's name and saying
    the cause in words; a missing channel stays a KeyError and a missing file an OSError."""
    path = tmp_path / "scan.sur"
    path.write_bytes(b"\0" * 16)
    causes = {struct.error("unpack requires a buffer of 4 bytes"): "truncated",
              ZeroDivisionError("division by zero"): "size or scale of zero",
              RecursionError("maximum recursion depth exceeded"): "nested too deeply",
              zipfile.BadZipFile("File is not a zip file"): "not a readable zip archive",
              OverflowError("cannot convert float infinity to integer"): "out of range",
              MemoryError(): "more data than fits in memory",
              UnicodeDecodeError("utf-8", b"\xff", 0, 1, "invalid start byte"): "reader failed",
              IndexError("list index out of range"): "reader failed"}
    for exc, words in causes.items():
        def fail(*args, exc=exc, **kwargs):
            raise exc
        monkeypatch.setitem(topography.FORMATS, "sur", (fail, (".sur",)))
        with pytest.raises(FormatError, match=rf"^scan.sur: cannot be read as a sur file: .*{words}"):
            read_topography(str(path))
    monkeypatch.undo()
    with pytest.raises(FormatError, match="^metropro-1.dat: a binary file .looks like Zygo MetroPro.*contactpetsc import"):
        read_topography(str(SAMPLES / "metropro-1.dat"))
    with pytest.raises(OSError, match="missing.txt"):
        read_topography(str(tmp_path / "missing.txt"))
