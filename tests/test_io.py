"""sunlab.io: exact round trips (Zarr, NetCDF), image-folder import, bad input, `sunlab info`."""

import json
import shutil

import dask.array as da
import h5netcdf
import numpy as np
import pytest
import tifffile
import xarray as xr
import zarr
from numpy.testing import assert_array_equal
from PIL import Image

from sunlab import SchemaError, SunlabError, integrity, io, schema
from sunlab.cli import main

NP, NS, NY, NX = 2, 2, 16, 20


def _frames(dtype=np.uint16, bits=10, seed=0):
    rng = np.random.default_rng(seed)
    return rng.integers(0, 2**bits, size=(NP, NS, NY, NX)).astype(dtype)


@pytest.fixture
def cube():
    """A small cube with every kind of coordinate and attribute the contract allows."""
    shots = np.arange(NP * NS).reshape(NP, NS)
    return schema.frames_dataset(
        _frames(),
        alpha=[-1.0, 1.0],
        beta=[0.5, 0.5],
        x_cf_px=9.25,
        y_cf_px=7.5,
        experiment="I",
        coords={
            "alpha_read": (("pose", "shot"), np.array([[-1.01, -0.99], [1.002, 0.998]])),
            "beta_read": (("pose", "shot"), np.array([[0.5, 0.51], [0.49, 0.5]])),
            "time": (
                ("pose", "shot"),
                np.datetime64("2005-06-01T12:00:00", "ns") + shots * np.timedelta64(125, "ms"),
            ),
            "file": (("pose", "shot"), np.array([["a", "bb"], ["ccc", ""]], dtype=object)),
        },
        attrs={
            "simulated": True,
            "defects": None,
            "hole_diameters_mm": [0.2, 0.19],
            "stage": {"axis": "beta", "backlash_deg": 0.01},
            "window_px": (130, 130),
            "seed": np.int64(7),
            "entropy": 2**100 + 1,
            "weights": np.array([[1, 2], [3, 4]], dtype=np.int8),
            "note": "",
        },
    )


@pytest.fixture
def centroids():
    x = np.array([[[1.5, np.nan], [2.25, 3.0]], [[4.0, 5.0], [np.nan, 6.5]]])
    status = np.where(np.isnan(x), schema.STATUS["no_spot"], schema.STATUS["ok"])
    status[0, 1, 1] = schema.STATUS["saturated"]
    return schema.centroids_dataset(
        x, x + 0.5, flux=np.ones_like(x), status=status, alpha=[0.0, 1.0], beta=[0.0, 0.0],
        method="projection_window", attrs={"bit_depth": 10, "clipped_ok": False},
    )


# ------------------------------------------------------------------------------------------
# Round trips
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["cube.zarr", "cube.nc"])
@pytest.mark.parametrize("chunks", ["frame", "pose"])
def test_frames_round_trip_is_exact(tmp_path, cube, name, chunks):
    before = {k: v for k, v in cube.attrs.items() if k != "weights"}
    io.save_frames(cube, tmp_path / name, chunks=chunks)
    with io.open_frames(tmp_path / name) as back:
        assert back.frames.dtype == np.uint16
        assert back.frames.chunks is not None, "frames must open lazily"
        block = (1, 1, NY, NX) if chunks == "frame" else (1, NS, NY, NX)
        assert back.frames.data.chunksize == block
        xr.testing.assert_identical(back.load(), cube)
        for var in cube.variables:
            assert back[var].dtype == cube[var].dtype, var
        assert back.attrs["simulated"] is True
        assert back.attrs["defects"] is None
        assert back.attrs["window_px"] == (130, 130)
        assert back.attrs["stage"] == {"axis": "beta", "backlash_deg": 0.01}
        assert type(back.attrs["seed"]) is int
        assert back.attrs["entropy"] == 2**100 + 1
        assert back.attrs["weights"].dtype == np.int8
        assert_array_equal(back.attrs["weights"], [[1, 2], [3, 4]])
    # Saving never touches the caller's dataset.
    assert {k: v for k, v in cube.attrs.items() if k != "weights"} == before
    assert isinstance(cube.attrs["weights"], np.ndarray)


