"""A lab's sensor.json (sunlab.io.sensor): every field checked, nothing guessed, one line per
bad field naming the file, the field and the fix."""

import json

import pytest

from sunlab.errors import SchemaError
from sunlab.io.sensor import SENSOR_FIELDS, find_sensor_json, read_sensor_json

FULL = {"pixel_pitch_mm": 0.0055, "mask_distance_mm": 4.8, "x_cf_px": 639.5, "y_cf_px": -3,
        "bit_depth": 12.0, "left_aligned": True, "mask": "single", "experiment": "I",
        "attrs": {"lab": "x"}, "comment": "tabs\tallowed here"}


def _write(folder, doc):
    path = folder / "sensor.json"
    path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return path


def test_every_documented_field_is_read_and_only_those_present(tmp_path):
    assert set(FULL) == set(SENSOR_FIELDS)
    out = read_sensor_json(_write(tmp_path, FULL))
    assert out == {**FULL, "bit_depth": 12} and type(out["bit_depth"]) is int
    assert read_sensor_json(_write(tmp_path, {"bit_depth": 10})) == {"bit_depth": 10}


@pytest.mark.parametrize("key, value, hint", [
    ("pixel_pitch_mm", "0.007", "without quotes"),
    ("pixel_pitch_mm", 0, "a number > 0"),
    ("mask_distance_mm", -5.0, "a number > 0"),
    ("x_cf_px", float("inf"), "a finite number"),
    ("bit_depth", 7, "an integer 8 .. 16"),
    ("bit_depth", 12.5, "an integer 8 .. 16"),
    ("left_aligned", "true", "true or false without quotes"),
    ("left_aligned", 1, "JSON boolean"),
    ("mask", "grid\x1b[2J", "control characters"),
    ("attrs", [1], "a JSON object"),
])
def test_a_field_of_the_wrong_kind_names_file_field_and_fix(tmp_path, key, value, hint):
    path = _write(tmp_path, json.dumps({key: value}, allow_nan=True).replace("Infinity", "1e999"))
    with pytest.raises(SchemaError, match=hint) as err:
        read_sensor_json(path)
    assert err.value.field == f"sensor.json field {key!r}"
    assert str(path) in str(err.value) and "\n" not in str(err.value)


def test_unknown_keys_and_non_objects_are_refused(tmp_path):
    with pytest.raises(SchemaError, match=r"sensor.json keys \['pitch'\]"):
        read_sensor_json(_write(tmp_path, {"pitch": 0.007}))
    with pytest.raises(SchemaError, match="a JSON object"):
        read_sensor_json(_write(tmp_path, "[0.007]"))


def test_found_beside_the_manifest_first_then_in_the_folder(tmp_path):
    frames, notes = tmp_path / "frames", tmp_path / "notes"
    frames.mkdir()
    notes.mkdir()
    assert find_sensor_json(frames) is None
    in_folder = _write(frames, {})
    assert find_sensor_json(frames) == in_folder
    beside = _write(notes, {})
    assert find_sensor_json(frames, manifest=notes / "manifest.csv") == beside
