"""The on-disk data contract: build and validate frame cubes, centroid tables, calibrations.

The contracts are JSON Schema files shipped in ``sunlab/schemas/`` (``data_schema/`` holds the
prose). The JSON Schema file checks ``ds.to_dict(data=False)`` (dims, dtypes, attribute types),
so the code and the published contract cannot drift; Python checks only what it cannot say (the
contract's name, dims in another order, finite values, the DN range, the index coordinates). Errors
are :class:`sunlab.SchemaError`: the field, the value found, the value expected and the fix.
Pixel coordinates are (x = column, y = row), the centre of the first pixel at 0; angles in deg.

Examples
--------
>>> import numpy as np
>>> from sunlab import schema
>>> cube = schema.frames_dataset(np.zeros((2, 8, 4, 5), np.uint16), alpha=[0.0, 1.0],
...                              beta=[0.0, 0.0])
>>> cube.frames.dims, schema.validate_frames(cube).attrs["sunlab_schema"]
(('pose', 'shot', 'y', 'x'), 'frames/1')
"""

from __future__ import annotations

import functools
import json
import math
from collections.abc import Mapping, Sequence
from importlib import resources

import numpy as np
import xarray as xr

from .errors import SchemaError

__all__ = []

FRAMES_SCHEMA = "frames/1"
CENTROIDS_SCHEMA = "centroids/1"
CALIBRATION_SCHEMA = "calibration/1"

#: JSON Schema file of each contract, in ``sunlab/schemas/`` (package data).
SCHEMA_FILES: dict[str, str] = {c: c.replace("/", "-") + ".schema.json"
                                for c in (FRAMES_SCHEMA, CENTROIDS_SCHEMA, CALIBRATION_SCHEMA)}

#: Centroid status codes (CF ``flag_values`` / ``flag_meanings`` on the ``status`` variable).
#: ``repaired``: a usable spot whose window held isolated clipped pixels (hot pixels), each
#: replaced by the median of its 8 neighbours before the centre of mass.
STATUS: dict[str, int] = {"ok": 0, "no_spot": 1, "saturated": 2, "clipped": 3, "ambiguous": 4,
                          "invalid": 5, "repaired": 6}
STATUS_NAMES: dict[int, str] = {v: k for k, v in STATUS.items()}
#: Status codes whose centroid is usable for calibration and statistics.
USABLE_STATUS: tuple[str, ...] = ("ok", "repaired")

#: Bit flags of the ``hole_defect`` coordinate on ``hole`` of a simulated cube or centroid
#: table: which defects the virtual bench gave each hole (0: a good hole).
DEFECT_FLAGS: dict[str, int] = {"dust": 1, "elliptical": 2, "burred": 4, "undersized": 8}

#: The paper's detector (docs/paper.md sec. 1): Ibis4, 1280 x 1024 pixels of 7 um, 10-bit ADC.
IBIS4 = {"nx": 1280, "ny": 1024, "pixel_pitch_mm": 0.007, "bit_depth": 10}

def status_name(code: int) -> str:
    """Name of a centroid status code, e.g. ``status_name(1) == 'no_spot'``.

    Parameters
    ----------
    code : int
        A code of :data:`STATUS` (a KeyError for another).

    Returns
    -------
    str
        Its name.
    """
    return STATUS_NAMES[int(code)]


def json_schema(contract: str) -> dict:
    """The JSON Schema (draft 2020-12) of a contract, parsed anew from its file in
    ``sunlab/schemas/`` (package data, ``SCHEMA_FILES``); the caller may change it.

    Parameters
    ----------
    contract : str
        ``"frames/1"``, ``"centroids/1"`` or ``"calibration/1"``.

    Returns
    -------
    dict
        The parsed file, e.g. ``json_schema("centroids/1")["properties"]["attrs"]``.
    """
    if contract not in SCHEMA_FILES:
        raise SchemaError("contract", contract, f"one of {sorted(SCHEMA_FILES)}",
                          "name a contract and version this sunlab knows, e.g. 'frames/1'")
    return json.loads(resources.files("sunlab").joinpath("schemas", SCHEMA_FILES[contract])
                      .read_text(encoding="utf-8"))


@functools.lru_cache(maxsize=len(SCHEMA_FILES))
def _validator(contract: str):
    import jsonschema

    return jsonschema.Draft202012Validator(json_schema(contract))


def _jsonable(obj):
    """Plain JSON types for a jsonschema check (tuples -> lists, numpy -> Python)."""
    if isinstance(obj, Mapping):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    return _jsonable(obj.tolist()) if isinstance(obj, np.ndarray | np.generic) else obj


