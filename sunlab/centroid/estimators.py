"""Single-spot estimators: the paper's algorithms A and B, the tight window and the disk fit.

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

from collections.abc import Callable

import numpy as np

from ..errors import ConfigurationError
from . import _k_aperture, _k_windows
from ._detection import _aperture_window, _background_band, _detect, _first_radius
from ._diskfit import _fit_from
from ._local import _local_centroid
from .moments import SpotMoments
from .result import (
    _INVALID,
    _NO_SPOT,
    _OK,
    _REPAIRED,
    Centroid,
    _all_zero,
    _fail,
    _full_scale,
    _prepare,
    _repair_hot,
    _status,
)

__all__ = [
    "METHODS",
    "threshold_window",
    "projection_window",
    "tight_window",
    "disk_fit",
    "border_mean",
    "first_hit",
    "projection_profiles",
]


# ------------------------------------------------------------------------------------------------
# Algorithm A
# ------------------------------------------------------------------------------------------------
def threshold_window(
    frame, *, border: int = 2, factor: float = 3.0, test_size: int = 5, test_count: int = 18,
    roi_size: int = 130, roi_border: int = 2, saturation: float | None = None,
    check_ambiguous: bool = True,
) -> Centroid:
    """Algorithm A: threshold, first-hit test window, fixed ROI, centre of mass (paper sec. 3).

    The steps, exactly as the paper lists them (defaults are the paper's values):

    1. ``I_m`` = mean of the ``border`` (2) outermost rows and columns of the frame (each pixel
       counted once); noise threshold ``T = factor * I_m`` (3 I_m).
    2. Raster-scan the inner frame (rows and columns 1 .. n-2, i.e. 1022 x 1278) for a pixel
       ``> T``; it is the spot if at least ``test_count`` (18) of the ``test_size`` x
       ``test_size`` (5 x 5) pixels centred on it are ``> T`` (pixels outside the frame count as
       below); otherwise keep scanning.
    3. Take the ``roi_size`` x ``roi_size`` (130 x 130) region of interest centred on that pixel
       (rows ``r - 65 .. r + 64``: an even size has no centre pixel, the extra row and column go
       before it).
    4. New threshold ``T'`` = mean of the ``roi_border`` (2) outermost rows and columns of the ROI.
    5. In the inner (128 x 128) part of the ROI, pixels ``<= T'`` become 0, the others
       ``I - T'``; the centroid is their centre of mass, eq. (2).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    border : int
        Width of the frame border that gives ``I_m``, px.
    factor : float
        Noise threshold as a multiple of ``I_m``.
    test_size, test_count : int
        Side of the test window, px, and how many of its pixels must exceed the threshold.
    roi_size : int
        Side of the region of interest, px.
    roi_border : int
        Width of the ROI border that gives the second threshold, px; the centroid uses the ROI
        without a 1-px frame (the inner ``roi_size - 2``).
    saturation : float
        Full-scale value, DN: a pixel at or above it in the window flags ``saturated``.
    check_ambiguous : bool
        Continue the scan outside the ROI; a second qualifying pixel flags ``ambiguous``.

    Returns
    -------
    Centroid
        ``window`` is the inner ROI. ``clipped`` when the ROI had to be cut at the frame edge.

    Notes
    -----
    Centre of mass, eq. (2):

    .. math:: x_c = \\frac{\\sum_i x_i I_i}{\\sum_i I_i}, \\qquad
              y_c = \\frac{\\sum_i y_i I_i}{\\sum_i I_i}

    The ROI is centred on the first pixel found, i.e. on the top edge of the spot, not on its
    centre (the weakness the paper names); positive noise above ``T'`` over the 128 x 128 window
    then pulls the estimate toward the window centre, up to a few tenths of a pixel at the
    paper's SNR. The scan is a compiled raster loop; it stops at the first hit (or scans the rest
    of the frame outside the ROI when ``check_ambiguous``).

    References
    ----------
    docs/paper.md sec. 3, algorithm A.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = threshold_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.status_name
    (200.5, 150.0, 'ok')
    """
    saturation = _full_scale(frame, saturation)
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    return _algorithm_a(arr, int(border), factor, int(test_size), int(test_count),
                        int(roi_size), int(roi_border), saturation, check_ambiguous)


def _algorithm_a(arr, border, factor, test_size, test_count, roi_size, roi_border, saturation,
                 check_ambiguous) -> Centroid:
    """Steps 1-2 of :func:`threshold_window` on a prepared frame, then its ROI's centroid."""
    ny, nx = arr.shape
    thr = factor * _k_windows.ring_mean(arr, 0, ny, 0, nx, border)
    test = (test_size // 2, test_count)
    r, c = _k_windows.scan_first(arr, thr, *test, 1, ny - 1, 1, nx - 1, 0, 0, 0, 0)
    if r < 0:
        return _fail(_INVALID if _all_zero(arr) else _NO_SPOT)
    roi, clipped = _roi(r, c, roi_size, ny, nx)
    ambiguous = False
    if check_ambiguous:
        ambiguous = _k_windows.scan_first(arr, thr, *test, 1, ny - 1, 1, nx - 1, *roi)[0] >= 0
    return _roi_centroid(arr, roi, roi_border, saturation, clipped, ambiguous)


def _roi(r, c, size, ny, nx):
    """Step 3 of algorithm A: the ``size`` x ``size`` ROI about the first hit (r, c), as rows
    and columns ``(r0, r1, c0, c1)`` cut at the frame edge, and whether it was cut."""
    h0 = size // 2
    rr0, rr1, cc0, cc1 = r - h0, r - h0 + size, c - h0, c - h0 + size
    clipped = rr0 < 0 or cc0 < 0 or rr1 > ny or cc1 > nx
    return (max(rr0, 0), min(rr1, ny), max(cc0, 0), min(cc1, nx)), clipped


def _roi_centroid(arr, roi, roi_border, saturation, clipped, ambiguous) -> Centroid:
    """Steps 4-5 of algorithm A: the ROI border's mean as the new threshold, then the centre
    of mass of the pixels above it in the inner ROI (hot pixels repaired)."""
    rr0, rr1, cc0, cc1 = roi
    thr2 = _k_windows.ring_mean(arr, rr0, rr1, cc0, cc1, roi_border)
    ir0, ir1, ic0, ic1 = rr0 + 1, rr1 - 1, cc0 + 1, cc1 - 1
    s, x, y, vmax = _k_windows.com_above(arr, ir0, ir1, ic0, ic1, thr2)
    if not s > 0:
        return _fail(_NO_SPOT)
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, (ic0, ic1, ir0, ir1), thr2, s, x, y,
                                                saturation, threshold=True)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous)
    if status == _OK and n_hot:
        status = _REPAIRED
    return Centroid(float(x), float(y), float(s), (ic0, ic1, ir0, ir1), status)


