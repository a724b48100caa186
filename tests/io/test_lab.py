"""A lab's own folder: sensor.json checked field by field, manifest paths kept inside the
folder, TIFF pages, left-aligned data, calibration frames, implausible fits flagged."""

import json

import dask.array as da
import numpy as np
import pandas as pd
import pytest
import tifffile
from PIL import Image

from sunlab import SchemaError, io, schema, sim
from sunlab.cli import main


def _folder(tmp_path, rows, frames, name="frames"):
    """A folder with the given frames (file name -> array) and manifest rows."""
    folder = tmp_path / name
    folder.mkdir()
    for fname, arr in frames.items():
        if fname.endswith(".png"):
            Image.fromarray(arr).save(folder / fname)
        else:
            tifffile.imwrite(folder / fname, arr, photometric="minisblack")
    (folder / "manifest.csv").write_text("\n".join(rows) + "\n")
    return folder


@pytest.mark.parametrize("doc, field, words", [
    ({"pixel_pitch_mm": "0.007"}, "pixel_pitch_mm", "without quotes"),
    ({"mask_distance_mm": -5}, "mask_distance_mm", "a number > 0"),
    ({"bit_depth": 20}, "bit_depth", "an integer 8 .. 16"),
    ({"bit_depth": 12.5}, "bit_depth", "an integer 8 .. 16"),
    ({"left_aligned": "yes"}, "left_aligned", "true or false"),
    ({"x_cf_px": None}, "x_cf_px", "a finite number"),
    ({"mask": 3}, "mask", "a string"),
])
def test_every_sensor_json_field_is_checked_by_name(tmp_path, doc, field, words):
    path = tmp_path / "sensor.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=words) as err:
        io.sensor.read_sensor_json(path)
    assert err.value.field == f"sensor.json field {field!r}"


def test_sensor_json_refuses_unknown_keys_and_names_the_place_for_extras(tmp_path):
    path = tmp_path / "sensor.json"
    path.write_text(json.dumps({"pixel_pitch": 0.007}))
    with pytest.raises(SchemaError, match="extra attributes go under 'attrs'"):
        io.sensor.read_sensor_json(path)


@pytest.mark.parametrize("name", ["../outside.png", "/etc/hostname", "sub/../../x.png"])
def test_manifest_paths_stay_inside_the_folder(tmp_path, name):
    (tmp_path / "outside.png").write_bytes(b"")
    folder = _folder(tmp_path, ["file,alpha,beta,shot", f"{name},0,0,0"],
                     {"a.png": np.zeros((8, 8), np.uint16)})
    with pytest.raises(SchemaError, match="inside it") as err:
        io.open_frames(folder)
    assert "line 2 column 'file'" in err.value.field


def test_one_image_per_pose_and_shot(tmp_path):
    stack = np.zeros((2, 8, 8), np.uint16)
    rows = ["file,alpha,beta,shot,page", "s.tif,0,0,0,0", "s.tif,0,0,1,1", "s.tif,1,0,0,1"]
    folder = _folder(tmp_path, rows, {"s.tif": stack})
    with pytest.raises(SchemaError, match="page 1 again.*first on line 3"):
        io.open_frames(folder)
    rows = ["file,alpha,beta,shot", "a.png,0,0,0", "a.png,1,0,0"]
    folder = _folder(tmp_path, rows, {"a.png": np.zeros((8, 8), np.uint16)}, "png")
    with pytest.raises(SchemaError, match="one image per"):
        io.open_frames(folder)


def test_tiff_stack_pages_are_the_shots_of_a_pose(tmp_path):
    stacks = {f"pose{p}.tif": (100 * p + np.arange(3)[:, None, None]
                               + np.zeros((3, 6, 7))).astype(np.uint16) for p in range(2)}
    rows = ["file,alpha,beta,shot,page"] + [f"pose{p}.tif,{p},0,{s},{2 - s}"
                                            for p in range(2) for s in range(3)]
    cube = io.open_frames(_folder(tmp_path, rows, stacks), bit_depth=10)
    assert dict(cube.sizes) == {"pose": 2, "shot": 3, "y": 6, "x": 7}
    assert cube.frames[:, :, 0, 0].values.tolist() == [[2, 1, 0], [102, 101, 100]]
    assert cube.page.values.tolist() == [[2, 1, 0], [2, 1, 0]]


