"""The on-disk data contract: build and validate frame cubes and centroid tables.

The contract is written down as JSON Schema files shipped with the package in ``sunlab/schemas/``
(``data_schema/`` at the top of the repository holds the prose and relative links to the same
files). This module builds datasets that follow it and checks datasets read from disk, raising
:class:`sunlab.SchemaError` with the field, the value found, the value expected and the fix.

Every check runs in two stages: explicit Python checks first (they give the most specific
messages and check what JSON Schema cannot, such as the DN range), then the JSON Schema file
itself against ``ds.to_dict(data=False)``, so the code and the published contract cannot drift.

Conventions (``docs/nomenclature.md``): pixel coordinates are (x = column, y = row) with the
centre of the first pixel at 0; angles are degrees; poses are a flat dimension.

Examples
--------
>>> import numpy as np
>>> from sunlab import schema
>>> cube = schema.frames_dataset(np.zeros((2, 8, 4, 5), np.uint16), alpha=[0.0, 1.0],
...                              beta=[0.0, 0.0])
>>> cube.frames.dims
('pose', 'shot', 'y', 'x')
>>> schema.validate_frames(cube).attrs["sunlab_schema"]
'frames/1'
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

__all__ = ["STATUS", "frames_dataset", "centroids_dataset"]

FRAMES_SCHEMA = "frames/1"
CENTROIDS_SCHEMA = "centroids/1"
CALIBRATION_SCHEMA = "calibration/1"

#: JSON Schema file of each contract, in ``sunlab/schemas/`` (package data).
SCHEMA_FILES: dict[str, str] = {
    FRAMES_SCHEMA: "frames-1.schema.json",
    CENTROIDS_SCHEMA: "centroids-1.schema.json",
    CALIBRATION_SCHEMA: "calibration-1.schema.json",
}

#: Centroid status codes (CF ``flag_values`` / ``flag_meanings`` on the ``status`` variable).
STATUS: dict[str, int] = {
    "ok": 0,
    "no_spot": 1,
    "saturated": 2,
    "clipped": 3,
    "ambiguous": 4,
    "invalid": 5,
    # a usable spot whose window held isolated clipped pixels (hot pixels), each replaced by the
    # median of its 8 neighbours before the centre of mass: the spot itself is not saturated
    "repaired": 6,
}
STATUS_NAMES: dict[int, str] = {v: k for k, v in STATUS.items()}
#: Status codes whose centroid is usable for calibration and statistics.
USABLE_STATUS: tuple[str, ...] = ("ok", "repaired")

#: Bit flags of the ``hole_defect`` coordinate on ``hole`` of a simulated cube or centroid
#: table: which defects the virtual bench gave each hole (0: a good hole).
DEFECT_FLAGS: dict[str, int] = {"dust": 1, "elliptical": 2, "burred": 4, "undersized": 8}

#: The paper's detector (docs/paper.md sec. 1): Ibis4, 1280 x 1024 pixels of 7 um, 10-bit ADC.
IBIS4 = {"nx": 1280, "ny": 1024, "pixel_pitch_mm": 0.007, "bit_depth": 10}

_FRAME_DTYPES = (np.dtype(np.uint8), np.dtype(np.uint16))
_SENSOR_ATTRS = {
    "pixel_pitch_mm": "pixel pitch in mm (Ibis4: 0.007)",
    "mask_distance_mm": "nominal mask-to-focal-plane distance F in mm",
    "x_cf_px": "column of the design projection of the hole centre (sun at zenith), px",
    "y_cf_px": "row of the design projection of the hole centre (sun at zenith), px",
    "bit_depth": "ADC bit depth (Ibis4: 10)",
}


def status_name(code: int) -> str:
    """Name of a centroid status code, e.g. ``status_name(1) == 'no_spot'``.

    Parameters
    ----------
    code : int
        A code of :data:`STATUS` (0 .. 6).

    Returns
    -------
    str
        Its name (``"ok"``, ``"no_spot"``, ...); a KeyError for a code not in :data:`STATUS`.
    """
    return STATUS_NAMES[int(code)]


def schema_file(contract: str):
    """The JSON Schema file of a contract, shipped as package data in ``sunlab/schemas/``.

    Parameters
    ----------
    contract : str
        ``"frames/1"``, ``"centroids/1"`` or ``"calibration/1"``.

    Returns
    -------
    importlib.resources.abc.Traversable
        The file (a :class:`pathlib.Path` for an ordinary installation).

    Examples
    --------
    >>> schema_file("frames/1").name
    'frames-1.schema.json'
    """
    name = SCHEMA_FILES.get(contract)
    if name is None:
        raise SchemaError(
            "contract", contract, f"one of {sorted(SCHEMA_FILES)}",
            "name a contract and version this sunlab knows, e.g. 'frames/1'",
        )
    return resources.files("sunlab").joinpath("schemas", name)


@functools.lru_cache(maxsize=len(SCHEMA_FILES))
def _schema_text(contract: str) -> str:
    return schema_file(contract).read_text(encoding="utf-8")


def json_schema(contract: str) -> dict:
    """The JSON Schema (draft 2020-12) of a contract, as a new dict.

    Parameters
    ----------
    contract : str
        ``"frames/1"``, ``"centroids/1"`` or ``"calibration/1"``.

    Returns
    -------
    dict
        The parsed schema file (:func:`schema_file`); the caller may change it.

    Examples
    --------
    >>> json_schema("centroids/1")["properties"]["attrs"]["required"]
    ['sunlab_schema', 'method']
    """
    return json.loads(_schema_text(contract))


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
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _short(value, limit: int = 80):
    """A value for an error message: small values as they are, large ones summarised."""
    if isinstance(value, Mapping):
        value = f"an object with keys {sorted(map(str, value))}"
    text = repr(value)
    if len(text) <= limit:
        return value
    return text[: limit - 5] + " ...)"


def _dataset_field(path: Sequence) -> str:
    """``['data_vars', 'frames', 'dtype']`` -> ``'frames.dtype'``; attrs -> ``attrs['name']``."""
    path = [str(p) for p in path]
    if not path:
        return "dataset"
    if path[0] in ("attrs", "dims"):
        return path[0] + "".join(f"[{p!r}]" for p in path[1:])
    if path[0] in ("data_vars", "coords") and len(path) > 1:
        field = path[1]
        rest = path[2:]
        if rest[:1] == ["attrs"]:
            return field + ".attrs" + "".join(f"[{p!r}]" for p in rest[1:])
        return ".".join([field, *rest])
    return ".".join(path)


def _json_field(path: Sequence) -> str:
    """``['domain', 'alpha', 1]`` -> ``'domain.alpha[1]'``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "document"


