"""sunlab.schema: the data contract in code agrees with data_schema/, and errors are clear."""

import copy
import json
import os
import re
from pathlib import Path

import dask.array as da
import jsonschema
import numpy as np
import pytest
import xarray as xr

from sunlab import SchemaError, schema

ROOT = Path(__file__).resolve().parents[1]
DATA_SCHEMA = ROOT / "data_schema"
CONTRACTS = ["frames/1", "centroids/1", "calibration/1"]


def _published(contract):
    """The schema as published in data_schema/, read without sunlab."""
    return json.loads((DATA_SCHEMA / schema.SCHEMA_FILES[contract]).read_text())


def _cube(**kwargs):
    frames = kwargs.pop("frames", np.zeros((2, 3, 4, 5), np.uint16))
    return schema.frames_dataset(frames, alpha=[0.0, 1.0], beta=[0.0, -1.0], **kwargs)


def _doc():
    return {
        "sunlab_schema": "calibration/1",
        "kind": "polynomial",
        "sunlab_version": "0.1.0",
        "parameters": {"degree": 2, "coef_alpha": [[0.1, 0.2], [0.3, None]], "note": "ok"},
        "training": {"experiment": "I", "n_samples": 24, "n_poses": 3, "n_shots": 8},
        "domain": {"alpha": [-30, 30], "beta": [-30.0, 30.0], "x": [1.5, 1200], "y": [2, 1000]},
        "residuals": {"alpha": {"rms": 0.01, "max_abs": 0.05}, "beta": {"rms": 0.02}},
    }


# ------------------------------------------------------------------------------------------
# One copy of each schema, valid, and matching what the code builds
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("contract", CONTRACTS)
def test_data_schema_holds_the_files_the_code_uses(contract):
    published = DATA_SCHEMA / schema.SCHEMA_FILES[contract]
    used = ROOT / "sunlab" / "schemas" / schema.SCHEMA_FILES[contract]  # the package data
    assert published.exists() and used.exists()
    assert os.path.samefile(published, used)
    if published.is_symlink():
        assert not os.path.isabs(os.readlink(published)), "links must be relative"
    assert schema.json_schema(contract) == _published(contract)


def test_same_set_of_schema_files_in_both_folders():
    published = {p.name for p in DATA_SCHEMA.glob("*.schema.json")}
    shipped = {p.name for p in (ROOT / "sunlab" / "schemas").glob("*.json")}
    assert published == shipped == set(schema.SCHEMA_FILES.values())


@pytest.mark.parametrize("contract", CONTRACTS)
def test_schemas_are_valid_draft_2020_12(contract):
    doc = _published(contract)
    jsonschema.Draft202012Validator.check_schema(doc)
    assert doc["$schema"].endswith("2020-12/schema")
    assert doc["title"].endswith(contract)


def _cubes():
    truth = np.zeros((2, 3, 4))
    yield "uint16", _cube()
    yield "uint8", _cube(frames=np.zeros((2, 3, 4, 5), np.uint8), bit_depth=8)
    yield "extras", _cube(
        coords={
            "alpha_read": (("pose", "shot"), np.zeros((2, 3))),
            "time": (("pose", "shot"), np.zeros((2, 3), "datetime64[ns]")),
            "true_x": (("pose", "shot", "hole"), truth),
            "true_y": (("pose", "shot", "hole"), truth),
        },
        attrs={"simulated": True, "seed": 3},
    )
    zeros = da.zeros((2, 3, 4, 5), dtype=np.uint16, chunks=(1, 1, 4, 5))
    yield "lazy", schema.frames_dataset(zeros, alpha=[0, 1], beta=[0, 0])


@pytest.mark.parametrize(("name", "cube"), list(_cubes()), ids=[n for n, _ in _cubes()])
def test_built_cubes_follow_the_published_schema(name, cube):
    instance = schema._jsonable(cube.to_dict(data=False))
    jsonschema.validate(instance, _published("frames/1"))
    assert schema.validate_frames(cube) is cube


@pytest.mark.parametrize("shape", [(2, 3), (2, 3, 4)])
def test_built_centroid_tables_follow_the_published_schema(shape):
    x = np.arange(np.prod(shape), dtype=float).reshape(shape)
    cen = schema.centroids_dataset(x, x, alpha=[0, 1], beta=[1, 2], method="threshold_window")
    jsonschema.validate(schema._jsonable(cen.to_dict(data=False)), _published("centroids/1"))
    assert cen.status.dtype == np.int8


def _readme_examples():
    text = (DATA_SCHEMA / "README.md").read_text()
    return [json.loads(block) for block in re.findall(r"```json\n(.*?)```", text, re.S)]


