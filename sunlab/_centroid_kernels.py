"""Numba kernels behind :mod:`sunlab.centroid` (private).

Every kernel is compiled with ``cache=True`` (compiled once per dtype, kept on disk) and
``nogil=True`` so that Dask's threaded scheduler runs frames in parallel. Frames are 2-D arrays
indexed ``frame[row, column]``; coordinates returned are (x = column, y = row) with the centre of
the first pixel at 0. Sums of integer frames are exact in float64, so the ``reassoc`` fast-math
flag (which lets LLVM vectorise the reductions) changes no result for DN frames; ``nnan`` is left
off because the callers test for NaN first.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

__all__: list[str] = []

_FM = {"reassoc", "contract", "nsz", "arcp"}

#: Inner loops over a row run on unsigned indices, ``for c in range(_U(c0), _U(c1))`` with
#: ``0 <= c0``: numba then drops its negative-index wrap-around from every access, and LLVM
#: vectorises the loop (measured 1.3-2.6x on the aperture sums of 100-spot frames).
_U = np.uint64


@intrinsic
def _prefetch(typingctx, arr, i):
    """Ask the CPU to fetch the cache line of ``arr[i]`` (1-D array) ahead of use (LLVM's
    prefetch intrinsic: no fault, no wait, no effect on results)."""
    if not isinstance(arr, types.Array) or arr.ndim != 1 or not isinstance(i, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        aryty = signature.args[0]
        ary = context.make_array(aryty)(context, builder, args[0])
        idx = context.cast(builder, args[1], signature.args[1], types.intp)
        ptr = cgutils.get_item_pointer(context, builder, aryty, ary, [idx], wraparound=False)
        i8p = ir.IntType(8).as_pointer()
        i32 = ir.IntType(32)
        fn = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [i8p, i32, i32, i32]),
            "llvm.prefetch.p0")
        # read, highest locality, data cache
        builder.call(fn, [builder.bitcast(ptr, i8p), ir.Constant(i32, 0), ir.Constant(i32, 3),
                          ir.Constant(i32, 1)])
        return context.get_dummy_value()

    return types.void(arr, i), codegen


@njit(cache=True, nogil=True, inline="always")
def _prefetch_row(line, c0, c1):
    """Prefetch line[c0:c1], one request per 64-byte cache line."""
    c1 = min(c1, line.size)
    for c in range(c0, c1, max(64 // line.itemsize, 1)):
        _prefetch(line, c)


@njit(cache=True, nogil=True)
def prefetch_box(frame, xc, yc, r, part=0, nparts=1):
    """Prefetch the pixels within ``r`` px (box) of (xc, yc), one request per 64-byte line
    (rows of part ``part`` of ``nparts``): issued for the next spot in parts while the current
    one is measured, the memory latency of a frame fresh from the camera or the disk overlaps
    the arithmetic without more requests in flight than the core can track."""
    ny, nx = frame.shape
    if not (math.isfinite(xc) and math.isfinite(yc)):
        return
    b0 = max(int(yc - r), 0)
    b1 = min(int(yc + r) + 1, ny)
    r0 = b0 + (b1 - b0) * part // nparts
    r1 = b0 + (b1 - b0) * (part + 1) // nparts
    c0 = max(int(xc - r), 0)
    c1 = min(int(xc + r) + 1, nx)
    if c1 <= c0:
        return
    for row in range(r0, r1):
        line = frame[row]
        _prefetch_row(line, c0, c1)
        _prefetch(line, c1 - 1)


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


@njit(cache=True, nogil=True)
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
        if i + 1 < gy:
            _prefetch_row(frame[off + (i + 1) * stride], off, stride * gx)
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


@njit(cache=True, nogil=True)
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
        if i + 1 < gy:  # the next sampled row's lines, while this one is compared
            _prefetch_row(frame[off + (i + 1) * stride], off, stride * gx)
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


# --------------------------------------------------------------------------------------------
# Tight, background-subtracted circular window
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True, inline="always")
def _span(xc, dy2, q2, nx):
    """Columns [c0, c1) whose centres satisfy (c - xc)^2 + dy2 <= q2, clipped to [0, nx)."""
    h2 = q2 - dy2
    if h2 < 0:
        return 0, 0
    h = math.sqrt(h2)
    c0 = max(int(math.ceil(xc - h)), 0)
    c1 = min(int(math.floor(xc + h)) + 1, nx)
    return c0, c1


@njit(cache=True, nogil=True, fastmath=_FM)
def _ring_sums(frame, xc, yc, r_in, r_out):
    """Sums of v and v^2 and the count of the pixels whose centres lie in the annulus
    r_in < d <= r_out around (xc, yc)."""
    ny, nx = frame.shape
    r0 = max(int(math.ceil(yc - r_out)), 0)
    r1 = min(int(math.floor(yc + r_out)) + 1, ny)
    a2 = r_in * r_in
    b2 = r_out * r_out
    s = 0.0
    s2 = 0.0
    n = 0
    for r in range(r0, r1):
        dy2 = (r - yc) ** 2
        o0, o1 = _span(xc, dy2, b2, nx)
        i0, i1 = _span(xc, dy2, a2, nx)
        if i1 <= i0:
            i0 = o1
            i1 = o1
        row = frame[r]
        for c in range(_U(o0), _U(i0)):
            v = float(row[c])
            s += v
            s2 += v * v
        for c in range(_U(i1), _U(o1)):
            v = float(row[c])
            s += v
            s2 += v * v
        n += (i0 - o0) + (o1 - i1)
    return s, s2, n


@njit(cache=True, nogil=True, inline="always")
def _psum(a, b, k):
    """Sum of u**k for integers a <= u < b (k = 0..3), closed form."""
    fa = float(a)
    fb = float(b)
    if k == 0:
        return fb - fa
    if k == 1:
        return (fb * (fb - 1.0) - fa * (fa - 1.0)) * 0.5
    if k == 2:
        return ((fb - 1.0) * fb * (2.0 * fb - 1.0) - (fa - 1.0) * fa * (2.0 * fa - 1.0)) / 6.0
    tb = fb * (fb - 1.0) * 0.5
    ta = fa * (fa - 1.0) * 0.5
    return tb * tb - ta * ta


# Apertures work on row tables: for each row r0 <= r < r1 of a circular aperture, its span of
# columns [c0, c1) (spn[r - r0]) and the power sums sum v u^k, k = 0..3, u = c - cr over the
# span (tab[r - r0, k]), cr = round(xc). For DN frames every sum is an integer below 2^53, so
# the sums are exact in float64 whatever the order of the additions: a table moved to a nearby
# centre by adding and removing the columns at the ends of each row (:func:`shift_rows`)
# holds the same numbers as one summed afresh there, and the moments and centroids computed
# from it are the same to the last bit. (For float frames they agree to rounding.)
@njit(cache=True, nogil=True, fastmath=_FM, inline="always")
def _row_pows(row, a, b, cr, npow):
    """Sums of row[c] (c - cr)^k over a <= c < b (0 <= a), k < npow (2 or 4; higher sums 0)."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    u = float(a - cr)
    if npow > 2:
        for c in range(_U(a), _U(b)):
            v = float(row[c])
            vu = v * u
            s0 += v
            s1 += vu
            vuu = vu * u
            s2 += vuu
            s3 += vuu * u
            u += 1.0
    else:
        for c in range(_U(a), _U(b)):
            v = float(row[c])
            s0 += v
            s1 += v * u
            u += 1.0
    return s0, s1, s2, s3


@njit(cache=True, nogil=True, inline="always")
def _signed_pows(row, x, y, cr, npow):
    """:func:`_row_pows` over [x, y), or minus those over [y, x) when y < x."""
    if y >= x:
        return _row_pows(row, x, y, cr, npow)
    s0, s1, s2, s3 = _row_pows(row, y, x, cr, npow)
    return -s0, -s1, -s2, -s3


