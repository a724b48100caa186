"""The attribute codec (sunlab.io.codec): exact round trips of attributes NetCDF and Zarr cannot
hold natively, through the encoder alone and through a real NetCDF4 and Zarr v3 file."""

import numpy as np
import pytest
import xarray as xr

from sunlab.errors import SchemaError
from sunlab.io.codec import _CODEC_ATTR, _decode_attrs, _encode_attrs

ATTRS = {
    "experiment": "I", "bit_depth": 10, "pitch": 0.007, "flag": True, "none": None,
    "cameras": ["a", "b"], "shape": (3, 4), "doc": {"k": [1, 2.5]}, "big": 2**70,
    "matrix": np.arange(6, dtype=np.int16).reshape(2, 3), "empty": np.zeros(0, np.float32),
    "scalar": np.float32(0.5),
}


def _same(a, b):
    assert set(a) == set(b)
    for k in a:
        if isinstance(a[k], np.ndarray):
            assert b[k].dtype == a[k].dtype and b[k].shape == a[k].shape, k
            np.testing.assert_array_equal(b[k], a[k])
        else:
            assert b[k] == a[k] and type(b[k]) is type(a[k] if not isinstance(a[k], np.generic)
                                                       else a[k].item()), k


def test_encoder_round_trip_is_exact_and_lists_what_it_encoded():
    enc = _encode_attrs(ATTRS, "")
    assert all(isinstance(v, str | int | float | np.ndarray) for v in enc.values())
    assert enc["experiment"] == "I" and enc["flag"] == "true"
    _same(ATTRS, _decode_attrs(enc))
    # plain values need no codec entry; a table without any has no codec attribute
    assert _CODEC_ATTR not in _encode_attrs({"a": 1, "b": "x"}, "")


@pytest.mark.parametrize("suffix", [".nc", ".zarr"])
def test_round_trip_through_a_file(tmp_path, suffix):
    ds = xr.Dataset({"x": ("pose", [1.0, 2.0])}, attrs=_encode_attrs(ATTRS, ""))
    path = tmp_path / f"t{suffix}"
    if suffix == ".nc":
        ds.to_netcdf(path, engine="h5netcdf")
        back = xr.open_dataset(path, engine="h5netcdf")
    else:
        ds.to_zarr(path, zarr_format=3, consolidated=False)
        back = xr.open_zarr(path, consolidated=False)
    with back:
        _same(ATTRS, _decode_attrs(back.attrs))


@pytest.mark.parametrize("value, words", [
    (object(), "a value of type object"),
    ({"f": float("nan")}, "JSON-serialisable"),
    (np.array(["a"]), "a value of type ndarray"),
])
def test_an_attribute_no_file_can_hold_is_refused_naming_it(value, words):
    with pytest.raises(SchemaError, match=words) as err:
        _encode_attrs({"bad": value}, "centroids.")
    assert str(err.value).startswith("centroids.attrs['bad']") and "Fix:" in str(err.value)
