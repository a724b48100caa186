"""The 2-D Fourier calibration (sunlab.calibration.trigonometric): its basis, exact recovery of
a mapping inside its span, its size rules and its saved form."""

import json

import numpy as np
import pytest

from sunlab import sim
from sunlab.calibration.artifact import from_dict
from sunlab.calibration.trigonometric import Trigonometric, fourier_basis
from sunlab.errors import ConfigurationError


def test_fourier_basis_columns_and_period():
    u = np.linspace(-1, 1, 5)
    B = fourier_basis(u, 2, period=4.0)
    w = 2 * np.pi / 4.0
    np.testing.assert_allclose(B, np.column_stack([np.ones(5), np.cos(w * u), np.sin(w * u),
                                                   np.cos(2 * w * u), np.sin(2 * w * u)]))
    # one period later the basis repeats
    np.testing.assert_allclose(fourier_basis(u + 4.0, 2), B, atol=1e-12)
    assert fourier_basis(u, 0).shape == (5, 1)


def test_a_mapping_in_its_span_is_recovered_to_rounding():
    a, b = np.meshgrid(np.arange(-6.0, 6.1, 2.0), np.arange(-6.0, 6.1, 2.0))  # 49 >= 25 poses
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
    cal = Trigonometric(order=2).fit(cen)
    # refit on its own predictions: the target now lies in the span, so the fit is exact
    x, y = cen.x.values[:, 0], cen.y.values[:, 0]
    pa, pb = cal.predict_xy(x, y)
    cen2 = cen.assign_coords(alpha=("pose", pa), beta=("pose", pb))
    cal2 = Trigonometric(order=2).fit(cen2)
    assert cal2.residuals["alpha"]["max_abs"] < 1e-9 and cal2.residuals["beta"]["max_abs"] < 1e-9


def test_size_rules():
    assert Trigonometric(order=2).min_poses() == 25 and Trigonometric(order=4).label == (
        "trigonometric(4)")
    few = sim.synthetic_centroids(np.arange(5.0), np.arange(5.0), shots=1)
    with pytest.raises(ConfigurationError, match=r"trigonometric\(2\) needs at least 25"):
        Trigonometric(order=2).fit(few)
    for bad in ({"order": -1}, {"order": 1.5}, {"period": 0.0}):
        with pytest.raises(ConfigurationError):
            Trigonometric(**bad)


def test_saved_and_read_back_predicts_the_same():
    a, b = np.meshgrid(np.arange(-4.0, 4.1), np.arange(-4.0, 4.1))
    cal = Trigonometric(order=1, period=3.0).fit(
        sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1))
    back = from_dict(json.loads(json.dumps(cal.to_dict())))
    assert isinstance(back, Trigonometric) and back.period == 3.0
    x, y = np.array([600.0, 650.0]), np.array([500.0, 520.0])
    np.testing.assert_array_equal(back.predict_xy(x, y), cal.predict_xy(x, y))
