"""Many spots of one frame (sunlab.centroid.lattice): a small 3 x 4 mask on a noiseless frame.

A noiseless, pixel-integrated disk is centred by the tight window to well under 0.01 px, so the
positions are held to 0.02 px; the lattice fit averages twelve of them, so its step is held to
1e-3 of the pitch.
"""

import _spots
import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab.centroid.lattice import SPOT_METRICS, Spots, locate_spots
from sunlab.schema import STATUS

PITCH = 60.0
SHAPE = (260, 370)


def _grid_frame(extra=()):
    pos, ii, jj = _spots.grid_spots(3, 4, pitch=PITCH, origin=(70.3, 60.6))
    spots = [tuple(p) for p in pos] + list(extra)
    frame = _spots.frame(spots, radius=12.0, edge=2.0, noise=False, shape=SHAPE)
    return frame, pos, ii, jj


@pytest.fixture(scope="module")
def grid():
    return _grid_frame()


@pytest.mark.parametrize("method", ["tight", "fit"])
def test_every_hole_is_found_and_indexed_in_raster_order(grid, method):
    frame, pos, ii, jj = grid
    s = locate_spots(frame, shape=(3, 4), pitch=PITCH, method=method)
    assert isinstance(s, Spots)
    assert np.all(s.status == STATUS["ok"])
    assert np.array_equal(s.i, ii) and np.array_equal(s.j, jj)
    assert_allclose(s.x, pos[:, 0], atol=0.02)
    assert_allclose(s.y, pos[:, 1], atol=0.02)
    # the fitted lattice: origin at hole (0, 0), steps along j (x) and i (y) of one pitch
    assert_allclose(s.lattice[0], pos[0], atol=0.02)
    assert_allclose(s.lattice[1], [PITCH, 0.0], atol=PITCH * 1e-3)
    assert_allclose(s.lattice[2], [0.0, PITCH], atol=PITCH * 1e-3)
    assert s.unassigned.shape == (0, 2)


def test_chosen_holes_come_back_in_the_order_asked(grid):
    frame, pos, *_ = grid
    want_i, want_j = np.array([2, 0, 1]), np.array([3, 1, 0])
    s = locate_spots(frame, shape=(3, 4), pitch=PITCH, holes=(want_i, want_j))
    assert s.i.tolist() == want_i.tolist() and s.j.tolist() == want_j.tolist()
    assert_allclose(s.x, pos[want_i * 4 + want_j, 0], atol=0.02)


def test_a_spot_off_the_lattice_is_unassigned_and_disturbs_no_hole():
    stray = (70.3 + 4.5 * PITCH, 60.6 + PITCH)  # half a pitch beyond the last column's node
    frame, pos, *_ = _grid_frame(extra=[stray])
    s = locate_spots(frame, shape=(3, 4), pitch=PITCH)
    assert np.all(s.status == STATUS["ok"])
    assert_allclose(s.x, pos[:, 0], atol=0.02)
    assert s.unassigned.shape == (1, 2)
    assert_allclose(s.unassigned[0], stray, atol=0.05)


def test_metrics_and_dataframe_carry_every_documented_metric(grid):
    frame, *_ = grid
    s = locate_spots(frame, shape=(3, 4), pitch=PITCH)
    assert set(s.metrics) == set(SPOT_METRICS)
    # round spots on a flat background: no ellipticity, the background recovered (30 DN)
    assert np.max(s.metrics["ellipticity"]) < 0.01
    assert_allclose(s.metrics["background"], 30.0, atol=0.5)
    df = s.to_dataframe()
    assert len(df) == 12 and df.index.name == "hole"
    assert set(SPOT_METRICS) | {"i", "j", "x", "y", "flux", "status", "x0", "y1"} <= set(df)


def test_a_frame_without_spots_has_no_spot_in_every_hole():
    s = locate_spots(np.full(SHAPE, 30.0), shape=(3, 4), pitch=PITCH)
    assert np.all(s.status == STATUS["no_spot"]) and np.all(np.isnan(s.x))
