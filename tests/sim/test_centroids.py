"""Tests of sunlab.sim.centroids: centroid-level tables with known truth, one hole and many."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import geometry
from sunlab.errors import ConfigurationError, SchemaError
from sunlab.schema import STATUS
from sunlab.sim import Mask, synthetic_centroids
from sunlab.sim.centroids import HoleLayout

F, P = 5.0, 0.007


def _grid(step):
    a, b = np.meshgrid(np.arange(-17.0, 3.0, step), np.arange(-2.0, 18.0, step), indexing="ij")
    return a.ravel(), b.ravel()


def test_synthetic_centroids_contract_truth_and_determinism():
    a, b = _grid(5.0)
    kw = dict(shots=3, delta_f_mm=0.05, pose_error_deg=(0.02, 0.04), jitter_deg=1e-3,
              noise_px=0.01, seed=7, experiment="I")
    c1 = synthetic_centroids(a, b, **kw)
    c2 = synthetic_centroids(a, b, **kw)
    assert c1.x.dims == ("pose", "shot") and c1.sizes["shot"] == 3
    assert c1.attrs["experiment"] == "I" and c1.attrs["sunlab_schema"] == "centroids/1"
    assert_allclose(c1.x, c2.x, rtol=0, atol=0)
    err = (c1.true_beta - c1.beta).values
    assert np.abs(err).max() < 0.04 + 5e-3
    # per-pose error is common to the shots of a pose, jitter is not
    assert np.abs(err - err.mean(axis=1, keepdims=True)).max() < 6e-3
    noise_free = synthetic_centroids(a, b, shots=1)
    assert_allclose(noise_free.x[:, 0], geometry.ideal_centroid(a, b, F, P, 639.5, 511.5)[0],
                    atol=1e-9)


def test_synthetic_centroids_bad_input():
    with pytest.raises(ConfigurationError, match="alpha, beta"):
        synthetic_centroids([0.0, 1.0], [0.0])
    with pytest.raises(ConfigurationError, match="shots"):
        synthetic_centroids([0.0], [0.0], shots=0)


def test_many_holes_follow_eq1_from_their_layout():
    lay = HoleLayout.from_mask(Mask.grid(), centre_px=(572.0, 375.0))
    assert_allclose(lay.x_cf[1] - lay.x_cf[0], 0.5 / P)
    cen = synthetic_centroids([-16.5, 0.0], [0.0, 3.0], shots=1, layout=lay)
    dx = cen.x.isel(pose=0, shot=0).values - cen.hole_x_cf.values
    assert_allclose(dx, F / P * np.tan(np.deg2rad(-16.5)), atol=1e-9)
    assert cen.x.dims == ("pose", "shot", "hole") and (cen.hole_i.values >= 0).all()


def test_many_holes_defects_and_edges():
    cen = synthetic_centroids([0.0] * 3, [0.0] * 3, shots=4, layout="grid",
                              defects={5: {"missing": 1.0, "flux": 0.5}},
                              detector_shape=(600, 1280))
    assert (cen.status.values[..., 5] == STATUS["no_spot"]).all()
    assert (cen.status == STATUS["clipped"]).any()  # the low rows leave a 600-row detector
    free = Mask.random_layout(20, seed=1)
    assert synthetic_centroids([0.0], [0.0], 1, layout=free).sizes["hole"] == 20


def test_bad_layout_and_shapes():
    with pytest.raises(ConfigurationError, match="layout"):
        synthetic_centroids([0.0], [0.0], layout="hexagonal")
    with pytest.raises(SchemaError):
        synthetic_centroids([0.0, 1.0], [0.0], layout="grid")