@njit(cache=True, nogil=True, inline="always")
def _aperture_spans(xc, yc, r_ap, ny, nx, spn):
    """Rows [r0, r1) of the aperture of radius ``r_ap`` about (xc, yc) and each row's span of
    columns into ``spn[r - r0]``, all before any row loop (which then starts without waiting on
    sqrt). Returns (r0, r1)."""
    r0 = max(int(math.ceil(yc - r_ap)), 0)
    r1 = min(int(math.floor(yc + r_ap)) + 1, ny)
    q2 = r_ap * r_ap
    for r in range(r0, r1):
        dy = r - yc
        spn[r - r0, 0], spn[r - r0, 1] = _span(xc, dy * dy, q2, nx)
    return r0, r1


@njit(cache=True, nogil=True, fastmath=_FM)
def aperture_rows(frame, xc, yc, r_ap, npow, tab, spn):
    """Row table of the aperture of radius ``r_ap`` about (xc, yc) (pixel centres within
    ``r_ap``; see the comment above): fills ``tab`` (rows, 4) and ``spn`` (rows, 2) and
    returns (r0, r1, cr). ``npow`` 2 sums the powers 0 and 1 only."""
    ny, nx = frame.shape
    r0, r1 = _aperture_spans(xc, yc, r_ap, ny, nx, spn)
    cr = int(math.floor(xc + 0.5))
    for r in range(r0, r1):
        i = r - r0
        c0 = spn[i, 0]
        c1 = spn[i, 1]
        if c1 <= c0:
            tab[i, 0] = tab[i, 1] = tab[i, 2] = tab[i, 3] = 0.0
            continue
        tab[i, 0], tab[i, 1], tab[i, 2], tab[i, 3] = _row_pows(frame[r], c0, c1, cr, npow)
    return r0, r1, cr


@njit(cache=True, nogil=True, fastmath=_FM)
def shift_rows(frame, tab, spn, r0, r1, cr, xc, yc, r_ap, npow, out, ospn):
    """The row table of the aperture of radius ``r_ap`` about (xc, yc) (into ``out``,
    ``ospn``) from that of a nearby aperture (``tab``, ``spn``, rows [r0, r1), centre column
    ``cr``): each row's sums plus those of the columns gained and minus those of the columns
    lost at its two ends, re-expanded about the new round(xc) (sum v (u + d)^k from the
    sums of v u^k); rows the old table lacks are summed afresh. Returns (r0, r1, cr) of the
    new table."""
    ny, nx = frame.shape
    n0, n1 = _aperture_spans(xc, yc, r_ap, ny, nx, ospn)
    nc = int(math.floor(xc + 0.5))
    d = float(cr - nc)  # c - nc = (c - cr) + d
    for r in range(n0, n1):
        i = r - n0
        c0 = ospn[i, 0]
        c1 = ospn[i, 1]
        if c1 <= c0:
            out[i, 0] = out[i, 1] = out[i, 2] = out[i, 3] = 0.0
            continue
        row = frame[r]
        t = r - r0
        if r0 <= r < r1 and spn[t, 1] > spn[t, 0]:
            a = spn[t, 0]
            b = spn[t, 1]
            e0, e1, e2, e3 = _signed_pows(row, c0, a, cr, npow)
            f0, f1, f2, f3 = _signed_pows(row, b, c1, cr, npow)
            s0 = tab[t, 0] + e0 + f0
            s1 = tab[t, 1] + e1 + f1
            s2 = tab[t, 2] + e2 + f2
            s3 = tab[t, 3] + e3 + f3
            out[i, 0] = s0
            out[i, 1] = s1 + d * s0
            if npow > 2:
                out[i, 2] = s2 + 2.0 * d * s1 + d * d * s0
                out[i, 3] = s3 + 3.0 * d * s2 + 3.0 * d * d * s1 + d * d * d * s0
            else:
                out[i, 2] = out[i, 3] = 0.0
        else:
            out[i, 0], out[i, 1], out[i, 2], out[i, 3] = _row_pows(row, c0, c1, nc, npow)
    return n0, n1, nc


@njit(cache=True, nogil=True, fastmath=_FM)
def rows_com(tab, spn, r0, r1, cr, yc, bkg):
    """Centre of mass of (I - bkg) from a row table: (sum, x, y)."""
    rr = int(math.floor(yc + 0.5))
    s = 0.0
    su = 0.0
    st = 0.0
    for r in range(r0, r1):
        i = r - r0
        c0 = spn[i, 0]
        c1 = spn[i, 1]
        if c1 <= c0:
            continue
        w0 = tab[i, 0] - bkg * (c1 - c0)
        w1 = tab[i, 1] - bkg * _psum(c0 - cr, c1 - cr, 1)
        s += w0
        su += w1
        st += w0 * (r - rr)
    if s > 0:
        return s, cr + su / s, rr + st / s
    return s, np.nan, np.nan


@njit(cache=True, nogil=True, fastmath=_FM)
def rows_moments(frame, tab, spn, r0, r1, cr, xc, yc, bkg, sat):
    """Moments of (I - bkg) from a row table (4 powers) of the aperture about (xc, yc).

    Returns an array: [sum, x, y, mxx, myy, mxy, m30, m21, m12, m03, max I, n_pixels,
    n_saturated (I >= sat)] with central moments about (x, y) in px^k.
    """
    rr = int(math.floor(yc + 0.5))
    # p[a, b] = sum of (I - bkg) u^a t^b, u = c - cr, t = r - rr (integers), a + b <= 3
    p00 = p10 = p20 = p30 = p01 = p11 = p21 = p02 = p12 = p03 = 0.0
    vmax = -np.inf
    npx = 0
    for r in range(r0, r1):
        i = r - r0
        c0 = spn[i, 0]
        c1 = spn[i, 1]
        if c1 <= c0:
            continue
        npx += c1 - c0
        row = frame[r]
        imax = row[c0]
        for c in range(_U(c0), _U(c1)):
            imax = max(imax, row[c])
        vmax = max(vmax, float(imax))
        ua = c0 - cr
        ub = c1 - cr
        w0 = tab[i, 0] - bkg * (ub - ua)
        w1 = tab[i, 1] - bkg * _psum(ua, ub, 1)
        w2 = tab[i, 2] - bkg * _psum(ua, ub, 2)
        w3 = tab[i, 3] - bkg * _psum(ua, ub, 3)
        t = float(r - rr)
        t2 = t * t
        p00 += w0
        p10 += w1
        p20 += w2
        p30 += w3
        p01 += w0 * t
        p11 += w1 * t
        p21 += w2 * t
        p02 += w0 * t2
        p12 += w1 * t2
        p03 += w0 * t2 * t
    nsat = 0
    if vmax >= sat:
        for r in range(r0, r1):
            i = r - r0
            for c in range(spn[i, 0], spn[i, 1]):
                if frame[r, c] >= sat:
                    nsat += 1
    out = np.full(13, np.nan)
    out[10] = vmax
    out[11] = npx
    out[12] = nsat
    s = p00
    out[0] = s
    if not s > 0:
        return out
    # Raw moments about (xc, yc): dx = u - f, dy = t - g.
    f = xc - cr
    g = yc - rr
    sx = p10 - f * p00
    sy = p01 - g * p00
    sxx = p20 - 2 * f * p10 + f * f * p00
    syy = p02 - 2 * g * p01 + g * g * p00
    sxy = p11 - f * p01 - g * p10 + f * g * p00
    sxxx = p30 - 3 * f * p20 + 3 * f * f * p10 - f * f * f * p00
    syyy = p03 - 3 * g * p02 + 3 * g * g * p01 - g * g * g * p00
    # sum w dx^2 dy = sum w (u-f)^2 (t-g)
    sxxy = (p21 - 2 * f * p11 + f * f * p01) - g * (p20 - 2 * f * p10 + f * f * p00)
    sxyy = (p12 - 2 * g * p11 + g * g * p10) - f * (p02 - 2 * g * p01 + g * g * p00)
    mx = sx / s
    my = sy / s
    out[1] = xc + mx
    out[2] = yc + my
    exx = sxx / s
    eyy = syy / s
    exy = sxy / s
    out[3] = exx - mx * mx
    out[4] = eyy - my * my
    out[5] = exy - mx * my
    out[6] = sxxx / s - 3 * mx * exx + 2 * mx**3
    out[7] = sxxy / s - 2 * mx * exy - my * exx + 2 * mx * mx * my
    out[8] = sxyy / s - 2 * my * exy - mx * eyy + 2 * mx * my * my
    out[9] = syyy / s - 3 * my * eyy + 2 * my**3
    return out