def _check_json_schema(instance, contract: str, field_of, fix: str | None = None) -> None:
    """Validate ``instance`` against the contract's JSON Schema; raise the most relevant error."""
    from jsonschema.exceptions import best_match

    error = best_match(_validator(contract).iter_errors(instance))
    if error is None:
        return
    path = list(error.absolute_path)
    if error.validator == "required" and isinstance(error.instance, Mapping):
        missing = [k for k in error.validator_value if k not in error.instance]
        name = missing[0] if missing else "?"
        prop = error.schema.get("properties", {}).get(name, {})
        expected = prop.get("description") or f"a required field {name!r}"
        raise SchemaError(
            field_of([*path, name]), "missing", expected,
            fix or f"add {name!r}; the contract is data_schema/{SCHEMA_FILES[contract]}",
        )
    expected = error.schema.get("description") if isinstance(error.schema, Mapping) else None
    expected = f"{expected} ({error.message})" if expected else error.message
    raise SchemaError(
        field_of(path), _short(error.instance), expected,
        fix or f"correct the value; the contract is data_schema/{SCHEMA_FILES[contract]}",
    )


def _sensor_attrs(
    pixel_pitch_mm: float | None,
    mask_distance_mm: float | None,
    x_cf_px: float,
    y_cf_px: float,
    bit_depth: int,
) -> dict:
    attrs = {
        "pixel_pitch_mm": None if pixel_pitch_mm is None else float(pixel_pitch_mm),
        "mask_distance_mm": None if mask_distance_mm is None else float(mask_distance_mm),
        "x_cf_px": float(x_cf_px),
        "y_cf_px": float(y_cf_px),
        "bit_depth": int(bit_depth),
    }
    return {k: v for k, v in attrs.items() if v is not None}  # geometry not said: left out


