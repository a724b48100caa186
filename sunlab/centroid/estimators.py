"""Single-spot estimators beyond the paper's two (:func:`threshold_window`,
:func:`projection_window`): the tight window and the disk fit, and the one table of methods.

Every estimator has the signature ``method(frame, **options)`` and returns a
:class:`~sunlab.centroid.result.Centroid`; :data:`METHODS` names them (the ``method=`` of
:func:`sunlab.centroid.locate`), the one table of centroid methods, and :data:`PER_SPOT` says
which of them runs on every spot of a multi-hole frame.

Examples
--------
>>> import numpy as np
>>> yy, xx = np.mgrid[0:200, 0:240]
>>> frame = (30 + 400 * (np.hypot(xx - 120.5, yy - 90.0) < 17.5)).astype(np.uint16)
>>> sorted(METHODS)
['fit', 'projection', 'threshold', 'tight']
>>> round(METHODS["tight"](frame).x, 2)
120.5
>>> set(PER_SPOT) == set(METHODS) and sorted(set(PER_SPOT.values()))
['fit', 'tight']
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..errors import ConfigurationError
from ._aperture import _background_band, _detect, _first_radius, _measure
from ._diskfit import _fit_from
from ._local import _local_centroid
from ._paper import projection_window, threshold_window
from .moments import SpotMoments
from .result import (
    _INVALID,
    _NO_SPOT,
    Centroid,
    _fail,
    _full_scale,
    _prepare,
    _status,
)

__all__ = ["METHODS", "tight_window", "disk_fit"]


def tight_window(
    frame, *, stride: int = 8, nsigma: float = 5.0, min_contrast: float = 5.0,
    min_samples: int = 3, margin: float = 5.0, annulus: float = 6.0, n_iter: int = 2,
    ambiguity_ratio: float = 0.1, saturation: float | None = None, background: str = "ring",
) -> Centroid:
    """Background-subtracted centre of mass in a circular window fitted to the spot (fast).

    1. Detection: the background level and noise are the median and 1.4826 MAD of a sample of
       the frame every ``2 stride`` px; the samples every ``stride`` px above
       ``level + max(nsigma * noise, min_contrast)`` are grouped 8-connected; groups of at least
       ``min_samples`` samples are spots (a hot pixel is at most one sample). The brightest
       group is the spot; another with at least ``ambiguity_ratio`` of its flux flags
       ``ambiguous``.
    2. Local background: sigma-clipped mean of an ``annulus`` px wide ring just outside the
       window, or (``background="plane"``) a plane fitted to that ring by least squares, for a
       background that slopes or drifts between frames (an uncorrected dark-offset ramp: a
       constant leaves the slope in the window and moves the centroid toward its bright side).
    3. Window: a circle about the detection, re-centred on the centre of mass of
       ``I - background`` (``n_iter`` passes); its radius becomes the spot's equivalent
       uniform-disk radius ``sqrt(2 (m_xx + m_yy))`` plus ``margin`` px, which holds the whole
       spot and few background pixels.

    An isolated pixel at full scale in the window (a hot pixel) is replaced by the median of its
    8 neighbours (status ``repaired``, as in algorithm B); touching clipped pixels: ``saturated``.

    Every pixel of the window counts (no threshold), so the estimate has no sub-pixel bias for
    a symmetric spot; noise comes from the spot's own photon noise and the few background pixels
    of the window. The work is a strided pass over the frame and a few passes over the window.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    stride : int
        Detection sampling step, px (must be well below the spot diameter).
    nsigma, min_contrast : float
        Detection threshold above the background: ``max(nsigma * noise, min_contrast)`` DN.
    min_samples : int
        Fewest detection samples of a spot.
    margin : float
        Window radius beyond the spot's equivalent radius, px.
    annulus : float
        Width of the background ring, px.
    n_iter : int
        Centre-of-mass passes that re-centre the window.
    ambiguity_ratio : float
        A second spot with at least this fraction of the flux flags ``ambiguous``.
    saturation : float, optional
        Full-scale value, DN: a pixel at or above it is clipped. Default: the full scale of
        the frame's integer type (255 for uint8, 65535 for uint16; none for float frames);
        pass ``2**bit_depth - 1`` for an ADC narrower than its word (``locate`` does).
    background : {"ring", "plane"}
        Model fitted to the ring: a constant (fastest) or a plane.

    Returns
    -------
    Centroid
        ``window`` is the bounding box of the circular window; ``clipped`` when the circle
        crosses the frame edge.

    Notes
    -----
    Centre of mass, eq. (2), of background-subtracted intensities.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = tight_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.status_name
    (200.5, 150.0, 'ok')
    """
    saturation = _full_scale(frame, saturation)
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    res = _tight(arr, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter,
                 ambiguity_ratio, saturation, background)
    return res[0]


def _tight(arr, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter,
           ambiguity_ratio, saturation, background="ring"):
    """Tight window on a prepared frame; returns (Centroid, its SpotMoments or None)."""
    if background not in ("ring", "plane"):
        raise ConfigurationError(
            f"background: found {background!r}, expected 'ring' (a constant fitted to the ring "
            "around the spot) or 'plane' (a plane, for a sloping background)"
        )
    det = _detect(arr, stride, nsigma, min_contrast, min_samples)
    if det.count.size == 0:
        return _fail(_INVALID if det.sample_max == 0 and not arr.any() else _NO_SPOT), None
    order = np.argsort(-det.flux)
    k = order[0]
    ambiguous = det.count.size > 1 and det.flux[order[1]] >= ambiguity_ratio * det.flux[k]
    r0 = _first_radius(det.count[k : k + 1], stride, margin)
    lo, hi = _background_band(det)
    m = SpotMoments(*_measure(arr, det.x[k : k + 1], det.y[k : k + 1], r0, float(margin),
                              float(annulus), lo, hi, int(n_iter), float(saturation))[0])
    if not m.flux > 0:
        return _fail(_NO_SPOT), None
    ny, nx = arr.shape
    x, y, r_ap, flux = float(m.x), float(m.y), float(m.r_ap), float(m.flux)
    n_hot, saturated = 0, m.nsat > 0
    if background == "plane" or saturated:  # the NumPy pass: plane, hot pixels repaired
        local = _local_centroid(arr, x, y, r_ap, annulus, n_iter, saturation,
                                background == "plane")
        if not local[3] and local[4] and background != "plane":
            local = (flux, x, y, 0, True)  # the spot saturates: the first values stand
        flux, x, y, n_hot, saturated = local
        if not flux > 0:
            return _fail(_NO_SPOT), None
    x0, x1 = math.ceil(x - r_ap), math.floor(x + r_ap) + 1
    y0, y1 = math.ceil(y - r_ap), math.floor(y + r_ap) + 1
    clipped = x0 < 0 or y0 < 0 or x1 > nx or y1 > ny
    window = (max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny))
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous,
                     repaired=n_hot > 0)
    return Centroid(x, y, flux, window, status), m


# ------------------------------------------------------------------------------------------------
# Disk-model fit
# ------------------------------------------------------------------------------------------------
def disk_fit(
    frame, *, edge: float = 1.5, max_iter: int = 30, reweight: bool = True,
    saturation: float | None = None, profile: str = "spline", **detect,
) -> Centroid:
    """Weighted least-squares fit of the spot's centre and radial profile (at the Cramér–Rao bound).

    The spot of a round pinhole lit by the sun's disk is a uniform disk whose edge is blurred by
    the sun (a ramp ~ 2 F tan(0.26 deg) wide) and the pixels. The model

    .. math:: m(c, r) = b + \\frac{A}{2}\\,
              \\operatorname{erfc}\\!\\left(\\frac{d - R}{\\sqrt{2}\\,s}\\right), \\qquad
              d = \\sqrt{(c - x)^2 + (r - y)^2}

    with six parameters (x, y, R, A, b, s) is fitted by Levenberg–Marquardt on a square cutout
    around the spot found by :func:`tight_window` (its start). An erfc edge is not the exact
    ramp of a disk convolved with the sun's disk, but the mismatch is symmetric about the centre
    and so does not bias (x, y). Pixels at or above ``saturation`` are left out of the fit, so a
    saturated spot still gives an unbiased centre (the status still says ``saturated``).

    Weights: with ``reweight`` a first unweighted fit gives the residual variance on the
    background (``v0``) and on the plateau (``v0 + k A``); the second fit weights each pixel by
    ``1 / (v0 + k (m - b))`` — the Poisson + read-noise variance, learned from the frame, so no
    gain needs to be known. This is the maximum-likelihood estimate under the Gaussian
    approximation of that noise, which reaches the Cramér–Rao bound of :func:`crlb`.

    Profile (``profile="spline"``, the default): the erfc edge is exact for a disk blurred by a
    Gaussian but not for the ramp of a disk convolved with the sun's disk, and with a sun disk
    as wide as the hole (long focal lengths) there is no plateau to learn the photon noise from.
    A third fit therefore frees the radial profile: the centre (x, y) with a uniform cubic
    B-spline of the distance d (knots 1 px apart over ``R +- (3 s + 2)``, flat inside and
    outside), weighted by a noise model ``v0 + k (m - b)`` regressed on the squared residuals
    of a first spline fit, then refitted with it. On spots from a renderer the fit was not
    written for (a disk convolved with a uniform disk, a Gaussian-blurred disk; Poisson + read
    noise), the scatter is within 1.1x of the CRLB where the erfc model alone gives 1.3-1.45x
    (``python benchmarks/bench_crlb.py``). ``profile="erfc"`` stops after the erfc fit (faster).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    edge : float
        Starting edge width ``s``, px.
    max_iter : int
        Levenberg–Marquardt iterations per fit.
    reweight : bool
        Do the second, noise-weighted fit.
    saturation : float, optional
        Full-scale value, DN: a pixel at or above it is clipped. Default: the full scale of
        the frame's integer type (255 for uint8, 65535 for uint16; none for float frames);
        pass ``2**bit_depth - 1`` for an ADC narrower than its word (``locate`` does).
    profile : {"spline", "erfc"}
        Radial profile of the final fit (see above).
    **detect
        Options of :func:`tight_window` (detection, start window).

    Returns
    -------
    Centroid
        ``flux``: the integral of the fitted profile above its outer level (erfc: ``A pi (R^2 +
        s^2)``); ``window`` is the fitted cutout. The status is the start's
        (:func:`tight_window`). If the fit does not converge inside the window, the result is NaN
        with status ``no_spot``.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = disk_fit(frame)
    >>> round(c.x, 2), round(c.y, 2), c.status_name
    (200.5, 150.0, 'ok')
    """
    saturation = _full_scale(frame, saturation)
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    start, m = _tight(arr, saturation=saturation, **_disk_fit_start(detect, profile))
    if m is None:
        return start
    return _fit_from(arr, m, start.status, edge, max_iter, reweight, saturation, profile)


def _disk_fit_start(detect, profile):
    """Options of the :func:`tight_window` start of :func:`disk_fit` (its defaults updated by
    ``detect``), after checking ``detect`` and ``profile``."""
    opts = {
        "stride": 8, "nsigma": 5.0, "min_contrast": 5.0, "min_samples": 3, "margin": 5.0,
        "annulus": 6.0, "n_iter": 2, "ambiguity_ratio": 0.1,
    }
    unknown = set(detect) - set(opts)
    if unknown:
        raise ConfigurationError(
            f"disk_fit: unknown option(s) {sorted(unknown)}; expected options of tight_window: "
            f"{sorted(opts)}"
        )
    if profile not in ("spline", "erfc"):
        raise ConfigurationError(
            f"disk_fit: profile={profile!r}; expected 'spline' (fitted radial profile) or "
            "'erfc' (the erfc edge only)."
        )
    return {**opts, **detect}


#: Single-spot estimators by name (the ``method=`` of :func:`locate`).
METHODS: dict[str, Callable[..., Centroid]] = {
    "threshold": threshold_window,
    "projection": projection_window,
    "tight": tight_window,
    "fit": disk_fit,
}

#: For each method of :data:`METHODS`, the estimator of every spot of a multi-hole frame
#: (:func:`sunlab.centroid.locate_spots`, ``locate(..., method)`` on a cube with holes): the
#: tight window and the disk fit measure each spot in its own window; the paper's algorithms A
#: and B, whose threshold scan and profiles span the whole frame, cannot separate 100 spots, so
#: they give each spot the tight window. The values are the per-spot estimators.
PER_SPOT: dict[str, str] = {
    "threshold": "tight",
    "projection": "tight",
    "tight": "tight",
    "fit": "fit",
}
