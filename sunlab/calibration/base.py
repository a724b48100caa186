"""The common interface of every calibration function, and the ``calibration/1`` JSON artifact.

A calibration maps a spot centroid ``(x, y)`` (px) to platform angles ``(alpha, beta)`` (deg):
``alpha = f1(x, y)``, ``beta = f2(x, y)`` (docs/paper.md sec. 4). Every method in
:mod:`sunlab.calibration` is a :class:`Calibration` with the same three verbs:

- ``fit(train, validation=None)`` on ``centroids/1`` tables with the commanded angles as
  coordinates ``alpha``, ``beta`` on ``pose``. Only shots of status ``ok`` with finite x, y are
  used. By default (``average="pose"``) each pose contributes the mean centroid of its ok shots,
  so every pose weighs the same whatever number of shots survived; ``average="shot"`` fits every
  ok shot instead (least squares on shots equals least squares on pose means weighted by the
  number of ok shots). Interpolation always uses pose means (its nodes must be unique).
- ``predict(centroids)`` returns an ``xarray.Dataset`` with the estimates ``alpha``, ``beta``
  (deg) on the dims of ``x`` (NaN where x or y is NaN), the table's ``status``, and the commanded
  angles renamed ``alpha_cmd``, ``beta_cmd`` (a dataset cannot hold a variable and a coordinate
  of the same name). :meth:`Calibration.predict_xy` does the same on plain arrays.
- ``save(path)`` writes JSON (contract ``calibration/1``, no pickle); :func:`load` restores it.

The artifact holds ``sunlab_schema``, ``kind``, ``sunlab_version``, ``parameters`` (kind-specific,
numbers as lists), ``training`` (the table it was fitted on), ``domain`` (``[low, high]`` of
the training angles ``alpha``, ``beta`` in deg and centroids ``x``, ``y`` in px: the calibration
is only trusted inside them) and ``residuals``: per-shot errors estimated - commanded over the
ok shots of the training table, per angle (``mean``, ``mean_abs``, ``rms``, ``std``,
``max_abs``, ``n``; deg), and the same under ``residuals["validation"]`` for the validation
table (or null). The contract is ``data_schema/calibration-1.schema.json``.

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> from sunlab.calibration import Polynomial
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0, 2), np.arange(-2.0, 18.0, 2), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, delta_f_mm=0.1)
>>> est = Polynomial(order=5).fit(cen).predict(cen)
>>> float(abs(est.alpha - est.alpha_cmd).max()) < 1e-3
True
"""

from __future__ import annotations

import importlib
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import xarray as xr

from ..errors import ConfigurationError, SchemaError
from ..schema import CALIBRATION_SCHEMA, STATUS, validate_calibration, validate_centroids

__all__ = [
    "Calibration",
    "TrainingData",
    "KINDS",
    "load",
    "from_dict",
    "validate_document",
    "training_data",
    "sensor_attrs",
    "combine",
]

#: Registered kinds: ``kind`` of the artifact -> ``"module:Class"`` in sunlab.calibration (or a
#: full module path: the multi-hole strategies of :mod:`sunlab.multihole.strategies`).
KINDS: dict[str, str] = {
    "ideal": "model:IdealModel",
    "optimised": "model:OptimisedModel",
    "polynomial": "polynomial:Polynomial",
    "trigonometric": "trigonometric:Trigonometric",
    "interpolation-linear": "interpolation:Interpolation",
    "interpolation-cubic": "interpolation:Interpolation",
    "neural": "neural:NeuralNet",
    "multihole-geometric-centre": "sunlab.multihole.strategies:GeometricCentre",
    "multihole-per-hole-average": "sunlab.multihole.strategies:PerHoleAverage",
}

_REQUIRED = ("sunlab_schema", "kind", "sunlab_version", "parameters", "training", "domain",
             "residuals")
_SENSOR = ("mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px")
_AVERAGES = ("pose", "shot")