# ------------------------------------------------------------------------------------------------
# Algorithm B
# ------------------------------------------------------------------------------------------------
def _robust_level(p: np.ndarray) -> tuple[float, float]:
    med, noise = _k_windows.robust_level(p)
    return float(med), float(noise)


def _zones(p, base, sigma, nsigma, edge_sigma, min_width):
    """Signal zones of a profile: runs above base + nsigma sigma (at least ``min_width`` long),
    widened while above base + edge_sigma sigma. Returns a list of (lo, hi, excess), hi
    exclusive, brightest first."""
    ex = p - base
    floor = max(sigma, 1e-9 * max(abs(base), 1.0))
    above = ex > nsigma * floor
    if not above.any():
        return []
    d = np.diff(above.astype(np.int8), prepend=0, append=0)
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1)
    keep = ends - starts >= min_width
    if not keep.any():
        return []
    weak = ex > edge_sigma * floor
    out = []
    n = p.size
    for a, b in zip(starts[keep], ends[keep], strict=True):
        lo, hi = int(a), int(b)
        while lo > 0 and weak[lo - 1]:
            lo -= 1
        while hi < n and weak[hi]:
            hi += 1
        out.append((lo, hi, float(ex[lo:hi].sum())))
    # Hysteresis can merge runs; keep distinct zones only.
    merged: list[tuple[int, int, float]] = []
    for z in sorted(out):
        if merged and z[0] < merged[-1][1]:
            continue
        merged.append(z)
    return sorted(merged, key=lambda z: -z[2])