@njit(cache=True, nogil=True)
def aperture_com(frame, xc, yc, r_ap, bkg):
    """Centre of mass of (I - bkg) over the pixels whose centres lie within ``r_ap`` of
    (xc, yc). Returns (sum, x, y)."""
    n = 2 * int(math.ceil(r_ap)) + 3
    tab = np.empty((n, 4))
    spn = np.empty((n, 2), np.int64)
    r0, r1, cr = aperture_rows(frame, xc, yc, r_ap, 2, tab, spn)
    return rows_com(tab, spn, r0, r1, cr, yc, bkg)


@njit(cache=True, nogil=True)
def aperture_moments(frame, xc, yc, r_ap, bkg, sat):
    """Moments of (I - bkg) over the pixels whose centres lie within ``r_ap`` of (xc, yc)
    (see :func:`rows_moments`)."""
    n = 2 * int(math.ceil(r_ap)) + 3
    tab = np.empty((n, 4))
    spn = np.empty((n, 2), np.int64)
    r0, r1, cr = aperture_rows(frame, xc, yc, r_ap, 4, tab, spn)
    return rows_moments(frame, tab, spn, r0, r1, cr, xc, yc, bkg, sat)


#: Columns of the array returned by :func:`measure_spots`.
MEASURE_FIELDS = (
    "flux", "x", "y", "mxx", "myy", "mxy", "m30", "m21", "m12", "m03", "peak", "npix", "nsat",
    "background", "background_std", "r_ap",
)


@njit(cache=True, nogil=True, fastmath=_FM, inline="always")
def _band_sums(row, a, b, lo, hi):
    """Sums of v, v^2 and the count of the pixels of row[a:b] with lo <= v <= hi (0 <= a)."""
    s = 0.0
    s2 = 0.0
    k = 0.0
    for c in range(_U(a), _U(b)):
        v = float(row[c])
        m = 1.0 if (v >= lo and v <= hi) else 0.0
        vm = v * m
        s += vm
        s2 += vm * v
        k += m
    return s, s2, k


@njit(cache=True, nogil=True, fastmath=_FM)
def annulus_mean(frame, xc, yc, r_in, r_out, lo, hi):
    """Mean of the pixels of the annulus r_in < d <= r_out around (xc, yc) whose values lie in
    [lo, hi] (one pass; falls back to all annulus pixels when none does). Returns (mean, std, n).
    """
    ny, nx = frame.shape
    r0 = max(int(math.ceil(yc - r_out)), 0)
    r1 = min(int(math.floor(yc + r_out)) + 1, ny)
    a2 = r_in * r_in
    b2 = r_out * r_out
    s = 0.0
    s2 = 0.0
    k = 0.0
    n = 0
    sp = np.empty((max(r1 - r0, 0), 4), np.int64)
    for r in range(r0, r1):  # spans first: the row loops then start without waiting on sqrt
        dy2 = (r - yc) ** 2
        o0, o1 = _span(xc, dy2, b2, nx)
        i0, i1 = _span(xc, dy2, a2, nx)
        if i1 <= i0:
            i0 = o1
            i1 = o1
        sp[r - r0, 0] = o0
        sp[r - r0, 1] = i0
        sp[r - r0, 2] = i1
        sp[r - r0, 3] = o1
    for r in range(r0, r1):
        o0 = sp[r - r0, 0]
        i0 = sp[r - r0, 1]
        i1 = sp[r - r0, 2]
        o1 = sp[r - r0, 3]
        row = frame[r]
        x1, x2, x3 = _band_sums(row, o0, i0, lo, hi)
        y1, y2, y3 = _band_sums(row, i1, o1, lo, hi)
        s += x1 + y1
        s2 += x2 + y2
        k += x3 + y3
        n += (i0 - o0) + (o1 - i1)
    if k == 0:
        if n == 0:
            return np.nan, np.nan, 0
        s, s2, n = _ring_sums(frame, xc, yc, r_in, r_out)
        k = float(n)
    m = s / k
    return m, math.sqrt(max(s2 / k - m * m, 0.0)), int(k)


@njit(cache=True, nogil=True)
def measure_spots(frame, xs, ys, r0s, margin, annulus, lo, hi, n_iter, sat):
    """Tight-window measurement of spots started at (xs, ys) with first aperture radii ``r0s``.

    For each spot: the background is the mean of the pixels of a ring ``annulus`` px wide just
    outside the first aperture whose values lie in [lo, hi] (a band about the frame's background
    level, which rejects hot pixels and neighbouring spots); the centre of mass of
    (I - background) inside the circular aperture re-centres it ``n_iter - 1`` times; the moments
    in that aperture give the spot's equivalent uniform-disk radius sqrt(2 (mxx + myy)); the
    final centroid and flux are the centre of mass in an aperture of that radius plus ``margin``
    (if smaller than the first), centred on the previous estimate.
    Returns an (n, 16) array, columns MEASURE_FIELDS (moments from the first aperture).
    """
    n = xs.shape[0]
    out = np.full((n, 16), np.nan)
    nt = 3
    for k in range(n):
        nt = max(nt, 2 * int(math.ceil(r0s[k])) + 3)
    ta = np.empty((nt, 4))
    sa = np.empty((nt, 2), np.int64)
    tb = np.empty((nt, 4))
    sb = np.empty((nt, 2), np.int64)
    if n > 0:
        prefetch_box(frame, xs[0], ys[0], r0s[0] + 1.0 + annulus)
    for k in range(n):
        xc = xs[k]
        yc = ys[k]
        r_ap = r0s[k]
        # the next spot's pixels, a third before each of this spot's passes
        nxt = min(k + 1, n - 1)
        rn = r0s[nxt] + 1.0 + annulus
        if k + 1 < n:
            prefetch_box(frame, xs[nxt], ys[nxt], rn, 0, 3)
        bkg, bsd, nb = annulus_mean(frame, xc, yc, r_ap + 1.0, r_ap + 1.0 + annulus, lo, hi)
        if k + 1 < n:
            prefetch_box(frame, xs[nxt], ys[nxt], rn, 1, 3)
        if nb == 0:
            continue
        # One pass over the pixels of the first aperture; the re-centred apertures are its
        # row table moved (shift_rows), which touches only the columns at the rows' ends.
        r0, r1, cr = aperture_rows(frame, xc, yc, r_ap, 4, ta, sa)
        good = True
        for _ in range(n_iter - 1):
            s, x1, y1 = rows_com(ta, sa, r0, r1, cr, yc, bkg)
            if not (s > 0) or not (abs(x1 - xc) < r_ap and abs(y1 - yc) < r_ap):
                good = False
                break
            xc = x1
            yc = y1
            r0, r1, cr = shift_rows(frame, ta, sa, r0, r1, cr, xc, yc, r_ap, 4, tb, sb)
            ta, tb = tb, ta
            sa, sb = sb, sa
        if k + 1 < n:
            prefetch_box(frame, xs[nxt], ys[nxt], rn, 2, 3)
        if not good:
            continue
        m = rows_moments(frame, ta, sa, r0, r1, cr, xc, yc, bkg, sat)
        if not (m[0] > 0):
            continue
        rad = math.sqrt(max(2.0 * (m[3] + m[4]), 0.0))
        if rad > 0 and rad + margin < r_ap - 0.5:
            r_ap = rad + margin
            f0, f1, fc = shift_rows(frame, ta, sa, r0, r1, cr, m[1], m[2], r_ap, 2, tb, sb)
            s, x1, y1 = rows_com(tb, sb, f0, f1, fc, m[2], bkg)
            if s > 0:
                m[0] = s
                m[1] = x1
                m[2] = y1
        out[k, :13] = m
        out[k, 13] = bkg
        out[k, 14] = bsd
        out[k, 15] = r_ap
    return out


