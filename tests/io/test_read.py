"""Opening what sunlab wrote (sunlab.io.read): the format from the path, the contract from the
file, a CSV table with the sensor.json beside it, and one error naming a bad path."""

import json

import numpy as np
import pytest

from sunlab import schema
from sunlab.errors import SchemaError, SunlabError
from sunlab.io.read import open_centroids, open_dataset, open_frames
from sunlab.io.write import save_centroids, save_frames


def _cube():
    return schema.frames_dataset(np.ones((1, 2, 8, 8), np.uint16), alpha=[0.0], beta=[0.0])


def test_open_dataset_follows_the_contract_written_in_the_file(tmp_path):
    save_frames(_cube(), tmp_path / "f.zarr")
    save_centroids(schema.centroids_dataset([[1.0]], [[2.0]]), tmp_path / "c.nc")
    with open_dataset(tmp_path / "f.zarr") as frames:
        assert frames.attrs["sunlab_schema"] == "frames/1"
        assert hasattr(frames.frames.data, "dask")  # frames stay lazy
    cen = open_dataset(tmp_path / "c.nc")
    assert cen.attrs["sunlab_schema"] == "centroids/1" and cen.x.item() == 1.0


def test_centroids_load_unless_lazy(tmp_path):
    save_centroids(schema.centroids_dataset([[1.0, 2.0]], [[3.0, 4.0]]), tmp_path / "c.zarr")
    assert isinstance(open_centroids(tmp_path / "c.zarr").x.data, np.ndarray)
    assert hasattr(open_centroids(tmp_path / "c.zarr", lazy=True).x.data, "dask")


def test_a_frame_cube_is_not_a_centroid_table(tmp_path):
    save_frames(_cube(), tmp_path / "f.zarr")
    with pytest.raises(SchemaError):
        open_centroids(tmp_path / "f.zarr")


def test_csv_table_takes_the_sensor_json_beside_it(tmp_path):
    csv = tmp_path / "table.csv"
    csv.write_text("alpha,beta,x,y\n0,0,639.5,511.5\n1,0,652.1,511.5\n")
    (tmp_path / "sensor.json").write_text(json.dumps(
        {"pixel_pitch_mm": 0.007, "mask_distance_mm": 5.0, "comment": "bench 2"}))
    cen = open_centroids(csv)
    assert cen.sizes["pose"] == 2
    assert cen.attrs["pixel_pitch_mm"] == 0.007 and cen.attrs["mask_distance_mm"] == 5.0
    np.testing.assert_array_equal(cen.x.values.ravel(), [639.5, 652.1])
    # attributes given by the caller replace the file's
    assert open_centroids(csv, attrs={"pixel_pitch_mm": 0.0055}).attrs["pixel_pitch_mm"] == 0.0055


@pytest.mark.parametrize("opener", [open_frames, open_centroids, open_dataset])
def test_a_missing_path_is_one_error_naming_it(tmp_path, opener):
    with pytest.raises(SunlabError, match="nothing.zarr") as err:
        opener(tmp_path / "nothing.zarr")
    assert "\n" not in str(err.value)
