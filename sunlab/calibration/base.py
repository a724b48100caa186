"""The common interface of every calibration function, and the ``calibration/1`` JSON artifact.

A calibration maps a spot centroid ``(x, y)`` (px) to platform angles ``(alpha, beta)`` (deg):
``alpha = f1(x, y)``, ``beta = f2(x, y)`` (docs/paper.md sec. 4). Every method in
:mod:`sunlab.calibration` is a :class:`Calibration` with the same three verbs:

- ``fit(train, validation=None)`` on ``centroids/1`` tables with the commanded angles as
  coordinates ``alpha``, ``beta`` on ``pose``. Only usable shots (status ``ok``, or
  ``repaired``: an isolated hot pixel replaced in the window, counted in the artifact's
  ``training["n_repaired_shots"]``) with finite x, y are used. By default
  (``average="pose"``) each pose contributes the mean centroid of its ok shots, so every pose
  weighs the same whatever number of shots survived; ``average="shot"`` fits every
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

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np
import xarray as xr

from .. import __version__, atomic, integrity
from ..errors import ConfigurationError, SchemaError
from ..schema import CALIBRATION_SCHEMA, STATUS, USABLE_STATUS, validate_centroids
from .artifact import validate_document
from .summary import calibration_summary

__all__ = ["Calibration"]

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
        Usable shots used (status ``ok`` or ``repaired``).
    attrs : dict
        Attributes of the centroid table (sensor, experiment, centroid method).
    n_repaired : int
        Of them, shots of status ``repaired`` (a hot pixel replaced in the window).
    """

    x: np.ndarray
    y: np.ndarray
    alpha: np.ndarray
    beta: np.ndarray
    n_poses: int
    n_shots: int
    attrs: dict
    n_repaired: int = 0


def _ok_mask(ds: xr.Dataset) -> np.ndarray:
    """The usable shots: status ``ok`` or ``repaired`` (an isolated hot pixel replaced in the
    window, the spot itself intact: :data:`sunlab.schema.USABLE_STATUS`) and finite x, y."""
    x = np.asarray(ds["x"].values, dtype=float)
    y = np.asarray(ds["y"].values, dtype=float)
    usable = np.isin(np.asarray(ds["status"].values), [STATUS[k] for k in USABLE_STATUS])
    return usable & np.isfinite(x) & np.isfinite(y)


#: Largest commanded angle a training table may hold, deg (as :data:`sunlab.plans.MAX_ANGLE_DEG`:
#: beyond 90 deg the sun is behind the mask).
_MAX_ANGLE_DEG = 90.0


def _check_angles(centroids: xr.Dataset, name: str) -> None:
    """Refuse commanded angles no sensor can see (one typo of 1e6 deg would bend the fit on
    every pose), naming the pose."""
    for c in ("alpha", "beta"):
        v = np.asarray(centroids[c].values, dtype=float)
        bad = np.flatnonzero(~(np.abs(v) < _MAX_ANGLE_DEG))
        if bad.size:
            raise SchemaError(
                f"{name}.{c}[pose={int(bad[0])}]", float(v[bad[0]]),
                f"a finite commanded angle within (-{_MAX_ANGLE_DEG:g}, {_MAX_ANGLE_DEG:g}) deg "
                "(the sun in front of the mask)",
                f"correct or drop the pose(s) ({bad.size} such pose(s)), e.g. "
                f"table.drop_isel(pose={int(bad[0])})",
            )


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
    _check_angles(centroids, name)
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
        raise SchemaError(f"{name}.status", "no shot of status ok or repaired",
                          "at least one usable centroid", "check the centroiding step")
    return TrainingData(
        x=np.asarray(xs, dtype=float), y=np.asarray(ys, dtype=float),
        alpha=np.asarray(a, dtype=float), beta=np.asarray(b, dtype=float),
        n_poses=int(keep.sum()), n_shots=int(ok.sum()), attrs=dict(centroids.attrs),
        n_repaired=int((ok & (np.asarray(centroids["status"].values)
                              == STATUS["repaired"])).sum()),
    )


