"""The holes of a multi-hole mask (sunlab.multihole.holes): grid indices, usable spots, cut-outs
and the free layout's centroiding on frames with exactly known spots."""

import _spots
import numpy as np
import pytest

from sunlab import schema
from sunlab.errors import SchemaError
from sunlab.multihole.holes import centroid_free_layout, cutout, hole_grid, usable
from sunlab.sim import synthetic_centroids


def test_hole_grid_from_coordinates_from_a_square_or_as_one_row():
    grid = synthetic_centroids([0.0], [0.0], shots=1, layout="grid")
    i, j, nr, nc = hole_grid(grid)
    assert (nr, nc) == (10, 10) and (i[57], j[57]) == (5, 7)
    square = grid.drop_vars(["hole_i", "hole_j"])
    assert hole_grid(square)[2:] == (10, 10)
    free = grid.isel(hole=slice(0, 7)).drop_vars(["hole_i", "hole_j"])
    i, j, nr, nc = hole_grid(free)
    assert (nr, nc) == (1, 7) and i.tolist() == [0] * 7 and j.tolist() == list(range(7))
    with pytest.raises(SchemaError, match="hole"):
        hole_grid(synthetic_centroids([0.0], [0.0], shots=1))


def test_usable_needs_a_finite_centroid_and_an_accepted_status():
    cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=1, layout="grid",
                              defects={3: {"missing": 1.0}})
    assert int(usable(cen).sum()) == 2 * 99 and not usable(cen)[:, :, 3].any()
    cen["status"][0, 0, 5] = schema.STATUS["repaired"]
    assert not bool(usable(cen)[0, 0, 5])
    assert bool(usable(cen, accept=("ok", "repaired"))[0, 0, 5])


def test_cutout_is_cut_at_the_frame_edges():
    frame = np.arange(100.0).reshape(10, 10)
    st, (x0, y0) = cutout(frame, 2.4, 7.6, 2)
    assert st.shape == (4, 5) and (x0, y0) == (0, 6)
    np.testing.assert_array_equal(st, frame[6:10, 0:5])
    inner, origin = cutout(frame, 5.0, 5.0, 1)
    assert origin == (4, 4) and np.array_equal(inner, frame[4:7, 4:7])


def test_free_layout_finds_each_hole_about_its_design_position():
    truth = [(80.3, 100.0), (200.0, 90.6), (150.2, 40.4)]
    frame = _spots.frame(truth, radius=10.0, noise=False, shape=(160, 260)).astype(np.uint16)
    cube = schema.frames_dataset(frame[None, None], alpha=[0.0], beta=[0.0])
    cube = cube.assign_coords(hole_x_cf=("hole", [80.0, 200.0, 150.0]),
                              hole_y_cf=("hole", [100.0, 90.0, 40.0]))
    cen = centroid_free_layout(cube, half=25)
    assert cen.x.dims == ("pose", "shot", "hole")
    assert np.all(cen.status.values == schema.STATUS["ok"])
    np.testing.assert_allclose(cen.x[0, 0], [t[0] for t in truth], atol=0.02)
    np.testing.assert_allclose(cen.y[0, 0], [t[1] for t in truth], atol=0.02)
    # the disks are round: the stamp moments say so
    assert float(cen.ellipticity.max()) < 0.02


def test_free_layout_needs_design_positions():
    cube = schema.frames_dataset(np.zeros((1, 1, 16, 16), np.uint16), alpha=[0.0], beta=[0.0])
    with pytest.raises(SchemaError, match="hole_x_cf"):
        centroid_free_layout(cube)
