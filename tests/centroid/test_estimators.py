"""disk_fit on spots from a renderer it was not written for, against the Cramér–Rao bound.

The spots are written here, independently of ``sunlab.sim`` and of ``disk_fit``'s models: exact
radial profiles (a disk convolved with a uniform disk: the circle-overlap area; a disk blurred by
a Gaussian: the non-central chi-square), pixel-integrated by 8 x 8 supersampling, Poisson
(40 e-/DN) + 0.875 DN read noise, rounded to 10-bit DN. The truth is the profile's centre.
"""

import math

import numpy as np
import pytest
from scipy import stats

from sunlab import centroid as C
from sunlab.errors import ConfigurationError

GAIN, READ_NOISE, BACKGROUND = 40.0, 0.875, 10.0


def _sun_disk(radius, sun):
    def prof(r):
        r = np.asarray(r, dtype=float)
        out = np.where(r <= radius - sun, 1.0, 0.0)
        part = (r > abs(radius - sun)) & (r < radius + sun)
        d = r[part]
        c1 = np.clip((d**2 + sun**2 - radius**2) / (2 * d * sun), -1, 1)
        c2 = np.clip((d**2 + radius**2 - sun**2) / (2 * d * radius), -1, 1)
        k = np.clip((-d + sun + radius) * (d + sun - radius) * (d - sun + radius)
                    * (d + sun + radius), 0, None)
        out[part] = (sun**2 * np.arccos(c1) + radius**2 * np.arccos(c2) - 0.5 * np.sqrt(k)) / (
            math.pi * sun**2)
        return out
    return prof


def _gauss_disk(radius, sigma, dmax=80.0):
    d = np.linspace(0.0, dmax, 8001)
    p = stats.ncx2.cdf((radius / sigma) ** 2, 2, (d / sigma) ** 2)
    return lambda r: np.interp(r, d, p, right=0.0)


def _spots(prof, half, flux, n, seed):
    rng = np.random.default_rng(seed)
    m, ss = int(2 * half + 1), 8
    off = (np.arange(ss) + 0.5) / ss - 0.5
    truth = half + 0.5 + rng.uniform(-0.5, 0.5, (n, 2))
    frames = []
    for x0, y0 in truth:
        xs = (np.arange(m)[:, None] + off).ravel() - x0
        ys = (np.arange(m)[:, None] + off).ravel() - y0
        p = prof(np.hypot(xs[None, :], ys[:, None])).reshape(m, ss, m, ss).mean(axis=(1, 3))
        mu = flux * p / p.sum() + BACKGROUND
        dn = rng.poisson(mu * GAIN) / GAIN + rng.normal(0.0, READ_NOISE, mu.shape)
        frames.append(np.clip(np.rint(dn), 0, 1023).astype(np.uint16))
    bound = C.crlb(flux, BACKGROUND, READ_NOISE, gain=GAIN, half_size=half - 1,
                   model=lambda dx, dy: prof(np.hypot(dx, dy)))
    return frames, truth, bound.sigma_x


def _rms(frames, truth, **kw):
    # the frames are 10-bit: their full scale is declared, as locate does from the cube
    got = np.array([(c.x, c.y) for c in (C.disk_fit(f, saturation=1023, **kw) for f in frames)])
    return float(np.sqrt(np.mean((got - truth) ** 2)))


def test_fit_reaches_the_crlb_on_a_sun_disk_wider_than_the_hole():
    # A 14.3 px hole convolved with an 11.1 px sun disk (no plateau; a ramp, not an erfc edge),
    # 800 000 DN: CRLB 0.0017 px. The fitted radial profile, weighted by the noise of its own
    # residuals, is within 1.2x of the bound (80 frames: the pooled rms is known to 6 %); the
    # erfc edge alone, with weights that miss the photon noise, is not.
    frames, truth, bound = _spots(_sun_disk(14.3, 11.1), 14.3 + 11.1 + 8, 8e5, 80, seed=11)
    assert 0.0015 < bound < 0.002
    assert _rms(frames, truth) < 1.2 * bound
    assert _rms(frames, truth, profile="erfc") > 1.25 * bound


def test_fit_reaches_the_crlb_on_a_gaussian_blurred_disk():
    # R = 24 px, sigma = 2 px, another radius and edge than the bench's spot.
    frames, truth, bound = _spots(_gauss_disk(24.0, 2.0), 24.0 + 8 + 8, 8e5, 60, seed=12)
    assert _rms(frames, truth) < 1.2 * bound


def test_unknown_profile_is_refused():
    with pytest.raises(ConfigurationError, match="profile"):
        C.disk_fit(np.zeros((64, 64), np.uint16), profile="gauss")
