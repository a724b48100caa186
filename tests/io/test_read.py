"""Opening what sunlab wrote (sunlab.io.read): the format from the path, the contract from the
file, a CSV table with the sensor.json beside it, and one error naming a bad path."""

import json

import numpy as np
import pytest
import xarray as xr

from sunlab import schema
from sunlab.errors import SchemaError, SunlabError
from sunlab.io.read import open_centroids, open_frames
from sunlab.io.write import save_centroids, save_frames


def _cube():
    return schema.frames_dataset(np.ones((1, 2, 8, 8), np.uint16), alpha=[0.0], beta=[0.0])


def test_each_opener_names_the_other_for_the_other_contract(tmp_path):
    save_frames(_cube(), tmp_path / "f.zarr")
    save_centroids(schema.centroids_dataset([[1.0]], [[2.0]]), tmp_path / "c.nc")
    with open_frames(tmp_path / "f.zarr") as frames:
        assert frames.attrs["sunlab_schema"] == "frames/1"
        assert hasattr(frames.frames.data, "dask")  # frames stay lazy
    with pytest.raises(SchemaError, match="open_centroids"):
        open_frames(tmp_path / "c.nc")
    cen = open_centroids(tmp_path / "c.nc")
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


@pytest.mark.parametrize("opener", [open_frames, open_centroids])
def test_a_missing_path_is_one_error_naming_it(tmp_path, opener):
    with pytest.raises(SunlabError, match="nothing.zarr") as err:
        opener(tmp_path / "nothing.zarr")
    assert "\n" not in str(err.value)


def test_one_opener_gives_identical_cubes_from_zarr_netcdf_and_the_image_folder(tmp_path):
    # issue 45: one opener for frames from every source, the same cube from each
    from sunlab import io

    folder = io.example_folder("test")
    cube = open_frames(folder).load()
    save_frames(cube, tmp_path / "run.zarr")
    save_frames(cube, tmp_path / "run.nc")
    for path in (tmp_path / "run.zarr", tmp_path / "run.nc", folder):
        with open_frames(path) as back:
            xr.testing.assert_identical(back.load(), cube)
    assert cube.attrs["sensor_json"].endswith("sensor.json") and cube.sizes["pose"] == 16


def test_a_tiff_stack_opens_with_the_manifest_beside_it(tmp_path):
    import tifffile

    frames = np.arange(4 * 6 * 8, dtype=np.uint16).reshape(4, 6, 8)
    tifffile.imwrite(tmp_path / "stack.tif", frames, photometric="minisblack")
    rows = ["file,alpha,beta,shot,page"] + [f"stack.tif,{k // 2},0,{k % 2},{k}"
                                            for k in range(4)]
    (tmp_path / "manifest.csv").write_text("\n".join(rows) + "\n")
    cube = open_frames(tmp_path / "stack.tif", bit_depth=10, lazy=False)
    np.testing.assert_array_equal(cube.frames.values, frames.reshape(2, 2, 6, 8))
    assert cube.alpha.values.tolist() == [0.0, 1.0] and "pixel_pitch_mm" not in cube.attrs
    with pytest.raises(SunlabError, match="bit_depth apply to a folder of images"):
        open_frames(_saved(tmp_path), bit_depth=10)


def _saved(tmp_path):
    save_frames(_cube(), tmp_path / "f.zarr")
    return tmp_path / "f.zarr"
