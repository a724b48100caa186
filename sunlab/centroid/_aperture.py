"""Spot detection on a coarse grid of samples and the tight circular aperture's measurement, in
vectorised numpy over all spots of a frame at once (private to :mod:`sunlab.centroid`).

Every spot gets a square stamp of the frame about its centre (one gather from a sliding-window
view for a few spots at a time), and masks select the pixels of its aperture or ring: those whose
centres lie within ``r`` of ``(x, y)``, or at ``r_in < d <= r_out``.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy import ndimage

__all__: list[str] = []

#: Columns of the array returned by :func:`_measure` (the fields of
#: :class:`sunlab.centroid.moments.SpotMoments`).
MEASURE_FIELDS = (
    "flux", "x", "y", "mxx", "myy", "mxy", "m30", "m21", "m12", "m03", "peak", "npix", "nsat",
    "background", "background_std", "r_ap",
)
FLUX, X, Y, MXX, MYY, MXY, M30, M21, M12, M03, PEAK, NPIX, NSAT, BKG, BKG_STD, R_AP = range(16)


class _Detection(NamedTuple):
    background: float
    sigma: float
    count: np.ndarray
    flux: np.ndarray
    x: np.ndarray
    y: np.ndarray
    sample_max: float


def _samples(arr, stride):
    off = stride // 2
    return arr[off::stride, off::stride].astype(np.float64), off


def _groups(arr, stride, thr, bkg):
    """8-connected groups of the strided samples above ``thr`` (``scipy.ndimage.label``, in
    raster order of their first sample): count, sum of ``I - bkg``, its centre of mass (the
    centre of the group's box when the sum is not positive)."""
    g, off = _samples(arr, stride)
    lab, n = ndimage.label(g > thr, structure=np.ones((3, 3)))
    sel = np.flatnonzero(lab)
    k = lab.ravel()[sel] - 1
    r, c = np.divmod(sel, g.shape[1])
    r, c = off + r * stride, off + c * stride
    w = g.ravel()[sel] - bkg
    cnt = np.bincount(k, minlength=n)
    s = np.bincount(k, w, minlength=n)
    box = np.array([(sy.start, sy.stop - 1, sx.start, sx.stop - 1)
                    for sy, sx in ndimage.find_objects(lab)], float).reshape(n, 4)
    box = off + box * stride
    with np.errstate(invalid="ignore", divide="ignore"):
        cx = np.where(s > 0, np.bincount(k, w * c, minlength=n) / s, 0.5 * (box[:, 2] + box[:, 3]))
        cy = np.where(s > 0, np.bincount(k, w * r, minlength=n) / s, 0.5 * (box[:, 0] + box[:, 1]))
    return cnt, s, cx, cy


def _detect(arr, stride, nsigma, min_contrast, min_samples) -> _Detection:
    """Frame level (median of the samples 2 ``stride`` apart), noise (1.4826 MAD), and the
    groups of samples ``stride`` apart above ``level + max(nsigma noise, min_contrast)`` with
    at least ``min_samples`` samples."""
    smp, _ = _samples(arr, max(2 * int(stride), 1))
    med = float(np.median(smp))
    sig = 1.4826 * float(np.median(np.abs(smp - med)))
    thr = med + max(nsigma * sig, min_contrast)
    cnt, flux, cx, cy = _groups(arr, int(stride), thr, med)
    keep = cnt >= min_samples
    return _Detection(med, sig, cnt[keep], flux[keep], cx[keep], cy[keep], float(smp.max()))


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


def _stamps(arr, xs, ys, radius):
    """Stamps (n, s, s) of the frame holding each circle of ``radius`` (the largest of the
    spots') about ``(xs, ys)``, cut from a sliding-window view (a stamp at the frame's edge is
    moved inside it), the column and row of each stamp's middle pixel, and the squared offsets
    ``dx2``, ``dy2`` (n, s) of the stamps' columns and rows from the centres (infinite beyond
    a frame smaller than a stamp)."""
    half = math.ceil(radius + 0.5)
    size = 2 * half + 1
    ny, nx = arr.shape
    if ny < size or nx < size:
        arr = np.pad(arr, ((0, max(size - ny, 0)), (0, max(size - nx, 0))))
    c0 = np.minimum(np.maximum(np.rint(xs).astype(np.intp) - half, 0), arr.shape[1] - size)
    r0 = np.minimum(np.maximum(np.rint(ys).astype(np.intp) - half, 0), arr.shape[0] - size)
    v = sliding_window_view(arr, (size, size))[r0, c0]
    cols, rows = c0[:, None] + np.arange(size), r0[:, None] + np.arange(size)
    dx, dy = cols - xs[:, None], rows - ys[:, None]
    return (v, c0 + half, r0 + half, np.where(cols < nx, dx * dx, np.inf),
            np.where(rows < ny, dy * dy, np.inf))


def _disk(dx2, dy2, r):
    """Pixels (n, s, s) whose centres lie within ``r`` of the centre."""
    return dx2[:, None, :] <= ((r * r)[:, None] - dy2)[:, :, None]


def _ring_level(v, ring, lo, hi):
    """Mean, standard deviation and count of the ``ring`` pixels of each stamp whose values lie
    in ``[lo, hi]`` (all the ring's pixels where none does)."""
    integer = v.dtype.kind == "u" and math.isfinite(lo) and math.isfinite(hi)
    if integer:  # the same pixels by integer comparisons (no float conversion)
        lo, hi = max(math.ceil(lo), 0), min(math.floor(hi), np.iinfo(v.dtype).max)
        lo, hi = (lo, hi) if lo <= hi else (1, 0)
    use = ring & (v >= lo) & (v <= hi)
    n = np.count_nonzero(use, axis=(1, 2))
    if not n.all():
        use |= ring & (n == 0)[:, None, None]
        n = np.count_nonzero(use, axis=(1, 2))
    vu = v * use  # no float64 copy: each fresh temporary of a stamp batch costs page faults
    s1 = vu.sum((1, 2), dtype=np.uint64 if integer else np.float64)
    s2 = np.einsum("nij,nij->n", vu, vu, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = s1 / n
        sd = np.sqrt(np.maximum(s2 / n - m * m, 0.0))
    return m, sd, n


def _annulus(arr, xs, ys, r_in, r_out, lo, hi):
    """:func:`_ring_level` of each ring ``r_in < d <= r_out`` about (xs, ys)."""
    v, _, _, dx2, dy2 = _stamps(arr, xs, ys, float(np.max(r_out)))
    return _ring_level(v, _disk(dx2, dy2, r_out) & ~_disk(dx2, dy2, r_in), lo, hi)


def _raw(v, inside, bkg, order):
    """Moments ``p[:, l, k]`` = sum of ``(I - bkg) v^l u^k`` over each aperture, l, k <=
    ``order``, u and v the column and row offsets from the stamp's middle pixel: one matrix
    product of all the stamps' rows with the powers of u, then one with those of v."""
    n, size, _ = v.shape
    pw = (np.arange(size) - size // 2)[:, None] ** np.arange(order + 1.0)
    w = v.astype(np.float64)
    w -= bkg[:, None, None]
    w *= inside
    return pw.T @ (w.reshape(-1, size) @ pw).reshape(n, size, order + 1)


def _com_of(cx, cy, p):
    """Sum and centre of mass from the moments of :func:`_raw` about the stamps' middle pixels
    (cx, cy); NaN where the sum is not positive."""
    s = p[:, 0, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        x, y = cx + p[:, 0, 1] / s, cy + p[:, 1, 0] / s
    bad = ~(s > 0)
    x[bad], y[bad] = np.nan, np.nan
    return s, x, y


def _com(arr, xs, ys, r, bkg):
    """Sum and centre of mass of ``I - bkg`` in each aperture of radius ``r`` about (xs, ys)."""
    v, cx, cy, dx2, dy2 = _stamps(arr, xs, ys, float(np.max(r)))
    return _com_of(cx, cy, _raw(v, _disk(dx2, dy2, r), bkg, 1))


def _moments(arr, xs, ys, r, bkg, sat):
    """Moments of ``I - bkg`` in each aperture of radius ``r`` about (xs, ys): an (n, 13) array,
    columns the first 13 of :data:`MEASURE_FIELDS` (central moments about the centre of mass;
    NaN where the sum is not positive, but for the sum, peak, pixel and saturated counts)."""
    v, cx, cy, dx2, dy2 = _stamps(arr, xs, ys, float(np.max(r)))
    inside = _disk(dx2, dy2, r)
    p = _raw(v, inside, bkg, 3)
    s, x, y = _com_of(cx, cy, p)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = p / s[:, None, None]
        # about the centre of mass: c[l, k] = sum_ab C(l, a) C(k, b) (-my)^(l-a) (-mx)^(k-b) p[a, b]
        c = _shift(-p[:, 1, 0]) @ p @ _shift(-p[:, 0, 1]).transpose(0, 2, 1)
    out = np.full((xs.size, 13), np.nan)
    out[:, FLUX], out[:, X], out[:, Y] = s, x, y
    out[:, MXX:M03 + 1] = c[:, [0, 2, 1, 0, 1, 2, 3], [2, 0, 1, 3, 2, 1, 0]]
    out[~(s > 0), X:M03 + 1] = np.nan
    out[:, PEAK] = np.max(v, axis=(1, 2), where=inside,
                          initial=0 if v.dtype.kind == "u" else -np.inf)
    out[:, NPIX] = np.count_nonzero(inside, axis=(1, 2))
    out[:, NSAT] = np.count_nonzero(inside & (v >= sat), axis=(1, 2))
    return out


_BINOM = np.array([[1, 0, 0, 0], [1, 1, 0, 0], [1, 2, 1, 0], [1, 3, 3, 1]], float)


def _shift(d):
    """Matrices (n, 4, 4) that move power sums of an offset u to those of u + d."""
    k = np.arange(4)
    with np.errstate(invalid="ignore"):
        return _BINOM * d[:, None, None] ** np.maximum(k[:, None] - k[None, :], 0)


def _measure(arr, xs, ys, r0s, margin, annulus, lo, hi, n_iter, sat):
    """Tight-window measurement of spots started at (xs, ys) with first aperture radii ``r0s``.

    For each spot: the background is the mean of the pixels of a ring ``annulus`` px wide just
    outside the first aperture whose values lie in [lo, hi] (a band about the frame's background
    level, which rejects hot pixels and neighbouring spots); the centre of mass of
    (I - background) inside the circular aperture re-centres it ``n_iter - 1`` times; the moments
    in that aperture give the spot's equivalent uniform-disk radius sqrt(2 (mxx + myy)); the
    final centroid and flux are the centre of mass in an aperture of that radius plus ``margin``
    (if smaller than the first), centred on the previous estimate.
    Returns an (n, 16) array, columns :data:`MEASURE_FIELDS` (moments from the first aperture;
    NaN rows for spots that failed).
    """
    xs, ys, r = (np.array(a, dtype=np.float64).reshape(-1) for a in (xs, ys, r0s))
    out = np.full((xs.size, len(MEASURE_FIELDS)), np.nan)
    # a few spots at a time: their stamps stay in the cache (and below the size at which
    # each temporary array is a fresh memory map)
    step = max(_CHUNK // (2 * math.ceil(float(np.max(r, initial=0)) + annulus) + 5) ** 2, 1)
    for k in range(0, xs.size, step):
        out[k:k + step] = _measure_some(arr, xs[k:k + step], ys[k:k + step], r[k:k + step],
                                        margin, annulus, lo, hi, n_iter, sat)
    return out


_CHUNK = 2**18  # pixels of the spots' stamps measured at a time


def _measure_some(arr, xs, ys, r, margin, annulus, lo, hi, n_iter, sat):
    out = np.full((xs.size, len(MEASURE_FIELDS)), np.nan)
    # the ring and the first aperture from the same stamps
    v, cx, cy, dx2, dy2 = _stamps(arr, xs, ys, float(np.max(r)) + 1.0 + annulus)
    bkg, bsd, nb = _ring_level(v, _disk(dx2, dy2, r + 1.0 + annulus) & ~_disk(dx2, dy2, r + 1.0),
                               lo, hi)
    live = nb > 0
    for it in range(int(n_iter) - 1):
        s, x1, y1 = (_com_of(cx, cy, _raw(v, _disk(dx2, dy2, r), bkg, 1)) if it == 0
                     else _com(arr, xs, ys, r, bkg))
        live &= (s > 0) & (np.abs(x1 - xs) < r) & (np.abs(y1 - ys) < r)
        xs, ys = np.where(live, x1, xs), np.where(live, y1, ys)
    idx = np.flatnonzero(live)
    if idx.size == 0:
        return out
    m = _moments(arr, xs[idx], ys[idx], r[idx], bkg[idx], sat)
    ok = m[:, FLUX] > 0
    idx, m = idx[ok], m[ok]
    rad = np.sqrt(np.maximum(2.0 * (m[:, MXX] + m[:, MYY]), 0.0))
    shrink = np.flatnonzero((rad > 0) & (rad + margin < r[idx] - 0.5))
    if shrink.size:
        k = idx[shrink]
        r[k] = rad[shrink] + margin
        s, x1, y1 = _com(arr, m[shrink, X], m[shrink, Y], r[k], bkg[k])
        pos = shrink[s > 0]
        m[pos, FLUX], m[pos, X], m[pos, Y] = s[s > 0], x1[s > 0], y1[s > 0]
    out[idx, :13] = m
    out[idx, BKG], out[idx, BKG_STD], out[idx, R_AP] = bkg[idx], bsd[idx], r[idx]
    return out