def frames_dataset(
    frames,
    alpha: Sequence[float],
    beta: Sequence[float],
    *,
    pixel_pitch_mm: float | None = IBIS4["pixel_pitch_mm"],
    mask_distance_mm: float | None = 5.0,
    x_cf_px: float | None = None,
    y_cf_px: float | None = None,
    bit_depth: int = IBIS4["bit_depth"],
    mask: str = "single",
    experiment: str = "",
    coords: Mapping[str, tuple] | None = None,
    attrs: Mapping | None = None,
) -> xr.Dataset:
    """Build a frame cube (contract ``frames/1``) from an array of frames.

    Parameters
    ----------
    frames : array_like of uint8 or uint16, shape (pose, shot, y, x)
        Raw frames in digital numbers (DN). NumPy or Dask arrays.
    alpha, beta : sequence of float, length pose
        Commanded platform angles of each pose, degrees (outer axis alpha, inner axis beta).
    pixel_pitch_mm : float or None
        Pixel pitch, mm; None leaves it out (not known: the methods that need it ask).
    mask_distance_mm : float or None
        Nominal mask-to-focal-plane distance F, mm; None leaves it out, as the pitch.
    x_cf_px, y_cf_px : float, optional
        Design projection of the hole centre (the spot centroid with the sun at zenith), px.
        Default: the centre of the detector.
    bit_depth : int
        ADC bit depth; every DN must be below ``2**bit_depth``.
    mask : str
        Mask description, e.g. ``"single"`` or ``"grid10x10"``.
    experiment : str
        Experiment name, e.g. ``"I"``.
    coords : mapping, optional
        Extra coordinates as ``name: (dims, values[, attrs])``, e.g. ``alpha_read`` on
        ``("pose", "shot")``.
    attrs : mapping, optional
        Extra attributes.

    Returns
    -------
    xarray.Dataset
        A validated frame cube.

    Examples
    --------
    >>> import numpy as np
    >>> cube = frames_dataset(np.zeros((1, 2, 3, 4), np.uint16), alpha=[0.0], beta=[1.0])
    >>> dict(cube.sizes)
    {'pose': 1, 'shot': 2, 'y': 3, 'x': 4}
    """
    if not hasattr(frames, "dtype"):
        frames = np.asarray(frames)
    if frames.ndim != 4:
        raise SchemaError(
            "frames", f"{frames.ndim}-d array of shape {frames.shape}", "4-d (pose, shot, y, x)",
            "stack single frames as frames[None, None] or reshape to (pose, shot, y, x)",
        )
    n_pose, n_shot, ny, nx = frames.shape
    alpha, beta = _pose_angles(alpha, beta, n_pose)
    all_attrs = {
        "sunlab_schema": FRAMES_SCHEMA,
        **_sensor_attrs(pixel_pitch_mm, mask_distance_mm,
                        (nx - 1) / 2 if x_cf_px is None else x_cf_px,
                        (ny - 1) / 2 if y_cf_px is None else y_cf_px, bit_depth),
        "mask": str(mask), "experiment": str(experiment), **(attrs or {}),
    }
    coords = {
        "pose": np.arange(n_pose), "shot": np.arange(n_shot),
        "alpha": ("pose", alpha, {"units": "deg", "long_name": "commanded outer-axis angle"}),
        "beta": ("pose", beta, {"units": "deg", "long_name": "commanded inner-axis angle"}),
        **dict(coords or {}),
    }
    frames = {"frames": (("pose", "shot", "y", "x"), frames, {"units": "DN"})}
    return validate_frames(xr.Dataset(frames, coords=coords, attrs=all_attrs))


def _pose_angles(alpha, beta, n_pose: int) -> tuple[np.ndarray, np.ndarray]:
    """The commanded angles as float arrays, one per pose."""
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    for name, val in (("alpha", alpha), ("beta", beta)):
        if val.shape != (n_pose,):
            raise SchemaError(name, f"shape {val.shape}", f"shape ({n_pose},), one angle per pose")
    return alpha, beta