@dataclass(frozen=True)
class TrainingData:
    """Flat arrays a calibration is fitted on (one entry per pose mean or per ok shot).

    Attributes
    ----------
    x, y : numpy.ndarray
        Centroids, px.
    alpha, beta : numpy.ndarray
        Commanded platform angles, deg.
    n_poses : int
        Poses with at least one ok shot.
    n_shots : int
        Ok shots used.
    attrs : dict
        Attributes of the centroid table (sensor, experiment, centroid method).
    """

    x: np.ndarray
    y: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    n_poses: int
    n_shots: int
    attrs: dict


def _ok_mask(ds: xr.Dataset) -> np.ndarray:
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    return (np.asarray(ds["status"].values) == STATUS["ok"]) & np.isfinite(x) & np.isfinite(y)


def training_data(centroids: xr.Dataset, average: str = "pose", *, name: str = "train"):
    """Extract the usable calibration points of a ``centroids/1`` table.

    Parameters
    ----------
    centroids : xarray.Dataset
        Centroid table on ``(pose, shot)`` with coordinates ``alpha``, ``beta`` on ``pose``.
    average : {"pose", "shot"}
        ``"pose"``: one point per pose, the mean centroid of its ok shots; ``"shot"``: one point
        per ok shot.
    name : str
        Name of the argument, for error messages.

    Returns
    -------
    TrainingData

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab.schema import centroids_dataset
    >>> cen = centroids_dataset([[1.0, 3.0], [5.0, np.nan]], [[0.0, 2.0], [4.0, np.nan]],
    ...                         alpha=[0.0, 1.0], beta=[0.0, 0.0])
    >>> d = training_data(cen)
    >>> d.x.tolist(), d.n_shots
    ([2.0, 5.0], 3)
    """
    if average not in _AVERAGES:
        raise ConfigurationError(
            f"average: found {average!r}, expected one of {_AVERAGES}. Fix: pass 'pose' (mean of "
            "the ok shots of each pose) or 'shot' (every ok shot)"
        )
    if not isinstance(centroids, xr.Dataset):
        raise SchemaError(name, type(centroids).__name__, "a centroids/1 xarray.Dataset",
                          "build it with sunlab.schema.centroids_dataset or sunlab.centroid")
    validate_centroids(centroids)
    if tuple(centroids["x"].dims) != ("pose", "shot"):
        raise SchemaError(
            f"{name}.x.dims", tuple(centroids["x"].dims), "('pose', 'shot')",
            "fit one hole at a time (centroids.isel(hole=k)) or use sunlab.multihole",
        )
    for c in ("alpha", "beta"):
        if c not in centroids.coords:
            raise SchemaError(
                f"{name}.coords[{c!r}]", "missing", "commanded angles on 'pose', degrees",
                "keep the cube's alpha/beta coordinates when building the centroid table",
            )
    ok = _ok_mask(centroids)
    x = np.where(ok, centroids["x"].values, 0.0)
    y = np.where(ok, centroids["y"].values, 0.0)
    alpha = np.asarray(centroids["alpha"].values, dtype=float)
    beta = np.asarray(centroids["beta"].values, dtype=float)
    n = ok.sum(axis=1)
    keep = n > 0
    if average == "pose":
        xs = x.sum(axis=1)[keep] / n[keep]
        ys = y.sum(axis=1)[keep] / n[keep]
        a, b = alpha[keep], beta[keep]
    else:
        xs, ys = x[ok], y[ok]
        a = np.broadcast_to(alpha[:, None], ok.shape)[ok]
        b = np.broadcast_to(beta[:, None], ok.shape)[ok]
    if xs.size == 0:
        raise SchemaError(f"{name}.status", "no shot of status ok",
                          "at least one usable centroid", "check the centroiding step")
    return TrainingData(
        x=np.asarray(xs, dtype=float), y=np.asarray(ys, dtype=float),
        alpha=np.asarray(a, dtype=float), beta=np.asarray(b, dtype=float),
        n_poses=int(keep.sum()), n_shots=int(ok.sum()), attrs=dict(centroids.attrs),
    )


