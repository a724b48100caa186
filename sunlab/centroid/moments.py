"""Moments of a spot: the one definition the tight window, the disk fit's start and the per-hole
quality metrics of :func:`sunlab.centroid.locate_spots` use.

A spot's moments are those of ``I - b`` over the pixels whose centres lie within an aperture
radius ``r`` of a centre, where ``b`` is the mean of the annulus ``r + 1 < d <= r + 1 +
annulus`` (the pixels of the annulus within an accepted band of values; all of them when none
is). From the second moments come the spot's equivalent uniform-disk radius
``sqrt(2 (mxx + myy))`` (a uniform disk of radius R has ``mxx = myy = R^2 / 4``), its
ellipticity and its third-moment asymmetry.

Examples
--------
>>> import numpy as np
>>> yy, xx = np.mgrid[0:120, 0:140]
>>> frame = (30 + 400 * (np.hypot(xx - 70.5, yy - 60.0) < 15)).astype(np.uint16)
>>> m = spot_moments(frame, 70.0, 60.0, 22.0)
>>> round(m.x, 3), round(m.y, 3), round(m.background, 1), round(m.radius, 1)
(70.5, 60.0, 30.0, 14.9)
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ._aperture import _annulus, _moments
from .result import _full_scale, _prepare

__all__ = ["stamp_moments"]


class SpotMoments(NamedTuple):
    """Moments of one spot (a row of the spot measurement, fields in this order).

    Attributes
    ----------
    flux : float
        Sum of ``I - background`` over the aperture, DN.
    x, y : float
        Centre of mass of ``I - background``, px (eq. (2)).
    mxx, myy, mxy : float
        Central second moments, px^2.
    m30, m21, m12, m03 : float
        Central third moments, px^3.
    peak : float
        Highest pixel of the aperture, DN.
    npix, nsat : float
        Pixels in the aperture and those at or above full scale.
    background, background_std : float
        Mean and standard deviation of the annulus, DN.
    r_ap : float
        Aperture radius the values were measured in, px.
    """

    flux: float
    x: float
    y: float
    mxx: float
    myy: float
    mxy: float
    m30: float
    m21: float
    m12: float
    m03: float
    peak: float
    npix: float
    nsat: float
    background: float
    background_std: float
    r_ap: float

    @property
    def radius(self) -> float:
        """Equivalent uniform-disk radius ``sqrt(2 (mxx + myy))``, px."""
        return math.sqrt(max(2.0 * (self.mxx + self.myy), 0.0))

    @property
    def ellipticity(self) -> float:
        """``(l1 - l2) / (l1 + l2)`` of the second-moment matrix (0 for a round spot)."""
        tr = self.mxx + self.myy
        return 2 * math.sqrt(max((self.mxx - self.myy) ** 2 / 4 + self.mxy**2, 0.0)) / tr

    @property
    def asymmetry(self) -> float:
        """Third-moment asymmetry ``|(m30 + m12, m21 + m03)| / (mxx + myy)^1.5``."""
        tr = self.mxx + self.myy
        return math.hypot(self.m30 + self.m12, self.m21 + self.m03) / tr**1.5




def spot_moments(
    frame,
    x: float,
    y: float,
    radius: float,
    *,
    annulus: float = 6.0,
    band: tuple[float, float] = (-math.inf, math.inf),
    saturation: float | None = None,
) -> SpotMoments:
    """Moments of the spot about ``(x, y)`` in a circular aperture of ``radius`` px.

    The background ``b`` is the mean of the annulus ``radius + 1 < d <= radius + 1 + annulus``
    (its pixels with values in ``band``; all of them when none is), then the moments of
    ``I - b`` over the pixels whose centres lie within ``radius`` of ``(x, y)``: the centre of
    mass, eq. (2), and the central second and third moments about it. The same code measures
    every spot of :func:`sunlab.centroid.tight_window` and :func:`sunlab.centroid.locate_spots`
    (which re-centre the aperture first).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    x, y : float
        Aperture centre, px (column, row; centre of the first pixel = 0).
    radius : float
        Aperture radius, px.
    annulus : float
        Width of the background ring, px.
    band : (float, float)
        Pixel values accepted in the background ring, DN.
    saturation : float, optional
        Full-scale value, DN (counts ``nsat``); default the frame type's full scale (as
        :func:`~sunlab.centroid.tight_window`).

    Returns
    -------
    SpotMoments
        NaN fields where the aperture holds no pixel.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:120, 0:140]
    >>> frame = (30 + 400 * (np.hypot(xx - 70.5, yy - 60.0) < 15)).astype(np.uint16)
    >>> m = spot_moments(frame, 70.0, 60.0, 22.0)
    >>> round(m.flux), int(m.npix), round(m.mxx, 1), round(m.myy, 1)
    (279200, 1517, 56.6, 54.4)
    """
    saturation = _full_scale(frame, saturation)
    arr, _ = _prepare(frame)
    xs, ys, rs = (np.array([float(v)]) for v in (x, y, radius))
    bkg, bsd, _ = _annulus(arr, xs, ys, rs + 1.0, rs + 1.0 + float(annulus),
                           *(float(v) for v in band))
    m = _moments(arr, xs, ys, rs, bkg, float(saturation))[0]
    return SpotMoments(*(float(v) for v in m), float(bkg[0]), float(bsd[0]), float(rs[0]))


def stamp_moments(img) -> tuple[float, float, float]:
    """RMS radius, ellipticity and asymmetry of the spot filling a stamp: the stamp variant.

    :func:`spot_moments` measures a spot at a known centre inside an aperture, against the
    mean of an annulus; a stamp cut around a multi-hole spot (:func:`sunlab.multihole.holes.cutout`)
    has neighbours' light in any annulus, so this variant takes the median of the stamp's
    border as the background and zeroes pixels under 10 % of the peak. Its radius is the RMS
    radius ``sqrt(mxx + myy)`` (``R / sqrt(2)`` for a uniform disk of radius ``R``, where
    :func:`spot_moments` reports ``R``); ellipticity ``(l1 - l2) / (l1 + l2)`` of the
    second-moment matrix and asymmetry ``|m3| / r^3`` have the same meaning in both. The
    per-hole shape metrics of :func:`sunlab.multihole.defect_metrics` use this variant.

    Parameters
    ----------
    img : array_like, 2-D
        The stamp, one spot near its middle.

    Returns
    -------
    (radius, ellipticity, asymmetry) : tuple of float
        NaN for a stamp with no light above its border.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:61, 0:61]
    >>> stamp = 20.0 + 500.0 * (np.hypot(xx - 30, yy - 30) < 15)
    >>> r, ell, asym = stamp_moments(stamp)
    >>> round(r * math.sqrt(2), 1), round(ell, 3), round(asym, 3)
    (14.9, 0.0, 0.0)
    """
    img = np.asarray(img, dtype=float)
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = np.median(border)
    w = img - bg
    peak = w.max()
    if not np.isfinite(peak) or peak <= 0:
        return math.nan, math.nan, math.nan
    w = np.where(w > 0.1 * peak, w, 0.0)
    yy, xx = np.indices(w.shape)
    s = w.sum()
    cx, cy = (w * xx).sum() / s, (w * yy).sum() / s
    dx, dy = xx - cx, yy - cy
    mxx, myy, mxy = (w * dx * dx).sum() / s, (w * dy * dy).sum() / s, (w * dx * dy).sum() / s
    tr = mxx + myy
    det = mxx * myy - mxy**2
    disc = np.sqrt(max(tr**2 / 4 - det, 0.0))
    l1, l2 = tr / 2 + disc, tr / 2 - disc
    ell = (l1 - l2) / (l1 + l2)
    r = np.sqrt(tr)
    m3x = (w * dx * (dx * dx + dy * dy)).sum() / s
    m3y = (w * dy * (dx * dx + dy * dy)).sum() / s
    asym = np.hypot(m3x, m3y) / r**3
    return float(r), float(ell), float(asym)