# --------------------------------------------------------------------------------------------
# Disk-model fit (Levenberg-Marquardt)
# --------------------------------------------------------------------------------------------
_SQRT2 = math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)


@njit(cache=True, nogil=True, fastmath=_FM)
def _disk_normal(frame, p, r0, r1, c0, c1, v0, vk, sat):
    """Normal equations of the weighted least-squares fit of the edge-blurred disk model

    m = b + A * erfc((d - R) / (sqrt(2) s)) / 2,  d = |(c, r) - (x, y)|,

    with weights 1 / (v0 + vk * max(m - b, 0)); pixels >= sat are left out.
    Returns (J^T W J, J^T W res, chi2)."""
    x, y, rad, amp, b, s = p[0], p[1], p[2], p[3], p[4], p[5]
    jtj = np.zeros((6, 6))
    jtr = np.zeros(6)
    g = np.empty(6)
    chi2 = 0.0
    inv = 1.0 / (_SQRT2 * s)
    for r in range(r0, r1):
        dy = r - y
        for c in range(c0, c1):
            v = float(frame[r, c])
            if v >= sat:
                continue
            dx = c - x
            d = math.sqrt(dx * dx + dy * dy)
            u = (d - rad) * inv
            e = 0.5 * math.erfc(u)
            phi = amp * _INV_SQRT2PI / s * math.exp(-u * u)
            res = v - (b + amp * e)
            wgt = 1.0 / (v0 + vk * max(amp * e, 0.0))
            dinv = 1.0 / d if d > 1e-9 else 0.0
            g[0] = phi * dx * dinv
            g[1] = phi * dy * dinv
            g[2] = phi
            g[3] = e
            g[4] = 1.0
            g[5] = phi * (d - rad) / s
            chi2 += wgt * res * res
            for i in range(6):
                gi = wgt * g[i]
                jtr[i] += gi * res
                for j in range(i + 1):
                    jtj[i, j] += gi * g[j]
    for i in range(6):
        for j in range(i + 1, 6):
            jtj[i, j] = jtj[j, i]
    return jtj, jtr, chi2


@njit(cache=True, nogil=True)
def fit_disk(frame, p0, half, max_iter, v0, vk, tol, sat):
    """Levenberg-Marquardt fit of the disk model of :func:`_disk_normal` on the square cutout of
    half-size ``half`` around the start (x, y). Returns (params, covariance, chi2, n_pixels,
    iterations, window r0, r1, c0, c1)."""
    ny, nx = frame.shape
    p = p0.copy()
    r0 = max(int(math.floor(p[1] - half)), 0)
    r1 = min(int(math.ceil(p[1] + half)) + 1, ny)
    c0 = max(int(math.floor(p[0] - half)), 0)
    c1 = min(int(math.ceil(p[0] + half)) + 1, nx)
    lam = 1e-3
    jtj, jtr, chi2 = _disk_normal(frame, p, r0, r1, c0, c1, v0, vk, sat)
    it = 0
    for _it in range(1, max_iter + 1):
        it = _it
        a = jtj.copy()
        for i in range(6):
            a[i, i] *= 1.0 + lam
        step = np.linalg.solve(a, jtr)
        q = p + step
        q[5] = max(q[5], 0.05)
        q[2] = max(q[2], 0.5)
        jtj2, jtr2, chi2_new = _disk_normal(frame, q, r0, r1, c0, c1, v0, vk, sat)
        if chi2_new <= chi2:
            p = q
            jtj, jtr = jtj2, jtr2
            small = abs(step[0]) < tol and abs(step[1]) < tol
            chi2 = chi2_new
            lam = max(lam * 0.1, 1e-7)
            if small:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    cov = np.full((6, 6), np.nan)
    if np.all(np.isfinite(jtj)) and abs(np.linalg.det(jtj)) > 0:
        cov = np.linalg.inv(jtj)
    return p, cov, chi2, (r1 - r0) * (c1 - c0), it, r0, r1, c0, c1


@njit(cache=True, nogil=True)
def disk_noise(frame, p, r0, r1, c0, c1, sat):
    """Noise model from the residuals of a disk fit: variance v0 on the background
    (model < b + 0.05 A) and v0 + vk A on the plateau (model > b + 0.95 A). Returns (v0, vk)."""
    x, y, rad, amp, b, s = p[0], p[1], p[2], p[3], p[4], p[5]
    inv = 1.0 / (_SQRT2 * s)
    sb = 0.0
    nb = 0
    sp = 0.0
    npl = 0
    for r in range(r0, r1):
        dy = r - y
        for c in range(c0, c1):
            v = float(frame[r, c])
            if v >= sat:
                continue
            dx = c - x
            e = 0.5 * math.erfc((math.sqrt(dx * dx + dy * dy) - rad) * inv)
            res = v - (b + amp * e)
            if e < 0.05:
                sb += res * res
                nb += 1
            elif e > 0.95:
                sp += res * res
                npl += 1
    if nb < 10:
        return np.nan, 0.0
    v0 = sb / nb
    vk = 0.0
    if npl >= 10 and amp > 0:
        vk = max((sp / npl - v0) / amp, 0.0)
    return v0, vk


@njit(cache=True, nogil=True, inline="always")
def _clipped_moments(frame, x, y, lo2, hi2, r0, r1, c0, c1, sat, centre, cut):
    """Count, mean and variance of the pixels with lo2 <= d^2 < hi2 about (x, y), leaving out
    those >= sat and those farther than ``cut`` from ``centre`` (no cut when cut <= 0)."""
    n = 0
    s1 = 0.0
    s2 = 0.0
    for r in range(r0, r1):
        dy = r - y
        for c in range(c0, c1):
            dx = c - x
            d2 = dx * dx + dy * dy
            if d2 < lo2 or d2 >= hi2:
                continue
            v = float(frame[r, c])
            if v >= sat or (cut > 0.0 and abs(v - centre) > cut):
                continue
            n += 1
            s1 += v
            s2 += v * v
    if n < 2:
        return n, np.nan, np.nan
    m = s1 / n
    return n, m, max(s2 / n - m * m, 0.0) * n / (n - 1)


@njit(cache=True, nogil=True)
def zone_noise(frame, x, y, d_in, d_out, r0, r1, c0, c1, sat):
    """Model-free noise model of a spot: mean and variance of the cutout's pixels farther than
    ``d_out`` from (x, y) (background: v0) and nearer than ``d_in`` (plateau: v0 + vk (mean -
    background)), each sigma-clipped at 5 sigma (two passes, for hot pixels). Unlike the
    residuals of a fit, these are unaffected by a mismatch of the fitted edge profile. Returns
    (v0, vk, n_background, n_plateau); v0 is NaN with fewer than 2 background pixels."""
    big = 1e300
    nb, mb, vb = _clipped_moments(frame, x, y, d_out * d_out, big, r0, r1, c0, c1, sat, 0.0, 0.0)
    for _ in range(2):
        if nb < 2:
            break
        nb, mb, vb = _clipped_moments(frame, x, y, d_out * d_out, big, r0, r1, c0, c1, sat, mb,
                                      5.0 * math.sqrt(vb) + 0.5)
    if nb < 2:
        return np.nan, 0.0, nb, 0
    lo = -1.0
    np_, mp, vp = _clipped_moments(frame, x, y, lo, d_in * d_in, r0, r1, c0, c1, sat, 0.0, 0.0)
    for _ in range(2):
        if np_ < 2:
            break
        np_, mp, vp = _clipped_moments(frame, x, y, lo, d_in * d_in, r0, r1, c0, c1, sat, mp,
                                       5.0 * math.sqrt(vp) + 0.5)
    vk = 0.0
    if np_ >= 2 and mp > mb:
        vk = max((vp - vb) / (mp - mb), 0.0)
    return vb, vk, nb, max(np_, 0)