def sensor_attrs(attrs: dict, *, name: str = "train") -> dict:
    """The sensor attributes a geometric model needs, read from a table's attributes.

    Parameters
    ----------
    attrs : dict
        Attributes of a centroid table (or frame cube).
    name : str
        The table's name in an error message.

    Returns
    -------
    dict
        ``{"mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px"}`` as floats (mm, mm,
        px, px).

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
                f"a geometric model needs it: write {key} in the frames' sensor.json (or pass "
                "it to sunlab import), carry the cube's attrs into the centroid table (a CSV "
                "table: sunlab.io.open_centroids(path, attrs={...}), or a sensor.json beside "
                "it for the command line), or pass the value to the model explicitly; the "
                "polynomial and interpolation methods do not need it",
            )
        out[key] = float(value)
    return out


def combine(*tables: xr.Dataset) -> xr.Dataset:
    """Concatenate centroid tables along ``pose`` (e.g. experiments I + II for interpolation).

    The attributes of the first table are kept and ``pose`` is renumbered.

    Parameters
    ----------
    *tables : xarray.Dataset
        ``centroids/1`` tables with the same dims of ``x`` (e.g. all on ``(pose, shot)``), at
        least one.

    Returns
    -------
    xarray.Dataset
        One ``centroids/1`` table whose poses are those of ``tables`` in order, ``pose``
        renumbered 0 .. N - 1 and the first table's attributes.

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

        Returns
        -------
        Calibration
            ``self``, fitted: ``training``, ``domain`` (deg, px) and ``residuals`` (deg) filled in.
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
            "n_repaired_shots": data.n_repaired,
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

        Returns
        -------
        int
            The smallest number of distinct ``(alpha, beta)`` poses :meth:`fit` accepts; 1 for
            the base class.

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

        Parameters
        ----------
        x, y : array_like
            Centroids, px (x = column, y = row), broadcast together.

        Returns
        -------
        numpy.ndarray of bool

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

        Returns
        -------
        str
            Several lines of text (:func:`sunlab.calibration.summary.calibration_summary` of
            :meth:`to_dict`).
        """
        return calibration_summary(self.to_dict())

    def predict_xy(self, x, y):
        """Angles (alpha, beta) in degrees for centroid arrays ``x``, ``y`` (px), any shape.

        NaN where x or y is not finite (and, for interpolation, outside the convex hull). No
        check of the domain: see :meth:`inside`, or :meth:`predict`, which flags extrapolation.

        Parameters
        ----------
        x, y : array_like
            Centroids, px (x = column, y = row), broadcast together.

        Returns
        -------
        alpha, beta : numpy.ndarray
            Platform angles, deg, of the broadcast shape.
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

        Parameters
        ----------
        centroids : xarray.Dataset
            A ``centroids/1`` table (``x``, ``y`` px, ``status``; commanded ``alpha``,
            ``beta`` as coordinates when known).

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
        """True where a centroid lies inside the calibrated domain (:meth:`inside`).

        Parameters
        ----------
        centroids : xarray.Dataset
            A ``centroids/1`` table.

        Returns
        -------
        xarray.DataArray of bool
            On the dims of ``x``.
        """
        return xr.DataArray(self.inside(centroids["x"].values, centroids["y"].values),
                            dims=centroids["x"].dims, coords=centroids["x"].coords)

    @property
    def label(self) -> str:
        """A short human-readable name (used as a column of the statistics tables)."""
        return self.kind

    def to_dict(self) -> dict:
        """The ``calibration/1`` document (JSON-ready).

        Returns
        -------
        dict
            ``sunlab_schema``, ``kind``, ``sunlab_version``, ``label``, ``parameters``,
            ``training``, ``domain`` (deg, px) and ``residuals`` (deg), in plain Python types
            (NaN and inf as None), as :meth:`save` writes them.
        """
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

        Parameters
        ----------
        path : str or path-like
            The JSON file to write.
        overwrite : bool
            Replace an existing file.

        Returns
        -------
        pathlib.Path

        Raises
        ------
        SunlabError
            ``path`` exists and ``overwrite`` is False, or its folder is missing or read-only.
        """
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

    @classmethod
    def _check_parameters(cls, parameters: dict) -> None:
        """Check a document's parameters before :meth:`_from_parameters` builds arrays."""

    @classmethod
    def for_kind(cls, kind: str, **options) -> Calibration:
        """An unfitted calibration of registered ``kind`` with ``options``.

        Parameters
        ----------
        kind : str
            A kind of :data:`sunlab.calibration.KINDS` served by this class.
        **options
            Keywords of the class's constructor (:class:`Interpolation` takes its mode from
            the kind).

        Returns
        -------
        Calibration
            A new, unfitted instance of ``cls``.
        """
        return cls(**options)
