"""Tests of sunlab.geometry: ideal model (1), optimised model (3)-(4), pinhole forward model."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import geometry
from sunlab.errors import ConfigurationError

F, P = 5.0, 0.007
TRUTH = {"delta_f_mm": 0.094, "alpha0": 1.864, "beta0": 0.415}


def _grid(step=1.0):
    a, b = np.meshgrid(np.arange(-17.0, 2.0 + 1e-9, step), np.arange(-2.0, 17.0 + 1e-9, step),
                       indexing="ij")
    return a.ravel(), b.ravel()


@pytest.mark.parametrize("alpha, beta", [(0.0, 0.0), (-17.0, 17.0), (2.0, -2.0), (-8.3, 4.1)])
def test_ideal_model_round_trip(alpha, beta):
    x, y = geometry.ideal_centroid(alpha, beta, F, P, 640.0, 512.0)
    assert_allclose(geometry.ideal_angles(x, y, F, P, 640.0, 512.0), (alpha, beta), atol=1e-12)


def test_sun_vector_matches_ideal_model():
    # the spot moves by -F (s_x/s_z, s_y/s_z): eq. (1) and the sun vector agree
    a, b = _grid(3.0)
    s = geometry.sun_vector(a, b)
    x, y = geometry.ideal_centroid(a, b, F, P, 0.0, 0.0)
    assert_allclose(x, -F / P * s[:, 0] / s[:, 2], atol=1e-9)
    assert_allclose(y, -F / P * s[:, 1] / s[:, 2], atol=1e-9)


def test_optimised_model_round_trip_and_zero_pose():
    pars = (F, P, 0.094, 1.864, 0.415, 610.0, 495.0)
    a, b = _grid(2.0)
    x, y = geometry.optimised_centroid(a, b, *pars)
    assert_allclose(geometry.optimised_angles(x, y, *pars), (a, b), atol=1e-10)
    assert_allclose(geometry.optimised_centroid(0.0, 0.0, *pars), (610.0, 495.0), atol=1e-10)


def test_optimised_model_reduces_to_ideal():
    a, b = _grid(3.0)
    x, y = geometry.ideal_centroid(a, b, F, P, 640.0, 512.0)
    assert_allclose(geometry.optimised_angles(x, y, F, P, 0.0, 0.0, 0.0, 640.0, 512.0), (a, b),
                    atol=1e-12)


@pytest.mark.parametrize("free_zero_pose", [False, True])
def test_fit_recovers_injected_parameters(free_zero_pose):
    a, b = _grid()
    x, y = geometry.optimised_centroid(a, b, F, P, *TRUTH.values(), 600.0, 520.0)
    zp = (None, None) if free_zero_pose else (600.0, 520.0)
    fit = geometry.fit_optimised_model(x, y, a, b, F, P, *zp)
    assert fit.success and fit.zero_pose_fitted is free_zero_pose
    assert_allclose([fit.delta_f_mm, fit.alpha0, fit.beta0], list(TRUTH.values()), atol=1e-7)
    assert_allclose([fit.x_zp, fit.y_zp], [600.0, 520.0], atol=1e-5)
    assert fit.rms_alpha < 1e-9 and fit.rms_beta < 1e-9


def test_fit_with_noise_reports_stderr_that_covers_truth():
    rng = np.random.default_rng(3)
    a, b = _grid()
    x, y = geometry.optimised_centroid(a, b, F, P, *TRUTH.values(), 600.0, 520.0)
    x = x + rng.normal(0, 0.05, x.shape)
    y = y + rng.normal(0, 0.05, y.shape)
    fit = geometry.fit_optimised_model(x, y, a, b, F, P, 600.0, 520.0)
    for k, v in TRUTH.items():
        assert abs(getattr(fit, k) - v) < 5 * fit.stderr[k]


def test_fit_ignores_nan_and_needs_points():
    a, b = _grid(4.0)
    x, y = geometry.optimised_centroid(a, b, F, P, *TRUTH.values(), 600.0, 520.0)
    x[3] = np.nan
    fit = geometry.fit_optimised_model(x, y, a, b, F, P, 600.0, 520.0)
    assert fit.n_points == a.size - 1
    with pytest.raises(ConfigurationError, match="usable centroids"):
        geometry.fit_optimised_model(x[:2], y[:2], a[:2], b[:2], F, P)


def test_pinhole_model_matches_ideal_and_optimised_along_alpha():
    a, b = _grid(3.0)
    assert_allclose(geometry.pinhole_centroid(a, b, F, P, 640.0, 512.0),
                    geometry.ideal_centroid(a, b, F, P, 640.0, 512.0), atol=1e-9)
    # a pure alpha mounting error adds to alpha exactly: the optimised model is exact then
    zp = geometry.pinhole_centroid(0.0, 0.0, F, P, 640.0, 512.0, delta_f_mm=0.1,
                                   mounting_deg=(1.5, 0.0, 0.0))
    x, y = geometry.pinhole_centroid(a, b, F, P, 640.0, 512.0, delta_f_mm=0.1,
                                     mounting_deg=(1.5, 0.0, 0.0))
    assert_allclose(geometry.optimised_angles(x, y, F, P, 0.1, 1.5, 0.0, *zp), (a, b), atol=1e-9)


def test_mounting_beta_error_is_not_additive_off_axis():
    # R_x(beta0) and R_y(-alpha) do not commute: the additive reading of (3)-(4) is approximate
    # off axis (a roll of about beta0 sin(alpha)), the rotation reading exact
    x, y = geometry.pinhole_centroid(-17.0, 0.0, F, P, 640.0, 512.0, mounting_deg=(0, 0.415, 0))
    zp = geometry.pinhole_centroid(0.0, 0.0, F, P, 640.0, 512.0, mounting_deg=(0, 0.415, 0))
    a, b = geometry.optimised_angles(x, y, F, P, 0.0, 0.0, 0.415, *zp, mounting="additive")
    assert 1e-3 < abs(float(a) + 17.0) + abs(float(b)) < 0.2
    a, b = geometry.optimised_angles(x, y, F, P, 0.0, 0.0, 0.415, *zp, mounting="rotation")
    assert abs(float(a) + 17.0) + abs(float(b)) < 1e-9


def test_rotations_are_right_handed_and_orthogonal():
    for rot in (geometry.rotation_x, geometry.rotation_y, geometry.rotation_z):
        r = rot(0.3)
        assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        assert_allclose(np.linalg.det(r), 1.0)
    assert_allclose(geometry.mounting_matrix(1.0, 2.0, 3.0),
                    geometry.rotation_z(np.deg2rad(3.0)) @ geometry.rotation_y(np.deg2rad(-1.0))
                    @ geometry.rotation_x(np.deg2rad(2.0)), rtol=0, atol=0)