def projection_window(
    frame, *, nsigma: float = 5.0, edge_sigma: float = 1.0, margin: int = 3, min_width: int = 3,
    subtract_background: bool = True, ambiguity_ratio: float = 0.1,
    saturation: float | None = None,
) -> Centroid:
    """Algorithm B: window from the row and column projection profiles (the paper's method).

    1. Column profile ``P_x[i]`` = sum of column ``i``; row profile ``P_y[j]`` = sum of row ``j``.
    2. In each profile, the integral noise level is its median (the spot covers a few percent of
       the columns and rows, so the median is a profile element without spot light) and the noise
       is ``1.4826 * MAD`` of the profile (robust standard deviation).
    3. Signal zone: runs of at least ``min_width`` elements above ``median + nsigma * noise``;
       each run is widened outward while the profile stays above ``median + edge_sigma *
       noise`` (hysteresis, so the zone reaches the spot's faint edge), then by ``margin`` px.
       The zone of the largest integrated excess is the spot; another zone with at least
       ``ambiguity_ratio`` of its excess flags ``ambiguous``. Runs shorter than ``min_width``
       (hot pixels, single bright columns) are ignored.
    4. Window = intersection of the column zone and the row zone; centroid = centre of mass
       inside it, eq. (2), of ``I - b`` where ``b`` is the per-pixel background implied by the
       profile levels, ``b = (median(P_x) / rows + median(P_y) / columns) / 2``.

    The paper leaves the noise level, the zone bounds and the background open; steps 2–4 above
    are this project's choices. ``subtract_background=False`` gives the literal eq. (2) on raw
    intensities (biased toward the window centre by the background).

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    nsigma : float
        Detection level of a zone, in units of the profile noise.
    edge_sigma : float
        Level down to which a zone is widened, in units of the profile noise.
    margin : int
        Extra pixels added on each side of the zone.
    min_width : int
        Shortest run, px, that counts as a spot.
    subtract_background : bool
        Subtract the profile-derived background before the centre of mass.
    ambiguity_ratio : float
        A second zone with at least this fraction of the main zone's excess flags ``ambiguous``.
    saturation : float, optional
        Full-scale value, DN: a pixel at or above it is clipped. Default: the full scale of
        the frame's integer type (255 for uint8, 65535 for uint16; none for float frames);
        pass ``2**bit_depth - 1`` for an ADC narrower than its word (``locate`` does).

    Returns
    -------
    Centroid
        ``clipped`` when the window touches the frame edge.

    Notes
    -----
    Centre of mass inside the window, eq. (2). One compiled pass over the frame builds both
    profiles.

    References
    ----------
    docs/paper.md sec. 3, algorithm B.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:300, 0:400]
    >>> frame = (30 + 400 * (np.hypot(xx - 200.5, yy - 150.0) < 17.5)).astype(np.uint16)
    >>> c = projection_window(frame)
    >>> round(c.x, 3), round(c.y, 3), c.window
    (200.5, 150.0, (181, 221, 130, 171))
    """
    saturation = _full_scale(frame, saturation)
    arr, usable = _prepare(frame)
    if not usable:
        return _fail(_INVALID)
    return _algorithm_b(arr, nsigma, edge_sigma, margin, min_width, subtract_background,
                        ambiguity_ratio, saturation)


def _algorithm_b(arr, nsigma, edge_sigma, margin, min_width, subtract_background,
                 ambiguity_ratio, saturation) -> Centroid:
    """Steps 1-4 of :func:`projection_window` on a prepared frame."""
    ny, nx = arr.shape
    px, py = _k_windows.profiles(arr)
    bx, sx = _robust_level(px)
    by, sy = _robust_level(py)
    zx = _zones(px, bx, sx, nsigma, edge_sigma, min_width)
    zy = _zones(py, by, sy, nsigma, edge_sigma, min_width)
    if not zx or not zy:
        return _fail(_INVALID if (px.max() == 0) else _NO_SPOT)
    ambiguous = any(len(z) > 1 and z[1][2] >= ambiguity_ratio * z[0][2] for z in (zx, zy))
    bkg = 0.5 * (bx / ny + by / nx) if subtract_background else 0.0
    n_zones = 2 if ambiguous else 1
    s, x, y, vmax, window, clipped = _brightest_window(arr, zx[:n_zones], zy[:n_zones], margin,
                                                       bkg)
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, window, bkg, s, x, y, saturation)
    if not s > 0:
        return _fail(_NO_SPOT)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous)
    if status == _OK and n_hot:
        status = _REPAIRED
    return Centroid(float(x), float(y), float(s), window, status)


