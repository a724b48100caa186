"""Tables and arrays shared by the two multi-hole strategies (:mod:`.strategies`): the
frames-by-hole arrays, one hole's calibration applied to arrays, the training summary and
residuals every fitted strategy records, and its estimates as a table."""

from __future__ import annotations

import numpy as np
import xarray as xr

from ..errors import ConfigurationError

#: the variables of one hole's own centroid table (``centroids/1`` on (pose, shot))
_HOLE_VARS = ("x", "y", "status", "flux", "x0", "x1", "y0", "y1")


def _hole_frames(cen, ok):
    """A table's centroids as (frame, hole, 2) and its usable mask (frame, hole)."""
    n_h = cen.sizes["hole"]
    X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, n_h, 2)
    return X, ok.values.reshape(-1, n_h)


def _frames(x, y):
    """Centroid arrays (..., hole) as (frames, hole, 2), their usable mask and leading shape."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    if x.ndim < 1:
        raise ConfigurationError(
            "x, y: found scalars; a multi-hole strategy needs every hole's centroid of a frame "
            "(arrays whose last axis is the hole)")
    X = np.stack([x, y], -1).reshape(-1, x.shape[-1], 2)
    return X, np.isfinite(X).all(-1), x.shape[:-1]


def _predict_arrays(model, x, y):
    """(alpha, beta) of a fitted calibration for centroid arrays; NaN where x or y is NaN."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    bad = ~(np.isfinite(x) & np.isfinite(y))
    a, b = model.predict_xy(np.where(bad, np.nan, x), np.where(bad, np.nan, y))
    return tuple(np.where(bad, np.nan, np.reshape(v, x.shape)) for v in (a, b))


def _error_stats(est, cmd) -> dict:
    """Statistics of estimated - commanded (deg) over the finite estimates, as ``calibration/1``
    writes residuals."""
    e = (est - cmd).values
    e = e[np.isfinite(e)]
    if e.size == 0:
        return dict.fromkeys(("mean", "mean_abs", "rms", "std", "max_abs"), None) | {"n": 0}
    return {"mean": float(e.mean()), "mean_abs": float(np.abs(e).mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "std": float(e.std()),
            "max_abs": float(np.abs(e).max()), "n": int(e.size)}


def _record_fit(strategy, cen, ok, residuals: dict, validation):
    """The training summary, domain and residuals (with the validation table's) every fitted
    calibration carries; returns the strategy."""
    ok = np.asarray(ok.values, dtype=bool)
    strategy.training = {
        "experiment": str(cen.attrs.get("experiment", "")),
        "centroid_method": str(cen.attrs.get("method", "")),
        "n_samples": int(ok.sum()), "n_poses": int(ok.any(axis=(1, 2)).sum()),
        "n_shots": int(cen.sizes["shot"]), "n_holes": int(cen.sizes["hole"])}
    values = {"alpha": cen["alpha"].values, "beta": cen["beta"].values,
              "x": cen["x"].values[ok], "y": cen["y"].values[ok]}
    strategy.domain = {k: [float(v.min()), float(v.max())] if v.size else [0.0, 0.0]
                       for k, v in values.items()}
    strategy.residuals = {"alpha": residuals["alpha"], "beta": residuals["beta"],
                          "validation": None}
    if validation is not None:
        est = strategy.predict(validation)
        strategy.residuals["validation"] = {a: _error_stats(est[a], est[f"{a}_cmd"])
                                            for a in ("alpha", "beta")}
    return strategy


def _settings(strategy, names) -> dict:
    """The strategy's settings (``names`` plus the shared ones) for its saved parameters."""
    holes = None if strategy.holes is None else np.asarray(strategy.holes, bool).tolist()
    return {**{k: getattr(strategy, k) for k in names}, "holes": holes,
            "accept": list(strategy.accept)}


def _restore_settings(p: dict) -> dict:
    return {"holes": None if p["holes"] is None else np.asarray(p["holes"], dtype=bool),
            "accept": tuple(str(s) for s in p["accept"])}


def _angles_dataset(cen, a, b, dims, extra=None):
    """Angle estimates on ``dims`` with the commanded angles (from a centroid table's
    ``alpha``/``beta`` or an estimate's ``alpha_cmd``/``beta_cmd``) as coordinates."""
    cmd = {k: (cen[f"{k}_cmd"] if f"{k}_cmd" in cen.coords else cen[k]).values
           for k in ("alpha", "beta")}
    coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
              **{f"{k}_cmd": ("pose", v, {"units": "deg"}) for k, v in cmd.items()}}
    if "hole" in dims:
        coords.update({c: ("hole", cen[c].values) for c in
                       ("hole", "hole_i", "hole_j", "hole_x_cf", "hole_y_cf") if c in cen.coords})
    return xr.Dataset({"alpha": (dims, a, {"units": "deg"}), "beta": (dims, b, {"units": "deg"}),
                       **(extra or {})}, coords=coords)
