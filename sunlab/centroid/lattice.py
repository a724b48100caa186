"""Many spots of one frame: detect, centroid and index every spot of a multi-hole mask.

Examples
--------
>>> sorted(SPOT_METRICS)[:3]
['asymmetry', 'background', 'ellipticity']
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from ..errors import ConfigurationError
from . import _k_aperture, _k_lattice
from ._detection import _background_band, _detect, _first_radius
from ._diskfit import _fit_from
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
    _all_zero,
    _check_positive,
    _full_scale,
    _prepare,
)

__all__ = ["locate_spots"]

# Columns of the compiled spot measurement (sunlab.centroid.moments.SpotMoments) read here.
_FLUX, _X, _Y = (_k_aperture.MEASURE_FIELDS.index(f) for f in ("flux", "x", "y"))


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


def _fit_lattice(p, shape, pitch, good, max_residual):
    """Lattice indices of spots ``p`` (n, 2): relative integer (j, i), the affine lattice
    (origin, step_j, step_i) and each spot's residual, px. ``good`` marks spots used for the fit
    (compiled: :func:`sunlab._centroid_kernels.fit_lattice`); None when no spot is good.
    """
    ij, origin, basis, resid, ok = _k_lattice.fit_lattice(
        np.ascontiguousarray(p, dtype=np.float64), np.ascontiguousarray(good, dtype=bool),
        float(pitch), float(max_residual))
    if not ok:
        return None
    return ij, origin, basis, resid


@functools.lru_cache(maxsize=8)
def _raster_holes(rows, cols):
    """Grid row, column of the holes in raster order and the (rows, cols) hole lookup table
    (read-only, shared between calls)."""
    hi, hj = np.divmod(np.arange(rows * cols), cols)
    lut = np.arange(rows * cols).reshape(rows, cols)
    for a in (hi, hj, lut):
        a.setflags(write=False)
    return hi, hj, lut


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
    opts = _SpotOptions(int(stride), float(nsigma), float(min_contrast), int(min_samples),
                        float(margin), float(annulus), int(n_iter), _full_scale(frame, saturation),
                        float(pitch), float(max_residual))
    exp = (np.empty((0, 2)) if expected is None else
           np.ascontiguousarray(np.asarray(expected, dtype=float).reshape(hi.size, 2)))
    locate_one = _locate_tight if method == "tight" else _locate_fit
    vals, window, status, unassigned, lattice = locate_one(frame, opts, lut, exp,
                                                           expected is not None, hi.size)
    # x, y, flux and the metrics (columns METRIC_FIELDS, the order of SPOT_METRICS) are rows
    # of one block.
    metrics = dict(zip(_k_lattice.METRIC_FIELDS, vals[3:], strict=True))
    return Spots(vals[0], vals[1], vals[2], window, status, hi, hj, metrics, unassigned, lattice)


class _SpotOptions(NamedTuple):
    """Detection, measurement and lattice options of :func:`locate_spots` (the kernels' order)."""

    stride: int
    nsigma: float
    min_contrast: float
    min_samples: int
    margin: float
    annulus: float
    n_iter: int
    saturation: float
    pitch: float
    max_residual: float


def _hole_table(shape, holes):
    """Grid row and column of each output hole and the (rows, cols) lookup table of the hole
    at each grid place (-1: not an output hole)."""
    rows, cols = (int(v) for v in shape)
    if rows < 1 or cols < 1:
        raise ConfigurationError(f"shape: found {shape!r}, expected (rows, cols) >= (1, 1)")
    if holes is None:
        hi, hj, lut = _raster_holes(rows, cols)
        return hi.copy(), hj.copy(), lut
    hi, hj = (np.asarray(h, dtype=int) for h in holes)
    lut = np.full((rows, cols), -1, dtype=int)
    inside = (hi >= 0) & (hi < rows) & (hj >= 0) & (hj < cols)
    lut[hi[inside], hj[inside]] = np.flatnonzero(inside)
    return hi, hj, lut


def _no_lattice():
    """Unassigned spots and lattice of a frame without any: (0, 2) and (3, 2) NaN."""
    return np.zeros((0, 2)), np.full((3, 2), np.nan)


def _locate_tight(frame, opts: _SpotOptions, lut, exp, has_exp, n_holes):
    """:func:`locate_spots` with the tight window: the compiled ``locate_tight`` with its
    arguments by name. Returns (values, windows, status, unassigned, lattice)."""
    arr, usable = _prepare(frame)
    if not usable:
        return (*_k_lattice.new_holes(n_holes, _INVALID), *_no_lattice())
    vals, window, status, n_detected, sample_max, unassigned, lattice = _k_lattice.locate_tight(
        arr, opts.stride, opts.nsigma, opts.min_contrast, opts.min_samples, opts.margin,
        opts.annulus, opts.n_iter, opts.saturation, opts.pitch, opts.max_residual,
        ok=_OK, saturated=_SATURATED, clipped=_CLIPPED, lut=lut, exp=exp, has_exp=has_exp,
        n_holes=n_holes, no_spot=_NO_SPOT, ambiguous=_AMBIGUOUS)
    if n_detected == 0 and sample_max == 0 and _all_zero(arr):
        status[:] = _INVALID
    _repair_hot_spots(arr, vals, window, status, opts)
    return vals, window, status, unassigned, lattice


def _repair_hot_spots(arr, vals, window, status, opts: _SpotOptions) -> None:
    """Spots flagged ``saturated`` for isolated pixels at full scale (hot pixels) in their
    window: those pixels replaced by the median of their neighbours and x, y, flux measured
    again (the tight window's repair, :func:`tight_window`), status ``repaired``; a spot with
    touching clipped pixels stays ``saturated``. The metrics keep the compiled values."""
    for k in np.flatnonzero(status == _SATURATED):
        x0, x1 = int(window[0, k]), int(window[1, k])
        flux, x, y, n_hot, saturated = _local_centroid(
            arr, float(vals[0, k]), float(vals[1, k]), 0.5 * (x1 - x0 - 1), opts.annulus,
            opts.n_iter, opts.saturation, False)
        if n_hot and not saturated and flux > 0:
            vals[0, k], vals[1, k], vals[2, k] = x, y, flux
            status[k] = _REPAIRED


def _locate_fit(frame, opts: _SpotOptions, lut, exp, has_exp, n_holes):
    """:func:`locate_spots` with the disk fit per spot: :func:`_measure_and_fit`, then the
    compiled grid assignment. Returns (values, windows, status, unassigned, lattice)."""
    arr, usable = _prepare(frame)
    if not usable:
        return (*_k_lattice.new_holes(n_holes, _INVALID), *_no_lattice())
    vals, window, status = _k_lattice.new_holes(n_holes, _NO_SPOT)
    unassigned, lattice = _no_lattice()
    fitted = _measure_and_fit(arr, opts)
    if fitted is None:
        if _all_zero(arr):
            status[:] = _INVALID
    elif fitted is not False:
        m, swin, sstat, good, ij, origin, basis, resid, on_node, pts = fitted
        unassigned, lattice = _k_lattice.assign_grid(
            m, swin, sstat, good, ij, origin, basis, resid, on_node, pts, lut, exp, has_exp,
            vals, window, status, _AMBIGUOUS)
    return vals, window, status, unassigned, lattice


def _measure_and_fit(arr, opts: _SpotOptions):
    """Steps 1-3 of :func:`locate_spots` for ``method="fit"`` (the tight-window measurement,
    then a disk fit of each spot). None: no spot detected and the frame's samples are all 0;
    False: nothing to index."""
    stride, saturation, max_residual = opts.stride, opts.saturation, opts.max_residual
    det = _detect(arr, stride, opts.nsigma, opts.min_contrast, opts.min_samples)
    if det.count.size == 0:
        return None if det.sample_max == 0 else False
    r0 = _first_radius(det.count, stride, opts.margin)
    band_lo, band_hi = _background_band(det)
    m = _k_aperture.measure_spots(arr, det.x, det.y, r0, opts.margin, opts.annulus, band_lo,
                                  band_hi, opts.n_iter, saturation)
    m = m[m[:, _FLUX] > 0]
    if m.shape[0] == 0:
        return False
    sx, sy = m[:, _X].copy(), m[:, _Y].copy()
    sflux = m[:, _FLUX].copy()
    ny, nx = arr.shape
    swin, sstat = _k_lattice.spot_table(m, nx, ny, _OK, _SATURATED, _CLIPPED)
    wx0, wx1, wy0, wy1 = swin
    for k in range(len(sx)):
        c = _fit_from(arr, SpotMoments(*m[k]), int(sstat[k]), 1.5, 30, True, saturation)
        if np.isfinite(c.x):
            sx[k], sy[k], sflux[k] = c.x, c.y, c.flux
            wx0[k], wx1[k], wy0[k], wy1[k] = c.window
    # The per-hole outputs are read from m: carry the fitted values there.
    m = m.copy()
    m[:, _FLUX], m[:, _X], m[:, _Y] = sflux, sx, sy
    pts = np.column_stack([sx, sy])
    med_flux = np.median(sflux)
    good = (sstat == _OK) & (sflux > 0.3 * med_flux)
    if not good.any():
        good = np.ones(len(sx), bool)
    ij, origin, basis, resid = _fit_lattice(pts, None, opts.pitch, good, max_residual)
    on_node = resid < max_residual * math.sqrt(abs(np.linalg.det(basis)))
    return m, swin, sstat, good, ij, origin, basis, resid, on_node, pts