def empty_frames(
    n_pose: int,
    n_shot: int,
    alpha: Sequence[float],
    beta: Sequence[float],
    *,
    ny: int = IBIS4["ny"],
    nx: int = IBIS4["nx"],
    dtype=np.uint16,
    **kwargs,
) -> xr.Dataset:
    """A lazily allocated (Dask zeros) frame cube, chunked one frame per chunk.

    Used to pre-allocate an acquisition store. Keyword arguments go to :func:`frames_dataset`.

    Parameters
    ----------
    n_pose, n_shot : int
        Poses and shots per pose.
    alpha, beta : sequence of float, length n_pose
        Commanded platform angles of each pose, deg.
    ny, nx : int
        Frame rows and columns, px (default the Ibis4's 1024 x 1280).
    dtype : numpy.dtype
        ``uint8`` or ``uint16`` DN.
    **kwargs
        Sensor attributes and the rest of :func:`frames_dataset`.

    Returns
    -------
    xarray.Dataset
        A validated ``frames/1`` cube of zeros, ``frames`` (pose, shot, y, x) a Dask array with
        one chunk per frame (nothing is allocated until computed).

    Examples
    --------
    >>> cube = empty_frames(3, 8, alpha=[0, 1, 2], beta=[0, 0, 0])
    >>> cube.frames.data.chunksize
    (1, 1, 1024, 1280)
    """
    import dask.array as da

    frames = da.zeros((n_pose, n_shot, ny, nx), dtype=dtype, chunks=(1, 1, ny, nx))
    return frames_dataset(frames, alpha, beta, **kwargs)


def _check_schema_attr(ds: xr.Dataset, expected: str) -> None:
    found = ds.attrs.get("sunlab_schema")
    if found is None:
        raise SchemaError(
            "attrs['sunlab_schema']", None, repr(expected),
            "build the dataset with sunlab.schema or set the attribute after checking the layout",
        )
    if found != expected:
        family, _, version = str(found).partition("/")
        if family == expected.partition("/")[0]:
            fix = (
                f"this sunlab reads {expected!r} but the file holds version {version!r}: open it "
                "with the sunlab version that wrote it (see attrs['sunlab_version'] if present) "
                "and save it again, or upgrade sunlab"
            )
        elif found in SCHEMA_FILES:
            fix = (
                f"this is a {found!r} dataset, not {expected!r}: open a frame cube with "
                "sunlab.io.open_frames, a centroid table with sunlab.io.open_centroids"
            )
        else:
            fix = "rebuild the dataset with sunlab.schema"
        raise SchemaError("attrs['sunlab_schema']", found, repr(expected), fix)


def _check_dims(ds: xr.Dataset, var: str, allowed: Sequence[tuple[str, ...]]) -> None:
    if var not in ds.variables:
        raise SchemaError(
            var, f"missing (variables: {sorted(map(str, ds.variables))})",
            f"a variable {var!r} on dims {' or '.join(map(str, allowed))}",
            f"add {var!r} (build the dataset with sunlab.schema), or check that this is the "
            "kind of dataset you meant: sunlab.io.open_frames for frame cubes, "
            "sunlab.io.open_centroids for centroid tables",
        )
    dims = tuple(map(str, ds[var].dims))
    if dims not in [tuple(a) for a in allowed]:
        fix = None
        if sorted(dims) in [sorted(a) for a in allowed]:
            fix = f"reorder with ds[{var!r}].transpose(*{allowed[0]!r})"
        raise SchemaError(f"{var}.dims", dims, " or ".join(map(str, allowed)), fix)


def _check_indices(ds: xr.Dataset, dims=("pose", "shot")) -> None:
    """The index coordinates ``pose`` and ``shot`` are 0 .. n-1, as the contract says."""
    for dim in dims:
        if dim not in ds.coords:
            continue
        values = np.asarray(ds[dim].values)
        n = values.size
        if values.dtype.kind not in "iu" or not np.array_equal(values, np.arange(n)):
            raise SchemaError(
                f"coords[{dim!r}]", _short(values.tolist()), f"the integers 0 .. {n - 1}",
                f"renumber with ds.assign_coords({dim}=np.arange(ds.sizes[{dim!r}])); keep "
                "labels of your own in another coordinate (e.g. 'shot_label')",
            )


def _check_dn(ds: xr.Dataset) -> None:
    """In-memory frames: every DN below 2**bit_depth. (Lazy frames are checked on read/write.)"""
    frames = ds["frames"]
    bits = int(ds.attrs["bit_depth"])
    if frames.chunks is not None or frames.size == 0 or bits >= 8 * frames.dtype.itemsize:
        return
    peak = int(np.asarray(frames.values).max())
    if peak >= 2**bits:
        n_over = int((np.asarray(frames.values) >= 2**bits).sum())
        raise SchemaError(
            "frames", f"DN up to {peak} ({n_over} pixels >= {2**bits})",
            f"DN < 2**{bits} = {2**bits} for attrs['bit_depth'] = {bits}",
            "give the true ADC bit depth (frames_dataset(bit_depth=...)); if the camera "
            "left-aligns its data in the 16-bit word, divide the frames by 2**(16 - bit_depth)",
        )


