"""The fitting stages of :func:`sunlab.centroid.disk_fit` (private to :mod:`sunlab.centroid`):
the erfc-edge Levenberg–Marquardt fit, its noise model and the radial-spline refit."""

from __future__ import annotations

import math

import numpy as np

from . import _k_diskfit as _kf
from .moments import SpotMoments
from .result import _NO_SPOT, Centroid, _fail

__all__: list[str] = []


def _fit_from(arr, m: SpotMoments, status, edge, max_iter, reweight, saturation,
              profile="spline") -> Centroid:
    """Disk fit of :func:`sunlab.centroid.disk_fit` started from a spot's tight-window
    moments ``m``; ``status`` is the start's."""
    x0, y0, flux0, bkg = float(m.x), float(m.y), float(m.flux), float(m.background)
    rad = math.sqrt(max(2.0 * (m.mxx + m.myy) - edge**2, 1.0))
    amp = flux0 / (math.pi * (rad**2 + edge**2))
    half = rad + 4.0 * edge + 4.0
    p0 = np.array([x0, y0, rad, amp, bkg, edge])
    sat = float(saturation)
    p, _, _, _, _, r0, r1, c0, c1 = _kf.fit_disk(arr, p0, half, int(max_iter), 1.0, 0.0, 1e-5, sat)
    flux = math.nan
    if reweight and np.all(np.isfinite(p)):
        v0, vk = _noise_model(arr, p, r0, r1, c0, c1, sat)
        if np.isfinite(v0) and v0 > 0:
            if profile == "spline":
                p, flux, (r0, r1, c0, c1) = _fit_spline(arr, p, int(max_iter), v0, vk, sat)
            else:
                p, _, _, _, _, r0, r1, c0, c1 = _kf.fit_disk(
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
    q, _, _ = _kf.fit_profile(arr, q0, d_lo, h, nint, r0, r1, c0, c1, max_iter, v0, vk, b, 1e-5,
                             sat)
    # Noise from the spline's own residuals, then refit: where the spot has no plateau (a
    # sun-disk ramp wider than the hole) the zones cannot see the photon noise, and weights
    # without it cost 20-40 % in scatter.
    if np.all(np.isfinite(q)):
        v1, vk1, _ = _kf.profile_noise(arr, q, d_lo, h, nint, r0, r1, c0, c1, b, sat)
        if np.isfinite(v1) and (abs(v1 - v0) > 0.1 * v0 or abs(vk1 - vk) > 0.1 * max(vk1, vk)):
            q1, _, _ = _kf.fit_profile(arr, q, d_lo, h, nint, r0, r1, c0, c1, max_iter, v1, vk1,
                                      b, 1e-5, sat)
            if np.all(np.isfinite(q1)):
                q = q1
    out = p.copy()
    out[0], out[1] = q[0], q[1]
    flux = _kf.profile_flux(q, d_lo, h, nint, 8) if np.all(np.isfinite(q)) else math.nan
    return out, float(flux), (r0, r1, c0, c1)


def _noise_model(arr, p, r0, r1, c0, c1, sat):
    """Pixel variance ``v0 + vk (m - b)`` of a spot fitted with parameters ``p``, from the
    background beyond ``R + 3 s + 2`` and the plateau within ``R - 3 s - 2`` (model-free: a
    mismatch of the fitted edge does not leak into it); the fit's residuals where either zone
    has too few pixels. ``v0`` is at least 1/12 DN^2 (quantisation)."""
    x, y, rad, s = float(p[0]), float(p[1]), float(p[2]), float(p[5])
    pad = 3.0 * s + 2.0
    v0, vk, n_bkg, n_plateau = _kf.zone_noise(arr, x, y, rad - pad, rad + pad, r0, r1, c0, c1, sat)
    if n_bkg < 20 or not np.isfinite(v0):
        v0, vk = _kf.disk_noise(arr, p, r0, r1, c0, c1, sat)
    elif n_plateau < 10:
        vk = _kf.disk_noise(arr, p, r0, r1, c0, c1, sat)[1]
    return max(float(v0), 1.0 / 12.0), float(vk)
