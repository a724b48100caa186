"""Masks and holes of sunlab.sim: layouts, outlines, defects and their validation."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import ConfigurationError
from sunlab.schema import DEFECT_FLAGS
from sunlab.sim import Bench, Mask, render, spots
from sunlab.sim.holes import Burred, Dust, Elliptical, Hole, Undersized


def _area(poly):
    x, y = poly.T
    return 0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)


def test_grid_layout_is_the_papers():
    m = Mask.grid()
    xy = np.array([[h.x_mm, h.y_mm] for h in m.holes])
    assert len(m.holes) == 100 and m.name == "grid10x10"
    assert_allclose(np.diff(xy[:10, 0]), 0.5)
    assert_allclose(xy.mean(axis=0), 0.0, atol=1e-12)
    assert [(h.i, h.j) for h in m.holes[:3]] == [(0, 0), (0, 1), (0, 2)]


def test_random_layout_respects_separation_and_diameters():
    m = Mask.random_layout(40, seed=3, diameter_mm=(0.1, 0.25), min_separation_mm=0.4)
    xy = np.array([[h.x_mm, h.y_mm] for h in m.holes])
    d = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    assert d[np.triu_indices(40, 1)].min() >= 0.4
    diam = np.array([h.diameter_mm for h in m.holes])
    assert diam.min() >= 0.1 and diam.max() <= 0.25 and diam.std() > 0.02
    assert Mask.random_layout(40, seed=3) == Mask.random_layout(40, seed=3)
    with pytest.raises(ConfigurationError, match="random_layout"):
        Mask.random_layout(500, seed=0, min_separation_mm=1.0)


@pytest.mark.parametrize(
    ("hole", "area"),
    [
        (Hole(0, 0, 0.2), math.pi * 0.01),
        (Hole(0, 0, 0.2, defect=Undersized(0.5)), math.pi * 0.0025),
        (Hole(0, 0, 0.2, defect=Elliptical(0.8, 30.0)), math.pi * 0.01 * 0.8),
        (Hole(0, 0, 0.2, shape="square"), 0.04),
        (Hole(0, 0, 0.2, defect=Burred(0.0)), math.pi * 0.01),
    ],
)
def test_outlines_have_the_right_area(hole, area):
    assert _area(hole.outline(720)) == pytest.approx(area, rel=2e-3)
    assert hole.area_mm2() == pytest.approx(area, rel=2e-3)


def test_affine_path_only_for_circles_and_ellipses():
    assert Hole(0, 0).affine() is not None
    assert Hole(0, 0, defect=Elliptical()).affine() is not None
    assert Hole(0, 0, defect=Burred()).affine() is None
    assert Hole(0, 0, shape="square").affine() is None


def test_defect_flags_and_random_defects():
    h = Hole(0, 0, defect=(Dust(), Burred()))
    assert h.defect_flags == DEFECT_FLAGS["dust"] | DEFECT_FLAGS["burred"]
    m = Mask.grid().with_random_defects(8, seed=1)
    flags = [h.defect_flags for h in m.holes]
    assert sum(f != 0 for f in flags) == 8
    assert {f for f in flags if f} == set(DEFECT_FLAGS.values())


def test_dust_reduces_the_flux_by_its_area():
    ideal = Bench.paper_single_hole().ideal_platform().ideal_mask()
    clean = spots.spot_image(ideal, 0.0, 0.0)[0].sum()
    dusty = ideal.replace(mask=Mask(holes=(Hole(0, 0, 0.2, defect=Dust(0.0, 0.0, 0.08, 0.0)),)))
    # a particle entirely inside the hole removes (0.08 / 0.2)^2 of the light
    assert spots.spot_image(dusty, 0.0, 0.0)[0].sum() / clean == pytest.approx(1 - 0.16, rel=1e-3)


def test_limb_darkening_keeps_flux_and_centroid():
    ideal = Bench.paper_single_hole().ideal_platform().ideal_mask()
    ld = ideal.replace(source__limb_darkening=0.6)
    for a, b in [(0.0, 0.0), (-14.0, 9.0)]:
        assert spots.spot_image(ld, a, b)[0].sum() == pytest.approx(
            spots.spot_image(ideal, a, b)[0].sum(), rel=1e-4
        )
        assert_allclose(spots.spot_truth(ld, a, b), spots.spot_truth(ideal, a, b), atol=2e-3)


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Hole(0, 0, shape="star"), "shape"),
        (lambda: Hole(0, 0, defect="dust"), "defect"),
        (lambda: Elliptical(1.5), "axis_ratio"),
        (lambda: Undersized(0.0), "factor"),
        (lambda: Burred(0.5), "amplitude"),
        (lambda: Dust(diameter_mm=0.0), "diameter_mm"),
        (lambda: Mask.single_hole(tilt_x_deg=45.0), "tilt_x_deg"),
        (lambda: Mask.single_hole(play_y_mm=-0.01), "play_y_mm"),
        (lambda: Mask.grid(pitch_mm=0.0), "pitch_mm"),
        (lambda: Mask.grid(30, 30, 0.5), "holes"),
    ],
)
def test_bad_mask_raises(call, field):
    with pytest.raises(ConfigurationError, match=field):
        call()


def test_a_loose_mask_is_spread_uniformly_within_its_play():
    # a loosely held mask settles anywhere within +-play at each pose: the offsets stay inside
    # the play, take both signs, and their mean magnitude is half the play (uniform)
    play = (0.003, 0.001)
    free = Bench.paper_single_hole().replace(mask__play_x_mm=play[0], mask__play_y_mm=play[1])
    within = np.array([render.mask_play(free, 7, p) for p in range(400)])
    assert (np.abs(within) <= play).all()
    assert (within > 0).any(axis=0).all() and (within < 0).any(axis=0).all()
    # the mean of |U(-p, p)| is p / 2, with a standard error p / sqrt(12 * 400) = 0.014 p
    assert_allclose(np.abs(within).mean(axis=0), np.array(play) / 2, rtol=0.1)
