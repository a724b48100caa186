"""``sensor.json``: the constants of a lab's own sensor, beside its frames, every field checked.

A folder of frames (``sunlab import FOLDER``) may hold a ``sensor.json`` that says what the
images cannot: the pixel pitch, the mask distance, the ADC's bit depth and whether its data are
left-aligned in a 16-bit word. Nothing is guessed: a field that is absent stays absent, and the
methods that need it (the geometric models need the pitch and the mask distance) ask for it with
an error that names this file. Every field is checked here, with a message that names the file,
the field and the fix; ``SENSOR_FIELDS`` is the one table the reader, the CLI and
``data_schema/README.md`` describe.

Examples
--------
>>> import json, tempfile, pathlib
>>> folder = pathlib.Path(tempfile.mkdtemp())
>>> _ = (folder / "sensor.json").write_text(json.dumps(
...     {"pixel_pitch_mm": 0.0055, "bit_depth": 12, "left_aligned": True}))
>>> read_sensor_json(folder / "sensor.json")
{'pixel_pitch_mm': 0.0055, 'bit_depth': 12, 'left_aligned': True}
>>> _ = (folder / "sensor.json").write_text('{"bit_depth": "12"}')
>>> try:
...     read_sensor_json(folder / "sensor.json")
... except Exception as err:
...     print(err.field)
sensor.json field 'bit_depth'
"""

from __future__ import annotations

import math
from pathlib import Path

from .. import integrity
from ..errors import SchemaError

__all__ = []

#: The fields of ``sensor.json``: name -> (kind, meaning). Kinds: ``positive`` (a number > 0),
#: ``number`` (finite), ``bits`` (an integer 8 .. 16), ``bool``, ``text``, ``note`` (any
#: string), ``object``.
SENSOR_FIELDS = {
    "pixel_pitch_mm": ("positive", "pixel pitch, mm (Ibis4: 0.007)"),
    "mask_distance_mm": ("positive", "nominal mask-to-focal-plane distance F, mm"),
    "x_cf_px": ("number", "column of the design projection of the hole centre, px"),
    "y_cf_px": ("number", "row of the design projection of the hole centre, px"),
    "bit_depth": ("bits", "ADC bit depth, 8 .. 16 (Ibis4: 10); sets the saturation level"),
    "left_aligned": ("bool", "true when the camera writes its DN in the top bits of a 16-bit "
                             "word (a 12-bit camera writing DN x 16); shifted down on read"),
    "mask": ("text", "mask description, e.g. 'single' or 'grid10x10'"),
    "experiment": ("text", "experiment name stored in the cube"),
    "attrs": ("object", "extra attributes stored in the cube"),
    "comment": ("note", "free text, ignored"),
}

def _number(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


#: Each kind of field: what a value must be (for the message), and its test.
_KINDS = {
    "positive": ("a number > 0 (JSON number, not a string)", lambda v: _number(v) and v > 0),
    "number": ("a finite number (JSON number, not a string)", _number),
    "bits": ("an integer 8 .. 16 (JSON number)",
             lambda v: _number(v) and float(v).is_integer() and 8 <= v <= 16),
    "bool": ("true or false (JSON boolean)", lambda v: isinstance(v, bool)),
    # a control character (a terminal's ESC) in a name would reach every summary printed
    "text": ("a string of printable characters", lambda v: isinstance(v, str) and v.isprintable()),
    "note": ("a string", lambda v: isinstance(v, str)),
    "object": ("a JSON object", lambda v: isinstance(v, dict)),
}


def find_sensor_json(folder, manifest=None) -> Path | None:
    """The ``sensor.json`` of a frame folder: beside the manifest first, then in the folder.

    Returns None when there is none.

    Parameters
    ----------
    folder : str or path-like
        The folder of frames.
    manifest : str or path-like, optional
        The manifest CSV, when it lies elsewhere; its folder is searched first.

    Returns
    -------
    pathlib.Path or None
        The first ``sensor.json`` found, or None.
    """
    places = [Path(manifest).resolve().parent] if manifest is not None else []
    return next((p / "sensor.json" for p in [*places, Path(folder)]
                 if (p / "sensor.json").is_file()), None)


def read_sensor_json(path) -> dict:
    """Read and check a ``sensor.json`` (fields: ``SENSOR_FIELDS``).

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    dict
        The fields present, with their JSON values (``bit_depth`` as int).

    Raises
    ------
    SchemaError
        Invalid JSON, an unknown key, or a field of the wrong kind (e.g. a string where a
        number is wanted), naming the file, the field and the fix.
    """
    path = Path(path)
    # a size and a nesting-depth limit: a sensor.json is a few hundred bytes
    doc = integrity.read_json(path, max_bytes=2**20,
                              what=f"a sensor.json object with keys among {list(SENSOR_FIELDS)}",
                              fix="fix the JSON syntax")
    if not isinstance(doc, dict):
        raise SchemaError(str(path), type(doc).__name__, "a JSON object {...}", "fix the file")
    unknown = sorted(set(doc) - set(SENSOR_FIELDS))
    if unknown:
        raise SchemaError(f"{path.name} keys {unknown}", "unknown",
                          f"keys among {list(SENSOR_FIELDS)}",
                          f"remove or rename them in {path} (extra attributes go under 'attrs')")
    return {k: _checked(path, k, v) for k, v in doc.items()}


def _checked(path: Path, key: str, value):
    """One field's value, checked against its kind in ``SENSOR_FIELDS``."""
    kind, meaning = SENSOR_FIELDS[key]
    expected, ok = _KINDS[kind]
    if not ok(value):
        text = str(value).strip()  # a string's hint, control characters escaped
        text = text if text.isprintable() else ascii(text)[1:-1]
        hint = {"bool": f"write {key}: true or false without quotes; ", "object": "",
                "text": "remove the control characters (ESC, tabs, line breaks); "}.get(
                    kind, f"write {key}: {text} without quotes; ") if isinstance(value, str) else ""
        raise SchemaError(f"{path.name} field {key!r}", value, f"{expected}: {meaning}",
                          f"{hint}correct it in {path}")
    return int(value) if kind == "bits" else value
