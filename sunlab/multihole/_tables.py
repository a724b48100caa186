"""Table and array plumbing shared by the multi-hole strategies (:mod:`.strategies`).

Private to :mod:`sunlab.multihole`: the per-hole and centre tables a strategy builds, the
frames-by-hole arrays of ``predict_xy``, the fit and prediction of one hole's calibration, and
the training summary and residuals every fitted strategy records.
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from .. import schema
from ..calibration import Polynomial
from ..errors import ConfigurationError


def _centre_table(cen, x, y, flux, n, method):
    status = np.where(n > 0, schema.STATUS["ok"], schema.STATUS["no_spot"])
    x = np.where(n > 0, x, np.nan)
    y = np.where(n > 0, y, np.nan)
    attrs = {k: v for k, v in cen.attrs.items() if k not in ("sunlab_schema", "method")}
    out = schema.centroids_dataset(
        x, y, flux=flux, status=status, alpha=cen["alpha"].values, beta=cen["beta"].values,
        method=method, attrs=attrs,
        extra={"n_holes": (("pose", "shot"), np.asarray(n, dtype=np.int16))},
    )
    for name in ("true_alpha", "true_beta"):
        if name in cen.variables:
            out[name] = (("pose", "shot"), np.asarray(cen[name].values))
    return out


def _default_model(order: int):
    def factory():
        return Polynomial(order)

    return factory


def _hole_table(cen: xr.Dataset, h: int, ok: xr.DataArray | None = None) -> xr.Dataset:
    """The centroid table (``centroids/1``) of one hole on (pose, shot); frames that are not
    usable get NaN and status ``no_spot``. Built directly (the parent table is valid)."""
    x = np.asarray(cen["x"].values[..., h], dtype=float)
    y = np.asarray(cen["y"].values[..., h], dtype=float)
    status = np.asarray(cen["status"].values[..., h])
    if ok is not None:
        okh = np.asarray(ok.values[..., h], dtype=bool)
        x = np.where(okh, x, np.nan)
        y = np.where(okh, y, np.nan)
        status = np.where(okh, status, np.where(status == 0, schema.STATUS["no_spot"], status))
    dims = ("pose", "shot")
    data = {"x": (dims, x), "y": (dims, y), "status": (dims, status.astype(np.int8))}
    for name in ("flux", "x0", "x1", "y0", "y1"):
        if name in cen.variables:
            data[name] = (dims, np.asarray(cen[name].values[..., h]))
    attrs = {k: v for k, v in cen.attrs.items() if k != "sunlab_schema"}
    attrs["sunlab_schema"] = schema.CENTROIDS_SCHEMA
    return xr.Dataset(
        data,
        coords={"pose": cen["pose"].values, "shot": cen["shot"].values,
                "alpha": ("pose", np.asarray(cen["alpha"].values, float)),
                "beta": ("pose", np.asarray(cen["beta"].values, float))},
        attrs=attrs,
    )


def _fit_model(factory, table: xr.Dataset):
    """Fit a calibration model on the usable frames of a (pose, shot) table."""
    ok = np.isfinite(table["x"].values) & np.isfinite(table["y"].values)
    if ok.sum() < 3:
        raise ConfigurationError("too few usable frames to fit a calibration (fewer than 3)")
    return factory().fit(table, outlier_mads=None)  # the strategy screened the whole table


def _predict_arrays(model, x, y):
    """(alpha, beta) of a fitted calibration for centroid arrays; NaN where x or y is NaN."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    bad = ~(np.isfinite(x) & np.isfinite(y))
    a, b = model.predict_xy(np.where(bad, np.nan, x), np.where(bad, np.nan, y))
    a = np.asarray(a, float).reshape(x.shape)
    b = np.asarray(b, float).reshape(x.shape)
    return np.where(bad, np.nan, a), np.where(bad, np.nan, b)


def _predict(model, table: xr.Dataset):
    """Predicted (alpha, beta) arrays on (pose, shot), NaN where the table has no centroid."""
    return _predict_arrays(model, table["x"].values, table["y"].values)


