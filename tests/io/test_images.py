"""One frame from an image file (sunlab.io.images): PNG and TIFF, 8 and 16 bits, TIFF stacks,
left-aligned cameras; every bad file ends in one error naming it."""

import numpy as np
import pytest
import tifffile
from PIL import Image

from sunlab.errors import SchemaError
from sunlab.io.images import IMAGE_SUFFIXES, read_image

RNG = np.random.default_rng(3)
FRAME = RNG.integers(0, 1024, (6, 5), dtype=np.uint16)  # 10-bit DN, rows != columns


def test_suffixes_are_png_and_tiff():
    assert set(IMAGE_SUFFIXES) == {".png", ".tif", ".tiff"}


@pytest.mark.parametrize("suffix", [".png", ".tif"])
def test_16_bit_files_read_back_exactly_as_rows_and_columns(tmp_path, suffix):
    path = tmp_path / f"f{suffix}"
    if suffix == ".png":
        Image.fromarray(FRAME).save(path)
    else:
        tifffile.imwrite(path, FRAME)
    out = read_image(path, bit_depth=10)
    assert out.dtype == np.uint16 and out.shape == (6, 5)
    np.testing.assert_array_equal(out, FRAME)


def test_8_bit_png_stays_8_bit(tmp_path):
    path = tmp_path / "f.png"
    Image.fromarray((FRAME // 4).astype(np.uint8)).save(path)
    out = read_image(path)
    assert out.dtype == np.uint8 and np.array_equal(out, FRAME // 4)


def test_a_page_of_a_tiff_stack(tmp_path):
    path = tmp_path / "stack.tif"
    stack = np.stack([FRAME, FRAME + 1, FRAME + 2])
    tifffile.imwrite(path, stack, photometric="minisblack")
    np.testing.assert_array_equal(read_image(path, page=2), FRAME + 2)
    with pytest.raises(SchemaError, match=r"a page 0 \.\. 2 of this stack"):
        read_image(path, page=3)


def test_left_aligned_12_bit_camera_is_shifted_down(tmp_path):
    path = tmp_path / "left.tif"
    tifffile.imwrite(path, (FRAME * 4) << 4)  # 12-bit DN in the top bits of the word
    np.testing.assert_array_equal(read_image(path, bit_depth=12, left_aligned=True), FRAME * 4)
    # read as right-aligned it overflows 12 bits: the message says to say left_aligned
    with pytest.raises(SchemaError, match="left_aligned"):
        read_image(path, bit_depth=12)


def test_dn_above_the_bit_depth_are_refused(tmp_path):
    path = tmp_path / "hot.tif"
    tifffile.imwrite(path, np.full((4, 4), 1024, np.uint16))
    with pytest.raises(SchemaError, match=r"maximum 1024 DN.*2\*\*10 = 1024"):
        read_image(path, bit_depth=10)


def test_float_images_and_truncated_files_are_refused_naming_the_file(tmp_path):
    path = tmp_path / "float.tif"
    tifffile.imwrite(path, np.zeros((4, 4), np.float32))
    with pytest.raises(SchemaError, match="image float.tif: found 'pixel type float32'"):
        read_image(path)
    good = tmp_path / "cut.png"
    Image.fromarray(FRAME).save(good)
    good.write_bytes(good.read_bytes()[:60])
    with pytest.raises(SchemaError, match="cut.png"):
        read_image(good)