def sensor_attrs(attrs: dict, *, name: str = "train") -> dict:
    """The sensor attributes a geometric model needs, read from a table's attributes.

    Returns ``{"mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px"}`` as floats.

    Examples
    --------
    >>> sensor_attrs({"mask_distance_mm": 5, "pixel_pitch_mm": 0.007, "x_cf_px": 1, "y_cf_px": 2})
    {'mask_distance_mm': 5.0, 'pixel_pitch_mm': 0.007, 'x_cf_px': 1.0, 'y_cf_px': 2.0}
    """
    out = {}
    for key in _SENSOR:
        value = attrs.get(key)
        if value is None or not np.isfinite(float(value)):
            raise SchemaError(
                f"{name}.attrs[{key!r}]", value, "the sensor attribute of the frame cube",
                "carry the cube's attrs into the centroid table, or pass the value explicitly",
            )
        out[key] = float(value)
    return out


def combine(*tables: xr.Dataset) -> xr.Dataset:
    """Concatenate centroid tables along ``pose`` (e.g. experiments I + II for interpolation).

    The attributes of the first table are kept and ``pose`` is renumbered.

    Examples
    --------
    >>> from sunlab import sim
    >>> t = combine(sim.synthetic_centroids([0.0], [0.0]),
    ...             sim.synthetic_centroids([1.0], [2.0]))
    >>> t.sizes["pose"], t.beta.values.tolist()
    (2, [0.0, 2.0])
    """
    if not tables:
        raise ConfigurationError("tables: found none, expected at least one centroid table")
    for k, t in enumerate(tables):
        validate_centroids(t)
        if k and t["x"].dims != tables[0]["x"].dims:
            raise SchemaError(f"tables[{k}].x.dims", t["x"].dims, str(tables[0]["x"].dims))
    out = xr.concat([t.drop_vars("pose") for t in tables], dim="pose",
                    combine_attrs="override", data_vars="all", coords="different",
                    compat="equals")
    out = out.assign_coords(pose=np.arange(out.sizes["pose"]))
    return validate_centroids(out)


