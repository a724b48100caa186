"""Spot centroids: the paper's two algorithms, estimators toward the Cramér–Rao bound, many spots.

Every single-spot estimator has the same signature ``method(frame, **options)`` and returns a
:class:`Centroid` ``(x, y, flux, window, status)``: ``x`` is the column and ``y`` the row of the
spot centroid in pixels (centre of the first pixel = 0), ``flux`` the background-subtracted flux
in DN, ``window`` the half-open pixel box ``(x0, x1, y0, y1)`` the estimate used, and ``status`` a
code of :data:`sunlab.schema.STATUS`. A frame without a usable spot gives NaN and a status, never
an exception; only a wrongly shaped argument (not 2-D) raises.

Estimators (docs/paper.md sec. 3 and beyond):

* :func:`threshold_window` — algorithm A, the group's earlier threshold + fixed 130 x 130 window;
* :func:`projection_window` — algorithm B, the paper's projection-profile window;
* :func:`tight_window` — a background-subtracted circular window fitted to the spot (fast);
* :func:`disk_fit` — a weighted least-squares fit of an edge-blurred disk (near the CRLB);
* :func:`crlb` — the Cramér–Rao lower bound of the centroid for a given spot, flux and noise.

Many spots (the 10 x 10 mask): :func:`locate_spots`. A whole frame cube: :func:`locate`.

Status precedence when several apply: invalid > no_spot > ambiguous > clipped > saturated >
repaired > ok. ``saturated`` means the spot saturates (touching clipped pixels); an isolated clipped
pixel in the window (a hot pixel) is replaced by the median of its 8 neighbours and the spot keeps
a usable status, ``repaired`` (algorithms A and B).
``x, y`` are NaN only for ``invalid`` and ``no_spot``; a clipped, saturated or ambiguous spot
keeps its (possibly biased) estimate so that it can be inspected.

Examples
--------
>>> import numpy as np
>>> from sunlab import centroid
>>> yy, xx = np.mgrid[0:200, 0:240]
>>> frame = (30 + 400 * (np.hypot(xx - 120.5, yy - 90.0) < 17.5)).astype(np.uint16)
>>> c = centroid.projection_window(frame)
>>> round(c.x, 2), round(c.y, 2), c.status_name
(120.5, 90.0, 'ok')
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from . import _centroid_kernels as _k
from . import parallel
from .errors import ConfigurationError, SchemaError
from .schema import STATUS, STATUS_NAMES

__all__ = [
    "Centroid",
    "Spots",
    "SPOT_METRICS",
    "CRLB",
    "METHODS",
    "threshold_window",
    "projection_window",
    "tight_window",
    "disk_fit",
    "crlb",
    "disk_profile",
    "locate_spots",
    "locate",
]

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
    # Two compiled specialisations only: uint16 (raw DN) and float64 (everything else).
    if arr.dtype.kind in "ub" and arr.dtype.itemsize <= 2:
        arr = arr.astype(np.uint16, copy=False)
    else:
        arr = arr.astype(np.float64, copy=False)
    arr = np.ascontiguousarray(arr)
    usable = min(arr.shape) >= 8
    if usable and arr.dtype.kind == "f":
        usable = bool(np.isfinite(arr).all())
    return arr, usable


def _all_zero(arr: np.ndarray) -> bool:
    return not arr.any()


def _status(*, clipped=False, saturated=False, ambiguous=False) -> int:
    if ambiguous:
        return _AMBIGUOUS
    if clipped:
        return _CLIPPED
    if saturated:
        return _SATURATED
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
    sub = arr[y0:y1, x0:x1]
    rows, cols = np.nonzero(sub >= saturation)
    if rows.size == 0:
        return s, x, y, 0, False
    ny, nx = arr.shape
    sx, sy = x * s, y * s
    n = 0
    for r, c in zip(rows + y0, cols + x0, strict=True):
        r0, r1, c0, c1 = max(r - 1, 0), min(r + 2, ny), max(c - 1, 0), min(c + 2, nx)
        nb = arr[r0:r1, c0:c1].astype(float).ravel()
        centre = (r - r0) * (c1 - c0) + (c - c0)
        nb = np.delete(nb, centre)
        if nb.size < 3 or (nb >= saturation).any():
            return s, x, y, 0, True
        m = float(np.median(nb))
        d = float(arr[r, c]) - bkg - (max(m - bkg, 0.0) if threshold else m - bkg)
        s, sx, sy = s - d, sx - d * c, sy - d * r
        n += 1
    return s, sx / s, sy / s, n, False


def _check_positive(name, value, fix="use a positive value"):
    if not (np.isfinite(value) and value > 0):
        raise ConfigurationError(f"{name}: found {value!r}, expected a positive number. Fix: {fix}")


# ------------------------------------------------------------------------------------------------
# Algorithm A
# ------------------------------------------------------------------------------------------------
def threshold_window(
    frame,
    *,
    border: int = 2,
    factor: float = 3.0,
    test_size: int = 5,
    test_count: int = 18,
    roi_size: int = 130,
    roi_border: int = 2,
    saturation: float = SATURATION_10BIT,
    check_ambiguous: bool = True,
) -> Centroid:
    """Algorithm A: threshold, first-hit test window, fixed ROI, centre of mass (paper sec. 3).

    The steps, exactly as the paper lists them (defaults are the paper's values):

    1. ``I_m`` = mean of the ``border`` (2) outermost rows and columns of the frame (each pixel
       counted once); noise threshold ``T = factor * I_m`` (3 I_m).
    2. Raster-scan the inner frame (rows and columns 1 .. n-2, i.e. 1022 x 1278) for a pixel
       ``> T``; it is the spot if at least ``test_count`` (18) of the ``test_size`` x
       ``test_size`` (5 x 5) pixels centred on it are ``> T`` (pixels outside the frame count as
       below); otherwise keep scanning.
    3. Take the ``roi_size`` x ``roi_size`` (130 x 130) region of interest centred on that pixel
       (rows ``r - 65 .. r + 64``: an even size has no centre pixel, the extra row and column go
       before it).
    4. New threshold ``T'`` = mean of the ``roi_border`` (2) outermost rows and columns of the ROI.
    5. In the inner (128 x 128) part of the ROI, pixels ``<= T'`` become 0, the others
       ``I - T'``; the centroid is their centre of mass, eq. (2).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    border : int
        Width of the frame border that gives ``I_m``, px.
    factor : float
        Noise threshold as a multiple of ``I_m``.
    test_size, test_count : int
        Side of the test window, px, and how many of its pixels must exceed the threshold.
    roi_size : int
        Side of the region of interest, px.
    roi_border : int
        Width of the ROI border that gives the second threshold, px; the centroid uses the ROI
        without a 1-px frame (the inner ``roi_size - 2``).
    saturation : float
        Full-scale value, DN: a pixel at or above it in the window flags ``saturated``.
    check_ambiguous : bool
        Continue the scan outside the ROI; a second qualifying pixel flags ``ambiguous``.

    Returns
    -------
    Centroid
        ``window`` is the inner ROI. ``clipped`` when the ROI had to be cut at the frame edge.

    Notes
    -----
    Centre of mass, eq. (2):

    .. math:: x_c = \\frac{\\sum_i x_i I_i}{\\sum_i I_i}, \\qquad
              y_c = \\frac{\\sum_i y_i I_i}{\\sum_i I_i}

    The ROI is centred on the first pixel found, i.e. on the top edge of the spot, not on its
    centre (the weakness the paper names); positive noise above ``T'`` over the 128 x 128 window
    then pulls the estimate toward the window centre, up to a few tenths of a pixel at the
    paper's SNR. The scan is a compiled raster loop; it stops at the first hit (or scans the rest
    of the frame outside the ROI when ``check_ambiguous``).

    References
    ----------
    docs/paper.md sec. 3, algorithm A.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = threshold_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.status_name
    (200.5, 150.0, 'ok')
    """
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    ny, nx = arr.shape
    i_m = _k.ring_mean(arr, 0, ny, 0, nx, int(border))
    thr = factor * i_m
    half = int(test_size) // 2
    r, c = _k.scan_first(arr, thr, half, int(test_count), 1, ny - 1, 1, nx - 1, 0, 0, 0, 0)
    if r < 0:
        return _fail(_INVALID if _all_zero(arr) else _NO_SPOT)
    h0 = int(roi_size) // 2
    rr0, rr1, cc0, cc1 = r - h0, r - h0 + int(roi_size), c - h0, c - h0 + int(roi_size)
    clipped = rr0 < 0 or cc0 < 0 or rr1 > ny or cc1 > nx
    rr0, rr1, cc0, cc1 = max(rr0, 0), min(rr1, ny), max(cc0, 0), min(cc1, nx)
    thr2 = _k.ring_mean(arr, rr0, rr1, cc0, cc1, int(roi_border))
    ir0, ir1, ic0, ic1 = rr0 + 1, rr1 - 1, cc0 + 1, cc1 - 1
    s, x, y, vmax = _k.com_above(arr, ir0, ir1, ic0, ic1, thr2)
    if not s > 0:
        return _fail(_NO_SPOT)
    ambiguous = False
    if check_ambiguous:
        r2, _ = _k.scan_first(
            arr, thr, half, int(test_count), 1, ny - 1, 1, nx - 1, rr0, rr1, cc0, cc1
        )
        ambiguous = r2 >= 0
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, (ic0, ic1, ir0, ir1), thr2, s, x, y,
                                                saturation, threshold=True)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous)
    if status == _OK and n_hot:
        status = _REPAIRED
    return Centroid(float(x), float(y), float(s), (ic0, ic1, ir0, ir1), status)


# ------------------------------------------------------------------------------------------------
# Algorithm B
# ------------------------------------------------------------------------------------------------
def _robust_level(p: np.ndarray) -> tuple[float, float]:
    med = float(np.median(p))
    return med, 1.4826 * float(np.median(np.abs(p - med)))


def _zones(p, base, sigma, nsigma, edge_sigma, min_width):
    """Signal zones of a profile: runs above base + nsigma sigma (at least ``min_width`` long),
    widened while above base + edge_sigma sigma. Returns a list of (lo, hi, excess), hi
    exclusive, brightest first."""
    ex = p - base
    floor = max(sigma, 1e-9 * max(abs(base), 1.0))
    above = ex > nsigma * floor
    if not above.any():
        return []
    d = np.diff(above.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    keep = ends - starts >= min_width
    if not keep.any():
        return []
    weak = ex > edge_sigma * floor
    out = []
    n = p.size
    for a, b in zip(starts[keep], ends[keep], strict=True):
        lo, hi = int(a), int(b)
        while lo > 0 and weak[lo - 1]:
            lo -= 1
        while hi < n and weak[hi]:
            hi += 1
        out.append((lo, hi, float(ex[lo:hi].sum())))
    # Hysteresis can merge runs; keep distinct zones only.
    merged: list[tuple[int, int, float]] = []
    for z in sorted(out):
        if merged and z[0] < merged[-1][1]:
            continue
        merged.append(z)
    return sorted(merged, key=lambda z: -z[2])


def projection_window(
    frame,
    *,
    nsigma: float = 5.0,
    edge_sigma: float = 1.0,
    margin: int = 3,
    min_width: int = 3,
    subtract_background: bool = True,
    ambiguity_ratio: float = 0.1,
    saturation: float = SATURATION_10BIT,
) -> Centroid:
    """Algorithm B: window from the row and column projection profiles (the paper's method).

    1. Column profile ``P_x[i]`` = sum of column ``i``; row profile ``P_y[j]`` = sum of row ``j``.
    2. In each profile, the integral noise level is its median (the spot covers a few percent of
       the columns and rows, so the median is a profile element without spot light) and the noise
       is ``1.4826 * MAD`` of the profile (robust standard deviation).
    3. Signal zone: runs of at least ``min_width`` elements above ``median + nsigma * noise``;
       each run is widened outward while the profile stays above ``median + edge_sigma *
       noise`` (hysteresis, so the zone reaches the spot's faint edge), then by ``margin`` px.
       The zone of the largest integrated excess is the spot; another zone with at least
       ``ambiguity_ratio`` of its excess flags ``ambiguous``. Runs shorter than ``min_width``
       (hot pixels, single bright columns) are ignored.
    4. Window = intersection of the column zone and the row zone; centroid = centre of mass
       inside it, eq. (2), of ``I - b`` where ``b`` is the per-pixel background implied by the
       profile levels, ``b = (median(P_x) / rows + median(P_y) / columns) / 2``.

    The paper leaves the noise level, the zone bounds and the background open; steps 2–4 above
    are this project's choices. ``subtract_background=False`` gives the literal eq. (2) on raw
    intensities (biased toward the window centre by the background).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    nsigma : float
        Detection level of a zone, in units of the profile noise.
    edge_sigma : float
        Level down to which a zone is widened, in units of the profile noise.
    margin : int
        Extra pixels added on each side of the zone.
    min_width : int
        Shortest run, px, that counts as a spot.
    subtract_background : bool
        Subtract the profile-derived background before the centre of mass.
    ambiguity_ratio : float
        A second zone with at least this fraction of the main zone's excess flags ``ambiguous``.
    saturation : float
        Full-scale value, DN.

    Returns
    -------
    Centroid
        ``clipped`` when the window touches the frame edge.

    Notes
    -----
    Centre of mass inside the window, eq. (2). One compiled pass over the frame builds both
    profiles.

    References
    ----------
    docs/paper.md sec. 3, algorithm B.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = projection_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.window
    (200.5, 150.0, (181, 221, 130, 171))
    """
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    ny, nx = arr.shape
    px, py = _k.profiles(arr)
    bx, sx = _robust_level(px)
    by, sy = _robust_level(py)
    zx = _zones(px, bx, sx, nsigma, edge_sigma, min_width)
    zy = _zones(py, by, sy, nsigma, edge_sigma, min_width)
    if not zx or not zy:
        return _fail(_INVALID if (px.max() == 0) else _NO_SPOT)
    ambiguous = any(len(z) > 1 and z[1][2] >= ambiguity_ratio * z[0][2] for z in (zx, zy))
    bkg = 0.5 * (bx / ny + by / nx) if subtract_background else 0.0
    best = None
    # With several zones the brightest column zone and row zone may belong to different spots:
    # take the pairing of the (up to) two main zones of each profile that holds the most flux.
    for a in zx[: 2 if ambiguous else 1]:
        for b in zy[: 2 if ambiguous else 1]:
            x0, x1 = a[0] - margin, a[1] + margin
            y0, y1 = b[0] - margin, b[1] + margin
            clipped = x0 <= 0 or y0 <= 0 or x1 >= nx or y1 >= ny
            x0, x1, y0, y1 = max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)
            s, x, y, vmax = _k.com_box(arr, y0, y1, x0, x1, bkg)
            if best is None or s > best[0]:
                best = (s, x, y, vmax, (x0, x1, y0, y1), clipped)
    s, x, y, vmax, (x0, x1, y0, y1), clipped = best
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, (x0, x1, y0, y1), bkg, s, x, y, saturation)
    if not s > 0:
        return _fail(_NO_SPOT)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous)
    if status == _OK and n_hot:
        status = _REPAIRED
    return Centroid(float(x), float(y), float(s), (x0, x1, y0, y1), status)


# ------------------------------------------------------------------------------------------------
# Detection shared by the tight window, the disk fit and the multi-spot locator
# ------------------------------------------------------------------------------------------------
class _Detection(NamedTuple):
    background: float
    sigma: float
    threshold: float
    count: np.ndarray
    flux: np.ndarray
    x: np.ndarray
    y: np.ndarray
    bbox: np.ndarray
    peak: np.ndarray
    sample_max: float


def _detect(arr, stride, nsigma, min_contrast, min_samples) -> _Detection:
    med, sig, smax = _k.sample_stats(arr, max(2 * int(stride), 1))
    thr = med + max(nsigma * sig, min_contrast)
    cnt, flux, cx, cy, bb, pk = _k.coarse_blobs(arr, int(stride), thr, med)
    keep = cnt >= min_samples
    return _Detection(med, sig, thr, cnt[keep], flux[keep], cx[keep], cy[keep], bb[keep], pk[keep],
                      smax)


def _first_radius(count, stride, margin):
    """First aperture radius: the equivalent radius of the above-threshold area, plus slack
    for the sampling (about stride / 3) and the margin."""
    return np.sqrt(count * float(stride) ** 2 / np.pi) + stride / 3.0 + margin


def _background_band(det: _Detection) -> tuple[float, float]:
    """Values accepted in a local background ring: the frame level +- max(10 sigma, 20 DN)."""
    half = max(10.0 * det.sigma, 20.0)
    return det.background - half, det.background + half


def _aperture_window(x, y, r, nx, ny):
    x0, x1 = math.ceil(x - r), math.floor(x + r) + 1
    y0, y1 = math.ceil(y - r), math.floor(y + r) + 1
    clipped = x0 < 0 or y0 < 0 or x1 > nx or y1 > ny
    return (max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)), clipped


def tight_window(
    frame,
    *,
    stride: int = 8,
    nsigma: float = 5.0,
    min_contrast: float = 5.0,
    min_samples: int = 3,
    margin: float = 5.0,
    annulus: float = 6.0,
    n_iter: int = 2,
    ambiguity_ratio: float = 0.1,
    saturation: float = SATURATION_10BIT,
) -> Centroid:
    """Background-subtracted centre of mass in a circular window fitted to the spot (fast).

    1. Detection: the background level and noise are the median and 1.4826 MAD of a sample of
       the frame every ``2 stride`` px; the samples every ``stride`` px above
       ``level + max(nsigma * noise, min_contrast)`` are grouped 8-connected; groups of at least
       ``min_samples`` samples are spots (a hot pixel is at most one sample). The brightest
       group is the spot; another with at least ``ambiguity_ratio`` of its flux flags
       ``ambiguous``.
    2. Local background: sigma-clipped mean of an ``annulus`` px wide ring just outside the
       window.
    3. Window: a circle about the detection, re-centred on the centre of mass of
       ``I - background`` (``n_iter`` passes); its radius becomes the spot's equivalent
       uniform-disk radius ``sqrt(2 (m_xx + m_yy))`` plus ``margin`` px, which holds the whole
       spot and few background pixels.

    Every pixel of the window counts (no threshold), so the estimate has no sub-pixel bias for
    a symmetric spot; noise comes from the spot's own photon noise and the few background pixels
    of the window. The work is a strided pass over the frame and a few passes over the window.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    stride : int
        Detection sampling step, px (must be well below the spot diameter).
    nsigma, min_contrast : float
        Detection threshold above the background: ``max(nsigma * noise, min_contrast)`` DN.
    min_samples : int
        Fewest detection samples of a spot.
    margin : float
        Window radius beyond the spot's equivalent radius, px.
    annulus : float
        Width of the background ring, px.
    n_iter : int
        Centre-of-mass passes that re-centre the window.
    ambiguity_ratio : float
        A second spot with at least this fraction of the flux flags ``ambiguous``.
    saturation : float
        Full-scale value, DN.

    Returns
    -------
    Centroid
        ``window`` is the bounding box of the circular window; ``clipped`` when the circle
        crosses the frame edge.

    Notes
    -----
    Centre of mass, eq. (2), of background-subtracted intensities.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = tight_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.status_name
    (200.5, 150.0, 'ok')
    """
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    res = _tight(arr, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter,
                 ambiguity_ratio, saturation)
    return res[0]


def _tight(arr, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter,
           ambiguity_ratio, saturation):
    """Tight window on a prepared frame; returns (Centroid, measurement row or None)."""
    det = _detect(arr, stride, nsigma, min_contrast, min_samples)
    if det.count.size == 0:
        return _fail(_INVALID if det.sample_max == 0 and _all_zero(arr) else _NO_SPOT), None
    order = np.argsort(-det.flux)
    k = order[0]
    ambiguous = det.count.size > 1 and det.flux[order[1]] >= ambiguity_ratio * det.flux[k]
    r0 = _first_radius(det.count[k : k + 1], stride, margin)
    lo, hi = _background_band(det)
    m = _k.measure_spots(arr, det.x[k : k + 1], det.y[k : k + 1], r0, float(margin),
                         float(annulus), lo, hi, int(n_iter), float(saturation))[0]
    if not m[0] > 0:
        return _fail(_NO_SPOT), None
    ny, nx = arr.shape
    x, y, r_ap = float(m[1]), float(m[2]), float(m[15])
    window, clipped = _aperture_window(x, y, r_ap, nx, ny)
    status = _status(clipped=clipped, saturated=m[12] > 0, ambiguous=ambiguous)
    return Centroid(x, y, float(m[0]), window, status), m


# ------------------------------------------------------------------------------------------------
# Disk-model fit
# ------------------------------------------------------------------------------------------------
def disk_fit(
    frame,
    *,
    edge: float = 1.5,
    max_iter: int = 30,
    reweight: bool = True,
    saturation: float = SATURATION_10BIT,
    profile: str = "spline",
    **detect,
) -> Centroid:
    """Weighted least-squares fit of the spot's centre and radial profile (at the Cramér–Rao bound).

    The spot of a round pinhole lit by the sun's disk is a uniform disk whose edge is blurred by
    the sun (a ramp ~ 2 F tan(0.26 deg) wide) and the pixels. The model

    .. math:: m(c, r) = b + \\frac{A}{2}\\,
              \\operatorname{erfc}\\!\\left(\\frac{d - R}{\\sqrt{2}\\,s}\\right), \\qquad
              d = \\sqrt{(c - x)^2 + (r - y)^2}

    with six parameters (x, y, R, A, b, s) is fitted by Levenberg–Marquardt on a square cutout
    around the spot found by :func:`tight_window` (its start). An erfc edge is not the exact
    ramp of a disk convolved with the sun's disk, but the mismatch is symmetric about the centre
    and so does not bias (x, y). Pixels at or above ``saturation`` are left out of the fit, so a
    saturated spot still gives an unbiased centre (the status still says ``saturated``).

    Weights: with ``reweight`` a first unweighted fit gives the residual variance on the
    background (``v0``) and on the plateau (``v0 + k A``); the second fit weights each pixel by
    ``1 / (v0 + k (m - b))`` — the Poisson + read-noise variance, learned from the frame, so no
    gain needs to be known. This is the maximum-likelihood estimate under the Gaussian
    approximation of that noise, which reaches the Cramér–Rao bound of :func:`crlb`.

    Profile (``profile="spline"``, the default): the erfc edge is exact for a disk blurred by a
    Gaussian but not for the ramp of a disk convolved with the sun's disk, and with a sun disk
    as wide as the hole (long focal lengths) there is no plateau to learn the photon noise from.
    A third fit therefore frees the radial profile: the centre (x, y) with a uniform cubic
    B-spline of the distance d (knots 1 px apart over ``R +- (3 s + 2)``, flat inside and
    outside), weighted by a noise model ``v0 + k (m - b)`` regressed on the squared residuals
    of a first spline fit, then refitted with it. On spots from a renderer the fit was not
    written for (a disk convolved with a uniform disk, a Gaussian-blurred disk; Poisson + read
    noise), the scatter is within 1.1x of the CRLB where the erfc model alone gives 1.3-1.45x
    (``python benchmarks/bench_crlb.py``). ``profile="erfc"`` stops after the erfc fit (faster).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    edge : float
        Starting edge width ``s``, px.
    max_iter : int
        Levenberg–Marquardt iterations per fit.
    reweight : bool
        Do the second, noise-weighted fit.
    saturation : float
        Full-scale value, DN.
    profile : {"spline", "erfc"}
        Radial profile of the final fit (see above).
    **detect
        Options of :func:`tight_window` (detection, start window).

    Returns
    -------
    Centroid
        ``flux``: the integral of the fitted profile above its outer level (erfc: ``A pi (R^2 +
        s^2)``); ``window`` is the fitted cutout. The status is the start's
        (:func:`tight_window`). If the fit does not converge inside the window, the result is NaN
        with status ``no_spot``.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = disk_fit(frame)
    >>> round(c.x, 2), round(c.y, 2), c.status_name
    (200.5, 150.0, 'ok')
    """
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    opts = {
        "stride": 8, "nsigma": 5.0, "min_contrast": 5.0, "min_samples": 3, "margin": 5.0,
        "annulus": 6.0, "n_iter": 2, "ambiguity_ratio": 0.1,
    }
    unknown = set(detect) - set(opts)
    if unknown:
        raise ConfigurationError(
            f"disk_fit: unknown option(s) {sorted(unknown)}; expected options of tight_window: "
            f"{sorted(opts)}"
        )
    if profile not in ("spline", "erfc"):
        raise ConfigurationError(
            f"disk_fit: profile={profile!r}; expected 'spline' (fitted radial profile) or "
            "'erfc' (the erfc edge only)."
        )
    opts.update(detect)
    start, m = _tight(arr, saturation=saturation, **opts)
    if m is None:
        return start
    return _fit_from(arr, m, start.status, edge, max_iter, reweight, saturation, profile)


def _fit_from(arr, m, status, edge, max_iter, reweight, saturation,
              profile="spline") -> Centroid:
    x0, y0, flux0, bkg = float(m[1]), float(m[2]), float(m[0]), float(m[13])
    rad = math.sqrt(max(2.0 * (m[3] + m[4]) - edge**2, 1.0))
    amp = flux0 / (math.pi * (rad**2 + edge**2))
    half = rad + 4.0 * edge + 4.0
    p0 = np.array([x0, y0, rad, amp, bkg, edge])
    sat = float(saturation)
    p, _, _, _, _, r0, r1, c0, c1 = _k.fit_disk(arr, p0, half, int(max_iter), 1.0, 0.0, 1e-5, sat)
    flux = math.nan
    if reweight and np.all(np.isfinite(p)):
        v0, vk = _noise_model(arr, p, r0, r1, c0, c1, sat)
        if np.isfinite(v0) and v0 > 0:
            if profile == "spline":
                p, flux, (r0, r1, c0, c1) = _fit_spline(arr, p, int(max_iter), v0, vk, sat)
            else:
                p, _, _, _, _, r0, r1, c0, c1 = _k.fit_disk(
                    arr, p, half, int(max_iter), v0, vk, 1e-5, sat
                )
    # A fit that wanders off the spot is a failure; a clipped spot may move by up to ~R.
    if not np.all(np.isfinite(p[:2])) or math.hypot(p[0] - x0, p[1] - y0) > rad + 2.0:
        return _fail(_NO_SPOT)
    if not np.isfinite(flux):
        flux = p[3] * math.pi * (p[2] ** 2 + p[5] ** 2)
    return Centroid(float(p[0]), float(p[1]), float(flux), (int(c0), int(c1), int(r0), int(r1)),
                    status)


#: Knot step of the radial spline of ``disk_fit(profile="spline")``, px, and the margin of its
#: knot span beyond the erfc fit's edge, ``R +- (3 s + 2)`` px.
_SPLINE_STEP = 1.0
_SPLINE_PAD = 2.0


def _fit_spline(arr, p, max_iter, v0, vk, sat):
    """Second stage of :func:`disk_fit`: the radial-spline profile fitted with the centre,
    started from the erfc fit ``p``. Returns (p with the new centre, flux, window)."""
    x, y, rad, amp, b, s = (float(v) for v in p)
    pad = 3.0 * s + _SPLINE_PAD
    d_lo, d_hi = max(rad - pad, 0.0), rad + pad
    nint = max(math.ceil((d_hi - d_lo) / _SPLINE_STEP), 1)
    h = (d_hi - d_lo) / nint
    # The window reaches 3 px beyond the knot span, so the background level is well measured.
    ny, nx = arr.shape
    half = d_hi + 3.0
    r0, r1 = max(math.floor(y - half), 0), min(math.ceil(y + half) + 1, ny)
    c0, c1 = max(math.floor(x - half), 0), min(math.ceil(x + half) + 1, nx)
    # Start: each B-spline coefficient at the erfc model's value at the centre of its basis.
    k = np.arange(nint + 3)
    centres = d_lo + (k - 1.0) * h
    a0 = [b + 0.5 * amp * math.erfc((c - rad) / (math.sqrt(2.0) * s)) for c in centres]
    q0 = np.concatenate([[x, y], a0])
    q, _, _ = _k.fit_profile(arr, q0, d_lo, h, nint, r0, r1, c0, c1, max_iter, v0, vk, b, 1e-5,
                             sat)
    # Noise from the spline's own residuals, then refit: where the spot has no plateau (a
    # sun-disk ramp wider than the hole) the zones cannot see the photon noise, and weights
    # without it cost 20-40 % in scatter.
    if np.all(np.isfinite(q)):
        v1, vk1, _ = _k.profile_noise(arr, q, d_lo, h, nint, r0, r1, c0, c1, b, sat)
        if np.isfinite(v1) and (abs(v1 - v0) > 0.1 * v0 or abs(vk1 - vk) > 0.1 * max(vk1, vk)):
            q1, _, _ = _k.fit_profile(arr, q, d_lo, h, nint, r0, r1, c0, c1, max_iter, v1, vk1,
                                      b, 1e-5, sat)
            if np.all(np.isfinite(q1)):
                q = q1
    out = p.copy()
    out[0], out[1] = q[0], q[1]
    flux = _k.profile_flux(q, d_lo, h, nint, 8) if np.all(np.isfinite(q)) else math.nan
    return out, float(flux), (r0, r1, c0, c1)


def _noise_model(arr, p, r0, r1, c0, c1, sat):
    """Pixel variance ``v0 + vk (m - b)`` of a spot fitted with parameters ``p``, from the
    background beyond ``R + 3 s + 2`` and the plateau within ``R - 3 s - 2`` (model-free: a
    mismatch of the fitted edge does not leak into it); the fit's residuals where either zone
    has too few pixels. ``v0`` is at least 1/12 DN^2 (quantisation)."""
    x, y, rad, s = float(p[0]), float(p[1]), float(p[2]), float(p[5])
    pad = 3.0 * s + 2.0
    v0, vk, n_bkg, n_plateau = _k.zone_noise(arr, x, y, rad - pad, rad + pad, r0, r1, c0, c1, sat)
    if n_bkg < 20 or not np.isfinite(v0):
        v0, vk = _k.disk_noise(arr, p, r0, r1, c0, c1, sat)
    elif n_plateau < 10:
        vk = _k.disk_noise(arr, p, r0, r1, c0, c1, sat)[1]
    return max(float(v0), 1.0 / 12.0), float(vk)


# ------------------------------------------------------------------------------------------------
# Cramér–Rao bound
# ------------------------------------------------------------------------------------------------
class CRLB(NamedTuple):
    """Cramér–Rao lower bound of the centroid standard deviation, px."""

    sigma_x: float
    sigma_y: float


def disk_profile(dx, dy, radius: float = 17.5, edge: float = 3.25):
    """Surface brightness (0..1) of a uniform disk spot blurred by a uniform source disk.

    The spot of a round hole of radius ``radius`` lit by a uniform disk source whose image has
    radius ``edge`` (F tan of the sun's angular radius: 5 mm x tan(0.26 deg) = 3.24 px for the
    paper's bench) is the hole convolved with that disk. For ``radius >> edge`` its edge profile
    is the fraction of the source disk inside a half-plane at distance ``d = r - radius``:

    .. math:: f(d) = \\frac{1}{\\pi}\\left[\\arccos u - u\\sqrt{1 - u^2}\\right],
              \\quad u = \\operatorname{clip}(d / \\rho, -1, 1),\\ \\rho = \\text{edge}

    ``edge = 0`` is a hard edge.

    Examples
    --------
    >>> [float(disk_profile(r, 0.0)) for r in (0.0, 17.5, 30.0)]
    [1.0, 0.5, 0.0]
    """
    r = np.hypot(dx, dy)
    if edge <= 0:
        return np.where(r <= radius, 1.0, 0.0)
    u = np.clip((r - radius) / edge, -1.0, 1.0)
    return (np.arccos(u) - u * np.sqrt(1.0 - u * u)) / np.pi


def crlb(
    flux: float,
    background: float,
    read_noise: float,
    *,
    gain: float = 1.0,
    radius: float = 17.5,
    edge: float = 3.25,
    model: Callable | None = None,
    half_size: float | None = None,
    position: tuple[float, float] = (0.3, 0.2),
    quantisation: bool = True,
    supersample: int = 16,
) -> CRLB:
    """Cramér–Rao lower bound of a spot centroid for pixel-integrated Poisson + read noise.

    The expected value of pixel ``i`` is ``mu_i = flux * P_i + background`` where ``P_i`` is the
    spot's surface brightness integrated over the pixel (normalised to 1 over the cutout); its
    variance is ``mu_i / gain + read_noise^2 (+ 1/12 for quantisation to integer DN)``. The
    Fisher information of the centre is

    .. math:: I_{ab} = \\sum_i \\frac{1}{\\operatorname{var}_i}
              \\frac{\\partial \\mu_i}{\\partial a}\\frac{\\partial \\mu_i}{\\partial b},
              \\qquad a, b \\in \\{x, y\\}

    and the bound is ``sqrt(diag(I^-1))``. The derivative of a pixel-integrated value with
    respect to the centre is computed exactly as the difference of line integrals of the surface
    brightness along the pixel's two edges, so hard-edged spots work too. The variance model is
    the Gaussian (shifted-Poisson) approximation of the Poisson + Gaussian likelihood, exact in
    the pure-Poisson and pure-Gaussian limits. Flux, background and spot shape are taken as
    known; for a centrally symmetric spot the centre decouples from them, so the bound holds
    when they are fitted too.

    Parameters
    ----------
    flux : float
        Total spot flux above the background, DN.
    background : float
        Background level per pixel (dark + stray light), DN.
    read_noise : float
        Read noise, DN rms.
    gain : float
        Conversion gain, electrons per DN (Poisson variance in DN^2 is ``mu / gain``).
    radius, edge : float
        Spot radius and edge half-width, px, of the default model :func:`disk_profile`.
    model : callable, optional
        Surface brightness ``model(dx, dy)`` (any scale) of the spot about its centre, for
        array offsets dx (column) and dy (row) in px; replaces the default disk.
    half_size : float, optional
        Half-size of the cutout, px (default ``radius + edge + 3``; give it with ``model``).
    position : tuple of 2 float
        Sub-pixel position of the centre (the bound depends on it weakly).
    quantisation : bool
        Add the quantisation variance 1/12 DN^2.
    supersample : int
        Sub-samples per pixel side (and line-integral samples per pixel edge x 4).

    Returns
    -------
    CRLB
        ``(sigma_x, sigma_y)``, px.

    Examples
    --------
    >>> b = crlb(385000.0, 30.0, 2.5, gain=4.0)
    >>> 0.002 < b.sigma_x < 0.02
    True
    """
    _check_positive("flux", flux)
    _check_positive("gain", gain)
    if not (background >= 0 and read_noise >= 0):
        raise ConfigurationError(
            f"background, read_noise: found {background!r}, {read_noise!r}, expected >= 0 DN"
        )
    prof = model if model is not None else (lambda dx, dy: disk_profile(dx, dy, radius, edge))
    h = float(half_size) if half_size is not None else float(radius + max(edge, 0) + 3)
    n = int(math.ceil(h))
    px0, py0 = position
    cols = np.arange(-n, n + 1)
    s = int(supersample)
    off = (np.arange(s) + 0.5) / s - 0.5
    # Pixel integrals of the surface brightness.
    sx = (cols[:, None] + off[None, :]).ravel() - px0
    sy = (cols[:, None] + off[None, :]).ravel() - py0
    sub = prof(sx[None, :], sy[:, None])
    pint = sub.reshape(cols.size, s, cols.size, s).mean(axis=(1, 3))
    total = pint.sum()
    if not total > 0:
        raise ConfigurationError("model: found a spot of zero brightness on the cutout")
    scale = flux / total
    mu = scale * pint + background
    var = mu / gain + read_noise**2 + (1.0 / 12.0 if quantisation else 0.0)
    # d mu / d x0 = -(line integral on the right edge - on the left edge), and likewise for y0.
    t = 4 * s
    lo = (np.arange(t) + 0.5) / t - 0.5
    ly = (cols[:, None] + lo[None, :]).ravel() - py0  # rows, finely sampled
    edges = np.concatenate([cols - 0.5, [cols[-1] + 0.5]]) - px0
    line = prof(edges[None, :], ly[:, None]).reshape(cols.size, t, edges.size).mean(axis=1)
    dmu_dx = -scale * (line[:, 1:] - line[:, :-1])
    lx = (cols[:, None] + lo[None, :]).ravel() - px0
    edges_y = np.concatenate([cols - 0.5, [cols[-1] + 0.5]]) - py0
    line_y = prof(lx[None, :], edges_y[:, None]).reshape(edges_y.size, cols.size, t).mean(axis=2)
    dmu_dy = -scale * (line_y[1:, :] - line_y[:-1, :])
    fisher = np.array([
        [np.sum(dmu_dx**2 / var), np.sum(dmu_dx * dmu_dy / var)],
        [np.sum(dmu_dx * dmu_dy / var), np.sum(dmu_dy**2 / var)],
    ])
    cov = np.linalg.inv(fisher)
    return CRLB(float(math.sqrt(cov[0, 0])), float(math.sqrt(cov[1, 1])))


#: Single-spot estimators by name (the ``method=`` of :func:`locate`).
METHODS: dict[str, Callable[..., Centroid]] = {
    "threshold": threshold_window,
    "projection": projection_window,
    "tight": tight_window,
    "fit": disk_fit,
}


# ------------------------------------------------------------------------------------------------
# Many spots: the 10 x 10 mask
# ------------------------------------------------------------------------------------------------
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
        """The spots as a pandas DataFrame, one row per hole."""
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
    ij, origin, basis, resid, ok = _k.fit_lattice(
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
    frame,
    *,
    shape: tuple[int, int] = (10, 10),
    pitch: float = 0.5 / 0.007,
    holes=None,
    expected=None,
    method: str = "tight",
    max_residual: float = 0.3,
    stride: int = 8,
    nsigma: float = 5.0,
    min_contrast: float = 5.0,
    min_samples: int = 3,
    margin: float = 5.0,
    annulus: float = 6.0,
    n_iter: int = 2,
    saturation: float = SATURATION_10BIT,
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
    rows, cols = (int(v) for v in shape)
    if rows < 1 or cols < 1:
        raise ConfigurationError(f"shape: found {shape!r}, expected (rows, cols) >= (1, 1)")
    _check_positive("pitch", pitch, "give the hole pitch on the detector in px")
    if method not in ("tight", "fit"):
        raise ConfigurationError(f"method: found {method!r}, expected 'tight' or 'fit'")
    if holes is None:
        hi, hj, lut = _raster_holes(rows, cols)
        hi, hj = hi.copy(), hj.copy()
    else:
        hi, hj = (np.asarray(h, dtype=int) for h in holes)
        lut = np.full((rows, cols), -1, dtype=int)
        inside = (hi >= 0) & (hi < rows) & (hj >= 0) & (hj < cols)
        lut[hi[inside], hj[inside]] = np.flatnonzero(inside)
    n_holes = hi.size
    arr, usable = _prepare(frame)
    if expected is not None:
        exp = np.ascontiguousarray(np.asarray(expected, dtype=float).reshape(n_holes, 2))
    else:
        exp = np.empty((0, 2))
    unassigned, lattice = np.zeros((0, 2)), np.full((3, 2), np.nan)
    if not usable:
        vals, window, status = _k.new_holes(n_holes, _INVALID)
    elif method == "tight":
        vals, window, status, nd, smax, unassigned, lattice = _k.locate_tight(
            arr, int(stride), float(nsigma), float(min_contrast), int(min_samples),
            float(margin), float(annulus), int(n_iter), float(saturation), float(pitch),
            float(max_residual), _OK, _SATURATED, _CLIPPED, lut, exp, expected is not None,
            n_holes, _NO_SPOT, _AMBIGUOUS)
        if nd == 0 and smax == 0 and _all_zero(arr):
            status[:] = _INVALID
    else:
        vals, window, status = _k.new_holes(n_holes, _NO_SPOT)
        fitted = _measure_and_fit(arr, method, stride, nsigma, min_contrast, min_samples, margin,
                                  annulus, n_iter, saturation, pitch, max_residual)
        if fitted is None:
            if _all_zero(arr):
                status[:] = _INVALID
        elif fitted is not False:
            m, swin, sstat, good, ij, origin, basis, resid, on_node, pts = fitted
            unassigned, lattice = _k.assign_grid(
                m, swin, sstat, good, ij, origin, basis, resid, on_node, pts, lut, exp,
                expected is not None, vals, window, status, _AMBIGUOUS)
    # x, y, flux and the metrics (columns METRIC_FIELDS, the order of SPOT_METRICS) are rows
    # of one block.
    metrics = dict(zip(_k.METRIC_FIELDS, vals[3:], strict=True))
    return Spots(vals[0], vals[1], vals[2], window, status, hi, hj, metrics, unassigned, lattice)


def _measure_and_fit(arr, method, stride, nsigma, min_contrast, min_samples, margin, annulus,
                     n_iter, saturation, pitch, max_residual):
    """Steps 1-3 of :func:`locate_spots` for ``method="fit"`` (the tight-window measurement,
    then a disk fit of each spot). None: no spot detected and the frame's samples are all 0;
    False: nothing to index."""
    det = _detect(arr, stride, nsigma, min_contrast, min_samples)
    if det.count.size == 0:
        return None if det.sample_max == 0 else False
    r0 = _first_radius(det.count, stride, margin)
    band_lo, band_hi = _background_band(det)
    m = _k.measure_spots(arr, det.x, det.y, r0, float(margin), float(annulus), band_lo, band_hi,
                         int(n_iter), float(saturation))
    m = m[m[:, 0] > 0]
    if m.shape[0] == 0:
        return False
    sx, sy = m[:, 1].copy(), m[:, 2].copy()
    sflux = m[:, 0].copy()
    ny, nx = arr.shape
    swin, sstat = _k.spot_table(m, nx, ny, _OK, _SATURATED, _CLIPPED)
    wx0, wx1, wy0, wy1 = swin
    for k in range(len(sx)):
        c = _fit_from(arr, m[k], int(sstat[k]), 1.5, 30, True, saturation)
        if np.isfinite(c.x):
            sx[k], sy[k], sflux[k] = c.x, c.y, c.flux
            wx0[k], wx1[k], wy0[k], wy1[k] = c.window
    # The per-hole outputs are read from m: carry the fitted values there.
    m = m.copy()
    m[:, 0], m[:, 1], m[:, 2] = sflux, sx, sy
    pts = np.column_stack([sx, sy])
    med_flux = np.median(sflux)
    good = (sstat == _OK) & (sflux > 0.3 * med_flux)
    if not good.any():
        good = np.ones(len(sx), bool)
    ij, origin, basis, resid = _fit_lattice(pts, None, pitch, good, max_residual)
    on_node = resid < max_residual * math.sqrt(abs(np.linalg.det(basis)))
    return m, swin, sstat, good, ij, origin, basis, resid, on_node, pts


# ------------------------------------------------------------------------------------------------
# Cube level
# ------------------------------------------------------------------------------------------------
_FIELDS = ("x", "y", "flux", "x0", "x1", "y0", "y1", "status")
_CARRY_ATTRS = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "bit_depth", "mask",
                "experiment")


def _single_block(frames, func, kwargs):
    """Apply a single-spot estimator to a block (..., y, x) -> (..., 8) float64."""
    lead = frames.shape[:-2]
    flat = np.asarray(frames).reshape((-1,) + frames.shape[-2:])
    out = np.empty((flat.shape[0], len(_FIELDS)))
    for n, fr in enumerate(flat):
        c = func(fr, **kwargs)
        out[n] = (c.x, c.y, c.flux, *c.window, c.status)
    return out.reshape(lead + (len(_FIELDS),))


def _multi_block(frames, shift_x, shift_y, kwargs, design):
    """locate_spots on a block (..., y, x) -> (..., hole, 8 + metrics) float64."""
    lead = frames.shape[:-2]
    flat = np.asarray(frames).reshape((-1,) + frames.shape[-2:])
    sx = np.broadcast_to(shift_x, lead).reshape(-1)
    sy = np.broadcast_to(shift_y, lead).reshape(-1)
    n_holes = kwargs["holes"][0].size
    nf = len(_FIELDS) + len(SPOT_METRICS)
    out = np.empty((flat.shape[0], n_holes, nf))
    for n, fr in enumerate(flat):
        expected = None
        if design is not None and np.isfinite(sx[n]) and np.isfinite(sy[n]):
            expected = design + np.array([sx[n], sy[n]])
        s = locate_spots(fr, expected=expected, **kwargs)
        out[n, :, 0], out[n, :, 1], out[n, :, 2] = s.x, s.y, s.flux
        out[n, :, 3:7] = s.window.T
        out[n, :, 7] = s.status
        for k, name in enumerate(SPOT_METRICS):
            out[n, :, 8 + k] = s.metrics[name]
    return out.reshape(lead + (n_holes, nf))


def locate(
    cube,
    method: str = "projection",
    *,
    multi: bool | None = None,
    scheduler: str = "threads",
    address: str | None = None,
    num_workers: int | None = None,
    progress: bool = True,
    compute: bool = True,
    **options,
):
    """Centroid every frame of a cube: a ``centroids/1`` dataset over (pose, shot[, hole]).

    The frames go through :func:`xarray.apply_ufunc` with ``dask="parallelized"``, one task per
    frame chunk, on Dask's threaded scheduler by default (the compiled kernels release the GIL,
    so threads scale), or on a ``dask.distributed`` cluster at ``address``.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``), NumPy- or Dask-backed.
    method : {"threshold", "projection", "tight", "fit"}
        Single-spot estimator (:data:`METHODS`); for a multi-hole cube the per-spot estimator of
        :func:`locate_spots` (``"tight"`` or ``"fit"``; ``"projection"`` and ``"threshold"`` are
        single-spot algorithms and fall back to ``"tight"`` there).
    multi : bool, optional
        Multi-hole cube (default: the cube has a ``hole`` dimension with ``hole_i``, ``hole_j``).
    scheduler : str
        Dask scheduler when no address is given: ``"threads"``, ``"processes"``,
        ``"synchronous"`` or ``"cluster"`` (a local cluster of processes; see :func:`compute`).
    address : str, optional
        Address of a ``dask.distributed`` scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    num_workers : int, optional
        Threads or processes of a local scheduler.
    progress : bool
        Show a progress bar.
    compute : bool
        Compute now (default); ``False`` returns the dataset with lazy Dask variables.
    **options
        Options of the estimator (``saturation`` defaults to ``2**bit_depth - 1`` of the cube).

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1``: ``x``, ``y`` (px), ``flux`` (DN), ``status``, window
        ``x0, x1, y0, y1``, with the cube's ``alpha``, ``beta`` coordinates, its sensor
        attributes, ground truth variables when present, and for multi-hole cubes the hole
        coordinates and the per-spot metrics of :data:`SPOT_METRICS`.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> yy, xx = np.mgrid[0:200, 0:240]
    >>> spot = lambda x, y: (30 + 400 * (np.hypot(xx - x, yy - y) < 15)).astype(np.uint16)
    >>> frames = np.stack([[spot(100.5, 80.0), spot(101.5, 80.0)]])
    >>> cube = schema.frames_dataset(frames, alpha=[0.0], beta=[0.0])
    >>> cen = locate(cube, "projection", progress=False)
    >>> cen.x.values.round(2).tolist(), cen.status.values.tolist()
    ([[100.5, 101.5]], [[0, 0]])
    """
    import dask.array as da
    import xarray as xr

    from . import schema

    schema.validate_frames(cube)
    if method not in METHODS:
        raise ConfigurationError(
            f"method: found {method!r}, expected one of {sorted(METHODS)}"
        )
    options = dict(options)
    options.setdefault("saturation", float(2 ** int(cube.attrs["bit_depth"]) - 1))
    if multi is None:
        multi = "hole" in cube.dims or ("hole_i" in cube.variables and "hole_j" in cube.variables)
    frames = cube["frames"]
    if not isinstance(frames.data, da.Array):
        frames = frames.chunk({"pose": 1, "shot": 1})
    frames = frames.chunk({"y": -1, "x": -1})
    n_pose, n_shot = cube.sizes["pose"], cube.sizes["shot"]
    extra = {}
    if not multi:
        func = METHODS[method]
        res = xr.apply_ufunc(
            _single_block, frames, kwargs={"func": func, "kwargs": options},
            input_core_dims=[["y", "x"]], output_core_dims=[["field"]],
            dask="parallelized", output_dtypes=[np.float64],
            dask_gufunc_kwargs={"output_sizes": {"field": len(_FIELDS)}},
        )
        dims = ("pose", "shot")
    else:
        if "hole_i" not in cube.variables or "hole_j" not in cube.variables:
            raise SchemaError("hole_i, hole_j", "missing", "grid row/column of each hole on dim "
                              "'hole'", "simulate with a multi-hole bench or add the coordinates")
        hi = np.asarray(cube["hole_i"].values, dtype=int)
        hj = np.asarray(cube["hole_j"].values, dtype=int)
        spot_opts = {k: v for k, v in options.items() if k != "method"}
        spot_opts["method"] = method if method in ("tight", "fit") else "tight"
        spot_opts.setdefault("shape", (int(hi.max()) + 1, int(hj.max()) + 1))
        spot_opts["holes"] = (hi, hj)
        design = None
        shift_x = shift_y = xr.full_like(cube["alpha"], np.nan)
        if "hole_x_cf" in cube.variables and "hole_y_cf" in cube.variables:
            from .geometry import ideal_centroid

            design = np.column_stack([cube["hole_x_cf"].values, cube["hole_y_cf"].values])
            a = cube["alpha"].values
            b = cube["beta"].values
            dx, dy = ideal_centroid(a, b, float(cube.attrs["mask_distance_mm"]),
                                    float(cube.attrs["pixel_pitch_mm"]), 0.0, 0.0)
            shift_x = xr.DataArray(dx, dims="pose")
            shift_y = xr.DataArray(dy, dims="pose")
        n_holes = hi.size
        res = xr.apply_ufunc(
            _multi_block, frames, shift_x, shift_y,
            kwargs={"kwargs": spot_opts, "design": design},
            input_core_dims=[["y", "x"], [], []], output_core_dims=[["hole", "field"]],
            dask="parallelized", output_dtypes=[np.float64],
            dask_gufunc_kwargs={"output_sizes": {"hole": n_holes,
                                                 "field": len(_FIELDS) + len(SPOT_METRICS)}},
        )
        dims = ("pose", "shot", "hole")
    res = res.transpose(*dims, "field")
    if compute:
        res = _compute(res, scheduler, address, num_workers, progress)
    data = res.data
    shape = tuple(res.sizes[d] for d in dims)
    if multi:
        for k, name in enumerate(SPOT_METRICS):
            extra[name] = (dims, data[..., 8 + k], {"long_name": SPOT_METRICS[name]})
    attrs = {k: cube.attrs[k] for k in _CARRY_ATTRS if k in cube.attrs}
    attrs.update({"source_schema": cube.attrs.get("sunlab_schema", ""),
                  "options": repr({k: v for k, v in options.items() if k != "holes"})})
    if compute:
        cen = schema.centroids_dataset(
            data[..., 0], data[..., 1], flux=data[..., 2], status=data[..., 7].astype(np.int8),
            window=[data[..., 3 + k].astype(np.int32) for k in range(4)],
            alpha=cube["alpha"].values, beta=cube["beta"].values, method=method, attrs=attrs,
            extra=extra,
        )
    else:
        template = schema.centroids_dataset(
            np.zeros(shape), np.zeros(shape), alpha=cube["alpha"].values,
            beta=cube["beta"].values, method=method, attrs=attrs,
        )
        cen = template.copy()
        for k, name in enumerate(_FIELDS):
            arr = data[..., k]
            if name == "status":
                arr = arr.astype(np.int8)
            elif name in ("x0", "x1", "y0", "y1"):
                arr = arr.astype(np.int32)
            cen[name] = (dims, arr, template[name].attrs)
        for name, val in extra.items():
            cen[name] = val
    for name in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf", "hole_defect"):
        if multi and name in cube.variables:
            cen = cen.assign_coords({name: ("hole", np.asarray(cube[name].values))})
    for name in ("true_x", "true_y", "true_alpha", "true_beta", "alpha_read", "beta_read"):
        if name in cube.variables and set(cube[name].dims) <= set(dims):
            # the bare variable: a cube's own coordinates (e.g. alpha_read, time on an
            # acquisition store) must not collide with the table's
            cen[name] = cube[name].variable.transpose(*[d for d in dims if d in cube[name].dims])
            if compute:
                cen[name] = cen[name].compute()
    if n_pose != cen.sizes["pose"] or n_shot != cen.sizes["shot"]:  # pragma: no cover
        raise SchemaError("centroids", dict(cen.sizes), f"pose={n_pose}, shot={n_shot}")
    return cen


def _compute(res, scheduler, address, num_workers, progress):
    """Compute one lazy result with :func:`sunlab.parallel.compute` (inside :func:`locate`,
    whose ``compute`` flag shadows that name)."""
    return parallel.compute(res, scheduler=scheduler, address=address,
                            num_workers=num_workers, progress=progress)[0]
