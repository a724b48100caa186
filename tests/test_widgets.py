"""Tests of sunlab.widgets.HoleExplorer, driven from pytest like a user would (.value, .click())."""

import base64

import numpy as np
import pytest

from sunlab import multihole as mh
from sunlab import plots, schema
from sunlab.errors import ConfigurationError
from sunlab.sim import synthetic_centroids

pytest.importorskip("ipywidgets")
from sunlab.widgets import HoleExplorer, figure_output  # noqa: E402

A = np.repeat(np.linspace(-8.0, 2.0, 5), 5)
B = np.tile(np.linspace(-2.0, 8.0, 5), 5)
BAD = {7: {"sigma_px": 1.5}, 33: {"flux": 0.3}}


def _cube_from(cen, half=14, shape=(1024, 1280)):
    """A lazy cube: a uniform disk at every centroid in frame (0, 0), blank frames elsewhere."""
    import dask.array as da

    n_p, n_s = cen.sizes["pose"], cen.sizes["shot"]
    frame = np.zeros(shape, np.uint16)
    yy, xx = np.mgrid[-half:half + 1, -half:half + 1]
    for h in range(cen.sizes["hole"]):
        x, y = cen.x.values[0, 0, h], cen.y.values[0, 0, h]
        xi, yi = int(round(x)), int(round(y))
        disk = ((xx + xi - x) ** 2 + (yy + yi - y) ** 2 < 12**2) * 600
        frame[yi - half:yi + half + 1, xi - half:xi + half + 1] = disk.astype(np.uint16)
    first = da.from_array(frame[None, None], chunks=(1, 1, *shape))
    rest = da.zeros((n_p * n_s - 1, 1, *shape), dtype=np.uint16, chunks=(1, 1, *shape))
    frames = da.concatenate([first, rest]).reshape(n_p, n_s, *shape)
    return schema.frames_dataset(frames, cen.alpha.values, cen.beta.values)


@pytest.fixture(scope="module")
def explorer():
    train = synthetic_centroids(A, B, shots=2, layout="grid", noise_px=0.01, hole_sigma_px=0.03,
                                   defects=BAD, seed=1)
    test = synthetic_centroids(A + 0.5, B + 0.5, shots=2, layout="grid", noise_px=0.01,
                                  hole_sigma_px=0.03, defects=BAD, seed=2)
    return HoleExplorer(_cube_from(test), test, train=train, order=2)


def _png(out):
    assert len(out.outputs) == 1
    return base64.b64decode(out.outputs[0]["data"]["image/png"])


def test_layout_and_flags(explorer):
    ex = explorer
    assert len(ex.buttons) == 100 and len(ex.grid.children) == 100
    assert np.flatnonzero(ex.flagged).tolist() == sorted(BAD)
    assert ex.grid.layout.grid_template_columns.startswith("repeat(10")
    # flagged holes are marked on the map from the start, before any rejection
    assert ex.included.all()
    marked = [h for h, b in enumerate(ex.buttons) if b.description.endswith("⚑")]
    assert marked == sorted(BAD)
    assert ex.buttons[33].layout.border == "3px solid #ff7f0e"
    assert "flagged ⚑: [7, 33]" in ex.legend.value
    # no simulated truth in this table: nothing claims to be injected
    assert ex.injected == {} and "injected" not in ex.legend.value
    # close-up and residual maps side by side, below the controls
    right = ex.ui.children[1].children[1]
    assert right.children[1].children == (ex.stamp_out, ex.residual_out)


def test_one_colour_scale_for_buttons_and_bar(explorer):
    import matplotlib as mpl

    ex = explorer
    ex.metric.value = "flux_deficit"
    v = ex.metrics["flux_deficit"].values
    lo, hi = mh.defects.metric_scale(v)
    cmap = mpl.colormaps["viridis"]
    for h in (0, 33, 50):
        want = mpl.colors.to_hex(cmap(np.clip((v[h] - lo) / (hi - lo), 0, 1)))
        assert ex.buttons[h].style.button_color == want
    assert _png(ex.colorbar_out)[:4] == b"\x89PNG"
    # the metric map of sunlab.multihole draws with the same limits
    fig = plots.plot_metric_map(ex.metrics, "flux_deficit")
    assert fig.axes[0].images[0].get_clim() == pytest.approx((lo, hi))
    import matplotlib.pyplot as plt

    plt.close(fig)


