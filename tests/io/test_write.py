"""Saving frame cubes and centroid tables (sunlab.io.write): Zarr v3 or NetCDF4 by the suffix,
exact round trips, the chunking asked for, and nothing overwritten unless asked."""

import numpy as np
import pytest
import xarray as xr

from sunlab import schema
from sunlab.errors import SunlabError
from sunlab.io.read import open_centroids, open_frames
from sunlab.io.write import NETCDF_SUFFIXES, save_centroids, save_frames

FRAMES = np.random.default_rng(0).integers(0, 1024, (2, 3, 6, 7), dtype=np.uint16)


def _cube():
    return schema.frames_dataset(FRAMES, alpha=[0.0, 1.5], beta=[-1.0, 0.5], experiment="I")


@pytest.mark.parametrize("name", ["cube.zarr", "cube.nc"])
def test_frames_round_trip_exactly_with_their_attributes(tmp_path, name):
    save_frames(_cube(), tmp_path / name)
    with open_frames(tmp_path / name) as back:
        assert back.frames.dtype == np.uint16
        np.testing.assert_array_equal(back.frames.values, FRAMES)
        np.testing.assert_array_equal(back.alpha.values, [0.0, 1.5])
        assert back.attrs["experiment"] == "I" and back.attrs["bit_depth"] == 10


def test_chunking_by_frame_or_by_pose(tmp_path):
    save_frames(_cube(), tmp_path / "f.zarr")
    save_frames(_cube(), tmp_path / "p.zarr", chunks="pose")
    with open_frames(tmp_path / "f.zarr") as f, open_frames(tmp_path / "p.zarr") as p:
        assert f.frames.data.chunksize == (1, 1, 6, 7)
        assert p.frames.data.chunksize == (1, 3, 6, 7)


def test_netcdf_suffixes_select_netcdf(tmp_path):
    assert ".nc" in NETCDF_SUFFIXES and ".zarr" not in NETCDF_SUFFIXES
    save_centroids(schema.centroids_dataset([[1.5]], [[2.5]]), tmp_path / "c.h5")
    assert (tmp_path / "c.h5").is_file()
    assert (tmp_path / "c.h5").read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"  # HDF5's signature


@pytest.mark.parametrize("name", ["c.zarr", "c.nc"])
def test_centroid_table_round_trip_keeps_nan_and_status(tmp_path, name):
    cen = schema.centroids_dataset([[1.5, np.nan]], [[2.5, np.nan]])
    cen.attrs["screened_outliers"] = [{"pose": 0, "shot": 1}]
    save_centroids(cen, tmp_path / name)
    back = open_centroids(tmp_path / name)
    xr.testing.assert_identical(back[["x", "y", "status"]].reset_coords(drop=True),
                                cen[["x", "y", "status"]].reset_coords(drop=True))
    assert back.attrs["screened_outliers"] == [{"pose": 0, "shot": 1}]


def test_an_existing_target_is_kept_unless_overwrite(tmp_path):
    path = tmp_path / "c.zarr"
    save_centroids(schema.centroids_dataset([[1.0]], [[2.0]]), path)
    with pytest.raises(SunlabError, match="c.zarr"):
        save_centroids(schema.centroids_dataset([[9.0]], [[9.0]]), path)
    assert open_centroids(path).x.item() == 1.0
    save_centroids(schema.centroids_dataset([[9.0]], [[9.0]]), path, overwrite=True)
    assert open_centroids(path).x.item() == 9.0
