"""Tests of sunlab.centroid.sources: many spots of one frame at given positions."""

from __future__ import annotations

import _spots
import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import centroid as C
from sunlab.errors import ConfigurationError

TRUTH = [(200.3, 150.7), (420.9, 160.2), (310.5, 400.25), (80.0, 600.6)]


@pytest.mark.parametrize("method", ["threshold", "projection", "tight", "fit"])
def test_centroid_sources_finds_each_spot_at_its_truth(method):
    frame = _spots.frame(TRUTH, noise=False, edge=3.25, background=30.0)
    guess = np.array(TRUTH) + [[3.0, -2.0], [-4.0, 1.0], [2.0, 2.0], [0.0, -3.0]]
    # the box: the spot (35 px) and background around it (algorithm B needs the spot to be a
    # minority of the box's rows and columns)
    x, y = C.centroid_sources(frame, guess[:, 0], guess[:, 1], 151,
                              centroid_func=C.METHODS[method])
    assert_allclose(np.column_stack([x, y]), TRUTH, atol=1e-3)


def test_centroid_sources_without_a_spot_is_nan_and_bad_input_raises():
    frame = _spots.frame(TRUTH[:1], noise=False, edge=3.25, background=30.0)
    x, y = C.centroid_sources(frame, [200.0, 900.0, np.nan], [150.0, 800.0, 10.0])
    assert_allclose(x[0], TRUTH[0][0], atol=1e-3)
    assert np.isnan(x[1:]).all() and np.isnan(y[1:]).all()
    with pytest.raises(ConfigurationError, match="x, y"):
        C.centroid_sources(frame, [1.0, 2.0], [1.0])