def _short(value, limit: int = 80):
    """A value for an error message: small values as they are, large ones summarised."""
    if isinstance(value, Mapping):
        value = f"an object with keys {sorted(map(str, value))}"
    text = repr(value)
    return value if len(text) <= limit else text[: limit - 5] + " ...)"


def _dataset_field(path: Sequence) -> str:
    """``['data_vars', 'frames', 'dtype']`` -> ``'frames.dtype'``; attrs -> ``attrs['name']``."""
    path = [str(p) for p in path]
    keys = lambda rest: "".join(f"[{p!r}]" for p in rest)  # noqa: E731
    if path[:1] in (["attrs"], ["dims"]):
        return path[0] + keys(path[1:])
    if path[:1] in (["data_vars"], ["coords"]) and len(path) > 1:
        if path[2:3] == ["attrs"]:
            return path[1] + ".attrs" + keys(path[3:])
        return ".".join(path[1:])
    return ".".join(path) or "dataset"


def _json_field(path: Sequence) -> str:
    """``['domain', 'alpha', 1]`` -> ``'domain.alpha[1]'``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "document"


#: The fix of a JSON Schema failure where "correct FIELD" says too little.
_FIXES = {"frames.dtype": "convert with np.asarray(frames).astype(np.uint16) after checking the "
                          "range",
          "status.dtype": "store the status codes as int8"}


def _check_json_schema(instance, contract: str, field_of) -> None:
    """Validate ``instance`` against the contract's JSON Schema; raise the most relevant error."""
    from jsonschema.exceptions import best_match

    error = best_match(_validator(contract).iter_errors(instance))
    if error is None:
        return
    path, where = list(error.absolute_path), f"the contract is data_schema/{SCHEMA_FILES[contract]}"
    if error.validator == "required" and isinstance(error.instance, Mapping):
        name = next((k for k in error.validator_value if k not in error.instance), "?")
        prop = error.schema.get("properties", {}).get(name, {})
        raise SchemaError(field_of([*path, name]), "missing",
                          prop.get("description") or f"a required field {name!r}",
                          f"add {name!r}; {where}")
    expected = error.schema.get("description") if isinstance(error.schema, Mapping) else None
    field = field_of(path)
    raise SchemaError(field, _short(error.instance),
                      f"{expected} ({error.message})" if expected else error.message,
                      f"{_FIXES.get(field, f'correct {field}')}; {where}")


def frames_dataset(frames, alpha: Sequence[float], beta: Sequence[float], *,
                   pixel_pitch_mm: float | None = IBIS4["pixel_pitch_mm"],
                   mask_distance_mm: float | None = 5.0, x_cf_px: float | None = None,
                   y_cf_px: float | None = None, bit_depth: int = IBIS4["bit_depth"],
                   mask: str = "single", experiment: str = "",
                   coords: Mapping[str, tuple] | None = None,
                   attrs: Mapping | None = None) -> xr.Dataset:
    """Build a frame cube (contract ``frames/1``) from an array of frames.

    Parameters
    ----------
    frames : array_like of uint8 or uint16, shape (pose, shot, y, x)
        Raw frames in digital numbers (DN), NumPy or Dask.
    alpha, beta : sequence of float, length pose
        Commanded platform angles of each pose, deg (outer axis alpha, inner axis beta).
    pixel_pitch_mm, mask_distance_mm : float or None
        Pixel pitch and nominal mask-to-focal-plane distance F, mm; None leaves one out (not
        known: the methods that need it ask).
    x_cf_px, y_cf_px : float, optional
        Design projection of the hole centre (the sun at zenith), px; default the detector's
        centre.
    bit_depth : int
        ADC bit depth; every DN must be below ``2**bit_depth``.
    mask, experiment : str
        Mask description (``"single"``, ``"grid10x10"``) and experiment name (``"I"``).
    coords, attrs : mapping, optional
        Extra coordinates ``name: (dims, values[, attrs])`` and extra attributes.

    Returns
    -------
    xarray.Dataset
        A validated frame cube.
    """
    if not hasattr(frames, "dtype"):
        frames = np.asarray(frames)
    if frames.ndim != 4:
        raise SchemaError(
            "frames", f"{frames.ndim}-d array of shape {frames.shape}", "4-d (pose, shot, y, x)",
            "stack single frames as frames[None, None] or reshape to (pose, shot, y, x)")
    n_pose, n_shot, ny, nx = frames.shape
    angles = {}
    for name, val in (("alpha", alpha), ("beta", beta)):
        angles[name] = np.asarray(val, dtype=float)
        if angles[name].shape != (n_pose,):
            raise SchemaError(name, f"shape {angles[name].shape}",
                              f"shape ({n_pose},), one angle per pose")
    sensor = {"pixel_pitch_mm": pixel_pitch_mm, "mask_distance_mm": mask_distance_mm,
              "x_cf_px": (nx - 1) / 2 if x_cf_px is None else x_cf_px,
              "y_cf_px": (ny - 1) / 2 if y_cf_px is None else y_cf_px}
    all_attrs = {"sunlab_schema": FRAMES_SCHEMA,  # a geometry not said is left out
                 **{k: float(v) for k, v in sensor.items() if v is not None},
                 "bit_depth": int(bit_depth), "mask": str(mask), "experiment": str(experiment),
                 **(attrs or {})}
    long = {"alpha": "commanded outer-axis angle", "beta": "commanded inner-axis angle"}
    coords = {"pose": np.arange(n_pose), "shot": np.arange(n_shot),
              **{k: ("pose", v, {"units": "deg", "long_name": long[k]}) for k, v in
                 angles.items()}, **dict(coords or {})}
    frames = {"frames": (("pose", "shot", "y", "x"), frames, {"units": "DN"})}
    return validate_frames(xr.Dataset(frames, coords=coords, attrs=all_attrs))


