"""disk_fit against the Cramér–Rao bound on spots from a renderer it was not written for.

Spots: a uniform disk convolved with a uniform disk (a pinhole lit by a sun disk of another
size than the bench's), and a uniform disk blurred by a Gaussian; radial profiles computed
exactly (circle-overlap area; non-central chi-square), pixel-integrated by 8 x 8 supersampling,
Poisson (``gain`` e-/DN) + Gaussian read noise, rounded, 10 bits. Nothing of ``sunlab.sim`` is
used. For each spot: the CRLB (:func:`sunlab.centroid.crlb` with the exact profile), the rms
error per axis of ``disk_fit(profile="erfc")`` and ``disk_fit(profile="spline")`` and their ratio
to the bound, and the time per cutout beside ``np.copy`` of a full 1024 x 1280 frame (a floor
measured in the same run).

    python benchmarks/bench_crlb.py [--frames 200]
"""

from __future__ import annotations

import argparse
import math
import time

import _timing
import numpy as np
from scipy import stats

from sunlab import centroid as C

GAIN = 40.0  # e-/DN, as the bench's detector
READ_NOISE = 0.875  # DN (35 e-)
BACKGROUND = 10.0  # DN above zero (dark signal)


def sun_disk_profile(radius, sun, dmax, n=20001):
    """Surface brightness (0..1) of a disk of ``radius`` px convolved with a uniform disk of
    radius ``sun`` px: the overlap area of the two circles over the small one's area."""
    d = np.linspace(0.0, dmax, n)
    out = np.where(d <= radius - sun, 1.0, 0.0)
    part = (d > abs(radius - sun)) & (d < radius + sun)
    dd = d[part]
    c1 = np.clip((dd**2 + sun**2 - radius**2) / (2 * dd * sun), -1, 1)
    c2 = np.clip((dd**2 + radius**2 - sun**2) / (2 * dd * radius), -1, 1)
    k = np.clip((sun + radius - dd) * (dd + sun - radius) * (dd - sun + radius)
                * (dd + sun + radius), 0, None)
    area = sun**2 * np.arccos(c1) + radius**2 * np.arccos(c2) - 0.5 * np.sqrt(k)
    out[part] = area / (math.pi * sun**2)
    return lambda r: np.interp(r, d, out, right=0.0)


def gauss_disk_profile(radius, sigma, dmax, n=20001):
    """Surface brightness of a disk of ``radius`` px blurred by a Gaussian of ``sigma`` px:
    P(|X| < radius) for X ~ N(d, sigma^2 I) (non-central chi-square, 2 degrees of freedom)."""
    d = np.linspace(0.0, dmax, n)
    p = stats.ncx2.cdf((radius / sigma) ** 2, 2, (d / sigma) ** 2)
    return lambda r: np.interp(r, d, p, right=0.0)


def render(profile, x0, y0, half, flux, rng, ss=8):
    """A (2 half + 1)^2 uint16 cutout of the spot centred at (x0, y0) with ``flux`` DN."""
    n = int(2 * half + 1)
    off = (np.arange(ss) + 0.5) / ss - 0.5
    grid = (np.arange(n)[:, None] + off).ravel()
    p = profile(np.hypot(grid[None, :] - x0, grid[:, None] - y0)).reshape(n, ss, n, ss).mean((1, 3))
    mu = flux * p / p.sum() + BACKGROUND
    dn = rng.poisson(mu * GAIN) / GAIN + rng.normal(0.0, READ_NOISE, mu.shape)
    return np.clip(np.rint(dn), 0, 1023).astype(np.uint16)


SPOTS = {
    # name: (profile factory, radius, second size, flux DN)
    "disk R 14.3 (x) sun 11.1, 800k DN": (sun_disk_profile, 14.3, 11.1, 8e5),
    "disk R 14.3 (x) sun 11.1, 220k DN": (sun_disk_profile, 14.3, 11.1, 2.2e5),
    "disk R 10 (x) sun 3, 400k DN": (sun_disk_profile, 10.0, 3.0, 4e5),
    "disk R 18 (x) sun 8, 220k DN": (sun_disk_profile, 18.0, 8.0, 2.2e5),
    "disk R 24 * Gauss 2, 800k DN": (gauss_disk_profile, 24.0, 2.0, 8e5),
}


def measure(name, n_frames, seed=1):
    factory, radius, second, flux = SPOTS[name]
    half = radius + 4 * second + 8
    prof = factory(radius, second, 2 * half)
    rng = np.random.default_rng(seed)
    c = half + 0.5
    truth = c + rng.uniform(-0.5, 0.5, (n_frames, 2))
    frames = [render(prof, x, y, half, flux, rng) for x, y in truth]
    bound = C.crlb(flux, BACKGROUND, READ_NOISE, gain=GAIN, half_size=half - 1,
                   model=lambda dx, dy: prof(np.hypot(dx, dy)))
    row = {"crlb": bound.sigma_x}
    for pr in ("erfc", "spline"):
        C.disk_fit(frames[0], profile=pr)
        t = time.perf_counter()
        got = np.array([(r.x, r.y) for r in (C.disk_fit(f, profile=pr) for f in frames)])
        row[pr + " ms"] = (time.perf_counter() - t) / n_frames * 1e3
        row[pr] = float(np.sqrt(np.mean((got - truth) ** 2)))  # both axes pooled
    return row


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=200)
    args = ap.parse_args(argv)
    floor = _timing.copy_ms(20)
    print(f"{args.frames} cutouts per spot; gain {GAIN:g} e-/DN, read noise {READ_NOISE} DN, "
          f"background {BACKGROUND:g} DN; floor: np.copy of a 1024 x 1280 frame {floor:.3f} ms")
    print(f"{'spot':36s} {'CRLB px':>8s} | {'erfc rms':>8s} {'/CRLB':>6s} {'ms':>6s} | "
          f"{'spline rms':>10s} {'/CRLB':>6s} {'ms':>6s}")
    for name in SPOTS:
        r = measure(name, args.frames)
        print(f"{name:36s} {r['crlb']:8.5f} | {r['erfc']:8.5f} {r['erfc'] / r['crlb']:6.2f} "
              f"{r['erfc ms']:6.2f} | {r['spline']:10.5f} {r['spline'] / r['crlb']:6.2f} "
              f"{r['spline ms']:6.2f}", flush=True)
    print("rms: both axes pooled (sqrt of the mean squared error); its relative standard error "
          f"is about {1 / math.sqrt(4 * args.frames):.3f}")


if __name__ == "__main__":
    main()