def test_click_selects_and_redraws(explorer):
    ex = explorer
    before = _png(ex.stamp_out)
    ex.pose.value = 0
    ex.shot.value = 0
    ex.buttons[33].click()
    assert ex.selected == 33
    assert "hole 33" in ex.info.value and "flagged" in ex.info.value
    assert ex.buttons[33].layout.border.startswith("3px")
    assert not ex.buttons[0].layout.border
    after = _png(ex.stamp_out)
    assert after[:8] == b"\x89PNG\r\n\x1a\n" and after != before
    assert "hole 33" in ex.stats_html.value
    assert ex.stats["hole"]["alpha"]["mu"] > 0


def test_stamp_follows_pose_slider(explorer):
    ex = explorer
    ex.buttons[5].click()
    ex.pose.value = 0
    with_spot = _png(ex.stamp_out)
    ex.pose.value = 3  # blank frame in this cube: a different picture
    assert _png(ex.stamp_out) != with_spot
    ex.pose.value = 0


def test_metric_dropdown_recolours_the_map(explorer):
    ex = explorer
    ex.metric.value = "scatter"
    c_scatter = [b.style.button_color for b in ex.buttons]
    ex.metric.value = "flux_deficit"
    c_flux = [b.style.button_color for b in ex.buttons]
    assert c_scatter != c_flux
    assert "flux_deficit" in ex.buttons[33].tooltip


def test_toggling_holes_changes_the_statistics(explorer):
    ex = explorer
    ex.include_all.click()
    base = ex.stats["included"]["alpha"]["mu"]
    assert base == pytest.approx(ex.stats["all"]["alpha"]["mu"])
    ex.buttons[7].click()
    ex.include.value = False
    assert not ex.included[7] and ex.buttons[7].description == "✕7"
    out7 = ex.stats["included"]["alpha"]["mu"]
    assert out7 < base  # the noisy hole spoiled the average
    assert "average of 99 included holes" in ex.stats_html.value
    ex.include.value = True
    assert ex.stats["included"]["alpha"]["mu"] == pytest.approx(base)
    # a hole left out by hand stays out when the flagged holes are rejected
    ex.buttons[50].click()
    ex.include.value = False
    ex.reject.click()
    assert np.flatnonzero(~ex.included).tolist() == [7, 33, 50]
    assert ex.buttons[50].description == "✕50" and ex.buttons[33].description == "✕33"
    assert ex.stats["included"]["alpha"]["mu"] < base
    assert "left out ✕: [7, 33, 50]" in ex.legend.value
    # only the reset puts every hole back
    ex.include_all.click()
    assert ex.included.all()
    assert ex.buttons[33].description == "33⚑"


def test_injected_defects_are_shown_beside_the_flags():
    train = synthetic_centroids(A, B, shots=2, layout="grid", noise_px=0.01, hole_sigma_px=0.03,
                                   defects=BAD, seed=1)
    # simulated truth as the bench writes it: hole 7 dust (1), hole 60 burred (4), a burr that
    # this centroid-level table cannot show, so it is injected but not flagged
    flags = np.zeros(100, np.int64)
    flags[7], flags[60] = 1, 4
    train = train.assign_coords(hole_defect=("hole", flags))
    ex = HoleExplorer(None, train, order=2)
    assert ex.injected == {7: "dust", 60: "burred"}
    assert ex.buttons[60].style.text_decoration == "underline"
    assert ex.buttons[5].style.text_decoration == ""
    assert "caught [7], missed [60], flagged good holes [33]" in ex.legend.value
    ex.buttons[60].click()
    assert "injected defect (simulation): burred" in ex.info.value
    assert "underlined" in ex.ui.children[0].value


def test_bad_arguments(explorer):
    with pytest.raises(ConfigurationError, match="hole"):
        explorer.select(100)
    with pytest.raises(ConfigurationError, match="pose, shot, hole"):
        HoleExplorer(None, explorer.centroids.isel(hole=0))


def test_figure_output_sets_png():
    import ipywidgets as w
    import matplotlib.pyplot as plt

    out = w.Output()
    fig, ax = plt.subplots()
    ax.plot([0, 1])
    assert fig.number in plt.get_fignums()
    figure_output(out, fig)
    assert _png(out)[:4] == b"\x89PNG"
    assert fig.number not in plt.get_fignums()  # closed: no figure leaks per callback