def validate_frames(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` is a frame cube of contract ``frames/1``; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        The cube to check: dims, dtypes, finite angles, the sensor attributes, DN below
        ``2**bit_depth`` (in-memory frames only: lazy ones are not read) and the JSON Schema
        of ``frames/1``.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself.

    Raises
    ------
    SchemaError
        Naming the first field that breaks the contract, the value found and the fix.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> try:
    ...     validate_frames(xr.Dataset({"img": (("y", "x"), np.zeros((2, 2)))}))
    ... except SchemaError as err:
    ...     print(err.field)
    attrs['sunlab_schema']
    """
    if not isinstance(ds, xr.Dataset):
        raise SchemaError("cube", type(ds).__name__, "an xarray.Dataset", "open it with sunlab.io")
    _check_schema_attr(ds, FRAMES_SCHEMA)
    _check_dims(ds, "frames", [("pose", "shot", "y", "x")])
    dtype = ds["frames"].dtype
    if dtype not in _FRAME_DTYPES:
        raise SchemaError(
            "frames.dtype", str(dtype), "uint8 or uint16 digital numbers",
            "convert with np.asarray(frames).astype(np.uint16) after checking the range",
        )
    for name in ("alpha", "beta"):
        _check_dims(ds, name, [("pose",)])
        if not np.issubdtype(ds[name].dtype, np.floating):
            raise SchemaError(f"{name}.dtype", str(ds[name].dtype), "float degrees")
        if not np.all(np.isfinite(ds[name].values)):
            raise SchemaError(name, "non-finite angles", "finite commanded angles in degrees")
    for name in ("alpha_read", "beta_read", "time", "true_alpha", "true_beta"):
        if name in ds.variables:
            _check_dims(ds, name, [("pose", "shot")])
    for name in ("true_x", "true_y"):
        if name in ds.variables:
            _check_dims(ds, name, [("pose", "shot"), ("pose", "shot", "hole")])
    for name, meaning in _SENSOR_ATTRS.items():
        value = ds.attrs.get(name)
        fix = f"set cube.attrs[{name!r}] (frames_dataset takes it as a keyword)"
        if value is None and name in ("pixel_pitch_mm", "mask_distance_mm"):
            continue  # not said (a lab's frames): the methods that need it ask for it
        if value is None:
            raise SchemaError(f"attrs[{name!r}]", None, meaning, fix)
        if isinstance(value, bool | np.bool_ | str) or not np.isscalar(value):
            raise SchemaError(f"attrs[{name!r}]", value, f"a number: {meaning}", fix)
        positive = name not in ("x_cf_px", "y_cf_px")
        if not np.isfinite(float(value)) or (positive and value <= 0):
            raise SchemaError(f"attrs[{name!r}]", value, meaning, fix)
    bits = ds.attrs["bit_depth"]
    if isinstance(bits, bool | np.bool_) or float(bits) != int(bits):
        raise SchemaError("attrs['bit_depth']", bits, "an integer number of bits, e.g. 10")
    if int(bits) > 8 * dtype.itemsize:
        raise SchemaError(
            "attrs['bit_depth']", bits, f"<= {8 * dtype.itemsize} for {dtype} frames",
            "store frames of more than 8 bits as uint16",
        )
    if int(bits) < 1:
        raise SchemaError("attrs['bit_depth']", bits, "an integer number of bits >= 1, e.g. 10")
    _check_indices(ds)
    _check_dn(ds)
    _check_json_schema(_jsonable(ds.to_dict(data=False)), FRAMES_SCHEMA, _dataset_field)
    return ds


def centroids_dataset(
    x,
    y,
    *,
    flux=None,
    status=None,
    window=None,
    alpha=None,
    beta=None,
    method: str = "",
    attrs: Mapping | None = None,
    extra: Mapping[str, tuple] | None = None,
) -> xr.Dataset:
    """Build a centroid table (contract ``centroids/1``).

    Parameters
    ----------
    x, y : array_like, shape (pose, shot) or (pose, shot, hole)
        Spot centroid, px (x = column, y = row, centre of the first pixel = 0). NaN where no
        usable spot was found.
    flux : array_like, optional
        Background-subtracted spot flux in the window, DN.
    status : array_like of int, optional
        Status codes of :data:`STATUS`; default ``ok`` where x is finite, ``no_spot`` elsewhere.
    window : tuple of 4 array_like, optional
        Window bounds ``(x0, x1, y0, y1)``, half-open pixel ranges; -1 where no window.
    alpha, beta : array_like of length pose, optional
        Commanded angles, degrees, carried over from the frame cube.
    method : str
        Name of the centroid method.
    attrs : mapping, optional
        Extra attributes (e.g. the cube's sensor attributes).
    extra : mapping, optional
        Extra data variables as ``name: (dims, values[, attrs])`` (quality metrics).

    Returns
    -------
    xarray.Dataset
        A validated ``centroids/1`` table: ``x``, ``y`` (px), ``flux`` (DN), ``status`` (int8),
        the window ``x0``, ``x1``, ``y0``, ``y1`` on (pose, shot[, hole]); coordinates ``pose``,
        ``shot`` (and ``hole``) numbered from 0, ``alpha``, ``beta`` (deg) when given; the
        ``extra`` variables.

    Examples
    --------
    >>> import numpy as np
    >>> cen = centroids_dataset(np.array([[1.0, np.nan]]), np.array([[2.0, np.nan]]))
    >>> cen.status.values.tolist()
    [[0, 1]]
    """
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    if x.shape != y.shape or x.ndim not in (2, 3):
        raise SchemaError(
            "x, y", f"shapes {x.shape}, {y.shape}", "equal (pose, shot[, hole]) shapes"
        )
    dims = ("pose", "shot", "hole")[: x.ndim]
    if status is None:
        status = np.where(np.isfinite(x) & np.isfinite(y), STATUS["ok"], STATUS["no_spot"])
    status = np.asarray(status, dtype=np.int8)
    flux = np.full(x.shape, np.nan) if flux is None else np.asarray(flux, dtype=float)
    if window is None:
        window = [np.full(x.shape, -1, dtype=np.int32)] * 4
    data = {**_centroid_variables(dims, x, y, flux, status, window), **dict(extra or {})}
    coords = {"pose": np.arange(x.shape[0]), "shot": np.arange(x.shape[1])}
    if x.ndim == 3:
        coords["hole"] = np.arange(x.shape[2])
    if alpha is not None:
        coords["alpha"] = ("pose", np.asarray(alpha, dtype=float), {"units": "deg"})
    if beta is not None:
        coords["beta"] = ("pose", np.asarray(beta, dtype=float), {"units": "deg"})
    ds = xr.Dataset(
        data,
        coords=coords,
        attrs={**dict(attrs or {}), "sunlab_schema": CENTROIDS_SCHEMA, "method": str(method)},
    )
    return validate_centroids(ds)


def _centroid_variables(dims, x, y, flux, status, window) -> dict:
    """The variables of a ``centroids/1`` table, with their units and status flags."""
    data = {
        "x": (dims, x, {"units": "px", "long_name": "spot centroid column"}),
        "y": (dims, y, {"units": "px", "long_name": "spot centroid row"}),
        "flux": (dims, flux, {"units": "DN", "long_name": "background-subtracted spot flux"}),
        "status": (
            dims,
            status,
            {
                "flag_values": np.array(list(STATUS.values()), dtype=np.int8),
                "flag_meanings": " ".join(STATUS),
            },
        ),
    }
    for name, bound in zip(("x0", "x1", "y0", "y1"), window, strict=True):
        data[name] = (dims, np.asarray(bound, dtype=np.int32), {"units": "px"})
    return data


def validate_centroids(ds: xr.Dataset) -> xr.Dataset:
    """Check that ``ds`` is a centroid table of contract ``centroids/1``; return it unchanged.

    Parameters
    ----------
    ds : xarray.Dataset
        The table to check: dims of ``x`` (pose, shot) or (pose, shot, hole) shared by ``y``,
        ``flux``, ``status`` and the window, known status codes, and the JSON Schema of
        ``centroids/1``.

    Returns
    -------
    xarray.Dataset
        ``ds`` itself.

    Raises
    ------
    SchemaError
        Naming the first field that breaks the contract, the value found and the fix.

    Examples
    --------
    >>> import numpy as np
    >>> cen = centroids_dataset(np.zeros((2, 3)), np.zeros((2, 3)))
    >>> validate_centroids(cen) is cen
    True
    """
    if not isinstance(ds, xr.Dataset):
        raise SchemaError("centroids", type(ds).__name__, "an xarray.Dataset")
    _check_schema_attr(ds, CENTROIDS_SCHEMA)
    allowed = [("pose", "shot"), ("pose", "shot", "hole")]
    _check_dims(ds, "x", allowed)
    dims = ds["x"].dims
    for name in ("y", "flux", "status", "x0", "x1", "y0", "y1"):
        _check_dims(ds, name, [dims])
    if not np.issubdtype(ds["status"].dtype, np.integer):
        raise SchemaError("status.dtype", str(ds["status"].dtype), "integer status codes")
    codes = np.unique(np.asarray(ds["status"].values))
    unknown = sorted(set(codes.tolist()) - set(STATUS.values()))
    if unknown:
        raise SchemaError("status", unknown, f"codes in {STATUS}")
    _check_indices(ds)
    _check_json_schema(_jsonable(ds.to_dict(data=False)), CENTROIDS_SCHEMA, _dataset_field)
    return ds


def _check_json_values(value, path: list) -> None:
    """Strict JSON: plain types only, finite numbers; raise naming the first offending value."""
    if isinstance(value, Mapping):
        for k, v in value.items():
            if not isinstance(k, str):
                raise SchemaError(
                    _json_field(path), f"key {k!r} of type {type(k).__name__}", "string keys",
                    "JSON object keys are strings: convert the key with str()",
                )
            _check_json_values(v, [*path, k])
    elif isinstance(value, list | tuple):
        for i, v in enumerate(value):
            _check_json_values(v, [*path, i])
    elif isinstance(value, float):
        if not math.isfinite(value):
            raise SchemaError(
                _json_field(path), value, "a finite number",
                "strict JSON has no NaN or Infinity: write null (None) for a missing value",
            )
    elif value is None or isinstance(value, str | int):
        return
    else:
        raise SchemaError(
            _json_field(path), f"a value of type {type(value).__name__}",
            "a JSON value: number, string, boolean, null, list or object",
            "convert arrays with .tolist() and numpy scalars with float() or int(); "
            "never embed pickles or binary blobs",
        )


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
        ``doc`` itself.

    Raises
    ------
    SchemaError
        Naming the first field at fault (a dotted path such as ``domain.alpha[1]``), the value
        found, the value expected and the fix.

    Examples
    --------
    >>> doc = {"sunlab_schema": "calibration/1", "kind": "polynomial", "sunlab_version": "0.1.0",
    ...        "parameters": {"degree": 3, "coef_alpha": [0.1, 0.2]}, "training": {"n_samples": 8},
    ...        "domain": {"alpha": [-30, 30], "beta": [-30, 30], "x": [10, 1270], "y": [5, 1010]},
    ...        "residuals": {"alpha": {"rms": 0.01}, "beta": {"rms": 0.02}}}
    >>> validate_calibration(doc)["kind"]
    'polynomial'
    >>> doc["domain"]["alpha"] = [30, -30]
    >>> try:
    ...     validate_calibration(doc)
    ... except SchemaError as err:
    ...     print(err.field)
    domain.alpha
    """
    if not isinstance(doc, Mapping):
        raise SchemaError(
            "calibration", type(doc).__name__, f"a JSON object of contract {CALIBRATION_SCHEMA!r}",
            "read the file with json.load or sunlab.calibration.load",
        )
    found = doc.get("sunlab_schema")
    if found != CALIBRATION_SCHEMA:
        fix = (
            "set 'sunlab_schema': 'calibration/1' when writing the artifact"
            if found is None
            else "this sunlab reads 'calibration/1': refit with this version, or load the file "
            "with the sunlab version that wrote it"
        )
        raise SchemaError("sunlab_schema", found if found is not None else "missing",
                          repr(CALIBRATION_SCHEMA), fix)
    _check_json_values(doc, [])
    _check_json_schema(_jsonable(doc), CALIBRATION_SCHEMA, _json_field)
    for name in ("alpha", "beta", "x", "y"):
        low, high = doc["domain"][name]
        if low > high:
            raise SchemaError(
                f"domain.{name}", [low, high], "[low, high] with low <= high", "swap the bounds"
            )
    return doc