@pytest.mark.parametrize("name", ["c.zarr", "c.nc"])
def test_uint8_round_trip(tmp_path, name):
    cube = schema.frames_dataset(_frames(np.uint8, 8), alpha=[0, 1], beta=[2, 3], bit_depth=8)
    io.save_frames(cube, tmp_path / name)
    with io.open_frames(tmp_path / name) as back:
        assert back.frames.dtype == np.uint8
        xr.testing.assert_identical(back.load(), cube)


def test_lazy_cube_writes_with_progress_on(tmp_path, capsys):
    zeros = da.zeros((NP, NS, NY, NX), dtype=np.uint16, chunks=(1, 1, NY, NX))
    cube = schema.frames_dataset(zeros, alpha=[0, 1], beta=[0, 0])
    cube["frames"] = cube.frames + np.uint16(3)
    cube["true_x"] = cube.alpha.chunk(pose=1) + xr.zeros_like(cube.shot, dtype=float)
    assert cube.true_x.dims == ("pose", "shot") and cube.true_x.chunks is not None
    io.save_frames(cube, tmp_path / "lazy.zarr", progress=True)
    said = capsys.readouterr()
    # not a terminal: plain lines only, and none for a write shorter than a second
    assert "\r" not in said.out + said.err
    back = io.open_frames(tmp_path / "lazy.zarr")
    assert int(back.frames.min()) == int(back.frames.max()) == 3
    # One chunk file per frame on disk.
    assert len(list((tmp_path / "lazy.zarr" / "frames" / "c").rglob("*"))) >= NP * NS
    zarr_frames = zarr.open_array(tmp_path / "lazy.zarr" / "frames", mode="r")
    assert zarr_frames.nchunks_initialized == NP * NS
    # Per-pose lazy metadata (ground truth) is not split into one file per pose.
    assert zarr.open_array(tmp_path / "lazy.zarr" / "true_x", mode="r").nchunks == 1


@pytest.mark.parametrize("name", ["cen.zarr", "cen.nc"])
def test_centroids_round_trip_is_exact(tmp_path, centroids, name):
    io.save_centroids(centroids, tmp_path / name)
    back = io.open_centroids(tmp_path / name)
    xr.testing.assert_identical(back, centroids)
    assert back.status.dtype == np.int8
    assert back.status.attrs["flag_values"].dtype == np.int8
    assert back.attrs["clipped_ok"] is False


@pytest.mark.parametrize("name", ["cube.zarr", "cube.nc"])
def test_open_frames_opens_frames_lazily(tmp_path, cube, name):
    io.save_frames(cube, tmp_path / name)
    with io.open_frames(tmp_path / name) as back:
        assert back.attrs["sunlab_schema"] == "frames/1"
        assert back.frames.chunks is not None


