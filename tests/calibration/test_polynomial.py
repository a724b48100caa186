"""Tests of the polynomial and trigonometric calibration functions."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import sim
from sunlab.calibration import Polynomial, Trigonometric
from sunlab.calibration.polynomial import design_matrix, monomial_exponents
from sunlab.schema import centroids_dataset


def _known_poly_table(order=3, shots=1):
    """Centroids on a scattered grid with alpha, beta exact polynomials of (x, y)."""
    rng = np.random.default_rng(0)
    x = rng.uniform(400, 660, (150, shots))
    y = rng.uniform(480, 740, (150, shots))
    xs, ys = (x - 530) / 100, (y - 610) / 100
    a = 2 * xs - 0.5 * ys + 0.3 * xs * ys - 0.05 * xs**2 + 0.02 * xs**3 - 0.01 * ys**3
    b = 1.5 * ys + 0.1 * xs - 0.2 * xs**2 * ys + 0.04 * ys**2
    # one pose per row: its commanded angles are the exact polynomial values
    return centroids_dataset(x, y, alpha=a[:, 0], beta=b[:, 0], attrs={"experiment": "poly"})


def test_monomials_count_and_order():
    for n in range(9):
        assert len(monomial_exponents(n)) == (n + 1) * (n + 2) // 2
    assert design_matrix(np.array([2.0]), np.array([3.0]), 2)[0].tolist() == [1, 2, 3, 4, 6, 9]


def test_right_order_reproduces_a_known_polynomial():
    train = _known_poly_table()
    cal = Polynomial(order=3).fit(train)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(420, 640, 50), rng.uniform(500, 720, 50)
    a, b = cal.predict_xy(x, y)
    xs, ys = (x - 530) / 100, (y - 610) / 100
    assert_allclose(a, 2 * xs - 0.5 * ys + 0.3 * xs * ys - 0.05 * xs**2 + 0.02 * xs**3
                    - 0.01 * ys**3, atol=1e-6)
    assert_allclose(b, 1.5 * ys + 0.1 * xs - 0.2 * xs**2 * ys + 0.04 * ys**2, atol=1e-6)
    assert cal.residuals["alpha"]["max_abs"] < 1e-9


def test_too_low_order_cannot_reproduce_it():
    cal = Polynomial(order=2).fit(_known_poly_table())
    assert cal.residuals["alpha"]["max_abs"] > 1e-3


def test_high_order_is_well_conditioned():
    # order 8 on the paper's 400-pose grid: approximation error of the arctan mapping only
    # (far below the 0.01 deg the paper reaches), no loss to conditioning
    a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, delta_f_mm=0.094,
                                       mounting_deg=(1.864, 0.415, 0.3))
    cal = Polynomial(order=8).fit(cen)
    assert cal.residuals["alpha"]["max_abs"] < 1e-6
    assert cal.residuals["beta"]["max_abs"] < 1e-6


def test_select_order_on_validation():
    train = _known_poly_table()
    val = _known_poly_table()
    best, scores = Polynomial.select_order(train, val, orders=range(1, 6))
    assert list(scores.index) == [1, 2, 3, 4, 5]
    assert scores.loc[1, "alpha_mean_abs"] > scores.loc[2, "alpha_mean_abs"] > 1e-4
    assert scores.loc[3, "alpha_mean_abs"] < 1e-9
    assert best.orders[0] >= 3 and best.residuals["validation"] is not None
    per, _ = Polynomial.select_order(train, val, orders=[1, 2, 3], per_angle=True)
    assert per.orders == (3, 3)


def test_select_order_refit_fits_the_chosen_order_on_both_tables():
    # the order is still chosen on II by fits on I; refit=True then fits it on I + II: with a
    # constant 0.02 deg offset in II's angles the refitted map moves toward II in proportion
    # to II's share of the poses, the plain fit not at all
    train = _known_poly_table()
    val = _known_poly_table().pipe(lambda t: t.assign_coords(beta=t.beta + 0.02))
    plain, _ = Polynomial.select_order(train, val, orders=[1, 2, 3, 4])
    both, _ = Polynomial.select_order(train, val, orders=[1, 2, 3, 4], refit=True)
    assert plain.orders == both.orders
    shift = float((both.predict(train).beta - plain.predict(train).beta).mean())
    assert shift == pytest.approx(0.02 * 150 / 300, abs=1e-6)
    assert both.training["n_poses"] == 300 and plain.training["n_poses"] == 150


def test_polynomial_smooths_noise_that_interpolation_keeps():
    a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
    kw = dict(shots=2, pose_error_deg=(0.02, 0.02), delta_f_mm=0.094)
    tr = sim.synthetic_centroids(a.ravel(), b.ravel(), seed=1, **kw)
    cal = Polynomial(order=4).fit(tr)
    # fit residual ~ the pose error (uniform, half-width 0.02: mean |e| = 0.01)
    assert 0.006 < cal.residuals["alpha"]["mean_abs"] < 0.014


@pytest.mark.parametrize("order", [2, 4])
def test_trigonometric_fits_but_worse_than_polynomial(order):
    a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
    kw = dict(shots=1, delta_f_mm=0.094, mounting_deg=(1.864, 0.415, 0.0))
    tr = sim.synthetic_centroids(a.ravel(), b.ravel(), **kw)
    te = sim.synthetic_centroids(a.ravel() + 0.5, b.ravel() + 0.5, **kw)
    trig = Trigonometric(order=order).fit(tr)
    poly = Polynomial(order=order).fit(tr)
    err = lambda c: float(abs(c.predict(te).alpha - te.alpha).max())  # noqa: E731
    assert err(trig) < 1.0
    assert err(poly) < err(trig)


def test_trigonometric_reproduces_a_fourier_mapping():
    rng = np.random.default_rng(2)
    x = rng.uniform(0, 100, (200, 1))
    y = rng.uniform(0, 100, (200, 1))
    # the fit scales the sample's own range to [-1, 1]: make it span [0, 100] exactly
    x[:4, 0], y[:4, 0] = [0, 100, 0, 100], [0, 0, 100, 100]
    u, v = (2 * x - 100) / 100, (2 * y - 100) / 100
    w = 2 * np.pi / 4.0
    a = 1 + np.cos(w * u) * np.sin(2 * w * v)
    b = np.sin(w * u) - 0.5 * np.cos(w * v)
    cen = centroids_dataset(x, y, alpha=a[:, 0], beta=b[:, 0])
    cal = Trigonometric(order=2).fit(cen)
    assert cal.residuals["alpha"]["max_abs"] < 1e-9 and cal.residuals["beta"]["max_abs"] < 1e-9
