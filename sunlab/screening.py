"""Robust outlier screening of a centroid table before a calibration is fitted.

One absurd row (a centroid of another spot, a hot pixel taken for the spot, a typing error such
as ``x = 1e20``) pulls a least-squares calibration by degrees. :func:`screen_outliers` fits each
centroid coordinate with a low-order model of the pinhole geometry by an outlier-resistant
(iteratively trimmed) least squares, and flags every usable shot whose residual lies beyond
``n_mad`` median absolute deviations (MAD) of the inliers' residuals. The model is a polynomial of
order 3 (order 1 for fewer than 30 points) in the ideal model's variables, eq. (1),

.. math:: u = \\tan\\alpha, \\qquad v = \\frac{\\tan\\beta}{\\cos\\alpha},

in which the ideal centroid is linear (:func:`sunlab.geometry.ideal_centroid`); the higher terms
absorb the mounting errors and the mask's distance, so the inliers' residuals are the centroid
noise. The MAD is floored at :data:`MAD_FLOOR_PX` so that a noise-free (simulated) table does not
flag its rounding errors. Flagged shots get the status ``invalid`` (not usable), keep their
values, and are listed in the table's ``screened_outliers`` attribute. Every calibration's
``fit`` screens its tables this way by default (``outlier_mads``).

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.linspace(-20, 20, 9), np.linspace(-20, 20, 9))
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel())
>>> cen["x"][40, 0] = 1e20
>>> screened, found = screen_outliers(cen)
>>> [(o["pose"], o["shot"]) for o in found]
[(40, 0)]
>>> int(screened.status[40, 0]) == int(schema.STATUS["invalid"])
True
"""

from __future__ import annotations

import numpy as np

from . import schema
from .errors import ConfigurationError

__all__ = []

#: Default threshold: residuals beyond this many MADs of the inliers' residuals are outliers
#: (10 MAD = 6.7 standard deviations of Gaussian noise: about one false flag in 10^10 shots).
N_MAD = 10.0
#: Smallest MAD used, px: centroid noise of the paper's algorithms is a few 0.01 px.
MAD_FLOOR_PX = 0.02


def _mad(r: np.ndarray) -> float:
    return float(np.median(np.abs(r - np.median(r)))) if r.size else 0.0


def _robust_residuals(A: np.ndarray, z: np.ndarray, n_mad: float) -> tuple[np.ndarray, float]:
    """Residuals of ``z`` from an iteratively trimmed least-squares fit on ``A``, and the MAD
    (floored) of the inliers' residuals."""
    # start from the points near the median: one absurd value cannot steer the first fit
    keep = np.abs(z - np.median(z)) <= 50 * (_mad(z) + 1.0)
    for _ in range(10):
        if keep.sum() < A.shape[1]:
            keep[:] = True
        coef, *_ = np.linalg.lstsq(A[keep], z[keep], rcond=None)
        r = z - A @ coef
        mad = max(_mad(r[keep]), MAD_FLOOR_PX)
        new = np.abs(r - np.median(r[keep])) <= min(n_mad, 4.0) * mad * 1.4826
        if np.array_equal(new, keep):
            break
        keep = new
    return r - np.median(r[keep]), mad


def screen_outliers(centroids, n_mad: float = N_MAD):
    """Flag the shots of a centroid table whose centroid a robust fit cannot explain.

    Parameters
    ----------
    centroids : xarray.Dataset
        A ``centroids/1`` table on (pose, shot) or (pose, shot, hole); commanded angles
        ``alpha``, ``beta`` (deg) on pose.
    n_mad : float
        Threshold in MADs of the inliers' residuals (:data:`N_MAD`); residuals are in px.

    Returns
    -------
    screened : xarray.Dataset
        A copy whose flagged shots have status ``invalid``; ``attrs['screened_outliers']``
        lists them (and the threshold in ``attrs['screening']``).
    outliers : list of dict
        One per flagged shot: ``pose``, ``shot`` (and ``hole``), ``alpha``, ``beta`` (deg),
        ``x``, ``y`` (px), ``residual_px`` (the larger of the two coordinates') and ``mads``.
        Empty when there are too few usable shots to screen (fewer than 6 per hole).

    Raises
    ------
    ConfigurationError
        ``n_mad`` is not a number above 3 (a lower threshold flags ordinary noise).
    """
    if not (isinstance(n_mad, int | float) and np.isfinite(n_mad) and n_mad > 3):
        raise ConfigurationError(f"n_mad: found {n_mad!r}, expected a number of MADs above 3 "
                                 f"(default {N_MAD:g})")
    v = centroids.variables
    status, x, y = v["status"].values.copy(), v["x"].values, v["y"].values
    alpha = np.broadcast_to(v["alpha"].values[:, None], x.shape[:2])
    beta = np.broadcast_to(v["beta"].values[:, None], x.shape[:2])
    usable = np.logical_or.reduce([status == schema.STATUS[k] for k in schema.USABLE_STATUS])
    usable &= np.isfinite(x) & np.isfinite(y)
    holes = x.shape[2] if x.ndim == 3 else 0
    outliers = []
    for hole in range(max(holes, 1)):
        pick = (slice(None), slice(None), hole) if holes else (slice(None), slice(None))
        ok = usable[pick]
        if ok.sum() < 6:
            continue
        order = 3 if ok.sum() >= 30 else 1
        u, v = np.tan(np.deg2rad(alpha[ok])), np.tan(np.deg2rad(beta[ok]))
        v = v / np.cos(np.deg2rad(alpha[ok]))
        A = np.stack([u**i * v**j for i in range(order + 1) for j in range(order + 1 - i)], 1)
        fits = [_robust_residuals(A, z, n_mad) for z in (x[pick][ok], y[pick][ok])]
        mads = np.max([np.abs(r) / mad for r, mad in fits], axis=0)
        worst = np.max([np.abs(r) for r, _ in fits], axis=0)
        bad = np.any([np.abs(r) > n_mad * mad for r, mad in fits], axis=0)
        for k in np.flatnonzero(bad):
            p, s = (int(i[k]) for i in np.nonzero(ok))
            where = (p, s, hole) if holes else (p, s)
            status[where] = schema.STATUS["invalid"]
            outliers.append({"pose": p, "shot": s, **({"hole": hole} if holes else {}),
                             "alpha": float(alpha[p, s]), "beta": float(beta[p, s]),
                             "x": float(x[where]), "y": float(y[where]),
                             "residual_px": float(worst[k]), "mads": float(mads[k])})
    screened = centroids.copy()  # shallow: the new status replaces the copy's only
    screened["status"].values = status
    screened.attrs["screening"] = {"n_mad": float(n_mad), "mad_floor_px": MAD_FLOOR_PX,
                                   "flagged": len(outliers)}
    screened.attrs["screened_outliers"] = outliers
    return screened, outliers