def _check_contract(found, expected: str, field: str) -> None:
    """The contract's name and version (``sunlab_schema``) is the one expected."""
    family, _, version = str(found).partition("/")
    if found is None:
        fix = f"build it with sunlab.schema, or set {field} = {expected!r} after checking it"
    elif family == expected.partition("/")[0]:
        fix = (f"this sunlab reads {expected!r} but the file holds version {version!r}: open it "
               "with the sunlab version that wrote it (its 'sunlab_version') and save it again "
               "(a calibration: refit it), or upgrade sunlab")
    elif found in SCHEMA_FILES:
        fix = (f"this is a {found!r} dataset, not {expected!r}: open a frame cube with "
               "sunlab.io.open_frames, a centroid table with sunlab.io.open_centroids")
    else:
        fix = "rebuild it with sunlab.schema"
    if found != expected:
        raise SchemaError(field, "missing" if found is None else found, repr(expected), fix)


def _check_dims(ds: xr.Dataset, var: str, allowed: Sequence[tuple[str, ...]]) -> None:
    if var not in ds.variables:
        raise SchemaError(
            var, f"missing (variables: {sorted(map(str, ds.variables))})",
            f"a variable {var!r} on dims {' or '.join(map(str, allowed))}",
            f"add {var!r} (build the dataset with sunlab.schema), or check that this is the "
            "kind of dataset you meant: sunlab.io.open_frames for frame cubes, "
            "sunlab.io.open_centroids for centroid tables")
    dims = tuple(map(str, ds[var].dims))
    if dims not in [tuple(a) for a in allowed]:
        fix = (f"reorder with ds[{var!r}].transpose(*{allowed[0]!r})"
               if sorted(dims) in [sorted(a) for a in allowed] else None)
        raise SchemaError(f"{var}.dims", dims, " or ".join(map(str, allowed)), fix)


def _check_indices(ds: xr.Dataset) -> None:
    """The index coordinates ``pose`` and ``shot`` are 0 .. n-1, as the contract says."""
    for dim in [d for d in ("pose", "shot") if d in ds.coords]:
        values = np.asarray(ds[dim].values)
        if values.dtype.kind not in "iu" or not np.array_equal(values, np.arange(values.size)):
            raise SchemaError(
                f"coords[{dim!r}]", _short(values.tolist()), f"the integers 0 .. {values.size - 1}",
                f"renumber with ds.assign_coords({dim}=np.arange(ds.sizes[{dim!r}])); keep "
                "labels of your own in another coordinate (e.g. 'shot_label')")


def _check_sensor(ds: xr.Dataset, dtype) -> None:
    """What the JSON Schema cannot say: the sensor's numbers are finite, and the bit depth fits
    the frames' type."""
    for name in ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px"):
        value = ds.attrs.get(name)
        if isinstance(value, float | np.floating) and not np.isfinite(value):
            raise SchemaError(f"attrs[{name!r}]", value, "a finite number",
                              f"set cube.attrs[{name!r}] (frames_dataset takes it as a keyword)")
    bits = ds.attrs["bit_depth"]
    if int(bits) > 8 * dtype.itemsize:
        raise SchemaError("attrs['bit_depth']", bits, f"<= {8 * dtype.itemsize} for {dtype} "
                          "frames", "store frames of more than 8 bits as uint16")