@njit(cache=True, nogil=True, inline="always")
def _bspline4(t, nint):
    """Knot interval j, the 4 uniform cubic B-spline values at t (in knot steps, clipped to
    [0, nint]) and their derivatives d/dt (0 outside [0, nint])."""
    inside = 0.0 < t < nint
    t = min(max(t, 0.0), float(nint))
    j = min(int(t), nint - 1)
    u = t - j
    w = 1.0 - u
    u2 = u * u
    b0 = w * w * w / 6.0
    b1 = (3.0 * u2 * u - 6.0 * u2 + 4.0) / 6.0
    b2 = (-3.0 * u2 * u + 3.0 * u2 + 3.0 * u + 1.0) / 6.0
    b3 = u2 * u / 6.0
    if inside:
        g0 = -0.5 * w * w
        g1 = 1.5 * u2 - 2.0 * u
        g2 = -1.5 * u2 + u + 0.5
        g3 = 0.5 * u2
    else:
        g0 = g1 = g2 = g3 = 0.0
    return j, b0, b1, b2, b3, g0, g1, g2, g3


@njit(cache=True, nogil=True, fastmath=_FM)
def _profile_normal(frame, q, d_lo, h, nint, r0, r1, c0, c1, v0, vk, b, sat):
    """Normal equations of the weighted least-squares fit of the radial-spline spot model

    m = sum_k a_k B_k(clip(d, d_lo, d_hi)),  d = |(c, r) - (x, y)|,  q = (x, y, a_0 .. a_{K-1}),

    B_k the uniform cubic B-splines of knot step h on [d_lo, d_hi = d_lo + nint h]
    (K = nint + 3), so the model is flat (plateau, background) outside; weights
    1 / (v0 + vk * max(m - b, 0)); pixels >= sat are left out. Returns (J^T W J, J^T W res,
    chi2)."""
    x, y = q[0], q[1]
    npar = q.size
    jtj = np.zeros((npar, npar))
    jtr = np.zeros(npar)
    g = np.empty(6)
    idx = np.empty(6, np.int64)
    idx[0] = 0
    idx[1] = 1
    chi2 = 0.0
    inv_h = 1.0 / h
    for r in range(r0, r1):
        dy = r - y
        for c in range(c0, c1):
            v = float(frame[r, c])
            if v >= sat:
                continue
            dx = c - x
            d = math.sqrt(dx * dx + dy * dy)
            j, b0, b1, b2, b3, g0, g1, g2, g3 = _bspline4((d - d_lo) * inv_h, nint)
            a0 = q[2 + j]
            a1 = q[3 + j]
            a2 = q[4 + j]
            a3 = q[5 + j]
            m = a0 * b0 + a1 * b1 + a2 * b2 + a3 * b3
            slope = (a0 * g0 + a1 * g1 + a2 * g2 + a3 * g3) * inv_h
            slope = slope / d if d > 1e-9 else 0.0
            res = v - m
            wgt = 1.0 / (v0 + vk * max(m - b, 0.0))
            g[0] = -slope * dx
            g[1] = -slope * dy
            g[2] = b0
            g[3] = b1
            g[4] = b2
            g[5] = b3
            idx[2] = 2 + j
            idx[3] = 3 + j
            idx[4] = 4 + j
            idx[5] = 5 + j
            chi2 += wgt * res * res
            for i in range(6):
                gi = wgt * g[i]
                ii = idx[i]
                jtr[ii] += gi * res
                for k in range(i + 1):
                    jtj[ii, idx[k]] += gi * g[k]
    for i in range(npar):
        for k in range(i + 1, npar):
            jtj[i, k] = jtj[k, i]
    return jtj, jtr, chi2


@njit(cache=True, nogil=True)
def fit_profile(frame, q0, d_lo, h, nint, r0, r1, c0, c1, max_iter, v0, vk, b, tol, sat):
    """Levenberg-Marquardt fit of the radial-spline model of :func:`_profile_normal` on the
    pixel box [r0, r1) x [c0, c1). A basis that no pixel reaches (a saturated plateau) keeps its
    start (a small ridge). Returns (params, chi2, iterations)."""
    q = q0.copy()
    npar = q.size
    lam = 1e-3
    jtj, jtr, chi2 = _profile_normal(frame, q, d_lo, h, nint, r0, r1, c0, c1, v0, vk, b, sat)
    it = 0
    for _it in range(1, max_iter + 1):
        it = _it
        a = jtj.copy()
        ridge = 0.0
        for i in range(npar):
            ridge = max(ridge, a[i, i])
        ridge = 1e-12 * ridge + 1e-300
        for i in range(npar):
            a[i, i] = a[i, i] * (1.0 + lam) + ridge
        step = np.linalg.solve(a, jtr)
        p = q + step
        jtj2, jtr2, chi2_new = _profile_normal(frame, p, d_lo, h, nint, r0, r1, c0, c1, v0, vk,
                                               b, sat)
        if chi2_new <= chi2:
            q = p
            jtj, jtr = jtj2, jtr2
            small = abs(step[0]) < tol and abs(step[1]) < tol
            chi2 = chi2_new
            lam = max(lam * 0.1, 1e-7)
            if small:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return q, chi2, it


@njit(cache=True, nogil=True)
def profile_noise(frame, q, d_lo, h, nint, r0, r1, c0, c1, b, sat):
    """Noise model ``var = v0 + vk max(m - b, 0)`` regressed on the squared residuals of the
    radial-spline fit ``q`` of :func:`fit_profile` (ordinary least squares of res^2 on the model
    level; a second pass leaves out residuals beyond 5 sigma of the first, e.g. hot pixels).
    Model-free where the spot has no plateau, unlike a zone estimate. Returns (v0, vk, n); v0
    NaN with fewer than 20 pixels."""
    x, y = q[0], q[1]
    inv_h = 1.0 / h
    v0 = np.nan
    vk = 0.0
    n = 0
    for pas in range(2):
        n = 0
        s1 = 0.0
        s2 = 0.0
        t1 = 0.0
        st = 0.0
        for r in range(r0, r1):
            dy = r - y
            for c in range(c0, c1):
                v = float(frame[r, c])
                if v >= sat:
                    continue
                dx = c - x
                d = math.sqrt(dx * dx + dy * dy)
                j, b0, b1, b2, b3, _, _, _, _ = _bspline4((d - d_lo) * inv_h, nint)
                m = q[2 + j] * b0 + q[3 + j] * b1 + q[4 + j] * b2 + q[5 + j] * b3
                lev = max(m - b, 0.0)
                res2 = (v - m) * (v - m)
                if pas == 1 and res2 > 25.0 * (v0 + vk * lev):
                    continue
                n += 1
                s1 += lev
                s2 += lev * lev
                t1 += res2
                st += lev * res2
        if n < 20:
            return np.nan, 0.0, n
        det = n * s2 - s1 * s1
        if det > 1e-12 * n * s2 and det > 0.0:
            vk = max((n * st - s1 * t1) / det, 0.0)
        else:
            vk = 0.0
        v0 = max((t1 - vk * s1) / n, 1.0 / 12.0)
    return v0, vk, n


@njit(cache=True, nogil=True)
def profile_flux(q, d_lo, h, nint, n_sub):
    """Integral over the plane of the radial-spline model of :func:`_profile_normal` above its
    outer (background) level: 2 pi int_0^d_hi (m(d) - m(d_hi)) d dd, midpoint rule with n_sub
    steps per knot step (the plateau inside d_lo exactly)."""
    k = q.size - 2
    bg = (q[1 + k - 2] + 4.0 * q[1 + k - 1] + q[1 + k]) / 6.0
    top = (q[2] + 4.0 * q[3] + q[4]) / 6.0
    total = math.pi * max(d_lo, 0.0) ** 2 * (top - bg)
    n = nint * n_sub
    step = h / n_sub
    for i in range(n):
        d = d_lo + (i + 0.5) * step
        j, b0, b1, b2, b3, _, _, _, _ = _bspline4((d - d_lo) / h, nint)
        m = q[2 + j] * b0 + q[3 + j] * b1 + q[4 + j] * b2 + q[5 + j] * b3
        total += 2.0 * math.pi * d * step * (m - bg)
    return total


