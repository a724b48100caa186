"""Many spots of one frame: detect, centroid and index every spot of a multi-hole mask.

Examples
--------
>>> sorted(SPOT_METRICS)[:3]
['asymmetry', 'background', 'ellipticity']
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from ..errors import ConfigurationError
from ._aperture import FLUX, X, Y, _background_band, _detect, _first_radius, _measure
from ._diskfit import _fit_from
from ._grid import METRIC_FIELDS, _assign, _fit_lattice, _new_holes, _spot_table
from ._local import _local_centroid
from .estimators import PER_SPOT
from .moments import SpotMoments
from .result import (
    _AMBIGUOUS,
    _CLIPPED,
    _INVALID,
    _NO_SPOT,
    _OK,
    _REPAIRED,
    _SATURATED,
    _check_positive,
    _full_scale,
    _prepare,
)

__all__ = ["locate_spots"]


#: Per-spot quality metrics returned by :func:`locate_spots` (name -> meaning).
SPOT_METRICS: dict[str, str] = {
    "peak": "highest pixel of the window, DN",
    "background": "local background (sigma-clipped annulus mean), DN",
    "mxx": "central second moment along x (columns), px^2",
    "myy": "central second moment along y (rows), px^2",
    "mxy": "central cross moment, px^2",
    "radius": "equivalent uniform-disk radius sqrt(2 (mxx + myy)), px",
    "ellipticity": "(l1 - l2) / (l1 + l2) of the second-moment matrix (0 for a round spot)",
    "asymmetry": "third-moment asymmetry |(m30 + m12, m21 + m03)| / (mxx + myy)^1.5",
    "lattice_residual": "distance from the fitted lattice position of its hole, px",
}


class Spots(NamedTuple):
    """Spots of one multi-hole frame, one entry per hole (see :func:`locate_spots`).

    Attributes
    ----------
    x, y, flux : numpy.ndarray, shape (n_holes,)
        Centroid (px) and background-subtracted flux (DN); NaN where the hole has no spot.
    window : numpy.ndarray of int, shape (4, n_holes)
        ``x0, x1, y0, y1`` of each spot's window; -1 where none.
    status : numpy.ndarray of int8, shape (n_holes,)
        Status codes (``no_spot`` for a hole without spot; ``ambiguous`` when two spots claim it).
    i, j : numpy.ndarray of int, shape (n_holes,)
        Grid row and column of each hole.
    metrics : dict of numpy.ndarray
        Per-hole quality metrics, see :data:`SPOT_METRICS`.
    unassigned : numpy.ndarray, shape (k, 2)
        (x, y) of spots that match no hole (outside the grid or far from the lattice).
    lattice : numpy.ndarray, shape (3, 2)
        Fitted lattice: origin (hole i = j = 0) and the steps along j (columns) and i (rows), px.
    """

    x: np.ndarray
    y: np.ndarray
    flux: np.ndarray
    window: np.ndarray
    status: np.ndarray
    i: np.ndarray
    j: np.ndarray
    metrics: dict
    unassigned: np.ndarray
    lattice: np.ndarray

    def to_dataframe(self):
        """The spots as a pandas DataFrame, one row per hole.

        Returns
        -------
        pandas.DataFrame
            Index ``hole`` (0 .. n_holes - 1); columns ``i``, ``j`` (grid row and column), ``x``,
            ``y`` (centroid, px), ``flux`` (DN), ``status``, the window ``x0``, ``x1``, ``y0``,
            ``y1`` (px) and one column per metric of :data:`SPOT_METRICS`.
        """
        import pandas as pd

        cols = {"i": self.i, "j": self.j, "x": self.x, "y": self.y, "flux": self.flux,
                "status": self.status, "x0": self.window[0], "x1": self.window[1],
                "y0": self.window[2], "y1": self.window[3], **self.metrics}
        return pd.DataFrame(cols).rename_axis("hole")




def locate_spots(
    frame, *, shape: tuple[int, int] = (10, 10), pitch: float = 0.5 / 0.007, holes=None,
    expected=None, method: str = "tight", max_residual: float = 0.3, stride: int = 8,
    nsigma: float = 5.0, min_contrast: float = 5.0, min_samples: int = 3, margin: float = 5.0,
    annulus: float = 6.0, n_iter: int = 2, saturation: float | None = None,
) -> Spots:
    """Find, centroid and index every spot of a multi-hole frame (the 10 x 10 mask).

    1. Detection as in :func:`tight_window` (strided samples above the noise, 8-connected
       groups); every group is a spot.
    2. Each spot is measured with the tight background-subtracted circular window (or fitted,
       ``method="fit"``), with its second and third moments for the quality metrics.
    3. Indexing: the lattice direction is the mean orientation (mod 90 deg) of the vectors
       between neighbouring spots (``0.7 .. 1.3 pitch`` apart), its step their median length;
       every spot gets integer lattice coordinates about a reference spot, and an affine lattice
       ``origin + j * step_j + i * step_i`` is fitted by least squares to the spots within
       ``max_residual`` pitch of a node (twice). Missing, dim or distorted spots do not disturb
       the others; a spot farther than ``max_residual`` pitch from every node is unassigned.
    4. The integer offset that maps the lattice coordinates into the grid ``shape`` is forced
       when the spots span the whole grid; otherwise (outer rows or columns missing) it is the
       one that brings the spots closest to ``expected`` positions when given, else the one
       that centres the spots in the grid.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    shape : (int, int)
        Grid rows and columns of the mask (rows along y, columns along x).
    pitch : float
        Expected hole pitch on the detector, px (0.5 mm / 7 um = 71.4 px).
    holes : tuple of array_like (hole_i, hole_j), optional
        Grid row and column of each hole of the output (e.g. the cube's ``hole_i``,
        ``hole_j``); default: all ``rows * cols`` holes in raster order (hole = i * cols + j).
    expected : array_like, shape (n_holes, 2), optional
        Predicted (x, y) of each hole's spot, px (design position + the shift of the pose);
        used only to choose the grid offset when the spots do not span the grid.
    method : {"tight", "fit"}
        Per-spot estimator.
    max_residual : float
        Largest distance of a spot from its lattice node, in pitches.
    stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, saturation
        As in :func:`tight_window`.

    Returns
    -------
    Spots
        One entry per hole.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:400, 0:500]
    >>> frame = np.full((400, 500), 30.0)
    >>> for i in range(3):
    ...     for j in range(4):
    ...         if (i, j) != (1, 2):                      # one hole is blocked
    ...             frame += 400 * (np.hypot(xx - 100.5 - 80 * j, yy - 90 - 80 * i) < 15)
    >>> s = locate_spots(frame, shape=(3, 4), pitch=80)
    >>> s.status.tolist()
    [0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0]
    >>> round(float(s.x[5]), 2), round(float(s.y[5]), 2), int(s.i[5]), int(s.j[5])
    (180.5, 170.0, 1, 1)
    """
    if method not in (spot := sorted(set(PER_SPOT.values()))):  # the per-spot estimators
        raise ConfigurationError(f"method: found {method!r}, expected one of {spot}")
    _check_positive("pitch", pitch, "give the hole pitch on the detector in px")
    hi, hj, lut = _hole_table(shape, holes)
    exp = None if expected is None else np.asarray(expected, dtype=float).reshape(hi.size, 2)
    vals, window, status = _new_holes(hi.size, _NO_SPOT)
    unassigned, lattice = _locate(frame, method, lut, exp, vals, window, status, stride, nsigma,
                                  min_contrast, min_samples, float(margin), float(annulus),
                                  int(n_iter), _full_scale(frame, saturation), float(pitch),
                                  float(max_residual))
    # x, y, flux and the metrics (the order of SPOT_METRICS) are rows of one block.
    metrics = dict(zip(METRIC_FIELDS, vals[3:], strict=True))
    return Spots(vals[0], vals[1], vals[2], window, status, hi, hj, metrics, unassigned, lattice)


def _locate(frame, method, lut, exp, vals, window, status, stride, nsigma, min_contrast,
            min_samples, margin, annulus, n_iter, saturation, pitch, max_residual):
    """Steps 1-4 of :func:`locate_spots` into the per-hole outputs ``vals``, ``window`` and
    ``status``; returns (unassigned spots, lattice)."""
    arr, usable = _prepare(frame)
    det = _detect(arr, stride, nsigma, min_contrast, min_samples) if usable else None
    if not usable or (det.count.size == 0 and det.sample_max == 0 and not arr.any()):
        status[:] = _INVALID
    if not usable or det.count.size == 0:
        return np.zeros((0, 2)), np.full((3, 2), np.nan)
    m = _measure(arr, det.x, det.y, _first_radius(det.count, stride, margin), margin, annulus,
                 *_background_band(det), n_iter, saturation)
    m = m[m[:, FLUX] > 0]
    win, st = _spot_table(m, arr.shape[1], arr.shape[0], _OK, _SATURATED, _CLIPPED)
    for k in range(len(m) if method == "fit" else 0):
        # x, y, flux and window of the disk fit started from the spot's moments, if it converges
        c = _fit_from(arr, SpotMoments(*m[k]), int(st[k]), 1.5, 30, True, saturation)
        if np.isfinite(c.x):
            m[k, X], m[k, Y], m[k, FLUX] = c.x, c.y, c.flux
            win[:, k] = c.window
    good = (st == _OK) & (m[:, FLUX] > 0.3 * np.median(m[:, FLUX])) if len(m) else st == 0
    fit = _fit_lattice(m[:, [X, Y]], good if good.any() else np.ones(len(m), bool), pitch,
                       max_residual)
    out = np.zeros((0, 2)), np.full((3, 2), np.nan)
    if fit is not None:
        out = _assign(m, win, st, good, fit, max_residual, lut, exp, vals, window, status,
                      _AMBIGUOUS)
    for k in np.flatnonzero(status == _SATURATED) if method == "tight" else ():
        # isolated pixels at full scale (hot pixels) in the window: repaired by the median of
        # their neighbours and x, y, flux measured again, as the tight window does; touching
        # clipped pixels stay ``saturated``; the metrics keep the first values
        flux, x, y, n_hot, saturated = _local_centroid(
            arr, float(vals[0, k]), float(vals[1, k]), 0.5 * (window[1, k] - window[0, k] - 1),
            annulus, n_iter, saturation, False)
        if n_hot and not saturated and flux > 0:
            vals[0, k], vals[1, k], vals[2, k] = x, y, flux
            status[k] = _REPAIRED
    return out


def _hole_table(shape, holes):
    """Grid row and column of each output hole and the (rows, cols) lookup table of the hole
    at each grid place (-1: not an output hole)."""
    rows, cols = (int(v) for v in shape)
    if rows < 1 or cols < 1:
        raise ConfigurationError(f"shape: found {shape!r}, expected (rows, cols) >= (1, 1)")
    hi, hj = (np.divmod(np.arange(rows * cols), cols) if holes is None else
              (np.asarray(h, dtype=int) for h in holes))
    lut = np.full((rows, cols), -1, dtype=int)
    inside = (hi >= 0) & (hi < rows) & (hj >= 0) & (hj < cols)
    lut[hi[inside], hj[inside]] = np.flatnonzero(inside)
    return hi, hj, lut