def test_readme_examples_follow_the_schemas(tmp_path):
    from sunlab.io.sensor import SENSOR_FIELDS, read_sensor_json

    examples = _readme_examples()
    found = set()
    for doc in examples:
        if "sunlab_schema" not in doc and "sunlab_schema" not in doc.get("attrs", {}):
            # not a contract: the sensor.json of an image folder, read as `sunlab import` does
            assert set(doc) <= set(SENSOR_FIELDS), doc
            (tmp_path / "sensor.json").write_text(json.dumps(doc))
            assert read_sensor_json(tmp_path / "sensor.json") == doc
            found.add("sensor.json")
            continue
        contract = doc.get("sunlab_schema") or doc["attrs"]["sunlab_schema"]
        jsonschema.validate(doc, _published(contract))
        found.add(contract)
    assert found == set(CONTRACTS) | {"sensor.json"}
    calibration = next(d for d in examples if d.get("sunlab_schema") == "calibration/1")
    assert schema.validate_calibration(calibration) is calibration


# ------------------------------------------------------------------------------------------
# Frame cubes: errors name field, value and fix
# ------------------------------------------------------------------------------------------
def test_error_message_layout():
    err = SchemaError("frames.dtype", "int32", "uint8 or uint16", "convert it")
    assert str(err) == "frames.dtype: found 'int32', expected uint8 or uint16. Fix: convert it"


def test_frames_of_wrong_rank():
    with pytest.raises(SchemaError, match=r"frames: found '3-d array of shape \(1, 4, 5\)'"):
        schema.frames_dataset(np.zeros((1, 4, 5), np.uint16), alpha=[0], beta=[0])


def test_angles_of_wrong_length():
    with pytest.raises(SchemaError, match=r"beta: found 'shape \(1,\)', expected shape \(2,\)"):
        schema.frames_dataset(np.zeros((2, 1, 4, 5), np.uint16), alpha=[0, 1], beta=[0])


def test_transposed_frames():
    cube = _cube().transpose("pose", "shot", "x", "y")
    with pytest.raises(SchemaError, match="frames.dims") as err:
        schema.validate_frames(cube)
    assert "transpose" in err.value.fix


def test_non_finite_angle():
    cube = _cube()
    cube = cube.assign_coords(alpha=("pose", [0.0, np.nan]))
    with pytest.raises(SchemaError, match="alpha: found 'non-finite angles'"):
        schema.validate_frames(cube)


@pytest.mark.parametrize(
    ("attr", "value", "message"),
    [
        ("pixel_pitch_mm", -0.007, "pixel pitch in mm"),
        ("pixel_pitch_mm", "7 um", "pixel pitch in mm (Ibis4: 0.007); absent when not known"),
        ("pixel_pitch_mm", "7 um", "'7 um' is not of type 'number'"),
        ("x_cf_px", float("nan"), "a finite number"),
        ("bit_depth", 12.5, "12.5 is not of type 'integer'"),
        ("bit_depth", None, "ADC bit depth"),
    ],
)
def test_bad_sensor_attributes(attr, value, message):
    cube = _cube()
    if value is None:
        del cube.attrs[attr]
    else:
        cube.attrs[attr] = value
    with pytest.raises(SchemaError, match=re.escape(f"attrs['{attr}']")) as err:
        schema.validate_frames(cube)
    assert message in err.value.expected
    assert attr in err.value.fix


def test_bit_depth_larger_than_the_dtype():
    with pytest.raises(SchemaError, match=r"attrs\['bit_depth'\]: found 10, expected <= 8") as err:
        _cube(frames=np.zeros((2, 3, 4, 5), np.uint8))
    assert "uint16" in err.value.fix


def test_json_schema_stage_catches_what_python_does_not():
    """The published schema is enforced at run time: a mask that is not text, DN units."""
    cube = _cube()
    cube.attrs["mask"] = 5
    with pytest.raises(SchemaError, match=r"attrs\['mask'\]: found 5, expected mask description"):
        schema.validate_frames(cube)
    cube = _cube()
    cube.frames.attrs["units"] = "counts"
    with pytest.raises(SchemaError, match=r"frames.attrs\['units'\]: found 'counts'") as err:
        schema.validate_frames(cube)
    assert "data_schema" in err.value.fix
    cube = _cube()
    del cube.attrs["experiment"]
    with pytest.raises(SchemaError, match=r"attrs\['experiment'\]: found 'missing'"):
        schema.validate_frames(cube)


