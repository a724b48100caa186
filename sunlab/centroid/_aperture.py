"""Spot detection on a coarse grid of samples and the tight circular aperture's measurement, in
vectorised numpy over all spots of a frame at once (private to :mod:`sunlab.centroid`).

Every spot gets a square stamp of the frame about its centre (one gather from a sliding-window
view for a few spots at a time), and masks select the pixels of its aperture or ring: those whose
centres lie within ``r`` of ``(x, y)``, or at ``r_in < d <= r_out``.
"""

from __future__ import annotations

import functools
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
    with np.errstate(invalid="ignore", divide="ignore"):
        cx, cy = np.bincount(k, w * c, minlength=n) / s, np.bincount(k, w * r, minlength=n) / s
    bad = np.flatnonzero(~(s > 0))
    if bad.size:
        box = off + stride * np.array([(sy.start, sy.stop - 1, sx.start, sx.stop - 1) for sy, sx
                                       in ndimage.find_objects(lab)], float)[bad]
        cx[bad], cy[bad] = 0.5 * (box[:, 2] + box[:, 3]), 0.5 * (box[:, 0] + box[:, 1])
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


def _stamps(arr, xs, ys, radius):
    """Stamps (n, s, s) of the frame holding each circle of ``radius`` (the largest of the
    spots') about ``(xs, ys)``, cut from a sliding-window view (a stamp at the frame's edge is
    moved inside it), the column and row of each stamp's middle pixel, the squared offsets
    ``dy2`` (n, s) of the stamps' rows from the centres (infinite beyond a frame smaller than a
    stamp), the centres' columns within the stamps and the stamps' columns inside the frame
    (n, 1)."""
    half = math.ceil(radius + 0.5)
    size = 2 * half + 1
    ny, nx = arr.shape
    if ny < size or nx < size:
        arr = np.pad(arr, ((0, max(size - ny, 0)), (0, max(size - nx, 0))))
    c0 = np.minimum(np.maximum(np.rint(xs).astype(np.intp) - half, 0), arr.shape[1] - size)
    r0 = np.minimum(np.maximum(np.rint(ys).astype(np.intp) - half, 0), arr.shape[0] - size)
    v = sliding_window_view(arr, (size, size))[r0, c0]
    rows = r0[:, None] + np.arange(size)
    return (v, c0 + half, r0 + half, np.where(rows < ny, (rows - ys[:, None]) ** 2, np.inf),
            (xs - c0)[:, None], np.minimum(nx - c0, size)[:, None])


def _disk(st, r):
    """Pixels (n, s, s) of the stamps ``st`` (:func:`_stamps`) whose centres lie within ``r``
    of the centre, and the first and end column (n, s) of each row's run of them: the run
    ``|c - x| <= sqrt(r^2 - dy^2)`` of each row, the mask looked up in a table of runs (one
    gather, not a comparison per pixel)."""
    (dy2, xc, ncol), size = st[3:], st[0].shape[1]
    q = (r * r)[:, None] - dy2
    t = np.sqrt(q, out=np.full(q.shape, -1.0), where=q >= 0)  # -1: no pixel in the row
    a = np.clip(np.ceil(xc - t), 0, size).astype(np.intp)
    b = np.maximum(np.clip(np.floor(xc + t) + 1, 0, ncol).astype(np.intp), a)
    return np.take(_runs(size), a * (size + 1) + b, axis=0), a, b


@functools.lru_cache(maxsize=8)
def _runs(size):
    """Table ((size + 1)^2, size) of rows of ``size`` pixels: row ``a (size + 1) + b`` holds the
    run of columns ``a <= c < b``."""
    c, k = np.arange(size), np.arange(size + 1)
    return ((k[:, None, None] <= c) & (c < k[None, :, None])).reshape(-1, size)


