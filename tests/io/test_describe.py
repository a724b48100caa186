"""``sunlab info``'s text (sunlab.io.describe.summary): what a frame cube or a centroid table
holds, computed from the data, with the sensor fields a lab did not give said to be absent."""

import numpy as np
import pytest
import xarray as xr

from sunlab import schema
from sunlab.errors import SchemaError
from sunlab.io.describe import summary


def test_frame_cube_summary_counts_poses_and_ranges():
    frames = np.zeros((3, 2, 8, 10), np.uint16)
    cube = schema.frames_dataset(frames, alpha=[-2.0, 0.0, 2.0], beta=[1.0, 1.0, 3.0],
                                 experiment="II", mask_distance_mm=None)
    lines = summary(cube).splitlines()
    assert lines[0] == "sunlab frame cube (frames/1)"
    text = "\n".join(lines)
    assert "dims: pose=3, shot=2, y=8, x=10" in text
    assert "frames: uint16 DN, 10-bit ADC, 960 B (in memory)" in text  # 3*2*8*10 px x 2 B
    assert "poses: 3, shots per pose: 2" in text
    assert "alpha: -2 .. 2 deg (3 distinct)" in text and "beta:  1 .. 3 deg (2 distinct)" in text
    assert "mask distance F not given" in text and "experiment: 'II'" in text


def test_a_lazy_cube_says_its_chunks():
    cube = schema.frames_dataset(np.zeros((2, 1, 8, 8), np.uint16), alpha=[0.0, 1.0],
                                 beta=[0.0, 0.0]).chunk({"pose": 1})
    assert "chunks (1, 1, 8, 8) (lazy)" in summary(cube)


def test_centroid_table_summary_counts_each_status():
    cen = schema.centroids_dataset([[1.0, np.nan], [3.0, 4.0]], [[2.0, np.nan], [5.0, 6.0]])
    text = summary(cen)
    assert text.splitlines()[0] == "sunlab centroid table (centroids/1)"
    assert "status (4 spots): ok 3 (75.0 %), no_spot 1 (25.0 %)" in text
    assert "x: 1 .. 4 px (3 distinct)" in text and "y: 2 .. 6 px (3 distinct)" in text
    assert "method: (not recorded)" in text


def test_a_dataset_of_no_sunlab_contract_is_refused():
    with pytest.raises(SchemaError, match=r"attrs\['sunlab_schema'\]"):
        summary(xr.Dataset({"x": ("pose", [1.0])}))