def _brightest_window(arr, zx, zy, margin, bkg):
    """Step 4 of algorithm B: of the windows of every pairing of a column zone and a row zone
    (each widened by ``margin``), the one whose centre of mass of ``I - bkg`` holds the most
    flux (with several zones the brightest column zone and row zone may belong to different
    spots). Returns (sum, x, y, peak, window (x0, x1, y0, y1), clipped)."""
    ny, nx = arr.shape
    best = None
    for a in zx:
        for b in zy:
            x0, x1 = a[0] - margin, a[1] + margin
            y0, y1 = b[0] - margin, b[1] + margin
            clipped = x0 <= 0 or y0 <= 0 or x1 >= nx or y1 >= ny
            x0, x1, y0, y1 = max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)
            s, x, y, vmax = _k_windows.com_box(arr, y0, y1, x0, x1, bkg)
            if best is None or s > best[0]:
                best = (s, x, y, vmax, (x0, x1, y0, y1), clipped)
    return best


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
        Model fitted to the ring: a constant (compiled, fastest) or a plane.

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
        return _fail(_INVALID if det.sample_max == 0 and _all_zero(arr) else _NO_SPOT), None
    order = np.argsort(-det.flux)
    k = order[0]
    ambiguous = det.count.size > 1 and det.flux[order[1]] >= ambiguity_ratio * det.flux[k]
    r0 = _first_radius(det.count[k : k + 1], stride, margin)
    lo, hi = _background_band(det)
    m = SpotMoments(*_k_aperture.measure_spots(
        arr, det.x[k : k + 1], det.y[k : k + 1], r0, float(margin), float(annulus), lo, hi,
        int(n_iter), float(saturation))[0])
    if not m.flux > 0:
        return _fail(_NO_SPOT), None
    ny, nx = arr.shape
    x, y, r_ap, flux = float(m.x), float(m.y), float(m.r_ap), float(m.flux)
    n_hot, saturated = 0, m.nsat > 0
    if background == "plane" or saturated:  # the NumPy pass: plane, hot pixels repaired
        local = _local_centroid(arr, x, y, r_ap, annulus, n_iter, saturation,
                                background == "plane")
        if not local[3] and local[4] and background != "plane":
            local = (flux, x, y, 0, True)  # the spot saturates: the compiled values stand
        flux, x, y, n_hot, saturated = local
        if not flux > 0:
            return _fail(_NO_SPOT), None
    window, clipped = _aperture_window(x, y, r_ap, nx, ny)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous)
    if status == _OK and n_hot:
        status = _REPAIRED
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
    opts.update(detect)
    return opts


# ------------------------------------------------------------------------------------------------
# The algorithms' steps, one by one (for teaching: notebook 02)
# ------------------------------------------------------------------------------------------------
def border_mean(frame, width: int = 2) -> float:
    """Mean of the ``width`` outermost rows and columns of a frame, each pixel counted once.

    Step 1 of algorithm A (:func:`threshold_window`): ``I_m``, whose multiple is the noise
    threshold.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    width : int
        Rows and columns taken from each edge, px (2 in the paper).

    Returns
    -------
    float
        The mean, DN.

    Examples
    --------
    >>> import numpy as np
    >>> frame = np.full((10, 12), 30, np.uint16)
    >>> frame[4:6, 5:7] = 500
    >>> border_mean(frame)
    30.0
    """
    arr, _ = _prepare(frame)
    ny, nx = arr.shape
    return float(_k_windows.ring_mean(arr, 0, ny, 0, nx, int(width)))


def first_hit(frame, threshold: float, *, test_size: int = 5,
              test_count: int = 18) -> tuple[int, int]:
    """Row and column of the first pixel of a raster scan that passes algorithm A's test.

    Step 2 of :func:`threshold_window`: scanning the frame without its outermost rows and
    columns, the first pixel above ``threshold`` of whose ``test_size`` x ``test_size``
    neighbourhood at least ``test_count`` pixels are above it. ``(-1, -1)`` when none.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.
    threshold : float
        Noise threshold T, DN (``3 I_m`` in the paper, :func:`border_mean`).
    test_size : int
        Side of the test window centred on the candidate pixel, px (5 in the paper).
    test_count : int
        Pixels of the test window that must exceed ``threshold`` (18 of 25 in the paper).

    Returns
    -------
    (int, int)
        Row and column of the first qualifying pixel, px; ``(-1, -1)`` when none qualifies.

    Examples
    --------
    >>> import numpy as np
    >>> yy, xx = np.mgrid[0:100, 0:120]
    >>> frame = (30 + 400 * (np.hypot(xx - 60, yy - 50) < 10)).astype(np.uint16)
    >>> first_hit(frame, 90.0)
    (42, 57)
    """
    arr, _ = _prepare(frame)
    ny, nx = arr.shape
    r, c = _k_windows.scan_first(arr, float(threshold), int(test_size) // 2, int(test_count), 1,
                                 ny - 1, 1, nx - 1, 0, 0, 0, 0)
    return int(r), int(c)


def projection_profiles(frame) -> tuple[np.ndarray, np.ndarray]:
    """Column profile ``P_x`` (sum of each column) and row profile ``P_y`` (sum of each row).

    Step 1 of algorithm B (:func:`projection_window`), in one compiled pass over the frame.

    Parameters
    ----------
    frame : array_like, shape (rows, columns)
        One detector frame, DN.

    Returns
    -------
    P_x : numpy.ndarray, shape (columns,)
        Sum of each column, DN.
    P_y : numpy.ndarray, shape (rows,)
        Sum of each row, DN.

    Examples
    --------
    >>> import numpy as np
    >>> px, py = projection_profiles(np.arange(6).reshape(2, 3))
    >>> px.tolist(), py.tolist()
    ([3.0, 5.0, 7.0], [3.0, 12.0])
    """
    arr, _ = _prepare(frame)
    return _k_windows.profiles(arr)


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
