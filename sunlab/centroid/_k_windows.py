"""Kernels of the paper's algorithms A (threshold + fixed window) and B (projection window).

Each kernel has its numpy reference beside it (``_<name>_numpy``, the same signature and the
same values to rounding), which runs under ``sunlab.set_options(kernels="numpy")``.

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import numpy as np

from .. import jit
from ._k_flags import _FM

__all__: list[str] = []


# --------------------------------------------------------------------------------------------
# Algorithm A (threshold + fixed window)
# --------------------------------------------------------------------------------------------
@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@ring_mean.reference
def _ring_mean_numpy(frame, r0, r1, c0, c1, w):
    """numpy reference of :func:`ring_mean`.

    Parameters
    ----------
    frame : ndarray, shape (ny, nx)
        The image (DN).
    r0, r1, c0, c1 : int
        The box frame[r0:r1, c0:c1].
    w : int
        Width of the border (px).

    Returns
    -------
    float
        Mean of the border's pixels (DN); NaN for an empty box.
    """
    box = np.asarray(frame[r0:r1, c0:c1], dtype=np.float64)
    edge = np.ones(box.shape, dtype=bool)
    edge[w:max(box.shape[0] - w, w), w:max(box.shape[1] - w, w)] = False
    return float(box[edge].mean()) if edge.any() else np.nan


@jit.kernel(cache=True, nogil=True)
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


@scan_first.reference
def _scan_first_numpy(frame, thr, half, need, r0, r1, c0, c1, er0, er1, ec0, ec1):
    """numpy reference of :func:`scan_first`: the neighbourhood counts of every pixel at once
    (a summed-area table of the pixels above ``thr``), then the first candidate in raster order.

    Parameters
    ----------
    frame : ndarray, shape (ny, nx)
        The image (DN).
    thr : float
        The threshold (DN).
    half : int
        Half-size of the square neighbourhood (px).
    need : int
        Pixels above ``thr`` the neighbourhood must hold.
    r0, r1, c0, c1 : int
        The scanned box.
    er0, er1, ec0, ec1 : int
        The excluded box.

    Returns
    -------
    tuple of int
        (row, col) of the first such pixel, or (-1, -1).
    """
    ny, nx = frame.shape
    above = np.asarray(frame) > thr
    sat = np.zeros((ny + 1, nx + 1), dtype=np.int64)
    sat[1:, 1:] = above.cumsum(0).cumsum(1)
    rr, cc = np.arange(ny)[:, None], np.arange(nx)[None, :]
    a0, a1 = np.maximum(rr - half, 0), np.minimum(rr + half + 1, ny)
    b0, b1 = np.maximum(cc - half, 0), np.minimum(cc + half + 1, nx)
    count = sat[a1, b1] - sat[a0, b1] - sat[a1, b0] + sat[a0, b0]
    ok = above & (count >= need)
    ok[er0:er1, ec0:ec1] = False
    box = ok[r0:r1, c0:c1]
    if not box.any():
        return -1, -1
    r, c = np.unravel_index(np.argmax(box), box.shape)
    return int(r) + r0, int(c) + c0


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@com_above.reference
def _com_above_numpy(frame, r0, r1, c0, c1, thr):
    """numpy reference of :func:`com_above`.

    Parameters
    ----------
    frame : ndarray, shape (ny, nx)
        The image (DN).
    r0, r1, c0, c1 : int
        The box frame[r0:r1, c0:c1].
    thr : float
        The threshold (DN).

    Returns
    -------
    tuple of float
        (sum of I - thr (DN), x, y (px; NaN when the sum is not positive), max I (DN)).
    """
    box = np.asarray(frame[r0:r1, c0:c1], dtype=np.float64)
    w = np.where(box > thr, box - thr, 0.0)
    s = float(w.sum())
    vmax = float(box.max()) if box.size else -np.inf
    if not s > 0:
        return s, np.nan, np.nan, vmax
    x = float((w.sum(0) * np.arange(c0, c1)).sum()) / s
    y = float((w.sum(1) * np.arange(r0, r1)).sum()) / s
    return s, x, y, vmax


# --------------------------------------------------------------------------------------------
# Algorithm B (projection window)
# --------------------------------------------------------------------------------------------
@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@profiles.reference
def _profiles_numpy(frame):
    """numpy reference of :func:`profiles`.

    Parameters
    ----------
    frame : ndarray, shape (ny, nx)
        The image (DN).

    Returns
    -------
    tuple of ndarray of float64
        The column profile (nx,) and the row profile (ny,) (DN).
    """
    return frame.sum(axis=0, dtype=np.float64), frame.sum(axis=1, dtype=np.float64)


@jit.kernel(cache=True, nogil=True)
def robust_level(p):
    """Median of a profile and 1.4826 x its median absolute deviation (numpy.median's values,
    without its Python-level overhead: two of them per profile, two profiles per frame)."""
    med = np.median(p)
    return med, 1.4826 * np.median(np.abs(p - med))


@robust_level.reference
def _robust_level_numpy(p):
    """numpy reference of :func:`robust_level`.

    Parameters
    ----------
    p : ndarray of float64
        A profile (DN).

    Returns
    -------
    tuple of float
        The median and 1.4826 x the median absolute deviation (DN).
    """
    med = np.median(p)
    return float(med), 1.4826 * float(np.median(np.abs(p - med)))


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@com_box.reference
def _com_box_numpy(frame, r0, r1, c0, c1, bkg):
    """numpy reference of :func:`com_box`.

    Parameters
    ----------
    frame : ndarray, shape (ny, nx)
        The image (DN).
    r0, r1, c0, c1 : int
        The box frame[r0:r1, c0:c1].
    bkg : float
        The background subtracted (DN).

    Returns
    -------
    tuple of float
        (sum of I - bkg (DN), x, y (px; NaN when the sum is 0), max I (DN)).
    """
    box = np.asarray(frame[r0:r1, c0:c1], dtype=np.float64)
    w = box - bkg
    s = float(w.sum())
    vmax = float(box.max()) if box.size else -np.inf
    if s == 0:
        return s, np.nan, np.nan, vmax
    x = float((w.sum(0) * np.arange(c0, c1)).sum()) / s
    y = float((w.sum(1) * np.arange(r0, r1)).sum()) / s
    return s, x, y, vmax