# --------------------------------------------------------------------------------------------
# Lattice of the multi-hole mask
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def neighbour_vectors(q, pitch, k):
    """Vectors from each point of ``q`` (m, 2) to those of its ``k`` nearest points (itself
    included) that lie between 0.7 and 1.3 ``pitch`` away. Returns an (n_vectors, 2) array.

    Only points less than 1.3 pitch away can be kept, and all points nearer than a kept one
    are nearer than 1.3 pitch too, so the search runs over the 3 x 3 cells of 1.3 pitch
    around each point, ranking candidates by (distance, index) as a scan of all pairs in
    index order would: the same vectors in the same order, in O(m) instead of O(m^2).
    """
    m = q.shape[0]
    kk = min(k, m)
    out = np.empty((m * kk, 2))
    nv = 0
    if m == 0:
        return out
    lo = 0.7 * pitch
    hi = 1.3 * pitch
    x0 = q[0, 0]
    y0 = q[0, 1]
    x1 = x0
    y1 = y0
    for i in range(m):
        x0 = min(x0, q[i, 0])
        x1 = max(x1, q[i, 0])
        y0 = min(y0, q[i, 1])
        y1 = max(y1, q[i, 1])
    ncx = min(int((x1 - x0) / hi), m) + 1
    ncy = min(int((y1 - y0) / hi), m) + 1
    cell = np.empty(m, np.int64)
    start = np.zeros(ncx * ncy + 1, np.int64)
    for i in range(m):
        c = min(int((q[i, 1] - y0) / hi), ncy - 1) * ncx + min(int((q[i, 0] - x0) / hi), ncx - 1)
        cell[i] = c
        start[c + 1] += 1
    for c in range(ncx * ncy):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, np.int64)
    for i in range(m):  # counting sort: each cell's points in index order
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    bd = np.empty(kk)  # squared distances (ordering only)
    bi = np.empty(kk, np.int64)
    for i in range(m):
        cy, cx = divmod(cell[i], ncx)
        nb = 0
        for yy in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for xx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                c = yy * ncx + xx
                for t in range(start[c], start[c + 1]):
                    j = order[t]
                    dx = q[j, 0] - q[i, 0]
                    dy = q[j, 1] - q[i, 1]
                    d = dx * dx + dy * dy
                    # the k smallest in (distance, index) order, which is what a scan in
                    # index order keeps
                    if nb < kk:
                        pos = nb
                        nb += 1
                    elif d < bd[kk - 1] or (d == bd[kk - 1] and j < bi[kk - 1]):
                        pos = kk - 1
                    else:
                        continue
                    while pos > 0 and (bd[pos - 1] > d or (bd[pos - 1] == d and bi[pos - 1] > j)):
                        bd[pos] = bd[pos - 1]
                        bi[pos] = bi[pos - 1]
                        pos -= 1
                    bd[pos] = d
                    bi[pos] = j
        for t in range(nb):
            if lo < math.hypot(q[bi[t], 0] - q[i, 0], q[bi[t], 1] - q[i, 1]) < hi:
                out[nv, 0] = q[bi[t], 0] - q[i, 0]
                out[nv, 1] = q[bi[t], 1] - q[i, 1]
                nv += 1
    return out[:nv]


@njit(cache=True, nogil=True)
def _lattice_coords(p, origin, basis):
    """Lattice coordinates (u, v) of points p: solve basis @ (u, v) = p - origin."""
    a, b, c, d = basis[0, 0], basis[0, 1], basis[1, 0], basis[1, 1]
    det = a * d - b * c
    n = p.shape[0]
    uv = np.empty((n, 2))
    for k in range(n):
        x = p[k, 0] - origin[0]
        y = p[k, 1] - origin[1]
        uv[k, 0] = (d * x - b * y) / det
        uv[k, 1] = (a * y - c * x) / det
    return uv


@njit(cache=True, nogil=True)
def _affine_fit(uv, q, keep):
    """Least-squares affine map from the rounded lattice coordinates ``rint(uv)`` (j, i) to
    the points ``q`` (x, y) over the rows marked ``keep``: q = origin + basis @ (j, i).
    Normal equations about the means of (j, i), whose 2 x 2 matrix is that of integer grid
    indices (well conditioned for any two independent directions); returns (origin (2,),
    basis (2, 2), whether the kept nodes span the plane)."""
    n = 0
    mj = 0.0
    mi = 0.0
    mx = 0.0
    my = 0.0
    for k in range(q.shape[0]):
        if keep[k]:
            n += 1
            mj += np.rint(uv[k, 0])
            mi += np.rint(uv[k, 1])
            mx += q[k, 0]
            my += q[k, 1]
    mj /= n
    mi /= n
    mx /= n
    my /= n
    sjj = sji = sii = sjx = six = sjy = siy = 0.0
    for k in range(q.shape[0]):
        if keep[k]:
            dj = np.rint(uv[k, 0]) - mj
            di = np.rint(uv[k, 1]) - mi
            dx = q[k, 0] - mx
            dy = q[k, 1] - my
            sjj += dj * dj
            sji += dj * di
            sii += di * di
            sjx += dj * dx
            six += di * dx
            sjy += dj * dy
            siy += di * dy
    det = sjj * sii - sji * sji
    basis = np.full((2, 2), np.nan)
    origin = np.full(2, np.nan)
    if not det > 1e-9 * sjj * sii:  # all kept nodes on one line of the grid
        return origin, basis, False
    basis[0, 0] = (sii * sjx - sji * six) / det
    basis[0, 1] = (sjj * six - sji * sjx) / det
    basis[1, 0] = (sii * sjy - sji * siy) / det
    basis[1, 1] = (sjj * siy - sji * sjy) / det
    origin[0] = mx - basis[0, 0] * mj - basis[0, 1] * mi
    origin[1] = my - basis[1, 0] * mj - basis[1, 1] * mi
    return origin, basis, True


@njit(cache=True, nogil=True)
def fit_lattice(p, good, pitch, max_residual):
    """Affine lattice through the spots ``p`` (n, 2) marked ``good`` (see
    :func:`sunlab.centroid.locate_spots`, step 3). Returns (ij (n, 2) int, origin (2,),
    basis (2, 2): columns the steps along j and i, residual (n,) px); ``ok`` False when no
    spot is good."""
    n = p.shape[0]
    m = 0
    for k in range(n):
        if good[k]:
            m += 1
    q = np.empty((m, 2))
    t = 0
    for k in range(n):
        if good[k]:
            q[t, 0] = p[k, 0]
            q[t, 1] = p[k, 1]
            t += 1
    if m == 0:
        return np.zeros((n, 2), np.int64), np.full(2, np.nan), np.full((2, 2), np.nan), \
            np.full(n, np.nan), False
    ex0, ex1, ey0, ey1, step = 1.0, 0.0, 0.0, 1.0, pitch
    if m >= 2:
        v = neighbour_vectors(q, pitch, 5)
        nv = v.shape[0]
        if nv > 0:
            sc = 0.0
            ss = 0.0
            for k in range(nv):  # cos and sin of 4 theta: (x + i y)^4 / |x + i y|^4
                x2 = v[k, 0] * v[k, 0]
                y2 = v[k, 1] * v[k, 1]
                r4 = (x2 + y2) * (x2 + y2)
                sc += ((x2 - y2) * (x2 - y2) - 4.0 * x2 * y2) / r4
                ss += 4.0 * v[k, 0] * v[k, 1] * (x2 - y2) / r4
            phi = math.atan2(ss / nv, sc / nv) / 4.0
            ex0, ex1 = math.cos(phi), math.sin(phi)
            ey0, ey1 = -math.sin(phi), math.cos(phi)
            proj = np.empty(nv)
            for k in range(nv):
                proj[k] = max(abs(v[k, 0] * ex0 + v[k, 1] * ex1),
                              abs(v[k, 0] * ey0 + v[k, 1] * ey1))
            step = np.median(proj)
    mx = np.median(q[:, 0])
    my = np.median(q[:, 1])
    best = 0
    bd = np.inf
    for k in range(m):
        d = math.hypot(q[k, 0] - mx, q[k, 1] - my)
        if d < bd:
            bd = d
            best = k
    origin = q[best].copy()
    basis = np.empty((2, 2))
    basis[0, 0] = ex0 * step
    basis[1, 0] = ex1 * step
    basis[0, 1] = ey0 * step
    basis[1, 1] = ey1 * step
    for _ in range(2):
        uv = _lattice_coords(q, origin, basis)
        keep = np.zeros(m, np.bool_)
        nk = 0
        j_lo = i_lo = 1 << 60
        j_hi = i_hi = -(1 << 60)
        for k in range(m):
            fj = np.rint(uv[k, 0])
            fi = np.rint(uv[k, 1])
            du = uv[k, 0] - fj
            dv = uv[k, 1] - fi
            rx = basis[0, 0] * du + basis[0, 1] * dv
            ry = basis[1, 0] * du + basis[1, 1] * dv
            if math.hypot(rx, ry) < max_residual * step:
                keep[k] = True
                nk += 1
                j_lo = min(j_lo, int(fj))
                j_hi = max(j_hi, int(fj))
                i_lo = min(i_lo, int(fi))
                i_hi = max(i_hi, int(fi))
        if nk >= 3 and j_hi > j_lo and i_hi > i_lo:
            o, b, ok = _affine_fit(uv, q, keep)
            if not ok:
                break
            origin, basis = o, b
        else:
            break
    uv = _lattice_coords(p, origin, basis)
    ij = np.empty((n, 2), np.int64)
    resid = np.empty(n)
    for k in range(n):
        fj = np.rint(uv[k, 0])
        fi = np.rint(uv[k, 1])
        ij[k, 0] = int(fj)
        ij[k, 1] = int(fi)
        du = uv[k, 0] - fj
        dv = uv[k, 1] - fi
        resid[k] = math.hypot(basis[0, 0] * du + basis[0, 1] * dv,
                              basis[1, 0] * du + basis[1, 1] * dv)
    return ij, origin, basis, resid, True