def test_a_page_beyond_the_stack_names_the_line(tmp_path):
    rows = ["file,alpha,beta,shot,page", "s.tif,0,0,0,0", "s.tif,0,0,1,5"]
    folder = _folder(tmp_path, rows, {"s.tif": np.zeros((2, 8, 8), np.uint16)})
    with pytest.raises(SchemaError, match="a page 0 .. 1 of s.tif") as err:
        io.open_frames(folder)
    assert err.value.field == "manifest manifest.csv line 3 column 'page'"


def test_a_stack_without_a_page_column_says_how(tmp_path):
    folder = _folder(tmp_path, ["file,alpha,beta,shot", "s.tif,0,0,0"],
                     {"s.tif": np.zeros((2, 8, 8), np.uint16)})
    with pytest.raises(SchemaError, match="add a 'page' column"):
        io.open_frames(folder)


def test_left_aligned_frames_are_shifted_and_checked(tmp_path):
    frame = (np.arange(64).reshape(8, 8) * 60).astype(np.uint16)  # 12-bit DN
    folder = _folder(tmp_path, ["file,alpha,beta,shot", "a.png,0,0,0"],
                     {"a.png": (frame << 4).astype(np.uint16)})
    cube = io.open_frames(folder, bit_depth=12, left_aligned=True, lazy=False)
    assert np.array_equal(cube.frames[0, 0].values, frame)
    assert cube.attrs["left_aligned"] is True
    with pytest.raises(SchemaError, match="bit depth for left-aligned"):
        io.open_frames(folder, left_aligned=True)
    right = _folder(tmp_path, ["file,alpha,beta,shot", "a.png,0,0,0"], {"a.png": frame + 1},
                    "right")  # right-aligned data said to be left-aligned: low bits set
    with pytest.raises(SchemaError, match="not multiples of 16"):
        io.open_frames(right, bit_depth=12, left_aligned=True, lazy=False)


def test_masters_are_medians_and_the_flat_is_normalised(tmp_path):
    rng = np.random.default_rng(0)
    offset = rng.uniform(50, 80, (6, 8))
    response = rng.uniform(0.9, 1.1, (6, 8))
    darks = np.rint(offset + rng.normal(0, 1, (5, 6, 8))).astype(np.uint16)
    darks[2, 3, 3] = 1000  # a cosmic ray in one dark: the median ignores it
    flats = np.rint(offset + 800 * response).astype(np.uint16)[None].repeat(3, axis=0)
    raw = np.rint(offset + 400 * response).astype(np.uint16)[None, None]
    cube = schema.frames_dataset(raw, alpha=[0.0], beta=[0.0])
    cube = io.with_calibration_frames(cube, dark=darks, flat=flats)
    np.testing.assert_allclose(cube.master_dark.values, np.median(darks, axis=0))
    assert float(np.median(cube.master_flat.values)) == pytest.approx(1.0)
    corrected = io.calframes.corrected_frames(cube).values[0, 0]
    # (raw - dark) / flat is uniform: 400 DN x the median response, to the rounding of the DN
    np.testing.assert_allclose(corrected, np.median(400 * response), rtol=0.01)


def test_correction_is_lazy_and_keeps_saturation_recognisable():
    raw = np.full((2, 1, 8, 8), 500, np.uint16)
    raw[1, 0, 4, 4] = 1023  # at the 10-bit full scale
    cube = schema.frames_dataset(da.from_array(raw, chunks=(1, 1, 8, 8)), alpha=[0.0, 1.0],
                                 beta=[0.0, 0.0], bit_depth=10)
    flat = np.full((8, 8), 1.0)
    flat[:, :4] = 0.5
    cube = io.with_calibration_frames(cube, dark=np.full((8, 8), 100), flat=flat * 1000)
    out = io.calframes.corrected_frames(cube)
    assert isinstance(out.data, da.Array)
    values = out.values
    level = io.calframes.corrected_saturation(cube)
    assert values[1, 0, 4, 4] == level
    unsaturated = np.delete(values.ravel(), np.ravel_multi_index((1, 0, 4, 4), values.shape))
    assert unsaturated.max() < level  # (1022 - 100) / 0.5 would not reach it either


def test_a_master_of_another_size_is_refused():
    cube = schema.frames_dataset(np.zeros((1, 1, 8, 8), np.uint16), alpha=[0.0], beta=[0.0])
    with pytest.raises(SchemaError, match="take the dark frames with the camera's settings"):
        io.with_calibration_frames(cube, dark=np.zeros((2, 8, 9)))


