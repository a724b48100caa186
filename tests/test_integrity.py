"""Digests of what an artifact means (sunlab.integrity): a document, a Zarr store's metadata and
a NetCDF file's values each read back only as written; JSON input is bounded in size and depth."""

import json

import numpy as np
import pytest
import xarray as xr

from sunlab import integrity as I
from sunlab.errors import SunlabError


def test_sealed_document_verifies_and_any_edit_is_refused_naming_the_source():
    doc = I.seal_document({"kind": "polynomial", "parameters": {"order": 3, "c": [0.1, 0.2]}})
    assert I.verify_document(doc, "cal.json") == {"kind": "polynomial",
                                                  "parameters": {"order": 3, "c": [0.1, 0.2]}}
    # the digest is of the canonical text: key order does not matter, a value does
    assert I.verify_document(dict(reversed(list(doc.items()))), "cal.json")["kind"] == "polynomial"
    doc["parameters"]["c"][1] = 0.2000001
    with pytest.raises(I.IntegrityError, match="^cal.json: checksum mismatch"):
        I.verify_document(doc, "cal.json")


def test_unsealed_document_reads_as_it_is_and_digest_ignores_the_seal():
    plain = {"kind": "ideal"}
    assert I.verify_document(plain, "x.json") is plain
    assert I.document_digest(I.seal_document(plain)) == I.document_digest(plain)


def test_depth_and_huge_integers_are_refused_before_a_reader_meets_them():
    deep = []
    for _ in range(I.MAX_JSON_DEPTH + 1):
        deep = [deep]
    with pytest.raises(SunlabError, match="nested more than"):
        I.check_depth(deep, "d.json")
    I.check_depth([[[1]]], "ok.json")
    with pytest.raises(SunlabError, match=r"a\.b\[1\]: found an integer of 400 digits"):
        I.check_depth({"a": {"b": [1, 10**399]}}, "big.json")


def test_read_json_names_the_file_and_what_is_wrong(tmp_path):
    good = tmp_path / "good.json"
    good.write_text(json.dumps({"a": [1, 2]}))
    assert I.read_json(good, max_bytes=100) == {"a": [1, 2]}
    cases = {
        "big": ("x" * 200, "more than the 100 bytes"),
        "bad": ("{not json", "invalid JSON"),
        "latin": (b"\xff\xfe", "not UTF-8"),
    }
    for name, (content, words) in cases.items():
        path = tmp_path / f"{name}.json"
        (path.write_bytes if isinstance(content, bytes) else path.write_text)(content)
        with pytest.raises(SunlabError, match=words) as err:
            I.read_json(path, max_bytes=100)
        assert str(err.value).startswith(str(path)) and "Fix:" in str(err.value)
    with pytest.raises(SunlabError, match="no such file"):
        I.read_json(tmp_path / "missing.json", max_bytes=100)
    with pytest.raises(SunlabError, match="not a regular file"):
        I.read_json(tmp_path, max_bytes=100)


def _dataset():
    return xr.Dataset({"x": (("pose",), np.array([1.5, 2.5, 3.5]))}, attrs={"experiment": "I"})


def test_zarr_store_metadata_is_sealed_and_an_edit_is_found(tmp_path):
    store = tmp_path / "cen.zarr"
    _dataset().to_zarr(store, zarr_format=3, consolidated=False)
    digest = I.seal_zarr(store)
    assert len(digest) == 64 and digest == I.zarr_digest(store)
    I.verify_zarr(store)
    meta = store / "x" / "zarr.json"
    doc = json.loads(meta.read_text())
    doc["shape"] = [4]  # a one-character edit of an array's shape
    meta.write_text(json.dumps(doc))
    with pytest.raises(I.IntegrityError, match="checksum mismatch"):
        I.verify_zarr(store)
    I.unseal_zarr(store)
    I.verify_zarr(store)  # without a digest the store is read as before


def test_netcdf_values_are_sealed_and_a_changed_value_is_found(tmp_path):
    path = tmp_path / "cen.nc"
    _dataset().to_netcdf(path, engine="h5netcdf")
    digest = I.seal_netcdf(path)
    with xr.open_dataset(path, engine="h5netcdf") as ds:
        assert I.netcdf_digest(ds) == digest
        I.verify_netcdf(ds, path)
        changed = ds.load().copy(deep=True)
    changed["x"].values[1] = 2.5000001
    with pytest.raises(I.IntegrityError, match="cen.nc: checksum mismatch"):
        I.verify_netcdf(changed, path)


DEEP = "[" * 100_000 + "]" * 100_000  # beyond the JSON parser's recursion limit


@pytest.mark.parametrize("sealed", [True, False])
def test_a_store_whose_metadata_nests_deep_is_refused_in_one_line(tmp_path, capsys, sealed):
    from sunlab import cli, io, sim

    store = tmp_path / "cen.zarr"
    io.save_centroids(sim.synthetic_centroids([0.0, 1, 2], [0.0, 0, 1]), store)
    if not sealed:
        I.unseal_zarr(store)
    meta = store / "zarr.json"
    meta.write_text(meta.read_text().replace('"attributes": {', f'"attributes": {{"d": {DEEP},', 1))
    with pytest.raises(SunlabError, match="cen.zarr/zarr.json: corrupt Zarr metadata.*nested"):
        io.open_centroids(store)
    assert cli.main(["info", str(store)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nested more than 64 levels" in err


def test_a_store_attribute_that_nests_deep_is_refused_naming_it(tmp_path):
    from sunlab import io, sim

    store = tmp_path / "cen.zarr"
    cen = sim.synthetic_centroids([0.0, 1, 2], [0.0, 0, 1]).assign_attrs(roi=[0, 4, 0, 4])
    io.save_centroids(cen, store)
    I.unseal_zarr(store)  # an attribute's JSON text is a string: the store's own check passes
    meta = store / "zarr.json"
    doc = json.loads(meta.read_text())
    key = next(k for k, v in doc["attributes"].items() if v == "[0, 4, 0, 4]")
    doc["attributes"][key] = DEEP
    meta.write_text(json.dumps(doc))
    with pytest.raises(SunlabError, match=f"attribute '{key}': JSON nested more than 64"):
        io.open_centroids(store)


def test_a_command_line_option_value_that_nests_deep_is_refused_in_one_line(tmp_path, capsys):
    from sunlab import cli

    # a lab's camera class (module:Class) is handed the options; "sim" takes none
    status = cli.main(["acquire", "--stage", "fake://", "--camera", "sunlab.hardware:SimCamera",
                       "--plan", "I", "--step", "50", "--shots", "1", "--out",
                       str(tmp_path / "run.zarr"), "--camera-option", f"roi={DEEP}",
                       "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1
    assert "--camera-option roi: JSON nested more than 64 levels" in err
    assert not (tmp_path / "run.zarr").exists()
