"""The common interface of every calibration function, and the ``calibration/1`` JSON artifact.

A calibration maps a spot centroid ``(x, y)`` (px) to platform angles ``(alpha, beta)`` (deg)
(docs/paper.md sec. 4). Every method in :mod:`sunlab.calibration` is a :class:`Calibration`:

- ``fit(train, validation=None, *, outlier_mads="default")`` on ``centroids/1`` tables with the
  commanded angles ``alpha``, ``beta`` on ``pose``: both tables are first screened for outliers
  (:func:`sunlab.screening.screen_outliers`, 10 MADs by default, the same as
  :func:`sunlab.calibration.fit`, which builds the class and calls this method); then the usable
  shots (status ``ok`` or ``repaired``, finite x, y) are fitted, one point per pose (the mean of
  its usable shots, ``average="pose"``) or per shot (``average="shot"``).
- ``predict(centroids)``: the estimates ``alpha``, ``beta`` (deg) on the dims of ``x``, the
  table's ``status``, ``in_domain`` and the commanded angles as ``alpha_cmd``, ``beta_cmd``;
  ``predict_xy(x, y)`` on plain arrays.
- ``save(path)``: JSON (contract ``calibration/1``, no pickle); :func:`load` restores it, with
  ``parameters``, ``training`` (the table, and the shots screening excluded), ``domain`` (deg,
  px) and ``residuals`` (per-shot errors of the training and validation tables, deg).

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
from types import SimpleNamespace
from typing import ClassVar

import numpy as np
import xarray as xr

from .. import __version__, atomic, integrity
from ..errors import ConfigurationError, SchemaError
from ..schema import CALIBRATION_SCHEMA, CENTROIDS_SCHEMA, STATUS, USABLE_STATUS
from ..screening import screen_outliers
from .artifact import validate_document
from .registry import OUTLIER_MADS, name_plugin_errors
from .summary import calibration_summary

__all__ = ["Calibration"]

#: Largest commanded angle a training table may hold, deg (beyond 90 the sun is behind the mask).
_MAX_ANGLE_DEG = 90.0


def _ok_mask(ds) -> np.ndarray:
    """The usable shots: a usable status (:data:`sunlab.schema.USABLE_STATUS`), finite x, y."""
    v = ds.variables
    usable = np.isin(np.asarray(v["status"].values), [STATUS[k] for k in USABLE_STATUS])
    return usable & np.isfinite(v["x"].values) & np.isfinite(v["y"].values)


def _check_spots_move(x: np.ndarray, y: np.ndarray, name: str) -> None:
    """Refuse training points whose spot (``x``, ``y``, px) never moves along an axis from pose
    to pose: no kind learns angles from a spot that stays put (a camera that kept one frame),
    and most would fit one anyway, with errors of degrees."""
    for c, v in (("x", x), ("y", y)):
        if not np.ptp(v) > 0:
            raise ConfigurationError(
                f"{name}: every usable shot has its spot at the same {c} ({v[0]:g} px) at "
                "every pose, nothing to calibrate. Fix: calibrate on poses that move the spot "
                "along both axes (a grid such as experiment I)")


def _screen(train, validation, outlier_mads, default):
    """Both tables screened for outliers (:func:`sunlab.screening.screen_outliers`,
    ``outlier_mads`` MADs; ``"default"``: ``default``), and what to add to the fitted
    calibration's ``training``: the threshold and the excluded shots."""
    outlier_mads = default if outlier_mads == "default" else outlier_mads
    if not outlier_mads:
        return train, validation, {}
    train, excluded = screen_outliers(train, outlier_mads)
    more = {"outlier_mads": float(outlier_mads), "excluded": excluded}
    if validation is not None:
        validation, more["validation_excluded"] = screen_outliers(validation, outlier_mads)
    return train, validation, more


