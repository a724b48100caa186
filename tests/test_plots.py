"""Tests of sunlab.plots.accuracy (Figs. 10-12; the mask's figures: tests/test_multihole.py):
the figures carry the expected artists (not pixels)."""

import numpy as np
import pytest
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from sunlab import ConfigurationError, plots, sim, stats
from sunlab.calibration import Polynomial


@pytest.fixture(scope="module")
def local():
    a, b = np.meshgrid(np.arange(-4.0, 1.0), np.arange(-1.0, 3.0), indexing="ij")
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), 3, pose_error_deg=(0.01, 0.02),
                                       seed=1)
    return stats.evaluate(Polynomial(order=2).fit(cen), cen, return_errors=True)[2]


def test_error_maps_fig10(local):
    fig = plots.error_maps(local, title="polynomial")
    assert isinstance(fig, Figure)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert [ax.get_title() for ax in panels] == [
        "local error of alpha", "local error of beta",
        "maximum error of alpha", "maximum error of beta"]
    mesh = panels[0].collections[0]
    assert mesh.get_array().shape == (4, 5)  # beta rows x alpha columns
    values = local.local_error.sel(angle="alpha").values
    assert np.isclose(mesh.get_array().max(), values.max())
    assert panels[0].get_xlabel() == "alpha (deg)"


def test_error_histogram_fig11(local):
    fig = plots.error_histogram(local, angle="beta")
    ax = fig.axes[0]
    assert len(ax.lines) == 1 and len(ax.patches) >= 2
    v = local.local_error.sel(angle="beta").values
    assert f"mu = {v.mean():.4f}" in ax.lines[0].get_label()
    # the normal curve integrates to about 1 over its range
    x, y = ax.lines[0].get_data()
    assert 0.95 < np.trapezoid(y, x) < 1.01
    with pytest.raises(ConfigurationError, match="variable"):
        plots.error_histogram(local, variable="nope")


def test_error_rectangles_fig12():
    tab = stats.paper_table4()
    fig = plots.error_rectangles(tab)
    rects = [p for p in fig.axes[0].patches if isinstance(p, Rectangle)]
    assert len(rects) == 4
    r = stats.rectangles(tab).loc["polynomial"]
    poly = rects[list(tab.columns).index("polynomial")]
    assert np.isclose(poly.get_x(), r["alpha_low"]) and np.isclose(poly.get_y(), r["beta_low"])
    assert np.isclose(poly.get_width() * poly.get_height(), r["area"])
    assert poly.get_label().startswith("3: polynomial (area")
    # the legend sits below the axes, over no rectangle (axes coordinates: y < 0)
    fig.canvas.draw()
    ax = fig.axes[0]
    box = ax.get_legend().get_window_extent().transformed(ax.transAxes.inverted())
    assert box.y1 < 0, box
    # each rectangle is tagged with its number at its corner
    assert sorted(t.get_text() for t in ax.texts) == ["1", "2", "3", "4"]
    # accepts the rectangles table too
    assert len(plots.error_rectangles(stats.rectangles(tab)).axes[0].patches) == 4


def test_coinciding_rectangles_share_a_tag():
    """Fig. 15's three 100-hole rectangles can coincide: one tag names them all."""
    from sunlab.plots.accuracy import draw_rectangles, new_figure

    ax = new_figure().subplots()
    groups = draw_rectangles(ax, [("geometric centre", 0.0, 0.01, 0.0, 0.05),
                                  ("averaging", 0.0, 0.0101, 0.0, 0.0502),
                                  ("1 hole", 0.0, 0.02, 0.0, 0.03)])
    assert groups == [[0, 1], [2]]
    assert [t.get_text() for t in ax.texts] == ["1 = 2", "3"]
    styles = [p.get_linestyle() for p in ax.patches]
    assert styles[0] != styles[1]  # both coinciding outlines stay visible


def test_figures_show_in_a_fresh_kernel():
    """A returned figure carries its own PNG (IPython shows it without pyplot's formatter)."""
    fig = plots.error_rectangles(stats.paper_table4())
    assert isinstance(fig, plots.accuracy.ShownFigure)
    png = fig._repr_png_()
    assert png.startswith(b"\x89PNG") and len(png) > 10_000


def test_tags_of_nearby_rectangles_do_not_overlap():
    """Two distinct rectangles with almost the same corner (05's linear and cubic interpolation):
    their tags are drawn apart, so both numbers stay readable."""
    from sunlab.plots.accuracy import draw_rectangles, new_figure

    fig = new_figure(figsize=(5.5, 5.6))
    ax = fig.subplots()
    draw_rectangles(ax, [("a", 0.0, 0.035, 0.0, 0.066), ("b", -0.01, 0.036, -0.02, 0.067),
                         ("c", 0.0, 0.08, -0.1, 0.17)])
    fig.canvas.draw()
    boxes = [t.get_window_extent() for t in ax.texts]
    assert [t.get_text() for t in ax.texts] == ["1", "2", "3"]
    assert not boxes[0].overlaps(boxes[1]), (boxes[0], boxes[1])


def test_a_rectangle_joins_the_nearest_coinciding_group():
    """Fig. 15: 'averaging + rejection' lies on 'averaging', a little off 'geometric centre'."""
    from sunlab.plots.accuracy import draw_rectangles, new_figure

    ax = new_figure().subplots()
    # the 100-hole rectangles of a quick `sunlab reproduce --table 5` run (deg)
    groups = draw_rectangles(ax, [("centre", -0.0045, 0.01474, -0.02829, 0.0718),
                                  ("averaging", -0.0048, 0.01532, -0.0259, 0.07152),
                                  ("1 hole", -0.0154, 0.03653, -0.01654, 0.04792),
                                  ("averaging + rejection", -0.00504, 0.01548, -0.02653, 0.07192)])
    assert groups == [[0], [1, 3], [2]]