def test_wrong_contract_and_version():
    cen = schema.centroids_dataset(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(SchemaError, match="found 'centroids/1', expected 'frames/1'") as err:
        schema.validate_frames(cen)
    assert "open_centroids" in err.value.fix
    cube = _cube().assign_attrs(sunlab_schema="frames/2")
    with pytest.raises(SchemaError, match="holds version '2'") as err:
        schema.validate_frames(cube)
    assert "upgrade sunlab" in err.value.fix


def test_not_a_dataset():
    with pytest.raises(SchemaError, match="cube: found 'DataArray'"):
        schema.validate_frames(xr.DataArray([1]))


def test_lazy_frames_stay_lazy_and_keep_their_chunks():
    zeros = da.zeros((3, 2, 4, 5), dtype=np.uint16, chunks=(1, 1, 4, 5))
    cube = schema.frames_dataset(zeros, alpha=[0, 1, 2], beta=[0, 0, 0])
    assert cube.frames.data.chunksize == (1, 1, 4, 5)
    assert int(cube.frames.sum()) == 0


# ------------------------------------------------------------------------------------------
# Centroid tables
# ------------------------------------------------------------------------------------------
def test_status_defaults_and_names():
    cen = schema.centroids_dataset([[1.0, np.nan]], [[1.0, 2.0]])
    assert cen.status.values.tolist() == [[0, 1]]
    assert [schema.status_name(c) for c in range(7)] == list(schema.STATUS)
    assert schema.STATUS_NAMES[2] == "saturated"


def test_unknown_status_code():
    cen = schema.centroids_dataset(np.zeros((1, 2)), np.zeros((1, 2)))
    cen["status"][:] = 9
    with pytest.raises(SchemaError, match=r"status: found \[9\]"):
        schema.validate_centroids(cen)


def test_centroid_variable_on_other_dims():
    cen = schema.centroids_dataset(np.zeros((2, 3)), np.zeros((2, 3)))
    cen["flux"] = (("shot", "pose"), np.zeros((3, 2)))
    with pytest.raises(SchemaError, match=r"flux.dims: found \('shot', 'pose'\)") as err:
        schema.validate_centroids(cen)
    assert "transpose" in err.value.fix


def test_centroid_method_attr_required_by_the_published_schema():
    cen = schema.centroids_dataset(np.zeros((2, 3)), np.zeros((2, 3)))
    del cen.attrs["method"]
    with pytest.raises(SchemaError, match=r"attrs\['method'\]: found 'missing'"):
        schema.validate_centroids(cen)


def test_centroid_shapes_must_agree():
    with pytest.raises(SchemaError, match="x, y: found 'shapes"):
        schema.centroids_dataset(np.zeros((2, 3)), np.zeros((2, 4)))


# ------------------------------------------------------------------------------------------
# Calibration artifacts
# ------------------------------------------------------------------------------------------
def test_valid_calibration_document_also_after_a_json_round_trip():
    doc = _doc()
    assert schema.validate_calibration(doc) is doc
    schema.validate_calibration(json.loads(json.dumps(doc)))
    jsonschema.validate(doc, _published("calibration/1"))


def _broken(path, value):
    doc = copy.deepcopy(_doc())
    *parents, last = path
    node = doc
    for key in parents:
        node = node[key]
    if value is KeyError:
        del node[last]
    else:
        node[last] = value
    return doc


@pytest.mark.parametrize(
    ("path", "value", "field", "hint"),
    [
        (["kind"], KeyError, "kind", "calibration method"),
        (["kind"], "Polynomial", "kind", "lower case"),
        (["domain", "x"], KeyError, "domain.x", "centroid column"),
        (["domain", "alpha"], [30, -30], "domain.alpha", "low <= high"),
        (["domain", "beta"], [0, 1, 2], "domain.beta", "[low, high]"),
        (["residuals", "alpha", "rms"], float("nan"), "residuals.alpha.rms", "finite"),
        (["parameters", "coef_alpha"], np.zeros(3), "parameters.coef_alpha", "JSON value"),
        (["parameters", "coef_alpha"], [1.0, float("inf")], "parameters.coef_alpha[1]", "finite"),
        (["training", "n_samples"], -1, "training.n_samples", "number of"),
        (["sunlab_schema"], "calibration/2", "sunlab_schema", "'calibration/1'"),
        (["sunlab_version"], 1, "sunlab_version", "version of sunlab"),
    ],
)
def test_bad_calibration_documents(path, value, field, hint):
    with pytest.raises(SchemaError) as err:
        schema.validate_calibration(_broken(path, value))
    assert err.value.field == field
    assert hint in err.value.expected
    assert err.value.fix


def test_calibration_fixes_are_specific():
    with pytest.raises(SchemaError) as err:
        schema.validate_calibration(_broken(["residuals", "beta", "rms"], float("nan")))
    assert "null" in err.value.fix
    with pytest.raises(SchemaError) as err:
        schema.validate_calibration(_broken(["parameters", "w"], np.ones(2)))
    assert ".tolist()" in err.value.fix
    with pytest.raises(SchemaError, match="calibration: found 'list'"):
        schema.validate_calibration([1, 2])


def test_unknown_contract_name():
    with pytest.raises(SchemaError, match="contract: found 'frames/9'"):
        schema.json_schema("frames/9")
