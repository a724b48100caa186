"""The fitting stages of :func:`sunlab.centroid.disk_fit` in numpy (private to
:mod:`sunlab.centroid`): the erfc-edge Levenberg–Marquardt fit, its noise model and the
radial-spline refit. Each works on the unsaturated pixels of a box of the frame, as flat arrays.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.special import erfc

from .moments import SpotMoments
from .result import _NO_SPOT, Centroid, _fail

__all__: list[str] = []

_SQRT2 = math.sqrt(2.0)
_INV_SQRT2PI = 1.0 / math.sqrt(2.0 * math.pi)
#: Knot step of the radial spline of ``disk_fit(profile="spline")``, px, and the margin of its
#: knot span beyond the erfc fit's edge, ``R +- (3 s + 2)`` px.
_SPLINE_STEP = 1.0
_SPLINE_PAD = 2.0


class _Pixels:
    """The pixels below ``sat`` of the box [r0, r1) x [c0, c1): values ``v``, columns ``c`` and
    rows ``r`` (flat float64 arrays)."""

    def __init__(self, arr, r0, r1, c0, c1, sat):
        self.box = (r0, r1, c0, c1)
        v = arr[r0:r1, c0:c1].astype(np.float64)
        r, c = np.mgrid[r0:r1, c0:c1]
        keep = v < sat
        self.v, self.r, self.c = v[keep], r[keep].astype(float), c[keep].astype(float)

    def dist(self, x, y):
        dx, dy = self.c - x, self.r - y
        return dx, dy, np.hypot(dx, dy)


def _box(arr, x, y, half):
    ny, nx = arr.shape
    return (max(math.floor(y - half), 0), min(math.ceil(y + half) + 1, ny),
            max(math.floor(x - half), 0), min(math.ceil(x + half) + 1, nx))


def _lm(normal, p0, max_iter, tol, step_fix, ridge=0.0):
    """Levenberg–Marquardt on the normal equations ``normal(p) -> (J^T W J, J^T W res, chi2)``;
    ``step_fix(q)`` bounds a trial, ``ridge`` (relative) keeps a basis no pixel reaches at its
    start. Stops when the centre moves less than ``tol`` px. Returns (p, J^T W J)."""
    p, lam = p0.copy(), 1e-3
    jtj, jtr, chi2 = normal(p)
    for _ in range(max_iter):
        a = jtj * (1.0 + lam * np.eye(p.size))
        if ridge:
            a[np.diag_indices(p.size)] += ridge * np.max(np.diag(jtj)) + 1e-300
        step = np.linalg.solve(a, jtr)
        q = step_fix(p + step)
        jtj2, jtr2, chi2_new = normal(q)
        if chi2_new <= chi2:
            p, jtj, jtr, chi2 = q, jtj2, jtr2, chi2_new
            lam = max(lam * 0.1, 1e-7)
            if abs(step[0]) < tol and abs(step[1]) < tol:
                break
        else:
            lam *= 10.0
            if lam > 1e8:
                break
    return p, jtj


def _erfc_model(px: _Pixels, p):
    """The edge-blurred disk ``b + A erfc((d - R) / (sqrt(2) s)) / 2`` at the pixels: (the
    erfc term e, its Jacobian (6, n) in (x, y, R, A, b, s))."""
    x, y, rad, amp, _, s = p
    dx, dy, d = px.dist(x, y)
    u = (d - rad) / (_SQRT2 * s)
    e = 0.5 * erfc(u)
    phi = amp * _INV_SQRT2PI / s * np.exp(-u * u)
    dinv = np.where(d > 1e-9, 1.0 / np.maximum(d, 1e-9), 0.0)
    jac = np.stack([phi * dx * dinv, phi * dy * dinv, phi, e, np.ones_like(e),
                    phi * (d - rad) / s])
    return e, jac


def _fit_disk(px: _Pixels, p0, max_iter, v0, vk, tol=1e-5):
    """Weighted Levenberg–Marquardt fit of the erfc disk, weights 1 / (v0 + vk max(A e, 0))."""
    def normal(p):
        e, jac = _erfc_model(px, p)
        res = px.v - (p[4] + p[3] * e)
        wgt = 1.0 / (v0 + vk * np.maximum(p[3] * e, 0.0))
        jw = jac * wgt
        return jw @ jac.T, jw @ res, float(wgt @ (res * res))

    def fix(q):
        q[5], q[2] = max(q[5], 0.05), max(q[2], 0.5)
        return q

    return _lm(normal, p0, max_iter, tol, fix)[0]


def _disk_noise(px: _Pixels, p):
    """Noise model from the residuals of a disk fit: variance v0 on the background (model
    < b + 0.05 A) and v0 + vk A on the plateau (model > b + 0.95 A). Returns (v0, vk)."""
    e, _ = _erfc_model(px, p)
    res2 = (px.v - (p[4] + p[3] * e)) ** 2
    bg, pl = e < 0.05, e > 0.95
    if bg.sum() < 10:
        return np.nan, 0.0
    v0 = res2[bg].mean()
    vk = max((res2[pl].mean() - v0) / p[3], 0.0) if pl.sum() >= 10 and p[3] > 0 else 0.0
    return v0, vk


def _clipped(v):
    """Count, mean and variance of values, then twice of those within 5 sigma + 0.5 DN of the
    mean before (for hot pixels)."""
    use, m, var = v, np.nan, np.nan
    for k in range(3):
        if k:
            use = v[np.abs(v - m) <= 5.0 * math.sqrt(var) + 0.5]
        if use.size < 2:
            return use.size, np.nan, np.nan
        m, var = use.mean(), use.var(ddof=1)
    return use.size, m, var


def _noise_model(px: _Pixels, p):
    """Pixel variance ``v0 + vk (m - b)`` of a spot fitted with parameters ``p``, from the
    background beyond ``R + 3 s + 2`` and the plateau within ``R - 3 s - 2`` (model-free: a
    mismatch of the fitted edge does not leak into it); the fit's residuals where either zone
    has too few pixels. ``v0`` is at least 1/12 DN^2 (quantisation). Each zone's mean and
    variance are sigma-clipped; the plateau's variance is ``v0 + vk (mean - background)``."""
    pad = 3.0 * p[5] + 2.0
    d_in, d_out = p[2] - pad, p[2] + pad
    d = px.dist(p[0], p[1])[2]
    n_bkg, mb, v0 = _clipped(px.v[d * d >= d_out * d_out])
    n_plateau, mp, vp = _clipped(px.v[d * d < d_in * d_in])
    vk = max((vp - v0) / (mp - mb), 0.0) if n_bkg >= 2 and n_plateau >= 2 and mp > mb else 0.0
    if n_bkg < 20 or not np.isfinite(v0):
        v0, vk = _disk_noise(px, p)
    elif n_plateau < 10:
        vk = _disk_noise(px, p)[1]
    return max(float(v0), 1.0 / 12.0), float(vk)


