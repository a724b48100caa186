"""Tests of sunlab.multihole.defects: the batched cubic resampling of the edge roughness.

:func:`sunlab.multihole.defects._harmonic_amplitudes` resamples the stamps of all holes of a
frame at once (the spline prefilter of ``map_coordinates`` on the part of the frame the spots
cover, then separable 4-tap B-spline weights); these tests hold it to the straightforward form,
one ``scipy.ndimage.map_coordinates`` call on the frame per stamp
(:func:`harmonic_amplitudes_reference`), on synthetic frames with spots at and across the
frame's edges.
"""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from scipy.ndimage import map_coordinates

from sunlab import schema
from sunlab.multihole import defects

# The batched form performs the same operations as map_coordinates (same padding, prefilter and
# B-spline weights); only the order of the float additions differs (4 + 4 separable taps for the
# 16 products of map_coordinates): the amplitudes differ by some 1e-13. rtol 1e-9 is float
# rounding only, with a wide margin: a wrong padding (11 or 13 px instead of scipy's 12) moves
# the amplitudes by 1e-10 to 1e-7.
RTOL = 1e-9


def harmonic_amplitudes_reference(cube, ok, xs, ys, poses, shot, radius_px, harmonics):
    """The per-stamp form: map_coordinates (cubic, "nearest") on the frame per hole."""
    n_r = int(np.ceil(radius_px))
    g = np.arange(-n_r, n_r + 1, dtype=float)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    rr = np.hypot(gx, gy)
    disk, ring = rr <= radius_px, (rr > 0.5) & (rr <= radius_px)
    acc, count = np.zeros((ok.shape[1], ring.sum())), np.zeros(ok.shape[1])
    for p in poses:
        frame = cube["frames"].values[p, shot].astype(float)
        hs = np.flatnonzero(ok[p])
        stamps = np.empty((hs.size, ring.sum()))
        for n, h in enumerate(hs):
            st = map_coordinates(frame, [ys[p, h] + gy, xs[p, h] + gx], order=3, mode="nearest")
            st = st - np.median(np.concatenate([st[0], st[-1], st[:, 0], st[:, -1]]))
            total = st[disk].sum()
            stamps[n] = st[ring] / total if total > 0 else np.nan
        template = np.nanmedian(stamps, axis=0)
        good = np.isfinite(stamps).all(axis=1)
        acc[hs[good]] += (stamps[good] - template) / np.nanmax(template)
        count[hs[good]] += 1
    m = np.arange(harmonics[0], harmonics[1] + 1)
    amp = np.abs(acc / np.maximum(count, 1)[:, None]
                 @ np.exp(-1j * m[None, :] * np.arctan2(gy, gx)[ring][:, None]))
    amp[count == 0] = np.nan
    return amp


#: Spot centres (x, y) on a 90 x 160 frame: inside, near each edge (sub-image clipped), in the
#: corners and with the centroid off the frame by a little (stamp grid off the frame by more).
CENTRES = [(40.0, 45.0), (80.0, 40.0), (120.0, 48.0), (60.0, 70.0), (100.0, 20.0),
           (3.3, 44.0), (157.6, 30.0), (90.0, 1.8), (30.0, 88.4), (2.1, 2.6), (158.2, 87.7),
           (-0.4, 70.0), (140.0, 90.3)]


@pytest.fixture(scope="module")
def frames():
    """Five frames of 14 holes (spots moving by sub-pixel steps, a wavy rim on hole 2, Poisson
    noise); hole 13 is an inverted spot (a dark disk in a bright annulus: no flux in a small
    stamp), hole 4 is lost in every frame, hole 5 in every frame but one."""
    rng = np.random.default_rng(3)
    yy, xx = np.indices((90, 160)).astype(float)
    cube, xs, ys = [], [], []
    for dx, dy in [(0.0, 0.0), (0.37, -0.21), (-0.45, 0.5), (0.12, 0.49), (0.5, -0.5)]:
        f = np.full(yy.shape, 20.0)
        for h, (x, y) in enumerate(CENTRES):
            phi = np.arctan2(yy - y - dy, xx - x - dx)
            r0 = 6.0 * (1 + (0.1 * np.cos(4 * phi) if h == 2 else 0.0))
            f += 900.0 / (1 + np.exp((np.hypot(xx - x - dx, yy - y - dy) - r0) / 1.2))
        inv = np.hypot(xx - 140.0 - dx, yy - 70.0 - dy)
        f += np.where(inv < 12, 600.0 * (inv > 5), 0.0)
        cube.append(rng.poisson(f))
        xs.append([x + dx for x, _ in CENTRES] + [140.0 + dx])
        ys.append([y + dy for _, y in CENTRES] + [70.0 + dy])
    xs, ys = np.array(xs), np.array(ys)
    ok = np.ones(xs.shape, bool)
    ok[:, 4] = False
    ok[1:, 5] = False
    cube = schema.frames_dataset(np.array(cube, np.uint16)[:, None], alpha=[0.0] * 5,
                                 beta=[0.0] * 5)
    return cube, ok, xs, ys


@pytest.mark.parametrize("radius_px", [7.5, 9.0, 16.2])
def test_harmonic_amplitudes_equal_per_stamp_map_coordinates(frames, radius_px):
    cube, ok, xs, ys = frames
    args = (cube, ok, xs, ys, list(range(5)), 0, radius_px, (2, 6))
    got = defects._harmonic_amplitudes(*args)
    ref = harmonic_amplitudes_reference(*args)
    assert_array_equal(np.isnan(got), np.isnan(ref))
    assert np.isnan(ref[4]).all() and np.isfinite(ref[5]).all()  # never usable, seen once
    assert np.isnan(ref[13]).all() == (radius_px < 12)  # no flux: never seen whole
    assert_allclose(got, ref, rtol=RTOL)


def test_edge_roughness_equals_the_per_stamp_form(frames, monkeypatch):
    cube, ok, xs, ys = frames
    status = np.where(ok, schema.STATUS["ok"], schema.STATUS["no_spot"])
    cen = schema.centroids_dataset(xs[:, None], ys[:, None], status=status[:, None])
    got = defects.edge_roughness(cube, cen, radius_px=9.0)
    monkeypatch.setattr(defects, "_harmonic_amplitudes", harmonic_amplitudes_reference)
    ref = defects.edge_roughness(cube, cen, radius_px=9.0)
    assert_array_equal(np.isnan(got.values), np.isnan(ref.values))
    assert_allclose(got.values, ref.values, rtol=RTOL)


@pytest.mark.parametrize("shape", [(29, 29), (17, 29), (29, 20), (6, 9)])
def test_cubic_stamps_are_map_coordinates_on_and_off_the_frame(shape):
    # centres inside the frame, off it by less and by more than scipy's 12 px of padding
    rng = np.random.default_rng(7)
    frame = rng.uniform(0, 4000, shape).round().astype(np.uint16)
    cy = np.array([14.2, 13.5, -3.7, 20.1, -30.4, shape[0] + 15.5])
    cx = np.array([14.8, 14.5, 30.2, -1.0, 50.6, -20.3])
    got = defects._cubic_stamps(frame, cx, cy, 10)
    g = np.arange(-10, 11, dtype=float)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    for k in range(len(cx)):
        ref = map_coordinates(frame.astype(float), [cy[k] + gy, cx[k] + gx], order=3,
                              mode="nearest")
        assert_allclose(got[k], ref, rtol=RTOL, atol=RTOL * np.abs(ref).max())
