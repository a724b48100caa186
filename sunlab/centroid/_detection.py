"""Spot detection on a coarse grid of samples, shared by the tight window, the disk fit and the
multi-spot lattice (private to :mod:`sunlab.centroid`)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from . import _k_detect

__all__: list[str] = []


class _Detection(NamedTuple):
    background: float
    sigma: float
    threshold: float
    count: np.ndarray
    flux: np.ndarray
    x: np.ndarray
    y: np.ndarray
    bbox: np.ndarray
    peak: np.ndarray
    sample_max: float


def _detect(arr, stride, nsigma, min_contrast, min_samples) -> _Detection:
    med, sig, smax = _k_detect.sample_stats(arr, max(2 * int(stride), 1))
    thr = med + max(nsigma * sig, min_contrast)
    cnt, flux, cx, cy, bb, pk = _k_detect.coarse_blobs(arr, int(stride), thr, med)
    keep = cnt >= min_samples
    return _Detection(med, sig, thr, cnt[keep], flux[keep], cx[keep], cy[keep], bb[keep], pk[keep],
                      smax)


def _first_radius(count, stride, margin):
    """First aperture radius: the equivalent radius of the above-threshold area, plus slack
    for the sampling (about stride / 3) and the margin."""
    return np.sqrt(count * float(stride) ** 2 / np.pi) + stride / 3.0 + margin


def _background_band(det: _Detection) -> tuple[float, float]:
    """Values accepted in a local background ring: the frame level +- max(10 sigma, 20 DN)."""
    half = max(10.0 * det.sigma, 20.0)
    return det.background - half, det.background + half


def _aperture_window(x, y, r, nx, ny):
    x0, x1 = math.ceil(x - r), math.floor(x + r) + 1
    y0, y1 = math.ceil(y - r), math.floor(y + r) + 1
    clipped = x0 < 0 or y0 < 0 or x1 > nx or y1 > ny
    return (max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)), clipped
