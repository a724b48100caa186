"""Calibration frames that do not fit the frames they correct (issue 37): each is refused with
one line naming the frames and the fix, or flagged in the cube, never averaged in silently."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from sunlab import cli, io, schema
from sunlab.errors import SchemaError

NY, NX = 12, 16


def _cube(bits: int = 10):
    raw = np.full((1, 1, NY, NX), 300, np.uint16)
    return schema.frames_dataset(raw, alpha=[0.0], beta=[0.0], bit_depth=bits)


def _pngs(folder: Path, frames) -> Path:
    folder.mkdir()
    for k, frame in enumerate(frames):
        Image.fromarray(frame).save(folder / f"c{k}.png")
    return folder


def _recording(root: Path) -> Path:
    imgs = root / "imgs"
    imgs.mkdir()
    rows = ["file,alpha,beta,shot"]
    for k in range(2):
        Image.fromarray(np.full((NY, NX), 200 + k, np.uint16)).save(imgs / f"f{k}.png")
        rows.append(f"f{k}.png,{k},0,0")
    (imgs / "manifest.csv").write_text("\n".join(rows) + "\n")
    (imgs / "sensor.json").write_text('{"bit_depth": 10}')
    return imgs


def _tree(root: Path) -> dict:
    return {p.relative_to(root).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(root.rglob("*")) if p.is_file()}


def test_a_dark_and_a_flat_of_different_shapes_are_refused_naming_the_flats():
    with pytest.raises(SchemaError, match=r"flat frames.*shape \(12, 8\).*cube's \(12, 16\)"):
        io.with_calibration_frames(_cube(), dark=np.full((2, NY, NX), 10, np.uint16),
                                   flat=np.full((2, NY, NX // 2), 500, np.uint16))


def test_master_flat_refuses_an_offset_of_another_shape():
    with pytest.raises(SchemaError, match=r"flat offset.*shape \(3, 3\)"):
        io.calframes.master_flat(np.full((2, 4, 4), 500.0), offset=np.zeros((3, 3)))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_master_that_is_not_finite_is_refused_naming_the_pixel(bad):
    dark = np.full((NY, NX), 10.0)
    dark[3, 5] = bad
    with pytest.raises(SchemaError, match=r"dark: found '1 value\(s\) that are not finite "
                                          r"\(first .* at frame 0, row 3, column 5\)"):
        io.with_calibration_frames(_cube(), dark=dark)


def test_eight_bit_darks_are_refused_on_sixteen_bit_frames():
    with pytest.raises(SchemaError, match=r"dark frames.*pixel type uint8.*uint16 like the "
                                          r"cube's frames \(10-bit DN\)"):
        io.with_calibration_frames(_cube(), dark=np.full((2, NY, NX), 10, np.uint8))


def test_the_command_refuses_mismatched_calibration_frames_and_writes_nothing(tmp_path, capsys):
    imgs = _recording(tmp_path)
    _pngs(tmp_path / "dark8", [np.full((NY, NX), 40, np.uint8)] * 2)
    _pngs(tmp_path / "dark", [np.full((NY, NX), 40, np.uint16)] * 2)
    _pngs(tmp_path / "flat", [np.full((NY, NX // 2), 600, np.uint16)] * 2)
    before = _tree(tmp_path)
    for extra, said in ((["--dark", "dark8"], "pixel type uint8"),
                        (["--dark", "dark", "--flat", "flat"], "shape (12, 8)")):
        status = cli.main(["import", str(imgs), "--out", str(tmp_path / "cube.zarr"),
                           "--no-progress", *[str(tmp_path / a) if a in ("dark8", "dark", "flat")
                                              else a for a in extra]])
        err = capsys.readouterr().err.strip()
        assert status == 1
        assert len(err.splitlines()) == 1 and said in err and "Fix:" in err
        assert _tree(tmp_path) == before and not (tmp_path / "cube.zarr").exists()


def test_a_flat_pixel_clipped_at_full_scale_reads_as_saturated_and_is_counted():
    flats = np.full((3, NY, NX), 600, np.uint16)
    flats[1, 4, 7] = 1023  # clipped in one flat frame only: its median would hide it
    cube = io.with_calibration_frames(_cube(), dark=np.full((2, NY, NX), 100, np.uint16),
                                      flat=flats)
    prov = cube.attrs["calibration_frames"]["flat"]
    assert prov["clipped_pixels"] == 1 and prov["first_clipped"] == [4, 7]
    corrected = io.calframes.corrected_frames(cube).values
    assert corrected[0, 0, 4, 7] == io.calframes.corrected_saturation(cube)
    assert np.isfinite(io.calframes.corrected_saturation(cube))
    np.testing.assert_array_equal(np.delete(corrected.ravel(), 4 * NX + 7), 200.0)


def test_flats_clipped_over_much_of_the_frame_are_refused():
    flats = np.full((2, NY, NX), 1023, np.uint16)
    with pytest.raises(SchemaError, match=r"flat frames.*192 of 192 pixels at full scale.*"
                                          r"expose the flats shorter"):
        io.with_calibration_frames(_cube(), flat=flats)


def test_the_import_says_how_many_flat_pixels_were_clipped(tmp_path, capsys):
    imgs = _recording(tmp_path)
    flats = [np.full((NY, NX), 600, np.uint16) for _ in range(2)]
    flats[0][2, 3] = 1023
    _pngs(tmp_path / "flat", flats)
    status = cli.main(["import", str(imgs), "--out", str(tmp_path / "cube.zarr"),
                       "--no-progress", "--flat", str(tmp_path / "flat")])
    out = capsys.readouterr().out
    assert status == 0
    assert "warning: 1 pixel(s) of the flats at full scale (first at row 2, column 3)" in out
    cube = io.open_frames(tmp_path / "cube.zarr")
    assert cube.attrs["calibration_frames"]["flat"]["clipped_pixels"] == 1
    assert np.isnan(cube["master_flat"].values[2, 3])
