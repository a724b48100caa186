"""Synthetic sun-sensor frames with exactly known truth, for the centroid tests.

Independent of ``sunlab.sim`` on purpose: a spot is a uniform disk (optionally with the ramp edge
of a disk convolved with the sun's disk), pixel-integrated by supersampling, so its centroid is the
disk centre to far below 1e-3 px. Noise: Poisson photon noise (``gain`` e-/DN) plus Gaussian read
noise, quantised to integer DN, clipped to the ADC range and stored as uint16.
"""

from __future__ import annotations

import numpy as np

SHAPE = (1024, 1280)


def disk_profile(r, radius, edge):
    """Surface brightness (0..1) of a disk of ``radius`` px, edge ramp of half-width ``edge``.

    ``edge == 0`` is a hard edge; ``edge > 0`` is the hole convolved with a small uniform disk of
    radius ``edge`` (the sun), in the limit radius >> edge: the fraction of the small disk that lies
    inside a half-plane.
    """
    if edge <= 0:
        return (r <= radius).astype(float)
    d = np.clip((r - radius) / edge, -1.0, 1.0)
    return (np.arccos(d) - d * np.sqrt(1.0 - d * d)) / np.pi


def add_spot(img, x, y, peak, radius=17.5, edge=0.0, supersample=None):
    """Add a pixel-integrated disk spot of height ``peak`` DN centred at (x, y) (in place)."""
    ny, nx = img.shape
    half = radius + edge + 2
    r0, r1 = max(int(np.floor(y - half)), 0), min(int(np.ceil(y + half)) + 1, ny)
    c0, c1 = max(int(np.floor(x - half)), 0), min(int(np.ceil(x + half)) + 1, nx)
    if r0 >= r1 or c0 >= c1:
        return img
    s = supersample or (8 if edge >= 1 else 32)
    off = (np.arange(s) + 0.5) / s - 0.5
    yy = (np.arange(r0, r1)[:, None] + off[None, :]).ravel()
    xx = (np.arange(c0, c1)[:, None] + off[None, :]).ravel()
    rr = np.hypot(xx[None, :] - x, yy[:, None] - y)
    sub = disk_profile(rr, radius, edge)
    pix = sub.reshape(r1 - r0, s, c1 - c0, s).mean(axis=(1, 3))
    img[r0:r1, c0:c1] += peak * pix
    return img


def noisy(signal, *, gain=4.0, read_noise=2.5, seed=0, bit_depth=10):
    """Poisson (``gain`` e-/DN) + Gaussian read noise, quantised, clipped, as uint16."""
    rng = np.random.default_rng(seed)
    electrons = rng.poisson(np.clip(signal, 0, None) * gain)
    dn = electrons / gain + rng.normal(0.0, read_noise, signal.shape)
    return np.clip(np.rint(dn), 0, 2**bit_depth - 1).astype(np.uint16)


def frame(
    spots=((640.3, 500.7),),
    *,
    peak=400.0,
    background=30.0,
    radius=17.5,
    edge=0.0,
    noise=True,
    gain=4.0,
    read_noise=2.5,
    seed=0,
    shape=SHAPE,
    bit_depth=10,
):
    """A full frame with disk spots at ``spots`` = [(x, y), ...] px; uint16 DN.

    ``peak`` may be a scalar or one value per spot. With ``noise=False`` the frame is float64
    (no quantisation), so that estimators can be checked to 1e-3 px.
    """
    img = np.full(shape, float(background))
    peaks = np.broadcast_to(np.asarray(peak, float), (len(spots),))
    for (x, y), p in zip(spots, peaks, strict=True):
        add_spot(img, x, y, p, radius, edge)
    if not noise:
        return np.minimum(img, 2**bit_depth - 1)
    return noisy(img, gain=gain, read_noise=read_noise, seed=seed, bit_depth=bit_depth)


def grid_spots(rows=10, cols=10, pitch=500 / 7, origin=(300.2, 180.6), angle_deg=0.0):
    """Positions (x, y) of a rows x cols spot lattice; row index i along y, column j along x."""
    t = np.deg2rad(angle_deg)
    ii, jj = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    u, v = jj.ravel() * pitch, ii.ravel() * pitch
    x = origin[0] + u * np.cos(t) - v * np.sin(t)
    y = origin[1] + u * np.sin(t) + v * np.cos(t)
    return np.column_stack([x, y]), ii.ravel(), jj.ravel()