def validate_frames(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` is a frame cube of contract ``frames/1``; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        The cube: dims, dtypes, finite angles, the sensor attributes, DN below
        ``2**bit_depth`` (in-memory frames only: lazy ones are checked on read and write) and
        the JSON Schema of ``frames/1``.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself; a :class:`SchemaError` names the first field at fault.
    """
    if not isinstance(ds, xr.Dataset):
        raise SchemaError("cube", type(ds).__name__, "an xarray.Dataset", "open it with sunlab.io")
    _check_contract(ds.attrs.get("sunlab_schema"), FRAMES_SCHEMA, "attrs['sunlab_schema']")
    _check_dims(ds, "frames", [("pose", "shot", "y", "x")])
    _check_indices(ds)
    # dims, dtypes and attribute types: the published contract; then what it cannot say
    _check_json_schema(_jsonable(ds.to_dict(data=False)), FRAMES_SCHEMA, _dataset_field)
    frames = ds["frames"]
    for name in ("alpha", "beta"):
        if not np.all(np.isfinite(ds[name].values)):
            raise SchemaError(name, "non-finite angles", "finite commanded angles in degrees")
    _check_sensor(ds, frames.dtype)
    bits = int(ds.attrs["bit_depth"])
    # in-memory frames: every DN below 2**bit_depth (lazy ones are checked on read and write)
    if frames.chunks is None and frames.size and bits < 8 * frames.dtype.itemsize:
        values = np.asarray(frames.values)
        if values.max() >= 2**bits:
            raise SchemaError(
                "frames", f"DN up to {int(values.max())} ({int((values >= 2**bits).sum())} "
                f"pixels >= {2**bits})", f"DN < 2**{bits} = {2**bits} for attrs['bit_depth'] = "
                f"{bits}", "give the true ADC bit depth (frames_dataset(bit_depth=...)); if the "
                "camera left-aligns its data in the 16-bit word, divide the frames by "
                "2**(16 - bit_depth)")
    return ds


def centroids_dataset(x, y, *, flux=None, status=None, window=None, alpha=None, beta=None,
                      method: str = "", attrs: Mapping | None = None,
                      extra: Mapping[str, tuple] | None = None) -> xr.Dataset:
    """Build a centroid table (contract ``centroids/1``).

    Parameters
    ----------
    x, y : array_like, shape (pose, shot) or (pose, shot, hole)
        Spot centroid, px (x = column, y = row); NaN where no usable spot was found.
    flux : array_like, optional
        Background-subtracted spot flux in the window, DN.
    status : array_like of int, optional
        Codes of :data:`STATUS`; default ``ok`` where x and y are finite, else ``no_spot``.
    window : tuple of 4 array_like, optional
        Window bounds ``(x0, x1, y0, y1)``, half-open pixel ranges; -1 where no window.
    alpha, beta : array_like of length pose, optional
        Commanded angles, deg, carried over from the frame cube.
    method : str
        Name of the centroid method.
    attrs, extra : mapping, optional
        Extra attributes (the cube's sensor), extra variables ``name: (dims, values[, attrs])``.

    Returns
    -------
    xarray.Dataset
        A validated table: ``x``, ``y``, ``flux``, ``status`` (int8) and the window on (pose,
        shot[, hole]) numbered from 0, ``alpha``, ``beta`` when given, the ``extra`` variables.

    Examples
    --------
    >>> centroids_dataset([[1.0, float("nan")]], [[2.0, float("nan")]]).status.values.tolist()
    [[0, 1]]
    """
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    if x.shape != y.shape or x.ndim not in (2, 3):
        raise SchemaError("x, y", f"shapes {x.shape}, {y.shape}",
                          "equal (pose, shot[, hole]) shapes")
    dims = ("pose", "shot", "hole")[: x.ndim]
    if status is None:
        status = np.where(np.isfinite(x) & np.isfinite(y), STATUS["ok"], STATUS["no_spot"])
    flags = {"flag_values": np.array(list(STATUS.values()), dtype=np.int8),
             "flag_meanings": " ".join(STATUS)}
    data = {
        "x": (dims, x, {"units": "px", "long_name": "spot centroid column"}),
        "y": (dims, y, {"units": "px", "long_name": "spot centroid row"}),
        "flux": (dims, np.full(x.shape, np.nan) if flux is None else np.asarray(flux, float),
                 {"units": "DN", "long_name": "background-subtracted spot flux"}),
        "status": (dims, np.asarray(status, dtype=np.int8), flags),
        **{name: (dims, np.asarray(bound, dtype=np.int32), {"units": "px"}) for name, bound in
           zip(("x0", "x1", "y0", "y1"), [np.full(x.shape, -1)] * 4 if window is None
               else window, strict=True)},
        **dict(extra or {}),
    }
    coords = {d: np.arange(n) for d, n in zip(dims, x.shape, strict=True)}
    for name, angle in (("alpha", alpha), ("beta", beta)):
        if angle is not None:
            coords[name] = ("pose", np.asarray(angle, dtype=float), {"units": "deg"})
    return validate_centroids(xr.Dataset(data, coords=coords, attrs={
        **dict(attrs or {}), "sunlab_schema": CENTROIDS_SCHEMA, "method": str(method)}))


def validate_centroids(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` is a centroid table of contract ``centroids/1``; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        The table: dims of ``x`` (pose, shot[, hole]) shared by ``y``, ``flux``, ``status``
        and the window, known status codes, and the JSON Schema of ``centroids/1``.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself; a :class:`SchemaError` names the first field at fault.
    """
    if not isinstance(ds, xr.Dataset):
        raise SchemaError("centroids", type(ds).__name__, "an xarray.Dataset")
    _check_contract(ds.attrs.get("sunlab_schema"), CENTROIDS_SCHEMA, "attrs['sunlab_schema']")
    _check_dims(ds, "x", [("pose", "shot"), ("pose", "shot", "hole")])
    for name in ("y", "flux", "status", "x0", "x1", "y0", "y1"):
        _check_dims(ds, name, [ds["x"].dims])
    _check_indices(ds)
    _check_json_schema(_jsonable(ds.to_dict(data=False)), CENTROIDS_SCHEMA, _dataset_field)
    unknown = sorted(set(np.unique(ds["status"].values).tolist()) - set(STATUS.values()))
    if unknown:
        raise SchemaError("status", unknown, f"codes in {STATUS}")
    return ds


def _check_json_values(value, path: list) -> None:
    """Strict JSON: plain types only, finite numbers; raise naming the first offending value."""
    field = _json_field(path)
    if isinstance(value, Mapping | list | tuple):
        for k, v in (value.items() if isinstance(value, Mapping) else enumerate(value)):
            if isinstance(value, Mapping) and not isinstance(k, str):
                raise SchemaError(field, f"key {k!r} of type {type(k).__name__}", "string keys",
                                  "JSON object keys are strings: convert the key with str()")
            _check_json_values(v, [*path, k])
    elif isinstance(value, float) and not math.isfinite(value):
        raise SchemaError(field, value, "a finite number", "strict JSON has no NaN or Infinity: "
                          "write null (None) for a missing value")
    elif not (value is None or isinstance(value, str | int | float)):
        raise SchemaError(field, f"a value of type {type(value).__name__}",
                          "a JSON value: number, string, boolean, null, list or object",
                          "convert arrays with .tolist() and numpy scalars with float() or "
                          "int(); never embed pickles or binary blobs")


def validate_calibration(doc: Mapping) -> Mapping:
    """Check a calibration artifact (contract ``calibration/1``); return it unchanged.

    The artifact is one strict JSON document (``data_schema/calibration-1.schema.json``)::

        {"sunlab_schema": "calibration/1", "kind": "polynomial", "sunlab_version": "0.1.0",
         "parameters": {...}, "training": {...}, "domain": {"alpha": [lo, hi], "beta": [lo, hi],
         "x": [lo, hi], "y": [lo, hi]}, "residuals": {"alpha": {...}, "beta": {...}}}

    Angles in the domain and residuals are degrees; x, y are pixels.

    Parameters
    ----------
    doc : mapping
        The document, as built before ``json.dump`` or as read by ``json.load``.

    Returns
    -------
    mapping
        ``doc`` itself; a :class:`SchemaError` names the first field at fault (a dotted path
        such as ``domain.alpha[1]``), the value found, the value expected and the fix.
    """
    if not isinstance(doc, Mapping):
        raise SchemaError(
            "calibration", type(doc).__name__, f"a JSON object of contract {CALIBRATION_SCHEMA!r}",
            "read the file with json.load or sunlab.calibration.load")
    _check_contract(doc.get("sunlab_schema"), CALIBRATION_SCHEMA, "sunlab_schema")
    _check_json_values(doc, [])
    _check_json_schema(_jsonable(doc), CALIBRATION_SCHEMA, _json_field)
    for name in ("alpha", "beta", "x", "y"):
        low, high = doc["domain"][name]
        if low > high:
            raise SchemaError(f"domain.{name}", [low, high], "[low, high] with low <= high",
                              "swap the bounds")
    return doc
