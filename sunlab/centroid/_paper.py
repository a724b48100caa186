"""The paper's two algorithms, A (threshold + fixed window) and B (projection-profile window),
and their steps one by one (for teaching: notebook 02), in numpy (private to
:mod:`sunlab.centroid`, which exports them).

Examples
--------
>>> import numpy as np
>>> yy, xx = np.mgrid[0:200, 0:240]
>>> frame = (30 + 400 * (np.hypot(xx - 120.5, yy - 90.0) < 17.5)).astype(np.uint16)
>>> round(projection_window(frame).x, 2), round(threshold_window(frame).y, 2)
(120.5, 90.0)
"""

from __future__ import annotations

import numpy as np

from .result import (
    _INVALID,
    _NO_SPOT,
    Centroid,
    _fail,
    _full_scale,
    _prepare,
    _repair_hot,
    _status,
)

__all__ = [
    "threshold_window",
    "projection_window",
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
    paper's SNR. The scan tests the pixels above ``T`` in raster order; it stops at the first hit
    (or tests the rest of the frame outside the ROI when ``check_ambiguous``).

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
    thr = factor * _ring_mean(arr, 0, ny, 0, nx, border)
    test = (test_size // 2, test_count)
    hits = np.flatnonzero(arr > thr)
    r, c = _scan_first(arr, thr, *test, (1, ny - 1, 1, nx - 1), hits=hits)
    if r < 0:
        return _fail(_NO_SPOT if arr.any() else _INVALID)
    # step 3: the roi_size x roi_size ROI about the first hit, cut at the frame edge
    h0 = roi_size // 2
    rr0, rr1, cc0, cc1 = r - h0, r - h0 + roi_size, c - h0, c - h0 + roi_size
    clipped = rr0 < 0 or cc0 < 0 or rr1 > ny or cc1 > nx
    rr0, rr1, cc0, cc1 = max(rr0, 0), min(rr1, ny), max(cc0, 0), min(cc1, nx)
    ambiguous = False
    if check_ambiguous:
        ambiguous = _scan_first(arr, thr, *test, (1, ny - 1, 1, nx - 1), (rr0, rr1, cc0, cc1),
                                hits)[0] >= 0
    # steps 4-5: the ROI border's mean as the new threshold, then the centre of mass of the
    # pixels above it in the inner ROI (hot pixels repaired)
    thr2 = _ring_mean(arr, rr0, rr1, cc0, cc1, roi_border)
    ir0, ir1, ic0, ic1 = rr0 + 1, rr1 - 1, cc0 + 1, cc1 - 1
    s, x, y, vmax = _box_com(arr, ir0, ir1, ic0, ic1, thr2, above=True)
    if not s > 0:
        return _fail(_NO_SPOT)
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, (ic0, ic1, ir0, ir1), thr2, s, x, y,
                                                saturation, threshold=True)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous,
                     repaired=n_hot > 0)
    return Centroid(float(x), float(y), float(s), (ic0, ic1, ir0, ir1), status)


# ------------------------------------------------------------------------------------------------
# Algorithm B
# ------------------------------------------------------------------------------------------------
def _robust_level(p: np.ndarray) -> tuple[float, float]:
    """Median of a profile and 1.4826 x its median absolute deviation."""
    med = float(np.median(p))
    return med, 1.4826 * float(np.median(np.abs(p - med)))


def _zones(p, base, sigma, nsigma, edge_sigma, min_width):
    """Signal zones of a profile: runs above base + nsigma sigma (at least ``min_width`` long),
    widened while above base + edge_sigma sigma (hysteresis: the runs of that weaker level
    holding such a run). Returns a list of (lo, hi, excess), hi exclusive, brightest first."""
    ex = p - base
    floor = max(sigma, 1e-9 * max(abs(base), 1.0))
    s0, s1 = _runs(ex > nsigma * floor)
    w0, w1 = _runs(ex > min(edge_sigma, nsigma) * floor)
    held = np.unique(np.searchsorted(w0, s0[s1 - s0 >= min_width], "right") - 1)
    zones = [(int(w0[k]), int(w1[k]), float(ex[w0[k]:w1[k]].sum())) for k in held]
    return sorted(zones, key=lambda z: -z[2])


