"""Tests of sunlab.centroid.moments: the one definition of a spot's moments."""

from __future__ import annotations

import _spots
import numpy as np
from numpy.testing import assert_allclose

from sunlab import centroid as C
from sunlab.centroid import _aperture


def test_fields_are_the_kernel_measurement_columns():
    assert C.moments.SpotMoments._fields == _aperture.MEASURE_FIELDS


def test_spot_moments_match_direct_sums():
    # Textbook per-pixel moments of (I - b) in the aperture, b the mean of the annulus.
    rng = np.random.default_rng(2)
    frame = rng.integers(20, 60, (120, 140)).astype(np.uint16)
    yy, xx = np.mgrid[0:120, 0:140]
    frame[np.hypot(xx - 70.3, (yy - 58.6) * 1.2) < 14] += 600
    xc, yc, r = 70.0, 59.0, 22.0
    m = C.moments.spot_moments(frame, xc, yc, r)
    d = np.hypot(xx - xc, yy - yc)
    ring = (d > r + 1) & (d <= r + 7)
    b = frame[ring].mean()
    sel = d <= r
    w = frame[sel] - b
    s = w.sum()
    x, y = (w * xx[sel]).sum() / s, (w * yy[sel]).sum() / s
    mxx = (w * (xx[sel] - x) ** 2).sum() / s
    myy = (w * (yy[sel] - y) ** 2).sum() / s
    assert_allclose([m.background, m.flux, m.x, m.y], [b, s, x, y], rtol=1e-10)
    assert_allclose([m.mxx, m.myy], [mxx, myy], rtol=1e-8)
    assert_allclose(m.radius, np.sqrt(2 * (mxx + myy)), rtol=1e-8)
    assert m.ellipticity > 0.05 and m.npix == sel.sum() and m.r_ap == r


def test_locate_spots_metrics_are_the_moments_of_each_spot():
    # The per-hole metrics of locate_spots use the same definitions (radius, ellipticity,
    # asymmetry) as SpotMoments, measured in the spot's first aperture.
    frame = _spots.frame([(300.4, 250.2)], noise=False, edge=3.25, background=30.0)
    s = C.locate_spots(frame, shape=(1, 1))
    m = C.moments.spot_moments(frame, s.x[0], s.y[0], 30.0)
    assert_allclose(s.metrics["radius"][0], m.radius, rtol=2e-3)
    assert s.metrics["ellipticity"][0] < 1e-3 and m.ellipticity < 1e-3
