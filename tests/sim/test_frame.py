"""Frames of the virtual bench (sunlab.sim.frame): deterministic in (seed, pose, shot), and their
pixels scatter about :func:`expected_frame`'s mean with its variance.

Over the ~4 000 pixels of the spot and its surroundings, the standardised residual
(frame - mean) / sqrt(var + 1/12) has a sample mean within 0.05 and a standard deviation within
0.05 of 1 (the sampling errors are 0.016 and 0.011: three of them).
"""

import numpy as np
import pytest

from sunlab.errors import ConfigurationError
from sunlab.sim import Bench
from sunlab.sim.frame import expected_frame, render_frame, render_pose
from sunlab.sim.spots import spot_truth


@pytest.fixture(scope="module")
def bench():
    return Bench.paper_single_hole()


def test_frames_are_deterministic_in_seed_pose_and_shot(bench):
    f = render_frame(bench, -5.0, 5.0, seed=1, pose=0, shot=0)
    assert f.dtype == np.uint16 and f.shape == bench.detector.shape
    assert np.array_equal(f, render_frame(bench, -5.0, 5.0, seed=1, pose=0, shot=0))
    for other in ({"seed": 2, "shot": 0}, {"seed": 1, "shot": 1}):
        assert not np.array_equal(f, render_frame(bench, -5.0, 5.0, pose=0, **other))
    assert int(f.max()) <= 2**bench.detector.bit_depth - 1


def test_pixels_scatter_about_the_expected_mean_with_its_variance(bench):
    f = render_frame(bench, 3.0, -2.0, seed=7, play_mm=(0.0, 0.0))
    mean, var = expected_frame(bench, 3.0, -2.0, play_mm=(0.0, 0.0))
    x, y = (int(round(float(v[0]))) for v in spot_truth(bench, 3.0, -2.0))
    win = (slice(y - 32, y + 32), slice(x - 32, x + 32))
    assert mean[win].max() > mean[win].min() + 100  # the spot is inside the window
    z = (f[win] - mean[win]) / np.sqrt(var[win] + 1 / 12)
    assert abs(z.mean()) < 0.05 and abs(z.std() - 1) < 0.05


def test_a_pose_shares_its_spot_shape_between_shots(bench):
    frames = render_pose(bench, [-5.0, -5.0004], [5.0, 5.0003], seed=1, pose=3)
    assert frames.shape == (2, *bench.detector.shape)
    one = render_frame(bench, -5.0004, 5.0003, seed=1, pose=3, shot=1,
                       shape_angles=(-5.0, 5.0))
    assert np.array_equal(frames[1], one)


def test_bad_outputs_and_angles_are_refused(bench):
    with pytest.raises(ConfigurationError, match="out: found float64"):
        render_frame(bench, 0.0, 0.0, seed=0, out=np.empty(bench.detector.shape))
    with pytest.raises(ConfigurationError, match="alpha_true, beta_true"):
        render_pose(bench, [0.0, 1.0], [0.0], seed=0)