def _ring_level(v, ring, lo, hi):
    """Mean, standard deviation and count of the ``ring`` pixels of each stamp whose values lie
    in ``[lo, hi]`` (all the ring's pixels where none does)."""
    if v.dtype.kind == "u" and math.isfinite(lo) and math.isfinite(hi):
        # the same pixels by integer comparisons (no float conversion)
        lo, hi = max(math.ceil(lo), 0), min(math.floor(hi), np.iinfo(v.dtype).max)
        lo, hi = (lo, hi) if lo <= hi else (1, 0)
    use = ring & (v >= lo) & (v <= hi)
    n = use.reshape(len(v), -1).view(np.uint8).sum(1, dtype=np.uint32).astype(np.int64)
    if not n.all():
        use |= ring & (n == 0)[:, None, None]
        n = use.reshape(len(v), -1).sum(1, dtype=np.int64)
    # integer sums below 2^53: exact in float64, in any order
    vu = (v * use).reshape(len(v), 1, -1).astype(np.float64)
    s1, s2 = vu.sum((1, 2)), (vu @ vu.transpose(0, 2, 1)).reshape(-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = s1 / n
        sd = np.sqrt(np.maximum(s2 / n - m * m, 0.0))
    return m, sd, n


def _annulus(arr, xs, ys, r_in, r_out, lo, hi):
    """:func:`_ring_level` of each ring ``r_in < d <= r_out`` about (xs, ys) (``a > b``: in
    the outer disk ``a`` and not in the inner ``b``)."""
    st = _stamps(arr, xs, ys, float(np.max(r_out)))
    return _ring_level(st[0], _disk(st, r_out)[0] > _disk(st, r_in)[0], lo, hi)


def _raw(v, disk, bkg, order):
    """Moments ``p[:, l, k]`` = sum of ``(I - bkg) v^l u^k`` over each aperture ``disk``
    (:func:`_disk`), l, k <= ``order``, u and v the column and row offsets from the stamp's
    middle pixel: one matrix product of the masked stamps' rows with the powers of u, less the
    background over each row's run (from cumulative sums of the powers), then one with the
    powers of v."""
    inside, a, b = disk
    n, size, _ = v.shape
    pw = (np.arange(size) - size // 2)[:, None] ** np.arange(order + 1.0)
    cum = np.concatenate([np.zeros((1, order + 1)), np.cumsum(pw, axis=0)])
    im = (v * inside).reshape(-1, size).astype(np.float64)
    # two powers at a time: BLAS's kernel for two columns is several times faster than for four
    rows = np.concatenate([im @ np.ascontiguousarray(pw[:, k:k + 2])
                           for k in range(0, order + 1, 2)], axis=1).reshape(n, size, order + 1)
    rows -= bkg[:, None, None] * (np.take(cum, b, axis=0) - np.take(cum, a, axis=0))
    return pw.T @ rows


def _com_of(cx, cy, p):
    """Sum and centre of mass from the moments of :func:`_raw` about the stamps' middle pixels
    (cx, cy); NaN where the sum is not positive."""
    s = p[:, 0, 0]
    with np.errstate(invalid="ignore", divide="ignore"):
        return s, *(np.where(s > 0, c + p[:, i, 1 - i] / s, np.nan) for i, c in ((0, cx), (1, cy)))


def _com(arr, xs, ys, r, bkg):
    """Sum and centre of mass of ``I - bkg`` in each aperture of radius ``r`` about (xs, ys)."""
    st = _stamps(arr, xs, ys, float(np.max(r)))
    return _com_of(st[1], st[2], _raw(st[0], _disk(st, r), bkg, 1))


def _moments(arr, xs, ys, r, bkg, sat):
    """Moments of ``I - bkg`` in each aperture of radius ``r`` about (xs, ys): an (n, 13) array,
    columns the first 13 of :data:`MEASURE_FIELDS` (central moments about the centre of mass;
    NaN where the sum is not positive, but for the sum, peak, pixel and saturated counts)."""
    st = _stamps(arr, xs, ys, float(np.max(r)))
    v, cx, cy = st[:3]
    inside, a, b = disk = _disk(st, r)
    p = _raw(v, disk, bkg, 3)
    s, x, y = _com_of(cx, cy, p)
    with np.errstate(invalid="ignore", divide="ignore"):
        p = p / s[:, None, None]
        # about the centre of mass: c[l, k] = sum_ab C(l, a) C(k, b) (-my)^(l-a) (-mx)^(k-b) p[a, b]
        c = _shift(-p[:, 1, 0]) @ p @ _shift(-p[:, 0, 1]).transpose(0, 2, 1)
    out = np.full((xs.size, 13), np.nan)
    out[:, FLUX], out[:, X], out[:, Y] = s, x, y
    out[:, MXX:M03 + 1] = c[:, [0, 2, 1, 0, 1, 2, 3], [2, 0, 1, 3, 2, 1, 0]]
    out[~(s > 0), X:M03 + 1] = np.nan
    out[:, PEAK] = ((v * inside).max((1, 2)) if v.dtype.kind == "u" else
                    np.max(v, axis=(1, 2), where=inside, initial=-np.inf))
    out[:, NPIX] = (b - a).sum(1)
    hot = out[:, PEAK] >= sat  # only these can hold pixels at full scale
    out[:, NSAT] = 0
    out[hot, NSAT] = np.count_nonzero(inside[hot] & (v[hot] >= sat), axis=(1, 2))
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
    # a few spots at a time: their stamps stay in the cache (and below the size at which
    # each temporary array is a fresh memory map)
    step = max(_CHUNK // (2 * math.ceil(float(np.max(r, initial=0)) + annulus) + 5) ** 2, 1)
    return np.concatenate([np.empty((0, len(MEASURE_FIELDS)))] + [
        _measure_some(arr, xs[k:k + step], ys[k:k + step], r[k:k + step], margin, annulus, lo,
                      hi, n_iter, sat) for k in range(0, xs.size, step)])


_CHUNK = 2**19  # pixels of the spots' stamps measured at a time


def _measure_some(arr, xs, ys, r, margin, annulus, lo, hi, n_iter, sat):
    out = np.full((xs.size, len(MEASURE_FIELDS)), np.nan)
    # the ring and the first aperture from the same stamps
    st = _stamps(arr, xs, ys, float(np.max(r)) + 1.0 + annulus)
    v, cx, cy = st[:3]
    bkg, bsd, nb = _ring_level(v, _disk(st, r + 1.0 + annulus)[0] > _disk(st, r + 1.0)[0],
                               lo, hi)
    live = nb > 0
    for it in range(int(n_iter) - 1):
        s, x1, y1 = (_com_of(cx, cy, _raw(v, _disk(st, r), bkg, 1)) if it == 0
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