@njit(cache=True, nogil=True)
def spot_table(m, nx, ny, ok, saturated, clipped):
    """Windows and status of measured spots (rows of :func:`measure_spots`, flux > 0).

    Returns (window (4, n) int32: x0, x1, y0, y1 of the circular aperture's bounding box,
    status (n,) int8: ``clipped`` when the aperture crosses the frame edge, else ``saturated``
    when a pixel reached full scale, else ``ok``)."""
    n = m.shape[0]
    win = np.empty((4, n), np.int32)
    st = np.empty(n, np.int8)
    for k in range(n):
        x = m[k, 1]
        y = m[k, 2]
        r = m[k, 15]
        win[0, k] = max(math.ceil(x - r), 0)
        win[1, k] = min(math.floor(x + r) + 1, nx)
        win[2, k] = max(math.ceil(y - r), 0)
        win[3, k] = min(math.floor(y + r) + 1, ny)
        if x - r < 0 or y - r < 0 or x + r >= nx - 1 or y + r >= ny - 1:
            st[k] = clipped
        elif m[k, 12] > 0:
            st[k] = saturated
        else:
            st[k] = ok
    return win, st


#: Columns of the array returned by :func:`spot_metrics` (the order of SPOT_METRICS).
METRIC_FIELDS = ("peak", "background", "mxx", "myy", "mxy", "radius", "ellipticity",
                 "asymmetry", "lattice_residual")


@njit(cache=True, nogil=True, error_model="numpy")
def spot_metrics(m, resid):
    """Quality metrics of measured spots (rows of :func:`measure_spots`) and their lattice
    residuals: an (n, 9) array, columns METRIC_FIELDS (NaN where undefined)."""
    n = m.shape[0]
    out = np.empty((n, 9))
    for k in range(n):
        mxx = m[k, 3]
        myy = m[k, 4]
        mxy = m[k, 5]
        tr = mxx + myy
        disc = math.sqrt(max((mxx - myy) ** 2 / 4 + mxy * mxy, 0.0))
        out[k, 0] = m[k, 10]
        out[k, 1] = m[k, 13]
        out[k, 2] = mxx
        out[k, 3] = myy
        out[k, 4] = mxy
        out[k, 5] = math.sqrt(max(2 * tr, 0.0))
        out[k, 6] = 2 * disc / tr
        out[k, 7] = math.hypot(m[k, 6] + m[k, 8], m[k, 7] + m[k, 9]) / tr**1.5
        out[k, 8] = resid[k]
    return out


@njit(cache=True, nogil=True)
def assign_holes(hole, resid, n_holes):
    """Nearest spot of each hole: ``hole`` (n,) the hole of each spot (-1: none), ``resid``
    its distance from the node. Returns (spot of each hole or -1, duplicate flag per hole:
    more than one spot claims it)."""
    win = np.full(n_holes, -1, np.int64)
    dup = np.zeros(n_holes, np.bool_)
    order = np.argsort(resid)
    for t in range(order.size):
        k = order[t]
        h = hole[k]
        if h < 0:
            continue
        if win[h] < 0:
            win[h] = k
        else:
            dup[h] = True
    return win, dup


# --------------------------------------------------------------------------------------------
# locate_spots (method "tight") in two compiled calls
# --------------------------------------------------------------------------------------------
@njit(cache=True, nogil=True)
def tight_spots(frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat,
                pitch, max_residual, ok, saturated, clipped):
    """Steps 1-3 of :func:`sunlab.centroid.locate_spots` with the tight window: detection,
    measurement (:func:`measure_spots`, spots with flux > 0), windows and status
    (:func:`spot_table`), the spots good for the lattice and the lattice fit
    (:func:`fit_lattice`). Returns (n_groups detected, sample maximum, m (n, 16), window (4, n),
    status (n,), good (n,), ij (n, 2), origin (2,), basis (2, 2), residual (n,), on_node (n,))."""
    ny, nx = frame.shape
    med, sig, smax = sample_stats(frame, max(2 * stride, 1))
    thr = med + max(nsigma * sig, min_contrast)
    cnt, _flux, cx, cy, _bb, _pk = coarse_blobs(frame, stride, thr, med)
    nd = 0
    for k in range(cnt.size):
        if cnt[k] >= min_samples:
            nd += 1
    xs = np.empty(nd)
    ys = np.empty(nd)
    r0s = np.empty(nd)
    t = 0
    for k in range(cnt.size):
        if cnt[k] >= min_samples:
            xs[t] = cx[k]
            ys[t] = cy[k]
            r0s[t] = math.sqrt(cnt[k] * float(stride) ** 2 / np.pi) + stride / 3.0 + margin
            t += 1
    half = max(10.0 * sig, 20.0)
    mall = measure_spots(frame, xs, ys, r0s, margin, annulus, med - half, med + half, n_iter,
                         sat)
    n = 0
    for k in range(nd):
        if mall[k, 0] > 0:
            n += 1
    m = np.empty((n, 16))
    t = 0
    for k in range(nd):
        if mall[k, 0] > 0:
            m[t] = mall[k]
            t += 1
    win, st = spot_table(m, nx, ny, ok, saturated, clipped)
    p = np.empty((n, 2))
    good = np.zeros(n, np.bool_)
    ij = np.zeros((n, 2), np.int64)
    origin = np.full(2, np.nan)
    basis = np.full((2, 2), np.nan)
    resid = np.full(n, np.nan)
    on_node = np.zeros(n, np.bool_)
    if n == 0:
        return nd, smax, m, win, st, good, ij, origin, basis, resid, on_node
    for k in range(n):
        p[k, 0] = m[k, 1]
        p[k, 1] = m[k, 2]
    med_flux = np.median(m[:, 0])
    ng = 0
    for k in range(n):
        good[k] = st[k] == ok and m[k, 0] > 0.3 * med_flux
        ng += good[k]
    if ng == 0:
        good[:] = True
    ij, origin, basis, resid, fitted = fit_lattice(p, good, pitch, max_residual)
    lim = max_residual * math.sqrt(abs(np.linalg.det(basis)))
    for k in range(n):
        on_node[k] = resid[k] < lim
    return nd, smax, m, win, st, good, ij, origin, basis, resid, on_node