def test_a_flat_below_the_dark_is_refused():
    with pytest.raises(SchemaError, match="expose the flats longer"):
        io.calframes.master_flat(np.full((2, 4, 4), 100.0), offset=np.full((4, 4), 100.0))


def test_masters_survive_a_save_and_are_applied_by_locate(tmp_path):
    yy, xx = np.mgrid[0:64, 0:80]
    offset = 100 + 2.0 * xx  # a steep dark ramp
    spot = 400 * (np.hypot(xx - 40.3, yy - 30.6) < 8)
    raw = np.rint(offset + spot).astype(np.uint16)[None, None]
    cube = schema.frames_dataset(raw, alpha=[0.0], beta=[0.0])
    cube = io.with_calibration_frames(cube, dark=np.rint(offset)[None].astype(np.uint16))
    path = tmp_path / "c.zarr"
    io.save_frames(cube, path)
    back = io.open_frames(path)
    assert back.attrs["calibration_frames"]["dark"]["n_frames"] == 1
    from sunlab import centroid

    cen = centroid.locate(back, "projection", progress=False)
    assert int(cen.status[0, 0]) == 0
    assert abs(float(cen.x[0, 0]) - 40.3) < 0.05 and abs(float(cen.y[0, 0]) - 30.6) < 0.05


def test_implausible_fits_are_flagged_by_calibrate_and_evaluate(tmp_path, capsys):
    a, b = np.meshgrid([-8.0, 0.0, 8.0], [-8.0, 0.0, 8.0], indexing="ij")
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), 1)  # F 5 mm
    csv = tmp_path / "train.csv"
    pd.DataFrame({"alpha": cen.alpha.values, "beta": cen.beta.values,
                  "x": cen.x.values[:, 0], "y": cen.y.values[:, 0]}).to_csv(csv, index=False)
    (tmp_path / "sensor.json").write_text(json.dumps(
        {"mask_distance_mm": 10.0, "pixel_pitch_mm": 0.007, "x_cf_px": 639.5, "y_cf_px": 511.5}))
    out = tmp_path / "ideal.json"
    assert main(["calibrate", str(csv), "--method", "ideal", "--out", str(out)]) == 0
    said = capsys.readouterr().out
    assert "warning: implausible fit: ideal model" in said and "mask_distance_mm" in said
    assert main(["evaluate", str(out), str(csv)]) == 0
    assert "warning: implausible: mean error of alpha" in capsys.readouterr().out
    poly = tmp_path / "poly.json"
    assert main(["calibrate", str(csv), "--method", "polynomial", "--order", "2", "--out",
                 str(poly)]) == 0
    assert "warning: implausible" not in capsys.readouterr().out


def test_bias_alone_is_subtracted_and_a_dark_takes_its_place(tmp_path):
    raw = np.full((1, 1, 4, 4), 300, np.uint16)
    cube = schema.frames_dataset(raw, alpha=[0.0], beta=[0.0])
    only_bias = io.with_calibration_frames(cube, bias=np.full((3, 4, 4), 40))
    assert float(io.calframes.corrected_frames(only_bias)[0, 0, 0, 0]) == 260.0
    both = io.with_calibration_frames(cube, bias=np.full((3, 4, 4), 40),
                                      dark=np.full((3, 4, 4), 70))
    # a dark taken at the frames' exposure holds the bias: subtracted once, not twice
    assert float(io.calframes.corrected_frames(both)[0, 0, 0, 0]) == 230.0
    assert sorted(both.attrs["calibration_frames"]) == ["bias", "dark"]


def test_a_stack_file_or_a_folder_of_stacks_and_images_are_calibration_frames(tmp_path):
    stack = np.arange(3 * 4 * 5, dtype=np.uint16).reshape(3, 4, 5)
    tifffile.imwrite(tmp_path / "dark.tif", stack, photometric="minisblack")
    assert np.array_equal(io.calframes.read_stack(tmp_path / "dark.tif"), stack)
    folder = tmp_path / "darks"
    folder.mkdir()
    tifffile.imwrite(folder / "a.tif", stack, photometric="minisblack")
    Image.fromarray(stack[0]).save(folder / "b.png")
    assert io.calframes.read_stack(folder).shape == (4, 4, 5)  # 3 pages + 1 image
    with pytest.raises(SchemaError, match="an existing folder or TIFF stack"):
        io.calframes.read_stack(tmp_path / "missing")
