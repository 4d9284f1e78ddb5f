"""Colour and histogram limits that one outlier node does not set
(contactpetsc.app.plots.scales), and the pressure map and histograms drawn on them.  numpy
(and matplotlib, where drawn), no communicator: checked on one rank."""
import numpy as np
import pytest

from contactpetsc.app.plots import scales

pytestmark = pytest.mark.serial


def bulk_with_outlier(n=64, contact=0.906, seed=1):
    """A (n, n) pressure field [Pa]: 90.6 % of the nodes in contact at 1-2 MPa, one node at
    1 GPa (a spike of a measured map), the rest 0."""
    rng = np.random.default_rng(seed)
    p = np.where(rng.random((n, n)) < contact, 1e6 * (1 + rng.random((n, n))), 0.0)
    p[5, 7] = 1e9
    return p


def test_one_outlier_node_does_not_set_the_colour_scale():
    p = bulk_with_outlier()
    lim = scales.pressure_limits(p)
    bulk = p[(p > 0) & (p < 1e9)]
    assert not lim.diverging and lim.vmin == 0.0
    assert bulk.max() * 0.99 <= lim.vmax <= bulk.max()          # the bulk's top, not the spike's
    assert lim.extend == "max" and lim.clipped and lim.high == 1e9
    # the scale is the field's maximum when nothing stands out, or with few nodes (< 200)
    assert scales.pressure_limits(np.minimum(p, 2e6)).vmax == pytest.approx(np.minimum(p, 2e6).max())
    few = np.array([[0.0, 1e6, 5e9]])
    assert scales.pressure_limits(few).vmax == 5e9 and scales.pressure_limits(few).extend == "neither"
    # a Hertzian field (a smooth peak) is drawn to its maximum
    y, x = np.mgrid[-1:1:64j, -1:1:64j]
    hertz = 1e9 * np.sqrt(np.maximum(0.0, 0.8 - x * x - y * y))
    assert scales.pressure_limits(hertz).vmax == hertz.max() and not scales.pressure_limits(hertz).clipped
    # no pressure: a unit scale, nothing clipped
    assert scales.pressure_limits(np.zeros((4, 4))).vmax == 1.0


def test_adhesive_scale_is_symmetric_and_robust_on_both_sides():
    """With tension: [-top, top], top the larger side's robust top; a compressive spike and a
    tensile one are both clipped."""
    p = bulk_with_outlier()
    p[p == 0] = -0.5e6                     # adhesive ring, up to 0.5 MPa of tension
    p[9, 9] = -2e8                         # a tensile outlier
    lim = scales.pressure_limits(p)
    assert lim.diverging and lim.vmin == -lim.vmax
    assert lim.vmax == pytest.approx(scales.robust_max(p[p > 0]))
    assert lim.vmax < 2.01e6 and lim.extend == "both" and (lim.low, lim.high) == (-2e8, 1e9)


def test_histogram_range_leaves_out_the_tails_and_counts_them():
    v = np.concatenate([np.linspace(1.0, 2.0, 1000), [1e3]])
    lo, hi, out = scales.histogram_range(v)
    assert lo == pytest.approx(1.0, abs=0.01) and hi == pytest.approx(2.0, abs=0.01) and 1 <= out <= 11
    # an adhesive field: many small tensile values do not make the compressive tail an outlier
    adhesive = np.concatenate([-np.linspace(0.0, 5e7, 5000), np.linspace(1e8, 1e9, 300)])
    assert scales.histogram_range(adhesive) == (-5e7, 1e9, 0)
    assert scales.histogram_range(np.append(adhesive, 1e11))[1:] == (pytest.approx(1e9, rel=0.01), 1)
    assert scales.histogram_range([3.0, 3.0]) == (3.0, 3.0, 0)
    assert scales.histogram_range([]) == (0.0, 1.0, 0)


def test_pressure_map_and_histograms_are_drawn_on_the_robust_scales(tmp_path):
    """The map's colour limits are the bulk's (arrow on the colorbar, the spike named in the
    title); the histogram's bins span the bulk, the left-out node named, the density's integral
    the share of the nodes drawn."""
    pytest.importorskip("matplotlib")
    from contactpetsc.app import plots
    p = bulk_with_outlier()
    fig = plots.pressure_map(p, 1e-8, 1e-8, path=str(tmp_path / "map.png"))
    image = fig.axes[0].images[0]
    assert image.norm.vmin == 0.0 and image.norm.vmax < 2.01            # MPa: the bulk's top
    assert "max 1000 MPa" in fig.axes[0].get_title() and (tmp_path / "map.png").stat().st_size > 0
    colorbar = fig.axes[1]
    assert image.colorbar.extend == "max" and colorbar is image.colorbar.ax
    gap = np.where(p > 0, 0.0, 1e-9)
    fig = plots.histograms(p, gap, path=str(tmp_path / "histograms.png"))
    patch = fig.axes[0].patches[0]
    values, edges = patch.get_data()[:2]
    assert edges[-1] < 2.01 and edges[0] >= 1.0 - 1e-9                    # MPa: the bulk
    drawn = np.count_nonzero((p >= edges[0] * 1e6) & (p <= edges[-1] * 1e6))
    assert np.sum(values * np.diff(edges)) == pytest.approx(drawn / p.size)
    assert any("left out" in t.get_text() for t in fig.axes[0].texts)
    assert (tmp_path / "histograms.png").stat().st_size > 0
