"""Robust outlier screening (sunlab.screening) on centroid tables with known noise.

The table has 0.05 px of Gaussian centroid noise; 10 MADs are 6.7 of its standard deviations,
so a shot moved by 1 px (20 sigma) must be flagged and no honest shot of the 648 may be (the
chance of a false flag is about 1e-8 per table).
"""

import numpy as np
import pytest

from sunlab import schema, sim
from sunlab.errors import ConfigurationError
from sunlab.screening import MAD_FLOOR_PX, N_MAD, screen_outliers


def _table(noise_px=0.05):
    a, b = np.meshgrid(np.linspace(-20, 20, 9), np.linspace(-20, 20, 9))
    return sim.synthetic_centroids(a.ravel(), b.ravel(), shots=8, noise_px=noise_px,
                                   mounting_deg=(1.0, -0.5, 0.2), delta_f_mm=0.1)


def test_a_shot_moved_by_twenty_sigma_is_flagged_and_only_it():
    cen = _table()
    x_before = cen["x"].values.copy()
    cen["y"][33, 5] += 1.0
    screened, found = screen_outliers(cen)
    assert [(o["pose"], o["shot"]) for o in found] == [(33, 5)]
    assert found[0]["residual_px"] == pytest.approx(1.0, abs=0.25)
    assert found[0]["mads"] > N_MAD
    invalid = screened.status.values == schema.STATUS["invalid"]
    assert invalid.sum() == 1 and invalid[33, 5]
    # values are kept, the input untouched, the finding recorded in the table
    np.testing.assert_array_equal(screened.x.values, x_before)
    assert int(cen.status[33, 5]) == schema.STATUS["ok"]
    assert screened.attrs["screened_outliers"] == found
    assert screened.attrs["screening"] == {"n_mad": N_MAD, "mad_floor_px": MAD_FLOOR_PX,
                                           "flagged": 1}


def test_a_shot_within_the_noise_is_kept():
    cen = _table()
    cen["x"][10, 2] += 0.1  # 2 sigma
    assert screen_outliers(cen)[1] == []


def test_a_noise_free_table_flags_nothing_thanks_to_the_mad_floor():
    cen = _table(noise_px=0.0)
    cen["x"][4, 0] += 5 * MAD_FLOOR_PX  # below 10 floored MADs
    assert screen_outliers(cen)[1] == []
    cen["x"][4, 0] += 20 * MAD_FLOOR_PX
    assert [(o["pose"], o["shot"]) for o in screen_outliers(cen)[1]] == [(4, 0)]


def test_too_few_usable_shots_are_not_screened():
    cen = sim.synthetic_centroids([0.0, 1.0, 2.0], [0.0, 0.0, 0.0], shots=1)
    cen["x"][1, 0] = 1e20
    assert screen_outliers(cen)[1] == []


@pytest.mark.parametrize("n_mad", [3, 0.5, float("nan"), "10"])
def test_a_threshold_that_would_flag_noise_is_refused(n_mad):
    with pytest.raises(ConfigurationError, match="n_mad"):
        screen_outliers(_table(), n_mad=n_mad)