@njit(cache=True, nogil=True)
def fill_holes(m, win, st, ij, dj, di, on_node, resid, lut, n_holes, x, y, flux, window, status,
               metrics, ambiguous):
    """Step 4 of :func:`sunlab.centroid.locate_spots` once the grid offset (dj, di) is known:
    hole of each spot (``lut[i, j]``, -1 none), the nearer spot of each hole
    (:func:`assign_holes`) written into the per-hole outputs (x, y, flux, window (4, n_holes),
    status, metrics (9, n_holes), columns METRIC_FIELDS). Returns whether each spot was
    assigned."""
    rows, cols = lut.shape
    n = m.shape[0]
    hole = np.full(n, -1, np.int64)
    for k in range(n):
        jj = ij[k, 0] + dj
        ii = ij[k, 1] + di
        if on_node[k] and 0 <= jj < cols and 0 <= ii < rows:
            hole[k] = lut[ii, jj]
    spot, dup = assign_holes(hole, resid, n_holes)
    assigned = np.zeros(n, np.bool_)
    one = np.empty((1, 16))
    rs = np.empty(1)
    for h in range(n_holes):
        k = spot[h]
        if k < 0:
            continue
        assigned[k] = True
        x[h] = m[k, 1]
        y[h] = m[k, 2]
        flux[h] = m[k, 0]
        for q in range(4):
            window[q, h] = win[q, k]
        status[h] = st[k]
        one[0] = m[k]
        rs[0] = resid[k]
        met = spot_metrics(one, rs)
        for q in range(9):
            metrics[q, h] = met[0, q]
    for h in range(n_holes):
        if dup[h]:
            status[h] = ambiguous
    return assigned



@njit(cache=True, nogil=True)
def grid_offset(ij, pts, ref, lut, exp, has_exp):
    """Step 4a of :func:`sunlab.centroid.locate_spots`: the offset (dj, di) that puts the
    lattice indices ``ij`` (n, 2) of the reference spots (``ref``) on the mask's grid (``lut``,
    (rows, cols)). Of the offsets that keep them all inside the grid, the first (dj outer, di
    inner) that minimises, when ``has_exp``, the mean distance of the reference spots at
    ``pts`` (n, 2) from the ``exp``ected positions of their holes ((n_holes, 2), NaN unknown),
    else the distance of their mean index from the grid's centre."""
    rows, cols = lut.shape
    n = ij.shape[0]
    jmin = imin = 1 << 60
    jmax = imax = -(1 << 60)
    nref = 0
    sj = 0
    si = 0
    for k in range(n):
        if ref[k]:
            jmin = min(jmin, ij[k, 0])
            jmax = max(jmax, ij[k, 0])
            imin = min(imin, ij[k, 1])
            imax = max(imax, ij[k, 1])
            sj += ij[k, 0]
            si += ij[k, 1]
            nref += 1
    if jmax - jmin < cols:
        dj0, dj1 = -jmin, cols - jmax
    else:
        dj0, dj1 = -jmin, -jmin + 1
    if imax - imin < rows:
        di0, di1 = -imin, rows - imax
    else:
        di0, di1 = -imin, -imin + 1
    if (dj1 - dj0) * (di1 - di0) == 1:
        return dj0, di0
    mj = sj / nref
    mi = si / nref
    cj = (cols - 1) / 2
    ci = (rows - 1) / 2
    best = np.inf
    bj = dj0
    bi = di0
    for dj in range(dj0, dj1):
        for di in range(di0, di1):
            if has_exp:
                tot = 0.0
                cnt = 0
                for k in range(n):
                    if not ref[k]:
                        continue
                    h = lut[min(max(ij[k, 1] + di, 0), rows - 1),
                            min(max(ij[k, 0] + dj, 0), cols - 1)]
                    if h >= 0 and math.isfinite(exp[h, 0]) and math.isfinite(exp[h, 1]):
                        tot += math.hypot(pts[k, 0] - exp[h, 0], pts[k, 1] - exp[h, 1])
                        cnt += 1
                cost = tot / cnt if cnt > 0 else np.inf
            else:
                cost = abs(mj + dj - cj) + abs(mi + di - ci)
            if cost < best:
                best = cost
                bj = dj
                bi = di
    return bj, bi


@njit(cache=True, nogil=True)
def new_holes(n_holes, no_spot):
    """Per-hole outputs of :func:`sunlab.centroid.locate_spots` before any spot is assigned:
    values (3 + 9, n_holes) (rows x, y, flux, then the metrics, columns METRIC_FIELDS) all
    NaN, windows (4, n_holes) all -1, status (n_holes,) all ``no_spot``."""
    return (np.full((3 + len(METRIC_FIELDS), n_holes), np.nan),
            np.full((4, n_holes), -1, np.int32), np.full(n_holes, no_spot, np.int8))


@njit(cache=True, nogil=True)
def assign_grid(m, win, st, good, ij, origin, basis, resid, on_node, pts, lut, exp, has_exp,
                vals, window, status, ambiguous):
    """Step 4 of :func:`sunlab.centroid.locate_spots` for measured spots (rows of
    :func:`measure_spots` with their windows, status, lattice indices, residuals and
    positions ``pts``): reference spots (on a node and good, or on a node if none is good),
    grid offset (:func:`grid_offset`) and the per-hole outputs (:func:`fill_holes`) written
    into ``vals``, ``window`` and ``status`` (see :func:`new_holes`). Returns (positions of
    the spots assigned to no hole (k, 2), lattice (3, 2): origin of hole (0, 0) and the steps
    along j and i; NaN when no spot is a reference)."""
    n = m.shape[0]
    ref = np.empty(n, np.bool_)
    nr = 0
    for k in range(n):
        ref[k] = on_node[k] and good[k]
        nr += ref[k]
    if nr == 0:
        for k in range(n):
            ref[k] = on_node[k]
            nr += ref[k]
    lattice = np.full((3, 2), np.nan)
    if nr == 0:
        return pts.copy(), lattice
    dj, di = grid_offset(ij, pts, ref, lut, exp, has_exp)
    for q in range(2):
        lattice[0, q] = origin[q] - dj * basis[q, 0] - di * basis[q, 1]
        lattice[1, q] = basis[q, 0]
        lattice[2, q] = basis[q, 1]
    assigned = fill_holes(m, win, st, ij, dj, di, on_node, resid, lut, vals.shape[1], vals[0],
                          vals[1], vals[2], window, status, vals[3:], ambiguous)
    nu = 0
    for k in range(n):
        nu += not assigned[k]
    unassigned = np.empty((nu, 2))
    t = 0
    for k in range(n):
        if not assigned[k]:
            unassigned[t, 0] = pts[k, 0]
            unassigned[t, 1] = pts[k, 1]
            t += 1
    return unassigned, lattice


@njit(cache=True, nogil=True)
def locate_tight(frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat,
                 pitch, max_residual, ok, saturated, clipped, lut, exp, has_exp, n_holes,
                 no_spot, ambiguous):
    """:func:`sunlab.centroid.locate_spots` with the tight window in one compiled call:
    :func:`tight_spots` then :func:`assign_grid`. Returns (values, windows, status (see
    :func:`new_holes`), n_groups detected, sample maximum, unassigned spots (k, 2),
    lattice (3, 2))."""
    vals, window, status = new_holes(n_holes, no_spot)
    nd, smax, m, win, st, good, ij, origin, basis, resid, on_node = tight_spots(
        frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat, pitch,
        max_residual, ok, saturated, clipped)
    n = m.shape[0]
    pts = np.empty((n, 2))
    for k in range(n):
        pts[k, 0] = m[k, 1]
        pts[k, 1] = m[k, 2]
    if n == 0:
        return vals, window, status, nd, smax, pts, np.full((3, 2), np.nan)
    unassigned, lattice = assign_grid(m, win, st, good, ij, origin, basis, resid, on_node, pts,
                                      lut, exp, has_exp, vals, window, status, ambiguous)
    return vals, window, status, nd, smax, unassigned, lattice