def _bspline(t, nint):
    """Knot interval j, the 4 uniform cubic B-spline values (4, n) at t (in knot steps, clipped
    to [0, nint]) and their derivatives d/dt (0 outside [0, nint])."""
    inside = (t > 0.0) & (t < nint)
    t = np.clip(t, 0.0, float(nint))
    j = np.minimum(t.astype(np.intp), nint - 1)
    u = t - j
    w, u2 = 1.0 - u, u * u
    b = np.stack([w**3 / 6.0, (3.0 * u2 * u - 6.0 * u2 + 4.0) / 6.0,
                  (-3.0 * u2 * u + 3.0 * u2 + 3.0 * u + 1.0) / 6.0, u2 * u / 6.0])
    g = np.stack([-0.5 * w * w, 1.5 * u2 - 2.0 * u, -1.5 * u2 + u + 0.5, 0.5 * u2]) * inside
    return j, b, g


def _spline_model(px: _Pixels, q, d_lo, h, nint):
    """The radial-spline spot ``sum_k a_k B_k(clip(d, d_lo, d_hi))`` at the pixels, q = (x, y,
    a_0 .. a_{K-1}): (model, its Jacobian (n, K + 2))."""
    dx, dy, d = px.dist(q[0], q[1])
    j, b, g = _bspline((d - d_lo) / h, nint)
    cols = j[None, :] + 2 + np.arange(4)[:, None]
    a = q[cols]
    m = (a * b).sum(0)
    slope = (a * g).sum(0) / h
    slope = np.where(d > 1e-9, slope / np.maximum(d, 1e-9), 0.0)
    jac = np.zeros((d.size, q.size))
    jac[:, 0], jac[:, 1] = -slope * dx, -slope * dy
    jac[np.arange(d.size)[:, None], cols.T] = b.T
    return m, jac


def _fit_profile(px: _Pixels, q0, d_lo, h, nint, max_iter, v0, vk, b, tol=1e-5):
    """Weighted Levenberg–Marquardt fit of the radial spline, weights 1 / (v0 + vk max(m - b,
    0)); a basis no pixel reaches (a saturated plateau) keeps its start (a small ridge)."""
    def normal(q):
        m, jac = _spline_model(px, q, d_lo, h, nint)
        res = px.v - m
        wgt = 1.0 / (v0 + vk * np.maximum(m - b, 0.0))
        jw = jac.T * wgt
        return jw @ jac, jw @ res, float(wgt @ (res * res))

    return _lm(normal, q0, max_iter, tol, lambda q: q, ridge=1e-12)[0]


def _profile_noise(px: _Pixels, q, d_lo, h, nint, b):
    """Noise model ``var = v0 + vk max(m - b, 0)`` regressed on the squared residuals of the
    spline fit ``q`` (a second pass leaves out residuals beyond 5 sigma of the first). Returns
    (v0, vk); v0 NaN with fewer than 20 pixels."""
    m = _spline_model(px, q, d_lo, h, nint)[0]
    lev, res2 = np.maximum(m - b, 0.0), (px.v - m) ** 2
    v0, vk, use = np.nan, 0.0, np.ones(m.size, bool)
    for pas in range(2):
        if pas:
            use = res2 <= 25.0 * (v0 + vk * lev)
        n, x, y = use.sum(), lev[use], res2[use]
        if n < 20:
            return np.nan, 0.0
        s1, s2, t1, st = x.sum(), x @ x, y.sum(), x @ y
        det = n * s2 - s1 * s1
        vk = max((n * st - s1 * t1) / det, 0.0) if det > 1e-12 * n * s2 and det > 0.0 else 0.0
        v0 = max((t1 - vk * s1) / n, 1.0 / 12.0)
    return v0, vk


