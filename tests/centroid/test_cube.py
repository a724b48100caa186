"""Centroiding a frame cube (sunlab.centroid.cube): the table equals the estimator frame by
frame, carries the cube's sensor attributes and truth, and is the same lazily or in one pass
over several cubes. Frames are small noiseless disks (tests/_spots.py), so the estimators'
own answers are compared exactly and the truth to 0.02 px.
"""

import _spots
import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from sunlab import schema
from sunlab.centroid import METHODS
from sunlab.centroid.cube import default_method, is_multi_hole, locate, locate_all
from sunlab.errors import ConfigurationError

SHAPE = (96, 112)
TRUTH = np.array([[[50.3, 40.7], [51.1, 41.2]], [[60.0, 45.5], [59.4, 44.9]]])  # pose, shot, xy


def _cube(truth=TRUTH):
    frames = np.stack([[_spots.frame([tuple(xy)], radius=12.0, noise=False, shape=SHAPE)
                        .astype(np.uint16) for xy in pose] for pose in truth])
    cube = schema.frames_dataset(frames, alpha=[0.0, 1.0], beta=[0.0, -1.0], experiment="I",
                                 x_cf_px=55.5, y_cf_px=47.5)
    return cube.assign(true_x=(("pose", "shot"), truth[..., 0]),
                       true_y=(("pose", "shot"), truth[..., 1]))


@pytest.fixture(scope="module")
def cube():
    return _cube()


@pytest.mark.parametrize("method", ["projection", "tight"])
def test_table_is_the_estimator_frame_by_frame(cube, method):
    cen = locate(cube, method, progress=False, scheduler="synchronous")
    assert cen.x.dims == ("pose", "shot") and cen.sizes == {"pose": 2, "shot": 2}
    for p in range(2):
        for s in range(2):
            one = METHODS[method](cube.frames[p, s].values, saturation=1023)
            assert (cen.x[p, s].item(), cen.y[p, s].item()) == (one.x, one.y)
            assert cen.status[p, s].item() == one.status == 0
            assert (cen.x0[p, s].item(), cen.x1[p, s].item()) == one.window[:2]
    assert_allclose(cen.x, TRUTH[..., 0], atol=0.02)
    assert_allclose(cen.y, TRUTH[..., 1], atol=0.02)


def test_table_carries_the_cube_attributes_coordinates_and_truth(cube):
    cen = locate(cube, "projection", progress=False, scheduler="synchronous")
    for key in ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "experiment"):
        assert cen.attrs[key] == cube.attrs[key]
    assert_array_equal(cen.alpha, [0.0, 1.0]) and assert_array_equal(cen.beta, [0.0, -1.0])
    assert_array_equal(cen.true_x, TRUTH[..., 0])
    schema.validate_centroids(cen)


def test_lazy_table_and_one_pass_over_several_cubes_agree(cube):
    eager = locate(cube, "projection", progress=False, scheduler="synchronous")
    lazy = locate(cube, "projection", progress=False, compute=False)
    assert hasattr(lazy.x.data, "dask")  # nothing computed yet
    assert_array_equal(lazy.x.compute(), eager.x)
    other = _cube(TRUTH + 3.0)
    both = locate_all({"I": cube, "II": other}, "projection", progress=False,
                      scheduler="synchronous")
    assert_array_equal(both["I"].x, eager.x)
    assert_allclose(both["II"].x, TRUTH[..., 0] + 3.0, atol=0.02)


def test_default_method_and_multi_hole_detection(cube):
    assert not is_multi_hole(cube)
    assert default_method(cube) == "projection"
    assert default_method(cube, background="ring") == "tight"
    multi = cube.assign_coords(hole_i=("hole", [0, 0]), hole_j=("hole", [0, 1]))
    assert is_multi_hole(multi) and default_method(multi) == "tight"


def test_single_spot_algorithm_on_a_multi_hole_cube_is_refused(cube):
    multi = cube.assign_coords(hole_i=("hole", [0, 0]), hole_j=("hole", [0, 1]))
    with pytest.raises(ConfigurationError, match="projection"):
        locate(multi, "projection", progress=False)