def _check_table(ds, name: str, fitting: bool = True) -> None:
    """What fitting or predicting needs of a ``centroids/1`` table (checked in full when it was
    built or opened: :func:`sunlab.schema.centroids_dataset`, :func:`sunlab.io.open_centroids`)."""
    if not isinstance(ds, xr.Dataset):
        raise SchemaError(name, type(ds).__name__, "a centroids/1 xarray.Dataset",
                          "build it with sunlab.schema.centroids_dataset or sunlab.centroid")
    if ds.attrs.get("sunlab_schema") != CENTROIDS_SCHEMA:
        raise SchemaError(f"{name}.attrs['sunlab_schema']", ds.attrs.get("sunlab_schema"),
                          repr(CENTROIDS_SCHEMA), "pass a centroid table, not frames or a file")
    dims = ds["x"].dims if "x" in ds else None
    if dims not in (("pose", "shot"), ("pose", "shot", "hole")) or any(
            v not in ds or ds[v].dims != dims for v in ("y", "status")):
        raise SchemaError(f"{name}.x.dims", dims, "x, y, status on ('pose', 'shot'[, 'hole'])")
    if not fitting:
        return
    if dims != ("pose", "shot"):
        raise SchemaError(f"{name}.x.dims", dims, "('pose', 'shot')",
                          "fit one hole at a time (centroids.isel(hole=k)) or use sunlab.multihole")
    for c in ("alpha", "beta"):
        if c not in ds.coords:
            raise SchemaError(f"{name}.coords[{c!r}]", "missing", "commanded angles on 'pose', "
                              "degrees", "keep the cube's alpha/beta coordinates")
        v = np.asarray(ds[c].values, dtype=float)
        bad = np.flatnonzero(~(np.abs(v) < _MAX_ANGLE_DEG))  # one typo of 1e6 deg bends all
        if bad.size:
            raise SchemaError(
                f"{name}.{c}[pose={int(bad[0])}]", float(v[bad[0]]),
                f"a finite commanded angle within (-{_MAX_ANGLE_DEG:g}, {_MAX_ANGLE_DEG:g}) deg "
                "(the sun in front of the mask)", f"correct or drop the pose(s) ({bad.size} such "
                f"pose(s)), e.g. table.drop_isel(pose={int(bad[0])})")


def _points(centroids: xr.Dataset, average: str, name: str) -> SimpleNamespace:
    """The flat training points of a table: ``x``, ``y`` (px), ``alpha``, ``beta`` (deg), one
    per pose mean or per usable shot, with ``n_poses``, ``n_shots`` (usable), ``n_repaired``
    and the table's ``attrs``."""
    if average not in ("pose", "shot"):
        raise ConfigurationError(f"average: found {average!r}, expected one of ('pose', 'shot')."
                                 " Fix: pass 'pose' (mean of each pose's usable shots) or 'shot'")
    _check_table(centroids, name)
    ok, v = _ok_mask(centroids), centroids.variables
    x, y = np.where(ok, v["x"].values, 0.0), np.where(ok, v["y"].values, 0.0)
    alpha = np.broadcast_to(np.asarray(v["alpha"].values, float)[:, None], ok.shape)
    beta = np.broadcast_to(np.asarray(v["beta"].values, float)[:, None], ok.shape)
    n = ok.sum(axis=1)
    keep = n > 0
    if not keep.any():
        raise SchemaError(f"{name}.status", "no shot of status ok or repaired",
                          "at least one usable centroid", "check the centroiding step")
    if average == "pose":
        pts = [x.sum(1)[keep] / n[keep], y.sum(1)[keep] / n[keep], alpha[keep, 0], beta[keep, 0]]
    else:
        pts = [x[ok], y[ok], alpha[ok], beta[ok]]
    repaired = ok & (np.asarray(v["status"].values) == STATUS["repaired"])
    return SimpleNamespace(**dict(zip(("x", "y", "alpha", "beta"), pts, strict=True)),
                           n_poses=int(keep.sum()), n_shots=int(ok.sum()),
                           n_repaired=int(repaired.sum()), attrs=dict(centroids.attrs))