def _fit_from(arr, m: SpotMoments, status, edge, max_iter, reweight, saturation,
              profile="spline") -> Centroid:
    """Disk fit of :func:`sunlab.centroid.disk_fit` started from a spot's tight-window
    moments ``m``; ``status`` is the start's."""
    x0, y0, flux0, bkg = float(m.x), float(m.y), float(m.flux), float(m.background)
    rad = math.sqrt(max(2.0 * (m.mxx + m.myy) - edge**2, 1.0))
    amp = flux0 / (math.pi * (rad**2 + edge**2))
    box = _box(arr, x0, y0, rad + 4.0 * edge + 4.0)
    px = _Pixels(arr, *box, float(saturation))
    p = _fit_disk(px, np.array([x0, y0, rad, amp, bkg, edge]), int(max_iter), 1.0, 0.0)
    flux = math.nan
    if reweight and np.all(np.isfinite(p)):
        v0, vk = _noise_model(px, p)
        if np.isfinite(v0) and v0 > 0:
            if profile == "spline":
                p, flux, box = _fit_spline(arr, p, int(max_iter), v0, vk, float(saturation))
            else:
                box = _box(arr, p[0], p[1], rad + 4.0 * edge + 4.0)
                p = _fit_disk(_Pixels(arr, *box, float(saturation)), p, int(max_iter), v0, vk)
    # A fit that wanders off the spot is a failure; a clipped spot may move by up to ~R.
    if not np.all(np.isfinite(p[:2])) or math.hypot(p[0] - x0, p[1] - y0) > rad + 2.0:
        return _fail(_NO_SPOT)
    if not np.isfinite(flux):
        flux = p[3] * math.pi * (p[2] ** 2 + p[5] ** 2)
    r0, r1, c0, c1 = box
    return Centroid(float(p[0]), float(p[1]), float(flux), (c0, c1, r0, r1), status)


def _fit_spline(arr, p, max_iter, v0, vk, sat):
    """Second stage of :func:`disk_fit`: the radial-spline profile fitted with the centre,
    started from the erfc fit ``p``. Returns (p with the new centre, flux, box)."""
    x, y, rad, amp, b, s = (float(v) for v in p)
    pad = 3.0 * s + _SPLINE_PAD
    d_lo, d_hi = max(rad - pad, 0.0), rad + pad
    nint = max(math.ceil((d_hi - d_lo) / _SPLINE_STEP), 1)
    h = (d_hi - d_lo) / nint
    # The box reaches 3 px beyond the knot span, so the background level is well measured.
    box = _box(arr, x, y, d_hi + 3.0)
    px = _Pixels(arr, *box, sat)
    # Start: each B-spline coefficient at the erfc model's value at the centre of its basis.
    centres = d_lo + (np.arange(nint + 3) - 1.0) * h
    q = np.concatenate([[x, y], b + 0.5 * amp * erfc((centres - rad) / (_SQRT2 * s))])
    q = _fit_profile(px, q, d_lo, h, nint, max_iter, v0, vk, b)
    # Noise from the spline's own residuals, then refit: where the spot has no plateau (a
    # sun-disk ramp wider than the hole) the zones cannot see the photon noise, and weights
    # without it cost 20-40 % in scatter.
    if np.all(np.isfinite(q)):
        v1, vk1 = _profile_noise(px, q, d_lo, h, nint, b)
        if np.isfinite(v1) and (abs(v1 - v0) > 0.1 * v0 or abs(vk1 - vk) > 0.1 * max(vk1, vk)):
            q1 = _fit_profile(px, q, d_lo, h, nint, max_iter, v1, vk1, b)
            if np.all(np.isfinite(q1)):
                q = q1
    out = p.copy()
    out[0], out[1] = q[0], q[1]
    flux = math.nan
    if np.all(np.isfinite(q)):
        # the integral over the plane of the spline above its outer (background) level:
        # 2 pi int_0^d_hi (m(d) - m(d_hi)) d dd, midpoint rule with 8 steps per knot step (the
        # plateau inside d_lo exactly)
        bg, top = (q[-3] + 4.0 * q[-2] + q[-1]) / 6.0, (q[2] + 4.0 * q[3] + q[4]) / 6.0
        step = h / 8
        d = d_lo + (np.arange(nint * 8) + 0.5) * step
        j, bs, _ = _bspline((d - d_lo) / h, nint)
        m = (q[j[None, :] + 2 + np.arange(4)[:, None]] * bs).sum(0)
        flux = (math.pi * max(d_lo, 0.0) ** 2 * (top - bg)
                + (2.0 * math.pi * step * d * (m - bg)).sum())
    return out, float(flux), box
