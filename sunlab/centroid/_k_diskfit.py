"""Kernels of the disk-model fit (Levenberg-Marquardt on an erfc edge, then a radial B-spline
profile).

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import jit
from ._k_flags import _FM

__all__: list[str] = []


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


@jit.kernel(cache=True, nogil=True)
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


@jit.kernel(cache=True, nogil=True)
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


@jit.kernel(cache=True, nogil=True)
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


@jit.kernel(cache=True, nogil=True)
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


@jit.kernel(cache=True, nogil=True)
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


@jit.kernel(cache=True, nogil=True)
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
