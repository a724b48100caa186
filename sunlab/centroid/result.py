"""The result of a single-spot estimator, :class:`Centroid`, and the frame checks, status rules
and hot-pixel repair that every estimator of :mod:`sunlab.centroid` shares.

Examples
--------
>>> from sunlab.centroid.result import Centroid
>>> Centroid(120.5, 90.0, 1.0e5, (100, 141, 70, 111), 0).status_name
'ok'
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import ConfigurationError, SchemaError
from ..schema import STATUS, STATUS_NAMES

__all__ = ["Centroid"]

#: Full scale of the paper's 10-bit ADC (Ibis4), DN: a pixel at or above it is saturated.
SATURATION_10BIT = 1023

_OK = STATUS["ok"]
_NO_SPOT = STATUS["no_spot"]
_SATURATED = STATUS["saturated"]
_CLIPPED = STATUS["clipped"]
_AMBIGUOUS = STATUS["ambiguous"]
_INVALID = STATUS["invalid"]
_REPAIRED = STATUS["repaired"]
_NO_WINDOW = (-1, -1, -1, -1)


class Centroid(NamedTuple):
    """Result of a single-spot estimator.

    Attributes
    ----------
    x, y : float
        Centroid column and row, px (centre of the first pixel = 0); NaN when no usable spot.
    flux : float
        Background-subtracted spot flux, DN (NaN when no spot).
    window : tuple of 4 int
        ``(x0, x1, y0, y1)``: the half-open pixel box the estimate used; -1 when none.
    status : int
        Status code of :data:`sunlab.schema.STATUS` (0 ok, 1 no_spot, 2 saturated, 3 clipped,
        4 ambiguous, 5 invalid).
    """

    x: float
    y: float
    flux: float
    window: tuple[int, int, int, int]
    status: int

    @property
    def status_name(self) -> str:
        """Name of :attr:`status`, e.g. ``'ok'``."""
        return STATUS_NAMES[int(self.status)]

    @property
    def ok(self) -> bool:
        """True when the centroid is usable: status ``ok`` or ``repaired``."""
        return int(self.status) in (_OK, _REPAIRED)


def _fail(status: int) -> Centroid:
    return Centroid(math.nan, math.nan, math.nan, _NO_WINDOW, status)


def _prepare(frame) -> tuple[np.ndarray, bool]:
    """Frame as a C-contiguous numeric 2-D array and whether it is usable (finite, not all 0)."""
    arr = np.asarray(frame)
    if arr.ndim != 2:
        raise SchemaError(
            "frame", f"{arr.ndim}-d array of shape {arr.shape}", "a 2-D image (rows, columns)",
            "pass one frame, e.g. cube.frames[pose, shot].values",
        )
    if arr.dtype.kind not in "uifb":
        raise SchemaError("frame.dtype", str(arr.dtype), "integer or float intensities (DN)")
    # Two dtypes only: uint16 (raw DN, exact integer sums) and float64 (everything else).
    if arr.dtype.kind in "ub" and arr.dtype.itemsize <= 2:
        arr = arr.astype(np.uint16, copy=False)
    else:
        arr = arr.astype(np.float64, copy=False)
    arr = np.ascontiguousarray(arr)
    usable = min(arr.shape) >= 8
    if usable and arr.dtype.kind == "f":
        usable = bool(np.isfinite(arr).all())
    return arr, usable


def _full_scale(frame, saturation) -> float:
    """The saturation level: ``saturation`` when given, else the full scale of the frame's
    unsigned integer type (255, 65535), else infinity (float frames have no full scale)."""
    if saturation is not None:
        return float(saturation)
    dtype = getattr(frame, "dtype", None)
    if dtype is None:
        dtype = np.asarray(frame).dtype
    if dtype.kind == "u" and dtype.itemsize <= 2:
        return float(np.iinfo(dtype).max)
    return math.inf


def _status(*, clipped=False, saturated=False, ambiguous=False, repaired=False) -> int:
    """The status by precedence: ambiguous > clipped > saturated > repaired > ok."""
    for flag, code in ((ambiguous, _AMBIGUOUS), (clipped, _CLIPPED), (saturated, _SATURATED),
                       (repaired, _REPAIRED)):
        if flag:
            return code
    return _OK


def _repair_hot(arr, window, bkg, s, x, y, saturation, threshold=False):
    """Separate a saturated spot from isolated clipped pixels (hot pixels) in a window.

    A pixel at or above ``saturation`` whose 8 neighbours are all below it is a hot pixel, not
    spot light at full scale: its value is replaced by the median of its 8 neighbours and the
    centre of mass ``(s, x, y)`` of ``I - bkg`` is corrected for the change (with
    ``threshold=True`` the weights are ``max(I - bkg, 0)``, algorithm A). Two or more touching
    clipped pixels mean the spot (or a cluster) saturates.

    Returns ``(s, x, y, n_repaired, saturated)``.
    """
    x0, x1, y0, y1 = window
    rows, cols = np.nonzero(arr[y0:y1, x0:x1] >= saturation)
    rows, cols = rows + y0, cols + x0
    med = _hot_medians(arr, rows, cols, saturation)
    if not med:  # None: the spot saturates; []: no clipped pixel
        return s, x, y, 0, med is None
    sx, sy = x * s, y * s
    for r, c, m in zip(rows, cols, med, strict=True):
        d = float(arr[r, c]) - bkg - (max(m - bkg, 0.0) if threshold else m - bkg)
        s, sx, sy = s - d, sx - d * c, sy - d * r
    return s, sx / s, sy / s, len(med), False


def _hot_medians(img, rows, cols, saturation):
    """Median of the 8 neighbours (those inside ``img``) of each clipped pixel (rows, cols), a
    hot pixel when they are all below ``saturation``; None when one of them is not (two
    clipped pixels touch: the spot saturates) or a pixel has fewer than 3 neighbours."""
    ny, nx = img.shape
    med = []
    for r, c in zip(rows, cols, strict=True):
        r0, r1, c0, c1 = max(r - 1, 0), min(r + 2, ny), max(c - 1, 0), min(c + 2, nx)
        nb = np.delete(img[r0:r1, c0:c1].astype(float).ravel(), (r - r0) * (c1 - c0) + (c - c0))
        if nb.size < 3 or (nb >= saturation).any():
            return None
        med.append(float(np.median(nb)))
    return med


def _check_positive(name, value, fix="use a positive value"):
    if not (np.isfinite(value) and value > 0):
        raise ConfigurationError(f"{name}: found {value!r}, expected a positive number. Fix: {fix}")