def test_overwrite(tmp_path, cube):
    io.save_frames(cube, tmp_path / "c.zarr")
    with pytest.raises(SunlabError, match="already exists.*overwrite=True"):
        io.save_frames(cube, tmp_path / "c.zarr")
    cube2 = cube.copy()
    cube2["frames"] = cube.frames // 2
    io.save_frames(cube2, tmp_path / "c.zarr", overwrite=True)
    assert_array_equal(io.open_frames(tmp_path / "c.zarr").frames, cube.frames.values // 2)


def test_overwrite_refuses_to_delete_a_plain_directory(tmp_path, cube):
    (tmp_path / "notes").mkdir()
    (tmp_path / "notes" / "keep.txt").write_text("x")
    with pytest.raises(SunlabError, match="not a Zarr store.*will not delete"):
        io.save_frames(cube, tmp_path / "notes", overwrite=True)
    assert (tmp_path / "notes" / "keep.txt").exists()


# ------------------------------------------------------------------------------------------
# Image folders
# ------------------------------------------------------------------------------------------
def _write_image(path, frame):
    if path.suffix == ".png":
        Image.fromarray(frame).save(path)
    else:
        tifffile.imwrite(path, frame)


def _folder(tmp_path, suffix=".png", dtype=np.uint16, bits=10, extra=True):
    """Frames for poses (5, -2) then (0, 0), rows in shuffled shot order; returns truth."""
    folder = tmp_path / "frames"
    folder.mkdir()
    truth = _frames(dtype, bits, seed=3)
    truth[0, 0, 0, 0] = 2**bits - 1  # the top DN is present, so the depth can be detected
    poses = [(5.0, -2.0), (0.0, 0.0)]
    header = "file,alpha,beta,shot" + (",temperature_C,note,time" if extra else "")
    lines = [header]
    for p, s in [(0, 1), (1, 0), (0, 0), (1, 1)]:
        name = f"img_{p}_{s}{suffix}"
        _write_image(folder / name, truth[p, s])
        row = f"{name},{poses[p][0]:g},{poses[p][1]:g},{s}"
        if extra:
            row += f",{20 + p + 0.1 * s},{'dark' if s else 'lit'},2005-06-01T12:0{p}:0{s}"
        lines.append(row)
    (folder / "manifest.csv").write_text("\n".join(lines) + "\n")
    return folder, truth


@pytest.mark.parametrize(
    ("suffix", "dtype", "bits"),
    [(".png", np.uint8, 8), (".png", np.uint16, 10),
     (".tif", np.uint8, 8), (".tif", np.uint16, 10)],
)
@pytest.mark.parametrize("lazy", [True, False])
def test_open_frames_of_an_image_folder(tmp_path, suffix, dtype, bits, lazy):
    folder, truth = _folder(tmp_path, suffix, dtype, bits)
    cube = io.open_frames(folder, lazy=lazy, experiment="II")
    assert cube.frames.dtype == dtype
    assert cube.attrs["bit_depth"] == bits  # detected: 8-bit files, or 10-bit data in 16 bits
    assert (cube.frames.chunks is not None) == lazy
    assert_array_equal(cube.frames.values, truth)
    assert cube.alpha.values.tolist() == [5.0, 0.0]  # manifest order, not sorted
    assert cube.beta.values.tolist() == [-2.0, 0.0]
    assert cube.file.values.tolist() == [[f"img_0_0{suffix}", f"img_0_1{suffix}"],
                                         [f"img_1_0{suffix}", f"img_1_1{suffix}"]]
    assert cube.temperature_C.dims == ("pose", "shot")
    assert_array_equal(cube.temperature_C.values, [[20.0, 20.1], [21.0, 21.1]])
    assert cube.note.values.tolist() == [["lit", "dark"], ["lit", "dark"]]
    assert cube.time.dtype == np.dtype("datetime64[ns]")
    assert cube.time.values[1, 1] == np.datetime64("2005-06-01T12:01:01")
    assert cube.attrs["experiment"] == "II"
    assert "shot_label" not in cube.coords


def test_image_folder_cube_round_trips_through_zarr(tmp_path):
    folder, truth = _folder(tmp_path, ".tif")
    cube = io.open_frames(folder, bit_depth=10, pixel_pitch_mm=0.007, mask="single")
    io.save_frames(cube, tmp_path / "c.zarr")
    back = io.open_frames(tmp_path / "c.zarr").load()
    xr.testing.assert_identical(back, cube.load())
    assert back.file.dtype == object and back.note.dtype == object


def test_shot_labels_kept_when_not_zero_based(tmp_path):
    folder = tmp_path / "f"
    folder.mkdir()
    rows = ["file,alpha,beta,shot"]
    for s in (1, 2):
        tifffile.imwrite(folder / f"s{s}.tif", np.full((3, 4), s, np.uint16))
        rows.append(f"s{s}.tif,0,0,{s}")
    (folder / "list.csv").write_text("\n".join(rows))
    cube = io.open_frames(folder, "list.csv", bit_depth=10)
    assert cube.shot.values.tolist() == [0, 1]
    assert cube.shot_label.values.tolist() == [1, 2]
    assert cube.frames.values[0, :, 0, 0].tolist() == [1, 2]


# ------------------------------------------------------------------------------------------
# Bad input: every error names the field and the fix
# ------------------------------------------------------------------------------------------
def _edit_manifest(folder, old, new):
    path = folder / "manifest.csv"
    path.write_text(path.read_text().replace(old, new, 1))


def test_missing_manifest_column(tmp_path):
    folder, _ = _folder(tmp_path, extra=False)
    _edit_manifest(folder, "file,alpha,beta,shot", "file,alpha,beta,frame")
    with pytest.raises(SchemaError, match=r"columns \['shot'\].*Fix: add them: file") as err:
        io.open_frames(folder)
    assert "frame" in str(err.value.found)


def test_manifest_row_for_missing_file(tmp_path):
    folder, _ = _folder(tmp_path)
    (folder / "img_1_0.png").unlink()
    with pytest.raises(SchemaError, match="line 3 column 'file'") as err:
        io.open_frames(folder)
    assert err.value.found == "img_1_0.png"
    assert "copy them into the folder or remove their rows" in err.value.fix


def test_image_of_the_wrong_shape(tmp_path):
    folder, _ = _folder(tmp_path)
    Image.fromarray(np.zeros((NY, NX + 1), np.uint16)).save(folder / "img_1_1.png")
    with pytest.raises(SchemaError, match=r"image img_1_1.png.*shape \(16, 21\)") as err:
        io.open_frames(folder)
    assert "same size" in err.value.fix
    assert "(16, 20)" in err.value.expected


def test_duplicate_pose_and_shot(tmp_path):
    folder, _ = _folder(tmp_path, extra=False)
    _edit_manifest(folder, "img_0_0.png,5,-2,0", "img_0_0.png,5,-2,1")
    with pytest.raises(SchemaError, match=r"line 4.*shot=1 again \(first on line 2\)") as err:
        io.open_frames(folder)
    assert "remove the duplicate row" in err.value.fix


def test_non_numeric_angle(tmp_path):
    folder, _ = _folder(tmp_path, extra=False)
    _edit_manifest(folder, "img_1_0.png,0,0,0", "img_1_0.png,zero,0,0")
    with pytest.raises(SchemaError, match="line 3 column 'alpha'") as err:
        io.open_frames(folder)
    assert err.value.found == "zero"
    assert "finite number of degrees" in err.value.expected
    assert "correct the value" in err.value.fix


def test_incomplete_pose(tmp_path):
    folder, _ = _folder(tmp_path, extra=False)
    path = folder / "manifest.csv"
    path.write_text("\n".join(line for line in path.read_text().splitlines()
                              if not line.startswith("img_1_1")))
    with pytest.raises(SchemaError, match=r"pose alpha=0, beta=0.*shots \[0\]") as err:
        io.open_frames(folder)
    assert "add rows for shot(s) [1]" in err.value.fix


def test_float_images_are_rejected(tmp_path):
    folder, truth = _folder(tmp_path, ".tif", extra=False)
    tifffile.imwrite(folder / "img_0_1.tif", truth[0, 1].astype(np.float32))
    with pytest.raises(SchemaError, match="image img_0_1.tif.*pixel type float32") as err:
        io.open_frames(folder)
    assert "8- or 16-bit unsigned" in err.value.fix


def test_rgb_png_is_rejected(tmp_path):
    folder, _ = _folder(tmp_path, ".png", np.uint8, 8, extra=False)
    Image.fromarray(np.zeros((NY, NX, 3), np.uint8)).save(folder / "img_0_0.png")
    with pytest.raises(SchemaError, match="PNG mode 'RGB'") as err:
        io.open_frames(folder)
    assert "grayscale" in err.value.fix


def test_int32_frames_are_rejected():
    with pytest.raises(SchemaError, match="frames.dtype: found 'int32'") as err:
        schema.frames_dataset(np.zeros((1, 1, 2, 2), np.int32), alpha=[0], beta=[0])
    assert "astype(np.uint16)" in err.value.fix


def test_bit_depth_too_small_for_the_data(tmp_path):
    folder, _ = _folder(tmp_path, ".tif", extra=False)
    with pytest.raises(SchemaError, match=r"maximum 1023 DN.*< 2\*\*8 = 256") as err:
        io.open_frames(folder, bit_depth=8, lazy=False)
    assert "true bit_depth" in err.value.fix
    # Lazily, the same check runs when the frame is read, naming the file.
    cube = io.open_frames(folder, bit_depth=8, lazy=True)
    with pytest.raises(SchemaError, match=r"image img_\d_\d.tif: found .maximum"):
        cube.frames.compute()


def test_empty_folder(tmp_path):
    with pytest.raises(SchemaError, match="folder: found .*no images, no manifest") as err:
        io.open_frames(tmp_path)
    assert "acquire them first" in err.value.fix


def test_images_without_manifest(tmp_path):
    folder, _ = _folder(tmp_path)
    (folder / "manifest.csv").unlink()
    with pytest.raises(SchemaError, match=r"manifest: found 'no manifest.csv .*\(4 images") as err:
        io.open_frames(folder)
    assert "write manifest.csv" in err.value.fix


def test_store_without_frames(tmp_path, cube):
    cube.drop_vars("frames").to_zarr(tmp_path / "bad.zarr", zarr_format=3, consolidated=False)
    with pytest.raises(SchemaError, match=r"frames: found .missing \(variables") as err:
        io.open_frames(tmp_path / "bad.zarr")
    assert "pose', 'shot', 'y', 'x'" in err.value.expected
    assert "open_centroids" in err.value.fix


@pytest.mark.parametrize("name", ["c.zarr", "c.nc"])
def test_wrong_schema_version(tmp_path, cube, name):
    # As a newer sunlab would write it: the same layout under another contract version.
    io.save_frames(cube, tmp_path / name)
    if name.endswith(".zarr"):
        zarr.open_group(tmp_path / name, mode="r+").attrs["sunlab_schema"] = "frames/2"
    else:
        with h5netcdf.File(tmp_path / name, "r+") as f:
            f.attrs["sunlab_schema"] = "frames/2"
    # which the newer sunlab seals with its checksum (sunlab.integrity)
    (integrity.seal_zarr if name.endswith(".zarr") else integrity.seal_netcdf)(tmp_path / name)
    with pytest.raises(SchemaError, match="found 'frames/2', expected 'frames/1'") as err:
        io.open_frames(tmp_path / name)
    assert "holds version '2'" in err.value.fix and "upgrade sunlab" in err.value.fix
    with pytest.raises(SchemaError, match="found 'frames/2', expected 'frames/1'") as err:
        io.summary(tmp_path / name)  # `sunlab info` opens by the contract the file names


def test_missing_chunk_is_detected(tmp_path, cube):
    io.save_frames(cube, tmp_path / "c.zarr")
    chunk = tmp_path / "c.zarr" / "frames" / "c" / "1" / "0" / "0" / "0"
    assert chunk.is_file()
    chunk.unlink()
    with pytest.raises(SchemaError, match=r"frames chunks: found '1 of 4 chunk files") as err:
        io.open_frames(tmp_path / "c.zarr")
    assert str(chunk) in str(err.value)
    assert "check_chunks=False" in err.value.fix
    with io.open_frames(tmp_path / "c.zarr", check_chunks=False) as partial:
        assert int(partial.frames[1, 0].max()) == 0  # a missing chunk reads as 0 DN


def test_all_zero_frames_are_still_written(tmp_path):
    cube = schema.frames_dataset(np.zeros((NP, NS, NY, NX), np.uint16), alpha=[0, 1], beta=[0, 0])
    io.save_frames(cube, tmp_path / "dark.zarr")
    # zarr skips chunks equal to the fill value unless told not to: one file per frame here
    chunk_files = [p for p in (tmp_path / "dark.zarr" / "frames").rglob("*")
                   if p.is_file() and p.name != "zarr.json"]
    assert len(chunk_files) == NP * NS
    with io.open_frames(tmp_path / "dark.zarr") as back:  # check_chunks finds every one
        assert int(back.frames.max()) == 0 and back.frames.shape == (NP, NS, NY, NX)


def test_garbled_zarr_metadata(tmp_path, cube):
    io.save_frames(cube, tmp_path / "c.zarr")
    meta = tmp_path / "c.zarr" / "frames" / "zarr.json"
    meta.write_text(meta.read_text()[:40])
    with pytest.raises(SunlabError, match="frames/zarr.json: corrupt Zarr metadata") as err:
        io.open_frames(tmp_path / "c.zarr")
    assert "Fix: restore this file" in str(err.value)


def test_store_without_root_metadata(tmp_path, cube):
    io.save_frames(cube, tmp_path / "c.zarr")
    (tmp_path / "c.zarr" / "zarr.json").unlink()
    with pytest.raises(SunlabError, match="not a Zarr store.*Fix"):
        io.open_frames(tmp_path / "c.zarr")


def test_truncated_netcdf(tmp_path, cube):
    io.save_frames(cube, tmp_path / "c.nc")
    data = (tmp_path / "c.nc").read_bytes()
    (tmp_path / "c.nc").write_bytes(data[: len(data) // 2])
    with pytest.raises(SunlabError, match=r"c.nc: cannot be read as NetCDF4.*truncated") as err:
        io.open_frames(tmp_path / "c.nc")
    assert "copy it again" in str(err.value)


def test_not_a_dataset_file(tmp_path):
    (tmp_path / "x.nc").write_text("hello")
    with pytest.raises(SunlabError, match="neither a Zarr store .* nor a NetCDF4"):
        io.open_frames(tmp_path / "x.nc")
    with pytest.raises(SunlabError, match="no such file or directory"):
        io.open_centroids(tmp_path / "missing.zarr")


def test_attribute_that_cannot_be_stored(tmp_path, cube):
    cube.attrs["callback"] = object()
    with pytest.raises(SchemaError, match=r"attrs\['callback'\]") as err:
        io.save_frames(cube, tmp_path / "c.zarr")
    assert "convert the attribute" in err.value.fix
    assert not (tmp_path / "c.zarr").exists()


def test_bad_chunking_option(tmp_path, cube):
    with pytest.raises(SchemaError, match="chunks: found 'shot'"):
        io.save_frames(cube, tmp_path / "c.zarr", chunks="shot")


# ------------------------------------------------------------------------------------------
# Summary and the command line
# ------------------------------------------------------------------------------------------
def test_summary_of_a_cube(cube):
    text = io.summary(cube)
    for part in ("sunlab frame cube (frames/1)", "pose=2, shot=2, y=16, x=20", "uint16 DN",
                 "10-bit", "alpha: -1 .. 1 deg (2 distinct)", "beta:  0.5 .. 0.5 deg (1 distinct)",
                 "pixel pitch 0.007 mm", "experiment: 'I'", "alpha_read: dims ('pose', 'shot')"):
        assert part in text, part


def test_summary_of_centroids(centroids):
    text = io.summary(centroids)
    assert "sunlab centroid table (centroids/1)" in text
    assert "status (8 spots): ok 5 (62.5 %), no_spot 2 (25.0 %), saturated 1 (12.5 %)" in text
    assert "method: projection_window" in text
    assert "dims: pose=2, shot=2, hole=2" in text


def test_cli_info(tmp_path, cube, centroids, capsys):
    io.save_frames(cube, tmp_path / "c.zarr")
    io.save_centroids(centroids, tmp_path / "cen.nc")
    assert main(["info", str(tmp_path / "c.zarr")]) == 0
    out = capsys.readouterr().out
    assert "sunlab frame cube (frames/1)" in out and "chunks (1, 1, 16, 20) (lazy)" in out
    assert str(tmp_path / "c.zarr") in out
    assert main(["info", str(tmp_path / "cen.nc")]) == 0
    assert "ok 5 (62.5 %)" in capsys.readouterr().out


def test_cli_info_describes_an_incomplete_store(tmp_path, cube, capsys):
    io.save_frames(cube, tmp_path / "c.zarr")
    shutil.rmtree(tmp_path / "c.zarr" / "frames" / "c" / "0")
    assert main(["info", str(tmp_path / "c.zarr")]) == 0
    out = capsys.readouterr().out
    assert "INCOMPLETE: frames: 2 of 4 chunk files missing" in out
    assert str(tmp_path / "c.zarr" / "frames" / "c" / "0" / "0" / "0" / "0") in out


def test_cli_info_reports_errors(tmp_path, capsys):
    (tmp_path / "c.nc").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    assert main(["info", str(tmp_path / "c.nc")]) == 1
    err = capsys.readouterr().err
    assert "sunlab info: error:" in err and "c.nc: cannot be read as NetCDF4" in err
    assert main(["info", str(tmp_path / "nothing.zarr")]) == 1
    assert "no such file or directory" in capsys.readouterr().err


def test_codec_attribute_is_plain_json(tmp_path, cube):
    """Other readers see the encoded attributes as documented text."""
    io.save_frames(cube, tmp_path / "c.zarr")
    attrs = json.loads((tmp_path / "c.zarr" / "zarr.json").read_text())["attributes"]
    codec = json.loads(attrs["sunlab_attr_codec"])
    assert codec["simulated"] == "json" and attrs["simulated"] == "true"
    assert codec["window_px"] == "tuple"
    assert codec["weights"] == {"ndarray": "|i1", "shape": [2, 2]}
