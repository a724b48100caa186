"""Tests of sunlab.geometry: ideal model (1), optimised model (3)-(4), pinhole forward model."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import geometry
from sunlab.errors import ConfigurationError
from sunlab.geometry import _fit
from sunlab.geometry.model import optimised_angles, pinhole_centroid

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
    assert_allclose(optimised_angles(x, y, *pars), (a, b), atol=1e-10)
    assert_allclose(geometry.optimised_centroid(0.0, 0.0, *pars), (610.0, 495.0), atol=1e-10)


def test_optimised_model_reduces_to_ideal():
    a, b = _grid(3.0)
    x, y = geometry.ideal_centroid(a, b, F, P, 640.0, 512.0)
    assert_allclose(optimised_angles(x, y, F, P, 0.0, 0.0, 0.0, 640.0, 512.0), (a, b),
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
    assert_allclose(pinhole_centroid(a, b, F, P, 640.0, 512.0),
                    geometry.ideal_centroid(a, b, F, P, 640.0, 512.0), atol=1e-9)
    # a pure alpha mounting error adds to alpha exactly: the optimised model is exact then
    zp = pinhole_centroid(0.0, 0.0, F, P, 640.0, 512.0, delta_f_mm=0.1,
                                   mounting_deg=(1.5, 0.0, 0.0))
    x, y = pinhole_centroid(a, b, F, P, 640.0, 512.0, delta_f_mm=0.1,
                                     mounting_deg=(1.5, 0.0, 0.0))
    assert_allclose(optimised_angles(x, y, F, P, 0.1, 1.5, 0.0, *zp), (a, b), atol=1e-9)


def test_mounting_beta_error_is_not_additive_off_axis():
    # R_x(beta0) and R_y(-alpha) do not commute: the additive reading of (3)-(4) is approximate
    # off axis (a roll of about beta0 sin(alpha)), the rotation reading exact
    x, y = pinhole_centroid(-17.0, 0.0, F, P, 640.0, 512.0, mounting_deg=(0, 0.415, 0))
    zp = pinhole_centroid(0.0, 0.0, F, P, 640.0, 512.0, mounting_deg=(0, 0.415, 0))
    a, b = optimised_angles(x, y, F, P, 0.0, 0.0, 0.415, *zp, mounting="additive")
    assert 1e-3 < abs(float(a) + 17.0) + abs(float(b)) < 0.2
    a, b = optimised_angles(x, y, F, P, 0.0, 0.0, 0.415, *zp, mounting="rotation")
    assert abs(float(a) + 17.0) + abs(float(b)) < 1e-9


def test_rotations_are_right_handed_and_orthogonal():
    for rot in (geometry.model.rotation_x, geometry.model.rotation_y, geometry.model.rotation_z):
        r = rot(0.3)
        assert_allclose(r @ r.T, np.eye(3), atol=1e-15)
        assert_allclose(np.linalg.det(r), 1.0)
    g = geometry.model
    assert_allclose(g.mounting_matrix(1.0, 2.0, 3.0),
                    g.rotation_z(np.deg2rad(3.0)) @ g.rotation_y(np.deg2rad(-1.0))
                    @ g.rotation_x(np.deg2rad(2.0)), rtol=0, atol=0)


def _noisy_grid(seed=7, noise_px=0.05):
    """Pose grid of 1 deg with centroids of the optimised model (known truth) plus white noise."""
    a, b = _grid()
    x, y = geometry.optimised_centroid(a, b, F, P, *TRUTH.values(), 600.0, 520.0)
    rng = np.random.default_rng(seed)
    return x + rng.normal(0, noise_px, x.shape), y + rng.normal(0, noise_px, y.shape), a, b


@pytest.mark.parametrize("mounting", ["rotation", "additive"])
@pytest.mark.parametrize("free_zero_pose", [True, False])
def test_analytic_jacobian_matches_finite_differences(mounting, free_zero_pose):
    x, y, a, b = _noisy_grid()
    w = np.sqrt(np.arange(a.size) % 3 + 1.0)  # bootstrap multiplicities 1..3
    q = np.array([0.12, 1.5, 0.6, 598.0, 523.0][: 5 if free_zero_pose else 3])
    zp = None if free_zero_pose else (598.0, 523.0)
    model = _fit._AngleResiduals(x, y, a, b, F, P, zp, mounting, w)
    # the residuals are those of optimised_angles, weighted
    am, bm = optimised_angles(x, y, F, P, *q[:3], *(zp or q[3:]), mounting=mounting)
    assert_allclose(model.residuals(q), np.concatenate([am - a, bm - b]) * np.tile(w, 2),
                    rtol=0, atol=1e-12)
    jac = model.jacobian(q)
    # central differences, steps ~1e-4 of each parameter's scale: truncation error h^2 |f'''| / 6
    # and rounding error eps |f| / h (|f| < 20 deg) are each ~1e-10..1e-9 of a column's largest
    # entry (measured: < 1e-8 with a tenth or ten times the steps, scaling as h^2 above); 1e-7
    # leaves a margin of 100 and fails on any wrong term of the derivation (O(1) relative)
    steps = np.array([1e-5, 1e-4, 1e-4, 1e-2, 1e-2])[: q.size]
    num = np.empty_like(jac)
    for j, h in enumerate(steps):
        dq = np.zeros_like(q)
        dq[j] = h
        num[:, j] = (model.residuals(q + dq) - model.residuals(q - dq)) / (2 * h)
    err = np.abs(jac - num).max(axis=0) / np.abs(num).max(axis=0)
    assert np.all(err < 1e-7), err
    # the Jacobian is asked for where the residuals were last evaluated: cached or not, the same
    model.residuals(q + 0.1)
    assert_allclose(model.jacobian(q), jac, rtol=1e-14, atol=0)


def test_integer_weights_equal_duplicated_points():
    # a point drawn k times = its residuals times sqrt(k): the same objective, the same minimiser
    x, y, a, b = _noisy_grid()
    k = np.random.default_rng(1).integers(0, 4, a.size)
    dup = np.repeat(np.arange(a.size), k)
    use = k > 0
    q0 = [0.0, 0.0, 0.0, 600.0, 520.0]
    by_copies = _fit._least_squares(x[dup], y[dup], a[dup], b[dup], q0, F, P, None, "rotation")
    by_weight = _fit._least_squares(x[use], y[use], a[use], b[use], q0, F, P, None, "rotation",
                                    np.sqrt(k[use]))
    # Two solves of one objective agree to what the solver and the arithmetic can resolve, not
    # to a fixed 1e-10 (issue 37: 3.4e-10 on another machine's BLAS): each stops within its
    # Gauss-Newton step of the minimiser (the stopping rule), and rounding of the m residuals
    # (terms up to |x|, |y| px) moves the minimiser by up to sqrt(m) eps max|term| / sigma_min(J)
    # (the conditioning), with a factor 10 of headroom for the residuals' few operations.
    def gauss_newton_step(res):
        return np.linalg.norm(np.linalg.lstsq(res.jac, -res.fun, rcond=None)[0])

    sigma_min = np.linalg.svd(by_copies.jac, compute_uv=False)[-1]
    m = by_copies.fun.size
    rounding = 10 * np.sqrt(m) * np.finfo(float).eps * max(np.abs(x).max(), np.abs(y).max())
    tol = gauss_newton_step(by_copies) + gauss_newton_step(by_weight) + rounding / sigma_min
    assert np.linalg.norm(by_weight.x - by_copies.x) <= tol
    # the costs: equal to first order at a minimum, so to the rounding of a sum of m squares
    assert_allclose(by_weight.cost, by_copies.cost, rtol=10 * m * np.finfo(float).eps)


def _reference_bootstrap_stderr(x, y, a, b, q, blocks, n_boot, seed, jac="2-point"):
    """The block bootstrap as first written: every drawn block's points copied into the replica,
    finite-difference Jacobian of optimised_angles, each replica started at the full fit ``q``."""
    from scipy.optimize import least_squares

    uniq, inv = np.unique(blocks, return_inverse=True)
    members = [np.flatnonzero(inv == i) for i in range(uniq.size)]
    rng = np.random.default_rng(seed)
    reps = []
    for _ in range(n_boot):
        pick = np.concatenate([members[i] for i in rng.integers(0, uniq.size, uniq.size)])

        def residuals(p, pick=pick):
            am, bm = optimised_angles(x[pick], y[pick], F, P, *p)
            return np.concatenate([am - a[pick], bm - b[pick]])

        reps.append(least_squares(residuals, q, jac=jac, method="trf", x_scale="jac", xtol=1e-14,
                                  ftol=1e-14, gtol=1e-14, max_nfev=2000).x)
    return np.std(np.array(reps), axis=0, ddof=1)


# Each replica stops where the cost changes by < ftol = 1e-14 relative, which leaves its
# parameters up to ~sqrt(ftol) = 1e-7 of a standard error from the exact minimiser: ~1e-7
# relative on the standard errors between any two solution paths (weights vs copies, analytic
# vs 3-point differences; measured: <= 2e-7). The 2-point differences of the first
# implementation also stop at their own stationary point, off the exact one by their
# truncation error (~1e-8 relative in each parameter, a scaled gradient of ~3e-8); over 30
# replicas that is up to ~1.5e-6 relative on the standard errors (measured over 3 noise seeds;
# 2-3e-7 with Table 4's 200 replicas).
@pytest.mark.parametrize("jac, rtol", [("2-point", 5e-6), ("3-point", 1e-6)])
def test_block_bootstrap_matches_resampling_reference(jac, rtol):
    x, y, a, b = _noisy_grid()
    blocks = np.floor(a / 2.0) * 1000 + np.floor(b / 2.0)  # 2 x 2-degree squares, as Table 4
    fit = geometry.fit_optimised_model(x, y, a, b, F, P, blocks=blocks, n_boot=30, seed=5)
    assert fit.stderr_method == "block bootstrap"
    names = ["delta_f_mm", "alpha0", "beta0", "x_zp", "y_zp"]
    q = [getattr(fit, k) for k in names]
    ref = _reference_bootstrap_stderr(x, y, a, b, q, blocks, 30, 5, jac)
    assert_allclose([fit.stderr[k] for k in names], ref, rtol=rtol)
    truth = [*TRUTH.values(), 600.0, 520.0]
    for k, v in zip(names, truth, strict=True):
        assert abs(getattr(fit, k) - v) < 5 * fit.stderr[k]
