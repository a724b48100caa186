"""Kernels of the tight, background-subtracted circular window: aperture row tables,
moments, annulus background, spot measurement.

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import jit
from ._k_flags import _FM, _U

__all__: list[str] = []


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


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@jit.kernel(cache=True, nogil=True)
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
#: Column of each of :data:`MEASURE_FIELDS` (module constants: numba compiles them in).
(FLUX, X, Y, MXX, MYY, MXY, M30, M21, M12, M03, PEAK, NPIX, NSAT, BACKGROUND, BACKGROUND_STD,
 R_AP) = range(len(MEASURE_FIELDS))


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


@jit.kernel(cache=True, nogil=True, fastmath=_FM)
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


@jit.kernel(cache=True, nogil=True)
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
    out = np.full((n, len(MEASURE_FIELDS)), np.nan)
    nt = 3
    for k in range(n):
        nt = max(nt, 2 * int(math.ceil(r0s[k])) + 3)
    ta = np.empty((nt, 4))
    sa = np.empty((nt, 2), np.int64)
    tb = np.empty((nt, 4))
    sb = np.empty((nt, 2), np.int64)
    for k in range(n):
        xc = xs[k]
        yc = ys[k]
        r_ap = r0s[k]
        bkg, bsd, nb = annulus_mean(frame, xc, yc, r_ap + 1.0, r_ap + 1.0 + annulus, lo, hi)
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
        out[k, :BACKGROUND] = m
        out[k, BACKGROUND] = bkg
        out[k, BACKGROUND_STD] = bsd
        out[k, R_AP] = r_ap
    return out
