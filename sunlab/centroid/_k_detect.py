"""Kernels of the spot detection on a coarse grid of samples (tight window, disk fit, many spots).

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import jit

__all__: list[str] = []


# --------------------------------------------------------------------------------------------
# Detection on a coarse grid of samples
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def _order_stat(hist, k):
    """Index of the k-th smallest (0-based) of the values counted by ``hist``."""
    c = 0
    for v in range(hist.size):
        c += hist[v]
        if c > k:
            return v
    return hist.size - 1


@njit(cache=True, nogil=True)
def _hist_median(hist, n):
    """Median of the n values counted by ``hist``, as :func:`numpy.median` gives it (the mean
    of the two middle values when n is even)."""
    if n % 2:
        return float(_order_stat(hist, n // 2))
    return (float(_order_stat(hist, n // 2 - 1)) + float(_order_stat(hist, n // 2))) / 2


@jit.kernel(cache=True, nogil=True)
def sample_stats(frame, stride):
    """Median and MAD-based sigma (1.4826 MAD) of a strided sample of the frame, plus the
    sample maximum.

    When the samples are non-negative integers (DN frames) below 65536, both medians come from
    counts of the values (O(n + range) instead of a selection over the samples; the same
    numbers: the deviations from a median are multiples of 1/2, counted doubled).
    """
    ny, nx = frame.shape
    off = stride // 2
    gy = (ny - off + stride - 1) // stride
    gx = (nx - off + stride - 1) // stride
    buf = np.empty(gy * gx, np.float64)
    k = 0
    vmax = -np.inf
    integral = True
    for i in range(gy):
        row = frame[off + i * stride]
        for j in range(gx):
            v = float(row[off + j * stride])
            buf[k] = v
            k += 1
            vmax = max(vmax, v)
            integral &= v >= 0 and v == math.floor(v)
    if integral and k > 0 and vmax < 65536:
        top = int(vmax)
        hist = np.zeros(top + 1, np.int64)
        for t in range(k):
            hist[int(buf[t])] += 1
        med = _hist_median(hist, k)
        m2 = int(2 * med)
        dev = np.zeros(max(m2, 2 * top - m2) + 1, np.int64)  # |2 v - 2 med|
        for v in range(top + 1):
            if hist[v]:
                dev[abs(2 * v - m2)] += hist[v]
        mad = _hist_median(dev, k) / 2
        return med, 1.4826 * mad, vmax
    med = np.median(buf)
    for i in range(k):
        buf[i] = abs(buf[i] - med)
    mad = np.median(buf)
    return med, 1.4826 * mad, vmax


@jit.kernel(cache=True, nogil=True)
def coarse_blobs(frame, stride, thr, bkg):
    """8-connected groups of strided samples above ``thr``.

    Samples sit at (off + i stride, off + j stride), off = stride // 2. Returns, per group,
    arrays: number of samples, sum of (I - bkg), weighted column and row (px), bounding box of
    the samples in frame pixels (r0, r1, c0, c1; inclusive) and the peak sample.
    """
    ny, nx = frame.shape
    off = stride // 2
    gy = (ny - off + stride - 1) // stride
    gx = (nx - off + stride - 1) // stride
    # Flags on a grid with a one-sample border: 1 above threshold, 2 visited, 0 otherwise.
    # One sequential pass over the samples, then the flood fill touches only the flagged ones.
    gw = gx + 2
    flag = np.zeros((gy + 2) * gw, np.uint8)
    nab = 0
    for i in range(gy):
        row = frame[off + i * stride]
        base = (i + 1) * gw + 1
        for j in range(gx):
            a = row[off + j * stride] > thr
            flag[base + j] = a
            nab += a
    # At most one group per flagged sample: allocated once (arrays re-bound inside the loops
    # would cost numba reference counting on every iteration).
    cap = max(nab, 1)
    stack = np.empty(cap, np.int64)
    cnt = np.zeros(cap, np.int64)
    flux = np.zeros(cap)
    cx = np.zeros(cap)
    cy = np.zeros(cap)
    bb = np.zeros((cap, 4), np.int64)
    peak = np.zeros(cap)
    nb = 0
    if nab == 0:
        return cnt[:0], flux[:0], cx[:0], cy[:0], bb[:0], peak[:0]
    for i in range(gy):
        for j in range(gx):
            if flag[(i + 1) * gw + j + 1] != 1:
                continue
            flag[(i + 1) * gw + j + 1] = 2
            top = 0
            stack[top] = i * gx + j
            top += 1
            n = 0
            s = 0.0
            sx = 0.0
            sy = 0.0
            pk = -np.inf
            bi0, bi1, bj0, bj1 = i, i, j, j
            while top > 0:
                top -= 1
                q = stack[top]
                qi = q // gx
                qj = q - qi * gx
                r = off + qi * stride
                c = off + qj * stride
                v = float(frame[r, c])
                w = v - bkg
                n += 1
                s += w
                sx += w * c
                sy += w * r
                if v > pk:
                    pk = v
                bi0 = min(bi0, qi)
                bi1 = max(bi1, qi)
                bj0 = min(bj0, qj)
                bj1 = max(bj1, qj)
                for di in range(-1, 2):
                    fb = (qi + di + 1) * gw + qj + 1
                    for dj in range(-1, 2):
                        if flag[fb + dj] == 1:
                            flag[fb + dj] = 2
                            stack[top] = (qi + di) * gx + qj + dj
                            top += 1
            cnt[nb] = n
            flux[nb] = s
            cx[nb] = sx / s if s > 0 else off + 0.5 * (bj0 + bj1) * stride
            cy[nb] = sy / s if s > 0 else off + 0.5 * (bi0 + bi1) * stride
            bb[nb, 0] = off + bi0 * stride
            bb[nb, 1] = off + bi1 * stride
            bb[nb, 2] = off + bj0 * stride
            bb[nb, 3] = off + bj1 * stride
            peak[nb] = pk
            nb += 1
    return cnt[:nb], flux[:nb], cx[:nb], cy[:nb], bb[:nb], peak[:nb]