def combine(*tables: xr.Dataset) -> xr.Dataset:
    """Concatenate centroid tables along ``pose`` (e.g. experiments I + II for a refit).

    Parameters
    ----------
    *tables : xarray.Dataset
        ``centroids/1`` tables with the same dims of ``x``, at least one.

    Returns
    -------
    xarray.Dataset
        One table whose poses are those of ``tables`` in order, ``pose`` renumbered
        0 .. N - 1, with the first table's attributes.

    Examples
    --------
    >>> from sunlab import sim
    >>> t = combine(sim.synthetic_centroids([0.0], [0.0]), sim.synthetic_centroids([1.0], [2.0]))
    >>> t.sizes["pose"], t.beta.values.tolist()
    (2, [0.0, 2.0])
    """
    if not tables:
        raise ConfigurationError("tables: found none, expected at least one centroid table")
    for k, t in enumerate(tables):
        _check_table(t, f"tables[{k}]", fitting=False)
        if t["x"].dims != tables[0]["x"].dims:
            raise SchemaError(f"tables[{k}].x.dims", t["x"].dims, str(tables[0]["x"].dims))
    out = xr.concat([t.drop_vars("pose") for t in tables], dim="pose", combine_attrs="override",
                    data_vars="all", coords="different", compat="equals")
    return out.assign_coords(pose=np.arange(out.sizes["pose"]))


def _jsonable(obj):
    """Numpy scalars/arrays to plain Python; NaN/inf become None."""
    if isinstance(obj, dict):
        return {str(k): _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, np.ndarray):
        return _jsonable(obj.tolist())
    if isinstance(obj, list | tuple):
        return [_jsonable(v) for v in obj]
    if isinstance(obj, bool | np.bool_ | int | np.integer):
        return bool(obj) if isinstance(obj, bool | np.bool_) else int(obj)
    return (float(obj) if math.isfinite(obj) else None) if isinstance(obj, float | np.floating) \
        else obj