def _runs(mask):
    """Starts and (exclusive) ends of the runs of True in a 1-D boolean array."""
    edges = np.flatnonzero(np.diff(mask, prepend=False, append=False))
    return edges[::2], edges[1::2]


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
    Centre of mass inside the window, eq. (2). The profiles are a row and a column sum.

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
    px, py = _profiles(arr)
    bx, sx = _robust_level(px)
    by, sy = _robust_level(py)
    zx = _zones(px, bx, sx, nsigma, edge_sigma, min_width)
    zy = _zones(py, by, sy, nsigma, edge_sigma, min_width)
    if not zx or not zy:
        return _fail(_INVALID if (px.max() == 0) else _NO_SPOT)
    ambiguous = any(len(z) > 1 and z[1][2] >= ambiguity_ratio * z[0][2] for z in (zx, zy))
    bkg = 0.5 * (bx / ny + by / nx) if subtract_background else 0.0
    n_zones = 2 if ambiguous else 1
    # step 4: of the windows of every pairing of a column zone and a row zone (each widened by
    # margin), the one whose centre of mass of I - bkg holds the most flux (with several zones
    # the brightest column zone and row zone may belong to different spots)
    best = None
    for a in zx[:n_zones]:
        for b in zy[:n_zones]:
            x0, x1 = a[0] - margin, a[1] + margin
            y0, y1 = b[0] - margin, b[1] + margin
            clipped = x0 <= 0 or y0 <= 0 or x1 >= nx or y1 >= ny
            x0, x1, y0, y1 = max(x0, 0), min(x1, nx), max(y0, 0), min(y1, ny)
            s, x, y, vmax = _box_com(arr, y0, y1, x0, x1, bkg)
            if best is None or s > best[0]:
                best = (s, x, y, vmax, (x0, x1, y0, y1), clipped)
    s, x, y, vmax, window, clipped = best
    n_hot, saturated = 0, False
    if vmax >= saturation:
        s, x, y, n_hot, saturated = _repair_hot(arr, window, bkg, s, x, y, saturation)
    if not s > 0:
        return _fail(_NO_SPOT)
    status = _status(clipped=clipped, saturated=saturated, ambiguous=ambiguous,
                     repaired=n_hot > 0)
    return Centroid(float(x), float(y), float(s), window, status)


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
    return float(_ring_mean(arr, 0, ny, 0, nx, int(width)))


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
    r, c = _scan_first(arr, float(threshold), int(test_size) // 2, int(test_count),
                       (1, ny - 1, 1, nx - 1))
    return int(r), int(c)


def projection_profiles(frame) -> tuple[np.ndarray, np.ndarray]:
    """Column profile ``P_x`` (sum of each column) and row profile ``P_y`` (sum of each row).

    Step 1 of algorithm B (:func:`projection_window`).

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
    return _profiles(arr)




# ------------------------------------------------------------------------------------------------
# The numpy passes both algorithms share
# ------------------------------------------------------------------------------------------------
def _ring_mean(arr, r0, r1, c0, c1, w):
    """Mean of the ``w`` outermost rows and columns of arr[r0:r1, c0:c1] (each pixel once)."""
    box = arr[r0:r1, c0:c1]
    h, wd = box.shape
    if 2 * w >= min(h, wd):
        return float(box.mean(dtype=np.float64)) if box.size and w > 0 else np.nan
    parts = (box[:w], box[h - w:], box[w:h - w, :w], box[w:h - w, wd - w:])
    n = sum(p.size for p in parts)
    return sum(float(p.sum(dtype=np.float64)) for p in parts) / n if n else np.nan


def _scan_first(arr, thr, half, need, box, excl=(0, 0, 0, 0), hits=None):
    """Raster scan of the ``box`` (r0, r1, c0, c1) for the first pixel above ``thr`` whose
    (2 half + 1)^2 neighbourhood holds at least ``need`` pixels above ``thr`` (pixels outside
    the frame count as below), skipping the pixels of the box ``excl``; ``hits`` the flat
    indices of the frame's pixels above ``thr`` when known. Returns (row, col), or (-1, -1)."""
    ny, nx = arr.shape
    r, c = np.divmod(np.flatnonzero(arr > thr) if hits is None else hits, nx)
    r0, r1, c0, c1 = box
    e0, e1, f0, f1 = excl
    sel = (r >= r0) & (r < r1) & (c >= c0) & (c < c1)
    sel &= ~((r >= e0) & (r < e1) & (c >= f0) & (c < f1))
    r, c = r[sel], c[sel]
    d = np.arange(-half, half + 1)
    for k in range(0, r.size, 2048):  # in chunks: the first qualifying pixel is usually early
        rr, cc = r[k:k + 2048, None, None] + d[:, None], c[k:k + 2048, None, None] + d
        inside = (rr >= 0) & (rr < ny) & (cc >= 0) & (cc < nx)
        n = (inside & (arr[np.clip(rr, 0, ny - 1), np.clip(cc, 0, nx - 1)] > thr)).sum((1, 2))
        q = np.flatnonzero(n >= need)
        if q.size:
            return int(r[k + q[0]]), int(c[k + q[0]])
    return -1, -1


def _box_com(arr, r0, r1, c0, c1, level, above=False):
    """Centre of mass of ``I - level`` over arr[r0:r1, c0:c1] (with ``above``, over its pixels
    above ``level`` only). Returns (sum, x, y, max I); x, y NaN when the sum is not positive."""
    box = arr[r0:r1, c0:c1].astype(np.float64)
    w = box - level
    if above:
        w[box <= level] = 0.0
    s = float(w.sum())
    vmax = float(box.max()) if box.size else -np.inf
    if not s > 0:
        return s, np.nan, np.nan, vmax
    return s, w.sum(0) @ np.arange(c0, c1) / s, w.sum(1) @ np.arange(r0, r1) / s, vmax


def _profiles(arr):
    """Column and row sums of a prepared frame (uint16: exact integer sums), float64."""
    acc = np.float64 if arr.dtype.kind == "f" else np.uint32 if max(arr.shape) <= 65536 else \
        np.uint64
    return (np.add.reduce(arr, 0, dtype=acc).astype(np.float64),
            np.add.reduce(arr, 1, dtype=acc).astype(np.float64))