def _jsonable(obj):
    """Convert numpy scalars/arrays to plain Python; NaN/inf become None."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        return v if math.isfinite(v) else None
    return obj


def _err_summary(est: np.ndarray, ref: np.ndarray) -> dict:
    """Statistics of the signed error estimated - commanded (deg), ``calibration/1`` names."""
    e = np.asarray(est, dtype=float) - np.asarray(ref, dtype=float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {"mean": None, "mean_abs": None, "rms": None, "std": None, "max_abs": None,
                "n": 0}
    return {"mean": float(e.mean()), "mean_abs": float(np.abs(e).mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "std": float(e.std()),
            "max_abs": float(np.abs(e).max()), "n": int(e.size)}


class Calibration:
    """Base class of the calibration functions: fit, predict, save.

    Subclasses set :attr:`kind` and implement ``_fit(data, validation)``, ``_predict_xy(x, y)``,
    ``_parameters()`` and the classmethod ``_from_parameters(parameters)``.
    """

    #: The ``kind`` written to the artifact.
    kind: ClassVar[str] = ""
    #: How training points are formed: ``"pose"`` (pose means) or ``"shot"``.
    average: str = "pose"

    def __init__(self) -> None:
        self.training: dict | None = None
        self.domain: dict | None = None
        self.residuals: dict | None = None

    # --- the interface -------------------------------------------------------------------
    @property
    def is_fitted(self) -> bool:
        """Whether the calibration has been fitted (or loaded)."""
        return self.training is not None

    def fit(self, train: xr.Dataset, validation: xr.Dataset | None = None):
        """Fit the calibration on a training table; return ``self``.

        Parameters
        ----------
        train : xarray.Dataset
            ``centroids/1`` table on ``(pose, shot)`` with coordinates ``alpha``, ``beta``
            (experiment I in the paper).
        validation : xarray.Dataset, optional
            A second table (experiment II): early stopping of networks, order selection of
            polynomials, and the validation residuals of the artifact.
        """
        data = training_data(train, self.average, name="train")
        self._check_poses(data)
        val = None if validation is None else training_data(validation, self.average,
                                                               name="validation")
        self._fit(data, val)
        self.training = {
            "experiment": str(data.attrs.get("experiment", "")),
            "centroid_method": str(data.attrs.get("method", "")),
            "n_samples": int(data.x.size),
            "n_poses": data.n_poses,
            "n_shots": int(train.sizes["shot"]),
            "n_ok_shots": data.n_shots,
            "average": self.average,
            "validation": None if val is None else {
                "experiment": str(val.attrs.get("experiment", "")),
                "n_samples": int(val.x.size), "n_poses": val.n_poses,
                "n_shots": int(validation.sizes["shot"]), "n_ok_shots": val.n_shots,
            },
        }
        self.domain = {
            "alpha": [float(data.alpha.min()), float(data.alpha.max())],
            "beta": [float(data.beta.min()), float(data.beta.max())],
            "x": [float(data.x.min()), float(data.x.max())],
            "y": [float(data.y.min()), float(data.y.max())],
        }
        self.residuals = {**self._residuals(train),
                          "validation": None if validation is None
                          else self._residuals(validation),
                          **self._extra_residuals(data)}
        return self

    def min_poses(self) -> int:
        """Fewest distinct training poses (alpha, beta) this calibration can be fitted on.

        One per free coefficient of a linear model (a polynomial of order n has
        (n + 1)(n + 2) / 2 per angle), one per weight of a network; fewer poses would be fitted
        exactly whatever the data, with meaningless zero residuals.

        Examples
        --------
        >>> from sunlab.calibration import Polynomial
        >>> Polynomial(order=2).min_poses()
        6
        """
        return 1

    def _check_poses(self, data: TrainingData) -> None:
        distinct = len(set(zip(data.alpha.tolist(), data.beta.tolist(), strict=True)))
        need = self.min_poses()
        if distinct < need:
            raise ConfigurationError(
                f"train: {distinct} distinct poses (alpha, beta) in {data.n_poses} poses with "
                f"ok shots, but {self.label} needs at least {need}. Fix: calibrate on more "
                "distinct poses (a grid such as experiment I), or choose a smaller model"
            )

    def inside(self, x, y) -> np.ndarray:
        """True where a centroid ``(x, y)`` (px) lies inside the calibrated domain.

        The domain is the box ``domain['x'] x domain['y']`` of the training centroids (for
        interpolation: the convex hull of the nodes). Outside it, estimates are
        extrapolations and :meth:`predict` flags them (``in_domain`` False).

        Examples
        --------
        >>> from sunlab import sim
        >>> from sunlab.calibration import Polynomial
        >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
        >>> cal = Polynomial(order=1).fit(cen)
        >>> cal.inside([cal.domain["x"][0], 1e4], [cal.domain["y"][0], 0.0]).tolist()
        [True, False]
        """
        self.check_fitted()
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        (x0, x1), (y0, y1) = self.domain["x"], self.domain["y"]
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    def summary(self) -> str:
        """A human-readable account of the calibration: method, size, domain, errors, origin.

        The same text as ``sunlab info CAL.json``.
        """
        from .summary import calibration_summary

        return calibration_summary(self.to_dict())

    def predict_xy(self, x, y):
        """Angles (alpha, beta) in degrees for centroid arrays ``x``, ``y`` (px), any shape.

        NaN where x or y is not finite (and, for interpolation, outside the convex hull). No
        check of the domain: see :meth:`inside`, or :meth:`predict`, which flags extrapolation.
        """
        self.check_fitted()
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        bad = ~(np.isfinite(x) & np.isfinite(y))
        xs, ys = np.where(bad, 0.0, x), np.where(bad, 0.0, y)
        a, b = self._predict_xy(xs.ravel(), ys.ravel())
        a = np.where(bad, np.nan, np.reshape(a, x.shape))
        b = np.where(bad, np.nan, np.reshape(b, x.shape))
        return a, b

    def predict(self, centroids: xr.Dataset) -> xr.Dataset:
        """Estimated platform angles for every centroid of a ``centroids/1`` table.

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) on the dims of ``x``; ``status`` copied from the table;
            ``in_domain`` (bool): False where the centroid lies outside the calibrated domain
            (:meth:`inside`), so that the estimate there is an extrapolation (or NaN for a
            method that cannot extrapolate) — attribute ``n_out_of_domain`` counts them;
            coordinates ``alpha_cmd``, ``beta_cmd`` (the table's commanded angles, if any).
        """
        validate_centroids(centroids)
        a, b = self.predict_xy(centroids["x"].values, centroids["y"].values)
        finite = np.isfinite(centroids["x"].values) & np.isfinite(centroids["y"].values)
        inside = self.inside(centroids["x"].values, centroids["y"].values)
        dims = centroids["x"].dims
        coords = {d: (d, centroids[d].values) for d in dims if d in centroids.coords}
        for c in ("alpha", "beta"):
            if c in centroids.coords:
                coords[f"{c}_cmd"] = (centroids[c].dims, centroids[c].values,
                                      {"units": "deg", "long_name": f"commanded {c}"})
        ds = xr.Dataset(
            {
                "alpha": (dims, a, {"units": "deg", "long_name": "estimated outer-axis angle"}),
                "beta": (dims, b, {"units": "deg", "long_name": "estimated inner-axis angle"}),
                "status": centroids["status"].variable.copy(),
                "in_domain": (dims, inside | ~finite, {
                    "long_name": "centroid inside the calibrated domain (False: extrapolated)"}),
            },
            coords=coords,
            attrs={"calibration": self.kind, "label": self.label,
                   "experiment": str(centroids.attrs.get("experiment", "")),
                   "n_out_of_domain": int((finite & ~inside).sum())},
        )
        return ds

    def in_domain(self, centroids: xr.Dataset) -> xr.DataArray:
        """True where a centroid lies inside the calibrated domain (:meth:`inside`)."""
        return xr.DataArray(self.inside(centroids["x"].values, centroids["y"].values),
                            dims=centroids["x"].dims, coords=centroids["x"].coords)

    @property
    def label(self) -> str:
        """A short human-readable name (used as a column of the statistics tables)."""
        return self.kind

    def to_dict(self) -> dict:
        """The ``calibration/1`` document (JSON-ready)."""
        from .. import __version__

        self.check_fitted()
        return _jsonable({
            "sunlab_schema": CALIBRATION_SCHEMA,
            "kind": self.kind,
            "sunlab_version": __version__,
            "label": self.label,
            "parameters": self._parameters(),
            "training": self.training,
            "domain": self.domain,
            "residuals": self.residuals,
        })

    def save(self, path, *, overwrite: bool = False) -> Path:
        """Write the calibration as JSON (contract ``calibration/1``); return the path.

        The file is written to a temporary sibling and renamed into place, so it is never
        half-written; an existing file is replaced only with ``overwrite=True``.

        Raises
        ------
        SunlabError
            ``path`` exists and ``overwrite`` is False, or its folder is missing or read-only.
        """
        from .. import atomic, integrity

        path = atomic.check_target(path, overwrite=overwrite)
        doc = self.to_dict()
        validate_document(doc)
        text = json.dumps(integrity.seal_document(doc), indent=1, allow_nan=False) + "\n"
        return atomic.write_text(path, text, overwrite=overwrite)

    def __repr__(self) -> str:
        state = "fitted" if self.is_fitted else "not fitted"
        return f"<{type(self).__name__} {self.label} ({state})>"

    # --- helpers for subclasses ------------------------------------------------------------
    def _residuals(self, table: xr.Dataset) -> dict:
        ok = _ok_mask(table)
        a, b = self.predict_xy(table["x"].values, table["y"].values)
        ca = np.broadcast_to(table["alpha"].values[:, None], ok.shape)
        cb = np.broadcast_to(table["beta"].values[:, None], ok.shape)
        return {"alpha": _err_summary(a[ok], ca[ok]), "beta": _err_summary(b[ok], cb[ok])}

    def _extra_residuals(self, data: TrainingData) -> dict:
        """Further entries of ``residuals`` (interpolation: its leave-one-out errors)."""
        return {}

    def check_fitted(self) -> None:
        """Raise :class:`sunlab.errors.ConfigurationError` unless the calibration is fitted
        (or loaded); what :meth:`predict`, :meth:`save` and the exporters check first.

        Examples
        --------
        >>> from sunlab.calibration import Polynomial
        >>> Polynomial(3).check_fitted()  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        sunlab.errors.ConfigurationError: Polynomial: not fitted. Fix: call .fit(...) or ...
        """
        if not self.is_fitted:
            raise ConfigurationError(
                f"{type(self).__name__}: not fitted. Fix: call .fit(train_centroids) or "
                "sunlab.calibration.load(path) first"
            )

    # --- to implement ----------------------------------------------------------------------
    def _fit(self, data: TrainingData, validation: TrainingData | None) -> None:
        raise NotImplementedError

    def _predict_xy(self, x: np.ndarray, y: np.ndarray):
        raise NotImplementedError

    def _parameters(self) -> dict:
        raise NotImplementedError

    @classmethod
    def _from_parameters(cls, parameters: dict):
        raise NotImplementedError


def _class_of(kind: str) -> type[Calibration]:
    module, name = KINDS[kind].split(":")
    if "." not in module:
        module = f"{__package__}.{module}"
    return getattr(importlib.import_module(module), name)


def validate_document(doc) -> dict:
    """Check a ``calibration/1`` document; return it unchanged.

    Checks the schema tag, then the JSON Schema of ``data_schema/`` with
    :func:`sunlab.schema.validate_calibration`, then that the kind is one sunlab can load.

    Raises
    ------
    SchemaError
        Naming the field, the value found, what is expected and the fix.

    Examples
    --------
    >>> try:
    ...     validate_document({"sunlab_schema": "calibration/0", "kind": "polynomial"})
    ... except SchemaError as err:
    ...     print(err.field)
    sunlab_schema
    """
    if not isinstance(doc, dict):
        raise SchemaError("calibration document", type(doc).__name__, "a JSON object",
                          "pass a file written by Calibration.save")
    found = doc.get("sunlab_schema")
    if found != CALIBRATION_SCHEMA:
        raise SchemaError(
            "sunlab_schema", found, repr(CALIBRATION_SCHEMA),
            "this file was not written by Calibration.save of this sunlab version; re-fit the "
            "calibration (sunlab calibrate) or convert it with the version that wrote it",
        )
    missing = [k for k in _REQUIRED if k not in doc]
    if missing:
        raise SchemaError(", ".join(missing), "missing", f"the keys {list(_REQUIRED)}",
                          "the file is truncated or edited; re-fit the calibration")
    validate_calibration(doc)
    kind = doc.get("kind")
    if kind not in KINDS:
        raise SchemaError("kind", kind, f"one of {sorted(KINDS)}",
                          "the file is corrupt or from a newer sunlab; re-fit the calibration")
    return doc


#: Largest calibration file :func:`load` reads (bytes); the biggest real one is a few MB.
MAX_FILE_BYTES = 64 * 2**20


def _bad(field: str, found, expected: str, fix: str = "the file is corrupt or edited by hand; "
         "re-fit the calibration with `sunlab calibrate`") -> SchemaError:
    return SchemaError(f"parameters.{field}", found, expected, fix)


def _numbers(value, field: str, length: int | None = None, *, positive: bool = False) -> list:
    """A flat list of finite numbers (checked without building an array)."""
    if not isinstance(value, list):
        raise _bad(field, type(value).__name__, "a list of numbers")
    if length is not None and len(value) != length:
        raise _bad(field, f"{len(value)} values", f"{length} values")
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) \
                or (positive and not v > 0):
            raise _bad(f"{field}[{i}]", v, "a finite positive number" if positive
                       else "a finite number")
    return value


def _number(value, field: str, *, positive: bool = False) -> float:
    """One finite number."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value) \
            or (positive and not value > 0):
        raise _bad(field, value, "a finite positive number" if positive else "a finite number")
    return value


def _count(value, field: str, low: int = 0) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low:
        raise _bad(field, value, f"an integer >= {low}")
    return value


def _scaling_ok(p: dict) -> None:
    scaling = p.get("scaling")
    if not isinstance(scaling, dict):
        raise _bad("scaling", type(scaling).__name__, "an object {'x': [lo, hi], 'y': [lo, hi]}")
    for axis in ("x", "y"):
        lo, hi = _numbers(scaling.get(axis), f"scaling.{axis}", 2)
        if not hi > lo:
            raise _bad(f"scaling.{axis}", [lo, hi], "[lo, hi] with hi > lo (a range of "
                       "centroids, px)", "a zero or negative range divides by zero in predict; "
                       "re-fit the calibration on poses that move the spot along both axes")


def _coefficients_ok(p: dict, counts: dict) -> None:
    coef = p.get("coefficients")
    if not isinstance(coef, dict):
        raise _bad("coefficients", type(coef).__name__, "an object {'alpha': [...], 'beta': [...]}")
    for angle, n in counts.items():
        _numbers(coef.get(angle), f"coefficients.{angle}", n)


def _check_parameters(kind: str, p) -> None:
    """Sizes, finiteness and ranges of a document's parameters, before anything is allocated.

    Array sizes implied by an order or a hidden-layer width are computed from the numbers, so
    a corrupt order (say 20000) cannot build gigabytes of monomials before it is refused.
    """
    if not isinstance(p, dict):
        raise _bad("", type(p).__name__, "an object")
    if kind == "polynomial":
        order = p.get("order")
        orders = [order] if not isinstance(order, list) else order
        if len(orders) not in (1, 2):
            raise _bad("order", order, "an integer or [order_alpha, order_beta]")
        orders = [_count(n, "order") for n in orders] * (3 - len(orders))
        _scaling_ok(p)
        _coefficients_ok(p, {a: (n + 1) * (n + 2) // 2
                             for a, n in zip(("alpha", "beta"), orders[:2], strict=True)})
    elif kind == "trigonometric":
        n = _count(p.get("order"), "order")
        _number(p.get("period"), "period", positive=True)
        _scaling_ok(p)
        _coefficients_ok(p, {"alpha": (2 * n + 1) ** 2, "beta": (2 * n + 1) ** 2})
    elif kind.startswith("interpolation"):
        nodes = p.get("nodes")
        if not isinstance(nodes, dict) or not isinstance(nodes.get("x"), list):
            raise _bad("nodes", type(nodes).__name__, "an object of lists x, y, alpha, beta")
        n = len(nodes["x"])
        if n < 3:
            raise _bad("nodes.x", f"{n} nodes", "at least 3 nodes (one triangle)")
        for k in ("x", "y", "alpha", "beta"):
            _numbers(nodes.get(k), f"nodes.{k}", n)
    elif kind == "neural":
        h = _count(p.get("hidden"), "hidden", 1)
        scaling = p.get("input_scaling")
        if not isinstance(scaling, dict):
            raise _bad("input_scaling", type(scaling).__name__, "an object {'mean', 'std'}")
        n_in = len(scaling.get("mean") or [])
        _numbers(scaling.get("mean"), "input_scaling.mean")
        _numbers(scaling.get("std"), "input_scaling.std", n_in, positive=True)
        nets = p.get("networks")
        if not isinstance(nets, dict):
            raise _bad("networks", type(nets).__name__, "an object {'alpha': ..., 'beta': ...}")
        for angle in ("alpha", "beta"):
            net = nets.get(angle)
            if not isinstance(net, dict):
                raise _bad(f"networks.{angle}", type(net).__name__, "an object of weights")
            w1 = net.get("W1")
            if not isinstance(w1, list) or len(w1) != h:
                raise _bad(f"networks.{angle}.W1", f"{len(w1) if isinstance(w1, list) else w1}"
                           " rows", f"{h} rows (hidden = {h})")
            for i, row in enumerate(w1):
                _numbers(row, f"networks.{angle}.W1[{i}]", n_in or None)
            _numbers(net.get("b1"), f"networks.{angle}.b1", h)
            _numbers(net.get("W2"), f"networks.{angle}.W2", h)
            for k in ("b2", "target_mean"):
                _number(net.get(k), f"networks.{angle}.{k}")
            _number(net.get("target_std"), f"networks.{angle}.target_std", positive=True)
    elif kind == "ideal":
        for k in _SENSOR:
            _number(p.get(k), k, positive=k in ("mask_distance_mm", "pixel_pitch_mm"))
    elif kind == "optimised":
        for k in ("delta_f_mm", "alpha0", "beta0", "x_zp", "y_zp", "x_cf", "y_cf"):
            _number(p.get(k), k)
        for k in ("mask_distance_mm", "pixel_pitch_mm"):
            _number(p.get(k), k, positive=True)


def from_dict(doc: dict) -> Calibration:
    """Rebuild a fitted calibration from its ``calibration/1`` document.

    Examples
    --------
    >>> from sunlab import sim
    >>> from sunlab.calibration import Polynomial
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> cal = from_dict(Polynomial(order=1).fit(cen).to_dict())
    >>> cal.kind
    'polynomial'
    """
    validate_document(doc)
    _check_parameters(doc["kind"], doc["parameters"])
    cls = _class_of(doc["kind"])
    try:
        obj = cls._from_parameters(doc["parameters"])
    except SchemaError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        raise SchemaError(
            f"parameters (kind {doc['kind']!r})", f"{type(err).__name__}: {err}",
            f"the parameters a {cls.__name__} writes", "the file is corrupt; re-fit it",
        ) from err
    obj.training = dict(doc["training"] or {})
    obj.domain = doc["domain"]
    obj.residuals = doc["residuals"]
    return obj


def load(path) -> Calibration:
    """Load a calibration written by :meth:`Calibration.save`.

    Sizes are checked before any array is built (the file itself at most
    :data:`MAX_FILE_BYTES`; an order or a layer width must match its coefficient lists), and
    non-finite numbers or degenerate scalings (a zero range) are refused, naming the field.

    Raises
    ------
    SchemaError
        If the file is not valid JSON, not ``calibration/1``, or its parameters are corrupt.

    Examples
    --------
    >>> import tempfile, os
    >>> from sunlab import sim
    >>> from sunlab.calibration import Polynomial
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> path = os.path.join(tempfile.mkdtemp(), "cal.json")
    >>> load(Polynomial(order=1).fit(cen).save(path)).label
    'polynomial(1)'
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if not path.is_file():  # a folder; a FIFO or a device would block or never end
            raise IsADirectoryError(f"{path} is not a regular file")
        if size > MAX_FILE_BYTES:
            raise SchemaError(
                str(path), f"{size} bytes", f"a calibration JSON file of at most "
                f"{MAX_FILE_BYTES} bytes", "this is not a calibration written by sunlab (or it "
                "is corrupt); re-fit the calibration with `sunlab calibrate`")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise SchemaError("path", str(path), "an existing calibration JSON file",
                          "check the path, or fit one with `sunlab calibrate`") from err
    except UnicodeDecodeError as err:
        raise SchemaError(str(path), f"not UTF-8 text ({err})", "a calibration/1 JSON document",
                          "the file is corrupt or not a calibration; re-fit it") from err
    except OSError as err:
        raise SchemaError("path", f"{path} ({type(err).__name__}: {err.strerror or err})",
                          "a readable calibration JSON file",
                          "check the path and its permissions") from err
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as err:  # and integers of more than 4300 digits
        raise SchemaError(
            str(path), f"invalid JSON ({err})", "a calibration/1 JSON document",
            "the file is corrupt or truncated; re-fit the calibration with `sunlab calibrate`",
        ) from err
    from .. import integrity  # a depth limit; the fields; the checksum Calibration.save wrote

    integrity.check_depth(doc, path)
    cal = from_dict(doc)
    integrity.verify_document(doc, path)
    return cal
