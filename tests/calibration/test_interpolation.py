"""Tests of the calibration-table interpolation (linear and cubic)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import ConfigurationError, sim
from sunlab.calibration import Interpolation
from sunlab.schema import centroids_dataset

KW = dict(delta_f_mm=0.094, mounting_deg=(1.864, 0.415, 0.3), pose_error_deg=(0.02, 0.03),
          noise_px=0.01, jitter_deg=1e-3)


@pytest.fixture(scope="module")
def table():
    a, b = np.meshgrid(np.arange(-17.0, 3.0, 1.0), np.arange(-2.0, 18.0, 1.0), indexing="ij")
    return sim.synthetic_centroids(a.ravel(), b.ravel(), 4, seed=5, **KW)


@pytest.mark.parametrize("method", ["linear", "cubic"])
def test_exact_at_the_nodes(table, method):
    cal = Interpolation(method).fit(table)
    # the nodes are the pose-mean centroids of the ok shots; noisy, but passed through exactly
    a, b = cal.predict_xy(table.x.mean("shot").values, table.y.mean("shot").values)
    assert_allclose(a, table.alpha.values, atol=1e-9)
    assert_allclose(b, table.beta.values, atol=1e-9)


def test_linear_reproduces_an_affine_map_everywhere_inside():
    rng = np.random.default_rng(0)
    x, y = rng.uniform(0, 50, (80, 1)), rng.uniform(0, 50, (80, 1))
    cen = centroids_dataset(x, y, alpha=0.1 * x[:, 0] - 0.02 * y[:, 0] + 1,
                            beta=0.03 * x[:, 0] + 0.12 * y[:, 0])
    cal = Interpolation("linear").fit(cen)
    xq, yq = rng.uniform(10, 40, 30), rng.uniform(10, 40, 30)
    a, b = cal.predict_xy(xq, yq)
    assert_allclose(a, 0.1 * xq - 0.02 * yq + 1, atol=1e-10)
    assert_allclose(b, 0.03 * xq + 0.12 * yq, atol=1e-10)


@pytest.mark.parametrize("method", ["linear", "cubic"])
def test_nan_outside_the_hull_unless_nearest(table, method):
    far_x, far_y = np.array([0.0, np.nan]), np.array([0.0, 500.0])
    a, _ = Interpolation(method).fit(table).predict_xy(far_x, far_y)
    assert np.isnan(a).all()
    a, b = Interpolation(method, extrapolate="nearest").fit(table).predict_xy(far_x, far_y)
    assert np.isfinite(a[0]) and np.isnan(a[1])  # NaN input stays NaN
    # nearest node to the detector corner (0, 0) is the pose with the most negative angles
    assert (a[0], b[0]) == (-17.0, -2.0)


def test_between_nodes_accuracy_is_at_the_noise_level(table):
    # test poses half-way between nodes: the error is about the pose error of the nodes
    a, b = np.meshgrid(np.arange(-16.5, 1.6, 1.0), np.arange(-1.5, 16.6, 1.0), indexing="ij")
    te = sim.synthetic_centroids(a.ravel(), b.ravel(), 2, seed=9, **KW)
    for method in ("linear", "cubic"):
        est = Interpolation(method).fit(table).predict(te)
        err = abs(est.alpha - te.true_alpha)
        assert 0.003 < float(err.mean()) < 0.03


def test_degenerate_table():
    cen = centroids_dataset(np.array([[1.0], [2.0], [3.0]]), np.array([[1.0], [2.0], [3.0]]),
                            alpha=[0.0, 1.0, 2.0], beta=[0.0, 1.0, 2.0])
    with pytest.raises(ConfigurationError, match="triangulate"):
        Interpolation("linear").fit(cen)
