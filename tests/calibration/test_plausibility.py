"""Plausibility flags (sunlab.calibration.plausibility): a fit that succeeded on a sensor that
cannot exist (wrong F, wrong pitch, a mask below the detector) is said to be implausible.

Tables are exact pinhole centroids (:func:`sunlab.sim.synthetic_centroids`, F = 5 mm): told the
right constants, the ideal model's errors are rounding; told F = 10 mm, every angle is halved,
errors of degrees at 8 deg.
"""

import numpy as np
import pytest

from sunlab import sim
from sunlab.calibration import IdealModel, OptimisedModel, Polynomial
from sunlab.calibration.plausibility import MAX_PLAUSIBLE_ERROR_DEG, implausible


def _table(**attrs):
    a, b = np.meshgrid(np.arange(-8.0, 8.1, 2.0), np.arange(-8.0, 8.1, 2.0))
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
    cen.attrs.update(attrs)
    return cen


def test_a_calibration_of_the_real_sensor_is_plausible():
    assert implausible(IdealModel().fit(_table())) == []
    assert implausible(OptimisedModel().fit(_table())) == []
    assert implausible(Polynomial(order=3).fit(_table()), test_mu={"alpha": 0.01,
                                                                  "beta": None}) == []


def test_a_wrong_mask_distance_is_named_with_the_file_to_check():
    found = implausible(IdealModel().fit(_table(mask_distance_mm=10.0)))
    assert len(found) == 1
    assert found[0].startswith("ideal model: its errors on its own training poses reach")
    assert "sensor.json (pixel_pitch_mm, mask_distance_mm" in found[0]


def test_an_optimised_model_that_moves_the_mask_by_more_than_half_F_is_flagged():
    # told F = 20 mm, the optimised model explains the 5 mm sensor with dF = -15 mm
    cal = OptimisedModel().fit(_table(mask_distance_mm=20.0))
    p = cal.to_dict()["parameters"]
    assert p["delta_f_mm"] == pytest.approx(-15.0, abs=0.01)
    found = implausible(cal)
    assert any(f.startswith("optimised model: dF = -15 mm against a nominal F of 20 mm")
               for f in found)


def test_a_test_error_above_the_limit_is_flagged_for_that_angle_only():
    cal = Polynomial(order=3).fit(_table())
    found = implausible(cal, test_mu={"alpha": 0.01, "beta": 2 * MAX_PLAUSIBLE_ERROR_DEG})
    assert len(found) == 1 and found[0].startswith("mean error of beta on the test table 1 deg")
    assert "check the centroid table" in found[0]