def _error_stats(est, cmd) -> dict:
    """Statistics of estimated - commanded (deg) over the finite estimates, as ``calibration/1``
    writes residuals."""
    e = np.asarray(est, dtype=float) - np.asarray(cmd, dtype=float).reshape(-1, 1)
    e = e[np.isfinite(e)]
    if e.size == 0:
        return {"mean": None, "mean_abs": None, "rms": None, "std": None, "max_abs": None, "n": 0}
    return {"mean": float(e.mean()), "mean_abs": float(np.abs(e).mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "std": float(e.std()),
            "max_abs": float(np.abs(e).max()), "n": int(e.size)}


def _record_fit(strategy, cen: xr.Dataset, ok: xr.DataArray, residuals: dict) -> None:
    """The training summary, domain and residuals every fitted calibration carries."""
    ok = np.asarray(ok.values, dtype=bool)
    x, y = np.asarray(cen["x"].values)[ok], np.asarray(cen["y"].values)[ok]
    a, b = np.asarray(cen["alpha"].values, float), np.asarray(cen["beta"].values, float)
    strategy.training = {
        "experiment": str(cen.attrs.get("experiment", "")),
        "centroid_method": str(cen.attrs.get("method", "")),
        "n_samples": int(ok.sum()), "n_poses": int(ok.any(axis=(1, 2)).sum()),
        "n_shots": int(cen.sizes["shot"]), "n_holes": int(cen.sizes["hole"]),
    }
    strategy.domain = {k: [float(v.min()), float(v.max())] if v.size else [0.0, 0.0]
                       for k, v in (("alpha", a), ("beta", b), ("x", x), ("y", y))}
    strategy.residuals = {"alpha": residuals["alpha"], "beta": residuals["beta"],
                          "validation": None}


def _validation_residuals(strategy, validation: xr.Dataset | None) -> None:
    """The validation residuals of a fitted strategy: its estimate of every frame of the
    validation table against the commanded angles (deg)."""
    if validation is not None:
        est = strategy.predict(validation)
        strategy.residuals["validation"] = {
            a: _error_stats(est[a].values, est[f"{a}_cmd"].values) for a in ("alpha", "beta")}


def _frames(x, y):
    """Centroid arrays (..., hole) as (frames, hole, 2), their usable mask and leading shape."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    if x.ndim < 1:
        raise ConfigurationError(
            "x, y: found scalars; a multi-hole strategy needs every hole's centroid of a frame "
            "(arrays whose last axis is the hole)")
    X = np.stack([x, y], -1).reshape(-1, x.shape[-1], 2)
    return X, np.isfinite(X).all(-1), x.shape[:-1]


def _settings(strategy, names) -> dict:
    """The strategy's settings (``names`` plus the shared ones) for its saved parameters."""
    holes = None if strategy.holes is None else np.asarray(strategy.holes, bool).tolist()
    return {**{k: getattr(strategy, k) for k in names}, "holes": holes,
            "accept": list(strategy.accept)}


def _restore_settings(p: dict) -> dict:
    holes = None if p["holes"] is None else np.asarray(p["holes"], dtype=bool)
    return {"holes": holes, "accept": tuple(str(s) for s in p["accept"])}


def _angles_dataset(cen, a, b, dims, extra=None):
    """Angle estimates on ``dims`` with the commanded angles (from a centroid table's
    ``alpha``/``beta`` or an estimate's ``alpha_cmd``/``beta_cmd``) as coordinates."""
    ca = cen["alpha_cmd"] if "alpha_cmd" in cen.coords else cen["alpha"]
    cb = cen["beta_cmd"] if "beta_cmd" in cen.coords else cen["beta"]
    coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
              "alpha_cmd": ("pose", np.asarray(ca.values), {"units": "deg"}),
              "beta_cmd": ("pose", np.asarray(cb.values), {"units": "deg"})}
    if "hole" in dims:
        coords["hole"] = cen["hole"].values
        for c in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf"):
            if c in cen.coords:
                coords[c] = ("hole", cen[c].values)
    data = {"alpha": (dims, a, {"units": "deg"}), "beta": (dims, b, {"units": "deg"})}
    data.update(extra or {})
    return xr.Dataset(data, coords=coords)
