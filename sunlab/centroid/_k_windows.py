"""Kernels of the paper's algorithms A (threshold + fixed window) and B (projection window).

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ._k_flags import _FM

__all__: list[str] = []


# --------------------------------------------------------------------------------------------
# Algorithm A (threshold + fixed window)
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, fastmath=_FM)
def ring_mean(frame, r0, r1, c0, c1, w):
    """Mean of the ``w`` outermost rows and columns of frame[r0:r1, c0:c1] (each pixel once)."""
    s = 0.0
    n = 0
    for r in range(r0, r1):
        edge_row = r < r0 + w or r >= r1 - w
        for c in range(c0, c1):
            if edge_row or c < c0 + w or c >= c1 - w:
                s += frame[r, c]
                n += 1
    return s / n if n > 0 else np.nan


@njit(cache=True, nogil=True)
def scan_first(frame, thr, half, need, r0, r1, c0, c1, er0, er1, ec0, ec1):
    """Raster scan of frame[r0:r1, c0:c1] for the first pixel above ``thr`` whose
    (2 half + 1)^2 neighbourhood holds at least ``need`` pixels above ``thr`` (pixels outside
    the frame count as below). Pixels inside the excluded box [er0:er1, ec0:ec1] are skipped.
    Returns (row, col), or (-1, -1)."""
    ny, nx = frame.shape
    for r in range(r0, r1):
        in_rows = er0 <= r < er1
        for c in range(c0, c1):
            if frame[r, c] > thr:
                if in_rows and ec0 <= c < ec1:
                    continue
                n = 0
                for rr in range(max(r - half, 0), min(r + half + 1, ny)):
                    for cc in range(max(c - half, 0), min(c + half + 1, nx)):
                        if frame[rr, cc] > thr:
                            n += 1
                if n >= need:
                    return r, c
    return -1, -1


@njit(cache=True, nogil=True, fastmath=_FM)
def com_above(frame, r0, r1, c0, c1, thr):
    """Centre of mass of (I - thr) over the pixels of frame[r0:r1, c0:c1] with I > thr.

    Returns (sum, x, y, max of I over the box)."""
    s = 0.0
    sx = 0.0
    sy = 0.0
    vmax = -np.inf
    for r in range(r0, r1):
        for c in range(c0, c1):
            v = float(frame[r, c])
            if v > vmax:
                vmax = v
            if v > thr:
                w = v - thr
                s += w
                sx += w * c
                sy += w * r
    if s > 0:
        return s, sx / s, sy / s, vmax
    return s, np.nan, np.nan, vmax


# --------------------------------------------------------------------------------------------
# Algorithm B (projection window)
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, fastmath=_FM)
def profiles(frame):
    """Column profile (sum over rows, length nx) and row profile (sum over columns, length ny)."""
    ny, nx = frame.shape
    col = np.zeros(nx, np.float64)
    row = np.zeros(ny, np.float64)
    for r in range(ny):
        s = 0.0
        for c in range(nx):
            v = float(frame[r, c])
            s += v
            col[c] += v
        row[r] = s
    return col, row


@njit(cache=True, nogil=True)
def robust_level(p):
    """Median of a profile and 1.4826 x its median absolute deviation (numpy.median's values,
    without its Python-level overhead: two of them per profile, two profiles per frame)."""
    med = np.median(p)
    return med, 1.4826 * np.median(np.abs(p - med))


@njit(cache=True, nogil=True, fastmath=_FM)
def com_box(frame, r0, r1, c0, c1, bkg):
    """Centre of mass of (I - bkg) over frame[r0:r1, c0:c1]; returns (sum, x, y, max I)."""
    s = 0.0
    sx = 0.0
    sy = 0.0
    vmax = -np.inf
    for r in range(r0, r1):
        rs = 0.0
        for c in range(c0, c1):
            v = float(frame[r, c])
            if v > vmax:
                vmax = v
            w = v - bkg
            rs += w
            sx += w * c
        s += rs
        sy += rs * r
    if s != 0:
        return s, sx / s, sy / s, vmax
    return s, np.nan, np.nan, vmax
