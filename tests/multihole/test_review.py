"""The per-hole review (sunlab.multihole.review): a noisy hole is flagged, and the review's
statistics and residual maps are the strategy's own numbers for the holes chosen."""

import numpy as np
import pytest
import xarray as xr

from sunlab.errors import ConfigurationError
from sunlab.multihole.review import HoleReview, injected_defects, review_holes
from sunlab.schema import DEFECT_FLAGS
from sunlab.sim import synthetic_centroids
from sunlab.stats import error_summary


@pytest.fixture(scope="module")
def review():
    a = np.repeat(np.linspace(-8, 2, 5), 5)
    b = np.tile(np.linspace(-2, 8, 5), 5)
    # hole 7 scatters by 1 px, a hundred times the others' 0.01 px
    cen = synthetic_centroids(a, b, shots=2, layout="grid", noise_px=0.01,
                              defects={7: {"sigma_px": 1.0}})
    return review_holes(cen, order=2)


def test_the_noisy_hole_and_only_it_is_flagged(review):
    assert isinstance(review, HoleReview)
    assert np.flatnonzero(review.flagged).tolist() == [7]
    assert review.n_holes == 100 and (review.n_rows, review.n_cols) == (10, 10)
    assert (review.hole_i[7], review.hole_j[7]) == (0, 7)


def test_statistics_are_the_strategys_average_of_the_chosen_holes(review):
    good = ~review.flagged
    st = review.stats(good, 7)
    expected = error_summary(review.strategy.combine(review.estimates, holes=good))
    assert st["included"] == expected and st["all"] == review.all_stats
    assert st["hole"] == error_summary(review.estimates.isel(hole=7))
    # dropping the 1-px hole makes the average better, and the hole alone is far worse
    assert st["included"]["alpha"]["sigma"] < st["all"]["alpha"]["sigma"]
    assert st["hole"]["alpha"]["sigma"] > 5 * st["included"]["alpha"]["sigma"]
    assert review.stats(np.zeros(100, bool), 0)["included"] is None


def test_residual_map_is_the_hole_minus_the_average_over_shots(review):
    good = ~review.flagged
    res = review.residual_map(3, good)
    comb = review.combined(good)
    expected = (review.estimates["alpha"].isel(hole=3) - comb["alpha"]).mean("shot").values
    np.testing.assert_array_equal(res["alpha"], expected)
    assert res["beta"].shape == (25,)
    # the noisy hole strays from the average far more than a good one
    assert np.abs(review.residual_map(7, good)["alpha"]).mean() > 5 * np.abs(res["alpha"]).mean()


def test_injected_defects_name_their_kinds():
    flag = next(iter(DEFECT_FLAGS.values()))
    both = flag | list(DEFECT_FLAGS.values())[1]
    cen = xr.Dataset(coords={"hole_defect": ("hole", [0, flag, 0, both])})
    found = injected_defects(cen)
    assert list(found) == [1, 3]
    assert found[1] == next(iter(DEFECT_FLAGS)) and "+" in found[3]
    assert injected_defects(xr.Dataset()) == {}


def test_a_single_hole_table_is_refused():
    with pytest.raises(ConfigurationError, match="expected \\(pose, shot, hole\\)"):
        review_holes(synthetic_centroids([0.0], [0.0], shots=1))
