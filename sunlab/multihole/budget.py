"""Averaging N holes (eq. 5): the combination, the gain over one hole and its error budget.

Averaging N independent errors divides the variance by N, eq. (5); errors common to all holes
(platform pose error, mask mounting) do not average out, and bad holes spoil the mean.
:func:`combine_estimates` is the average (weighted, clipped) of per-hole estimates and
:func:`angle_errors` their errors against the commanded angles; :func:`error_budget` splits the
per-hole errors into their common and hole-specific parts and predicts the gain;
:func:`gain_study` measures it for both strategies, with and without the rejection of bad
holes (:mod:`sunlab.multihole.defects`).

References
----------
.. [1] docs/paper.md, sec. 6 and Table 5 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr

from ..errors import ConfigurationError
from ..stats import error_summary

__all__ = ["error_budget", "gain_study"]


def combine_estimates(est, *, holes=None, weights=None, clip: float | None = None,
                      n_iter: int = 3, dim: str = "hole"):
    """Combine per-hole angle estimates of each frame into one: mean, weighted and/or clipped.

    Parameters
    ----------
    est : xarray.DataArray
        Angle estimates, deg, with a ``hole`` dimension; NaN for a hole missing in a frame.
    holes : array_like of bool, shape (hole,), optional
        Holes allowed in the combination.
    weights : array_like, shape (hole,), optional
        Non-negative weights, e.g. 1 / (hole's residual variance); default equal.
    clip : float, optional
        Sigma-clipping threshold: in every frame, estimates further than ``clip`` robust standard
        deviations from the median of the kept ones are dropped, ``n_iter`` times (the scale is
        1.4826 MAD, bounded below by the standard deviation of the survivors after the first
        pass).
    dim : str
        Dimension to combine.

    Returns
    -------
    mean, n : xarray.DataArray
        The combined estimate and the number of holes used in each frame.

    Notes
    -----
    Averaging N independent estimates of equal variance divides the variance by N, eq. (5):

    .. math:: \\sigma^2_N = \\sigma^2 / N.

    The mean over the holes present is unbiased as long as each hole's estimate is.

    Examples
    --------
    >>> e = xr.DataArray([[1.0, 1.1, 0.9, 5.0, np.nan]], dims=("pose", "hole"))
    >>> float(combine_estimates(e)[0][0])
    2.0
    >>> round(float(combine_estimates(e, clip=4.0)[0][0]), 6)
    1.0
    """
    ok = np.isfinite(est)
    if holes is not None:
        ok = ok & xr.DataArray(np.asarray(holes, dtype=bool), dims=dim)
    w = xr.ones_like(est) if weights is None else xr.DataArray(np.asarray(weights, float), dims=dim)
    w = w.where(ok, 0.0)
    if clip is not None:
        for it in range(n_iter):
            cur = est.where(w > 0)
            med = cur.median(dim)
            scale = 1.4826 * np.abs(cur - med).median(dim)
            if it > 0:  # a few survivors can have MAD 0: their standard deviation bounds it
                scale = np.maximum(scale, cur.std(dim))
            keep = np.abs(est - med) <= clip * scale
            w = w.where(keep, 0.0)
    wsum = w.sum(dim)
    mean = (est.fillna(0.0) * w).sum(dim) / wsum.where(wsum > 0)
    return mean, (w > 0).sum(dim)


def angle_errors(pred: xr.Dataset) -> xr.Dataset:
    """Estimated minus commanded angles, deg (the paper's test protocol, sec. 5).

    ``pred`` carries the commanded angles as ``alpha_cmd``/``beta_cmd``, as the strategies return
    them.

    Parameters
    ----------
    pred : xarray.Dataset
        Estimates ``alpha``, ``beta`` (deg) on (pose, shot) or (pose, shot, hole).

    Returns
    -------
    xarray.Dataset
        ``alpha``, ``beta``: estimated minus commanded, deg, on ``pred``'s dims.

    Examples
    --------
    >>> p = xr.Dataset({"alpha": (("pose", "shot"), [[1.5]]), "beta": (("pose", "shot"), [[0.0]])},
    ...                coords={"alpha_cmd": ("pose", [1.0]), "beta_cmd": ("pose", [0.5])})
    >>> float(angle_errors(p).alpha[0, 0]), float(angle_errors(p).beta[0, 0])
    (0.5, -0.5)
    """
    return xr.Dataset({a: pred[a] - pred[f"{a}_cmd"] for a in ("alpha", "beta")})


def error_budget(est: xr.Dataset, holes=None) -> dict:
    """Split the per-hole test errors into a part common to all holes and a hole-specific part.

    With e_h the error of hole h's estimate in a frame, the common part is the mean over holes
    e_bar and the specific part e_h - e_bar. For N holes with independent specific errors of
    variance s^2 and a common error of variance c^2, one hole has variance c^2 + s^2 and the
    average c^2 + s^2 / N, so the gain in standard deviation is at most
    sqrt((c^2 + s^2) / (c^2 + s^2 / N)), which tends to sqrt(N) (eq. 5) only when c -> 0.

    Parameters
    ----------
    est : xarray.Dataset
        Per-hole estimates ``alpha``, ``beta`` (deg) on (pose, shot, hole) with the commanded
        angles ``alpha_cmd``, ``beta_cmd`` on ``pose``
        (:meth:`PerHoleAverage.predict_holes <sunlab.multihole.PerHoleAverage.predict_holes>`).
    holes : array_like of bool, shape (hole,), optional
        Holes counted (default all); a missing estimate (NaN) is left out of its frame.

    Returns
    -------
    dict
        Per angle (``"alpha"``, ``"beta"``) a dict: ``single`` (RMS of one hole's error, deg),
        ``common`` (RMS of the common part, deg, corrected for the specific part's leftover
        s/sqrt(N)), ``specific`` (RMS of the specific part, deg), ``n_holes`` (mean number of
        holes per frame, N), ``gain_limit`` (the predicted gain) and ``sqrt_n``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> e = rng.normal(0, 1, (400, 1, 100)) + rng.normal(0, 0.3, (400, 1, 1))
    >>> dims = ("pose", "shot", "hole")
    >>> est = xr.Dataset({"alpha": (dims, e), "beta": (dims, e)},
    ...                  coords={"alpha_cmd": ("pose", np.zeros(400)),
    ...                          "beta_cmd": ("pose", np.zeros(400))})
    >>> b = error_budget(est)["alpha"]
    >>> round(b["specific"], 1), round(b["common"], 1)
    (1.0, 0.3)
    """
    err = angle_errors(est)
    out = {}
    for name in ("alpha", "beta"):
        e = err[name]
        if holes is not None:
            e = e.where(xr.DataArray(np.asarray(holes, bool), dims="hole"))
        n = float(np.isfinite(e).sum("hole").mean())
        mean = e.mean("hole")
        spec = e - mean
        s2 = float((spec**2).mean()) * n / max(n - 1, 1)
        m2 = float((mean**2).mean())
        c2 = max(m2 - s2 / n, 0.0)
        single = float(np.sqrt((e**2).mean()))
        out[name] = {"single": single, "common": math.sqrt(c2), "specific": math.sqrt(s2),
                     "n_holes": n, "gain_limit": math.sqrt((c2 + s2) / (c2 + s2 / n)),
                     "sqrt_n": math.sqrt(n)}
    return out


def gain_study(train: xr.Dataset, test: xr.Dataset, *, order: int = 5, model=None,
               cube=None, kappa: float = 5.0, clip: float = 4.0) -> dict:
    """How far 100 holes get toward the sqrt(N) of eq. (5), with and without bad-hole rejection.

    Fits both strategies and the per-hole calibrations on ``train``; on ``test`` compares one
    hole (every good hole alone: the median of their statistics, and the best single hole), the
    geometric centre, the plain average, and the average after rejection with inverse-variance
    weights and sigma clipping. Adds the error budget of :func:`error_budget`.

    Parameters
    ----------
    train, test : xarray.Dataset
        Training (experiment I) and test (experiment II) centroid tables on (pose, shot, hole).
    order : int
        Polynomial order of the calibrations (ignored when ``model`` is given).
    model : callable, optional
        Factory of an unfitted :class:`sunlab.calibration.Calibration`.
    cube : xarray.Dataset, optional
        Frame cube of ``train``, for the spot-shape metrics of :func:`defect_metrics`.
    kappa : float
        Rejection threshold of :func:`reject_bad_holes`, robust standard deviations.
    clip : float
        Per-frame sigma-clipping threshold of the rejected average, robust standard deviations.

    Returns
    -------
    dict
        ``stats`` (strategy -> angle -> :func:`sunlab.stats.error_summary` statistic, deg),
        ``gain`` (strategy -> angle -> ``sigma``, ``mu`` and ``rms`` of one hole divided by the
        strategy's), ``budget`` (:func:`error_budget`, good holes), ``budget_all`` (all holes),
        ``bad`` (indices of the rejected holes) and ``metrics`` (the defect metrics).

    Raises
    ------
    ConfigurationError
        No good hole has a usable estimate at any test pose.

    Examples
    --------
    >>> a = np.repeat(np.linspace(-8, 2, 6), 6); b = np.tile(np.linspace(-2, 8, 6), 6)
    >>> from sunlab.sim import synthetic_centroids
    >>> kw = dict(shots=2, hole_sigma_px=0.1, noise_px=0.01, layout="grid")
    >>> tr = synthetic_centroids(a, b, seed=1, **kw)
    >>> te = synthetic_centroids(a + 0.5, b + 0.5, seed=2, **kw)
    >>> g = gain_study(tr, te, order=4)
    >>> bool(g["gain"]["averaging"]["alpha"]["rms"] > 5)
    True
    """
    from .defects import defect_metrics, reject_bad_holes  # above this module
    from .strategies import GeometricCentre, PerHoleAverage
    s2 = PerHoleAverage(order=order, model=model).fit(train)
    metrics = defect_metrics(train, strategy=s2, cube=cube)
    bad = reject_bad_holes(metrics, kappa=kappa).values
    good = ~bad
    s1 = GeometricCentre(order=order, model=model).fit(train)
    s1r = GeometricCentre(order=order, model=model, holes=good).fit(train)
    est = s2.predict_holes(test)
    # one hole: each good hole alone (one never on the detector has no statistics)
    singles = [s for s in (error_summary(est.isel(hole=h)) for h in np.flatnonzero(good))
               if s["alpha"]["n_poses"] and s["beta"]["n_poses"]]
    if not singles:
        raise ConfigurationError("test: no good hole has a usable estimate at any test pose")
    stats = {
        "one_hole_median": {a: {k: float(np.median([s[a][k] for s in singles]))
                                for k in singles[0][a]} for a in ("alpha", "beta")},
        "geometric_centre": error_summary(s1.predict(test)),
        "geometric_centre_rejected": error_summary(s1r.predict(test)),
        "averaging": error_summary(s2.combine(est)),
        "averaging_rejected": error_summary(
            PerHoleAverage(order=order, model=model, holes=good, weighting="inverse_variance",
                           clip=clip, calibrations_=s2.calibrations_, variance_=s2.variance_
                           ).combine(est)),
    }
    one = stats["one_hole_median"]
    gain = {k: {a: {"sigma": one[a]["sigma"] / v[a]["sigma"], "mu": one[a]["mu"] / v[a]["mu"],
                    "rms": one[a]["rms"] / v[a]["rms"]} for a in ("alpha", "beta")}
            for k, v in stats.items() if k != "one_hole_median"}
    return {"stats": stats, "gain": gain, "budget": error_budget(est, holes=good),
            "budget_all": error_budget(est), "bad": np.flatnonzero(bad).tolist(),
            "metrics": metrics}