def _err_summary(est, ref) -> dict:
    """Statistics of the signed error estimated - commanded (deg), ``calibration/1`` names."""
    e = np.asarray(est, dtype=float) - np.asarray(ref, dtype=float)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return dict.fromkeys(("mean", "mean_abs", "rms", "std", "max_abs")) | {"n": 0}
    return {"mean": float(e.mean()), "mean_abs": float(np.abs(e).mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "std": float(e.std()),
            "max_abs": float(np.abs(e).max()), "n": int(e.size)}


def _estimates(cal, table, dims, a, b, finite, inside, **variables) -> xr.Dataset:
    """What ``predict`` returns: angles ``a``, ``b`` (deg) on ``dims``, ``variables``,
    ``in_domain`` (``inside``, or not ``finite``: no estimate to flag), the commanded angles
    of ``table`` (a centroid table or a frame cube) as ``alpha_cmd``, ``beta_cmd``."""
    coords = {d: (d, table[d].values) for d in dims if d in table.coords}
    for c in ("alpha", "beta"):
        if c in table.coords:
            coords[f"{c}_cmd"] = (table[c].dims, table[c].values,
                                  {"units": "deg", "long_name": f"commanded {c}"})
    return xr.Dataset(
        {"alpha": (dims, a, {"units": "deg", "long_name": "estimated outer-axis angle"}),
         "beta": (dims, b, {"units": "deg", "long_name": "estimated inner-axis angle"}),
         **variables, "in_domain": (dims, inside | ~finite, {
             "long_name": "inside the calibrated domain (False: extrapolated)"})},
        coords=coords, attrs={"calibration": cal.kind, "label": cal.label,
                              "experiment": str(table.attrs.get("experiment", "")),
                              "n_out_of_domain": int((finite & ~inside).sum())})


class Calibration:
    """Base class of the calibration functions: fit, predict, save.

    Subclasses set :attr:`kind` and implement ``_fit(points, validation_points)``,
    ``_predict_xy(x, y)``, ``_parameters()`` and the classmethods ``_check_parameters(p)``
    and ``_from_parameters(p)``; a calibration fitted on other tables (the multi-hole
    strategies) overrides ``_fit_tables(train, validation)`` instead.
    """

    #: The ``kind`` written to the artifact.
    kind: ClassVar[str] = ""
    #: How training points are formed: ``"pose"`` (pose means) or ``"shot"``.
    average: str = "pose"
    #: The default screening of :meth:`fit`, MADs (None: none): 10 for every method fitted on
    #: shots (the multi-hole strategies, which judge whole holes, set None).
    default_outlier_mads: ClassVar[float | None] = OUTLIER_MADS

    def __init_subclass__(cls, **kwargs) -> None:  # a plug-in's exceptions named in one line
        super().__init_subclass__(**kwargs)
        name_plugin_errors(cls)

    def __init__(self) -> None:
        self.training: dict | None = None
        self.domain: dict | None = None
        self.residuals: dict | None = None

    @property
    def is_fitted(self) -> bool:
        """Whether the calibration has been fitted (or loaded)."""
        return self.training is not None

    @property
    def label(self) -> str:
        """A short human-readable name (a column of the statistics tables)."""
        return self.kind

    def fit(self, train: xr.Dataset, validation: xr.Dataset | None = None, *,
            outlier_mads: float | str | None = "default"):
        """Fit the calibration on a training table; return ``self``.

        Parameters
        ----------
        train : xarray.Dataset
            ``centroids/1`` table on ``(pose, shot)`` with coordinates ``alpha``, ``beta``
            (experiment I in the paper).
        validation : xarray.Dataset, optional
            A second table (experiment II): early stopping of networks, order selection, and
            the validation residuals of the artifact.
        outlier_mads : float or None
            Screen both tables first (:func:`sunlab.screening.screen_outliers`): shots whose
            centroid lies more than this many MADs from a robust fit are excluded; 0 or None
            keeps every shot. ``"default"``: :attr:`default_outlier_mads`, 10 MADs
            (:data:`sunlab.calibration.registry.OUTLIER_MADS`, as :func:`sunlab.calibration.fit`
            and ``sunlab calibrate``). The excluded shots are listed in ``training["excluded"]``
            (and ``training["validation_excluded"]``).

        Returns
        -------
        Calibration
            ``self``, fitted: ``training``, ``domain`` (deg, px) and ``residuals`` (deg).
        """
        train, validation, screened = _screen(train, validation, outlier_mads,
                                              self.default_outlier_mads)
        self._fit_tables(train, validation)
        self.training.update(screened)
        return self

    def _fit_tables(self, train: xr.Dataset, validation: xr.Dataset | None) -> None:
        data = _points(train, self.average, "train")
        distinct = len(set(zip(data.alpha.tolist(), data.beta.tolist(), strict=True)))
        if distinct < self.min_poses():
            raise ConfigurationError(
                f"train: {distinct} distinct poses (alpha, beta) in {data.n_poses} poses with "
                f"ok shots, but {self.label} needs at least {self.min_poses()}. Fix: calibrate "
                "on more distinct poses (a grid such as experiment I), or choose a smaller model")
        _check_spots_move(data.x, data.y, "train")
        val = None if validation is None else _points(validation, self.average, "validation")
        self._fit(data, val)

        def about(t, d, **more):
            return {"experiment": str(d.attrs.get("experiment", "")), **more,
                    "n_samples": d.x.size, "n_poses": d.n_poses, "n_shots": t.sizes["shot"],
                    "n_ok_shots": d.n_shots}

        self.training = {**about(train, data, centroid_method=str(data.attrs.get("method", ""))),
                         "n_repaired_shots": data.n_repaired, "average": self.average,
                         "validation": None if val is None else about(validation, val)}
        self.domain = {k: [float(getattr(data, k).min()), float(getattr(data, k).max())]
                       for k in ("alpha", "beta", "x", "y")}
        self.residuals = {**self._residuals(train), "validation": None if validation is None
                          else self._residuals(validation), **self._extra_residuals(data)}

    def min_poses(self) -> int:
        """Fewest distinct training poses (alpha, beta) this calibration can be fitted on.

        One per free coefficient of a linear model, one per weight of a network; fewer poses
        would be fitted exactly whatever the data, with meaningless zero residuals.

        Returns
        -------
        int
            The smallest number of distinct poses :meth:`fit` accepts; 1 for the base class.

        Examples
        --------
        >>> from sunlab.calibration import Polynomial
        >>> Polynomial(order=2).min_poses()
        6
        """
        return 1

    def inside(self, x, y) -> np.ndarray:
        """True where a centroid ``(x, y)`` (px) lies inside the calibrated domain.

        The domain is the box ``domain['x'] x domain['y']`` of the training centroids (for
        interpolation: the convex hull of the nodes); outside it, estimates are extrapolations.

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
        """A human-readable account of the calibration (the text of ``sunlab info CAL.json``).

        Returns
        -------
        str
            :func:`sunlab.calibration.summary.calibration_summary` of :meth:`to_dict`.
        """
        return calibration_summary(self.to_dict())

    def predict_xy(self, x, y):
        """Angles (alpha, beta) in degrees for centroid arrays ``x``, ``y`` (px), any shape.

        NaN where x or y is not finite (and, for interpolation, outside the convex hull); no
        check of the domain (:meth:`inside`; :meth:`predict` flags extrapolation).

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
        a, b = self._predict_xy(np.where(bad, 0.0, x).ravel(), np.where(bad, 0.0, y).ravel())
        return (np.where(bad, np.nan, np.reshape(a, x.shape)),
                np.where(bad, np.nan, np.reshape(b, x.shape)))

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
            (:meth:`inside`: an extrapolation, or NaN for a method that cannot extrapolate),
            attribute ``n_out_of_domain`` counting them; coordinates ``alpha_cmd``,
            ``beta_cmd`` (the table's commanded angles, if any).
        """
        _check_table(centroids, "centroids", fitting=False)
        x, y = centroids["x"].values, centroids["y"].values
        a, b = self.predict_xy(x, y)
        return _estimates(self, centroids, centroids["x"].dims, a, b, np.isfinite(x) &
                          np.isfinite(y), self.inside(x, y),
                          status=centroids["status"].variable.copy())

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
        return _jsonable({"sunlab_schema": CALIBRATION_SCHEMA, "kind": self.kind,
                          "sunlab_version": __version__, "label": self.label,
                          "parameters": self._parameters(), "training": self.training,
                          "domain": self.domain, "residuals": self.residuals})

    def save(self, path, *, overwrite: bool = False):
        """Write the calibration as JSON (contract ``calibration/1``, sealed); return the path.

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
        """
        path = atomic.check_target(path, overwrite=overwrite)
        doc = validate_document(self.to_dict())
        text = json.dumps(integrity.seal_document(doc), indent=1, allow_nan=False) + "\n"
        return atomic.write_text(path, text, overwrite=overwrite)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.label} ({'' if self.is_fitted else 'not '}fitted)>"
    def _residuals(self, table: xr.Dataset) -> dict:
        ok, v = _ok_mask(table), table.variables
        a, b = self.predict_xy(v["x"].values, v["y"].values)
        return {c: _err_summary(e[ok], np.broadcast_to(v[c].values[:, None], ok.shape)[ok])
                for c, e in (("alpha", a), ("beta", b))}

    def _extra_residuals(self, data) -> dict:
        """Further entries of ``residuals`` (interpolation: its leave-one-out errors)."""
        return {}

    def check_fitted(self) -> None:
        """Raise :class:`sunlab.errors.ConfigurationError` unless fitted (or loaded).

        Examples
        --------
        >>> from sunlab.calibration import Polynomial
        >>> Polynomial(3).check_fitted()  # doctest: +ELLIPSIS
        Traceback (most recent call last):
        ...
        sunlab.errors.ConfigurationError: Polynomial: not fitted. Fix: call .fit(...) or ...
        """
        if not self.is_fitted:
            raise ConfigurationError(f"{type(self).__name__}: not fitted. Fix: call "
                                     ".fit(train_centroids) or sunlab.calibration.load(path) first")

    @classmethod
    def _check_parameters(cls, parameters: dict) -> None:
        """Check a document's parameters before :meth:`_from_parameters` builds arrays."""
