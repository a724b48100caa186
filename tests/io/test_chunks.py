"""Checked chunks (sunlab.io.chunks): a frame chunk whose DN exceed the bit depth fails naming
its chunk, lazily, when it is read; chunks within the bit depth pass through unchanged."""

import dask.array as da
import numpy as np
import pytest

from sunlab.errors import SchemaError
from sunlab.io.chunks import _checked_dn


def _frames(peak_at=None, peak=1024):
    data = np.full((2, 3, 8, 8), 100, np.uint16)
    if peak_at is not None:
        data[peak_at] = peak
    return da.from_array(data, chunks=(1, 1, 8, 8))


def test_chunks_within_the_bit_depth_come_back_unchanged():
    frames = _frames((1, 2, 3, 3), peak=1023)
    checked = _checked_dn(frames, 10, "cube.zarr:")
    np.testing.assert_array_equal(checked.compute(), frames.compute())


def test_a_chunk_at_two_to_the_bits_fails_naming_its_chunk_and_the_fix():
    checked = _checked_dn(_frames((1, 2, 3, 3), peak=1024), 10, "cube.zarr:")
    checked[0].compute()  # the lazy check costs nothing until the bad chunk is read
    with pytest.raises(SchemaError) as err:
        checked.compute()
    text = str(err.value)
    assert text.startswith("cube.zarr: frames chunk (pose 1, shot 2, y 0, x 0)")
    assert "DN up to 1024" in text and "2**10 = 1024" in text and "left-aligns" in text


def test_nothing_to_check_leaves_the_data_as_it_is():
    frames = _frames()
    assert _checked_dn(frames, 16, "x") is frames  # a 16-bit ADC fills the word
    plain = np.zeros((1, 1, 8, 8), np.uint16)
    assert _checked_dn(plain, 10, "x") is plain  # not Dask: checked where it is read
    floats = frames.astype(float)
    assert _checked_dn(floats, 10, "x") is floats  # corrected frames are not raw DN
