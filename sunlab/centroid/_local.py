"""The tight window's local pass in NumPy: a background plane fitted around the spot, and
isolated hot pixels repaired (private to :mod:`sunlab.centroid`).

The tight window's aperture (:mod:`sunlab.centroid._aperture`) subtracts the sigma-clipped *mean*
of a ring around the spot. On a background that slopes (an uncorrected dark-offset ramp, stray
light that drifts between frames) a constant leaves the slope inside the window, and a slope
``g`` DN/px moves the centre of mass of a circular window of radius ``r`` by about
``g * pi r^4 / 4 / flux`` px toward the brighter side (0.6 px for a 35 px spot on a 1.7 DN/px
ramp of a 10-bit frame). A plane ``b0 + bx (x - xc) + by (y - yc)`` fitted to the ring takes
the slope out: the centre of mass of ``I - plane`` is unbiased for any linear background.
"""

from __future__ import annotations

import math

import numpy as np

from .result import _hot_medians

__all__: list[str] = []


def _local_centroid(arr, x, y, r_ap, annulus, n_iter, saturation, plane: bool):
    """Centre of mass of ``I - background`` in the circle of radius ``r_ap`` about ``(x, y)``,
    re-centred ``n_iter`` times, with the background fitted to the ring
    ``r_ap < r <= r_ap + annulus`` and isolated hot pixels repaired first.

    Returns ``(flux, x, y, n_repaired, saturated)``; flux NaN when the window is empty.
    """
    ny, nx = arr.shape
    outer = r_ap + annulus
    n_hot, saturated, flux = 0, False, math.nan
    for _ in range(max(int(n_iter), 1)):
        x0, x1 = max(math.floor(x - outer), 0), min(math.ceil(x + outer) + 1, nx)
        y0, y1 = max(math.floor(y - outer), 0), min(math.ceil(y + outer) + 1, ny)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return math.nan, x, y, n_hot, saturated
        cut = arr[y0:y1, x0:x1].astype(np.float64)
        # each pixel at or above saturation whose 8 neighbours are all below it (a hot pixel,
        # not spot light at full scale) replaced by the median of its neighbours; nothing
        # repaired when two clipped pixels touch (the spot saturates)
        rows, cols = np.nonzero(cut >= saturation)
        med = _hot_medians(cut, rows, cols, saturation)
        n_hot, saturated = (0, True) if med is None else (len(med), False)
        if med:
            cut[rows, cols] = med
        dx = np.arange(x0, x1)[None, :] - x + np.zeros((y1 - y0, 1))
        dy = np.arange(y0, y1)[:, None] - y + np.zeros((1, x1 - x0))
        d2 = dx**2 + dy**2
        inside = d2 <= r_ap**2
        ring = (d2 > r_ap**2) & (d2 <= outer**2)
        # the background: a plane (or a constant) fitted to the ring by least squares, twice
        # clipped at 3 sigma (a neighbouring spot or a hot pixel in the ring)
        use = ring.copy()
        coef = np.zeros(3)
        for _ in range(3):
            design = np.column_stack([np.ones(use.sum()), dx[use], dy[use]]) if plane else \
                np.ones((use.sum(), 1))
            if design.shape[0] < design.shape[1] + 2:
                break
            sol, *_ = np.linalg.lstsq(design, cut[use], rcond=None)
            coef[: sol.size] = sol
            resid = cut - (coef[0] + coef[1] * dx + coef[2] * dy)
            sigma = 1.4826 * np.median(np.abs(resid[use]))
            keep = ring & (np.abs(resid) <= 3.0 * max(sigma, 1e-12))
            if keep.sum() == use.sum():
                break
            use = keep
        w = (cut - (coef[0] + coef[1] * dx + coef[2] * dy))[inside]
        flux = float(w.sum())
        if not flux > 0:
            return math.nan, x, y, n_hot, saturated
        x += float((w * dx[inside]).sum()) / flux
        y += float((w * dy[inside]).sum()) / flux
    return flux, x, y, n_hot, saturated
