"""Centroid many spots of one frame at given positions with any single-spot estimator.

The pattern of photutils' ``centroid_sources``: a square box about each guessed position is cut
from the frame, the estimator runs on the cutout, and its result is moved back to frame
coordinates.

Examples
--------
>>> import numpy as np
>>> from sunlab.centroid import centroid_sources
>>> yy, xx = np.mgrid[0:100, 0:200]
>>> frame = 30 + 400 * ((np.hypot(xx - 50.5, yy - 50) < 10) | (np.hypot(xx - 150, yy - 40) < 10))
>>> x, y = centroid_sources(frame.astype(np.uint16), [52, 148], [49, 41], box=41)
>>> x.round(3).tolist(), y.round(3).tolist()
([50.5, 150.0], [50.0, 40.0])
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ConfigurationError
from .estimators import tight_window
from .result import Centroid

__all__ = ["centroid_sources"]


def centroid_sources(
    frame,
    x,
    y,
    box: int = 61,
    *,
    centroid_func: Callable[..., Centroid] = tight_window,
    **options,
) -> tuple[np.ndarray, np.ndarray]:
    """Centroid the spots near the positions ``(x, y)`` of one frame (photutils' pattern).

    For each position a ``box`` x ``box`` cutout centred on the nearest pixel (cut at the frame
    edge) goes to ``centroid_func(cutout, **options)``, any single-spot estimator of
    :data:`sunlab.centroid.METHODS` or one with the same signature and result; the estimate is
    shifted back by the cutout's origin. The box must hold the whole spot and some background
    around it, and no other spot.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    x, y : array_like of float
        Guessed column and row of each spot, px (centre of the first pixel = 0).
    box : int
        Side of the square cutout, px (odd: centred on the guess).
    centroid_func : callable
        Single-spot estimator ``centroid_func(cutout, **options) -> Centroid``
        (default :func:`sunlab.centroid.tight_window`).
    **options
        Options of ``centroid_func``.

    Returns
    -------
    x, y : numpy.ndarray of float
        Centroid of each spot, px; NaN where the estimator found no usable spot.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab.centroid import projection_window
    >>> yy, xx = np.mgrid[0:100, 0:200]
    >>> frame = (30 + 400 * (np.hypot(xx - 120.5, yy - 60.0) < 12)).astype(np.uint16)
    >>> centroid_sources(frame, [118.0], [62.0], 51, centroid_func=projection_window)
    (array([120.5]), array([60.]))
    """
    arr = np.asarray(frame)
    if arr.ndim != 2:
        raise ConfigurationError(f"frame: found a {arr.ndim}-d array, expected one 2-D frame")
    xs = np.atleast_1d(np.asarray(x, dtype=float))
    ys = np.atleast_1d(np.asarray(y, dtype=float))
    if xs.shape != ys.shape or xs.ndim != 1:
        raise ConfigurationError(f"x, y: found shapes {xs.shape}, {ys.shape}; expected two "
                                 "1-D arrays of the same length")
    if int(box) < 3:
        raise ConfigurationError(f"box: found {box!r}, expected at least 3 px")
    half = int(box) // 2
    ny, nx = arr.shape
    out_x = np.full(xs.shape, np.nan)
    out_y = np.full(xs.shape, np.nan)
    for k, (gx, gy) in enumerate(zip(xs, ys, strict=True)):
        if not (np.isfinite(gx) and np.isfinite(gy)):
            continue
        c, r = int(round(gx)), int(round(gy))
        c0, c1 = max(c - half, 0), min(c + half + 1, nx)
        r0, r1 = max(r - half, 0), min(r + half + 1, ny)
        if c1 - c0 < 3 or r1 - r0 < 3:
            continue
        res = centroid_func(arr[r0:r1, c0:c1], **options)
        out_x[k], out_y[k] = res.x + c0, res.y + r0
    return out_x, out_y
