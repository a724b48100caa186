"""Defects of a multi-hole mask: per-hole metrics and the rejection of bad holes (Fig. 14).

"Bad" holes (dust, burrs, misshapen or partly closed holes) spoil the average of sec. 6. Every
hole is scored by metrics that are large for a bad hole (``DEFECT_METRICS``): from its spots
(lost frames, flux, size, shape: :func:`stamp_metrics`, :func:`edge_roughness`) and from its
calibration residuals (:func:`residual_metrics`); :func:`defect_metrics` gathers them,
:func:`robust_z` scores them against the fleet and :func:`reject_bad_holes` flags the outliers.

References
----------
.. [1] docs/paper.md, sec. 6 and Fig. 14 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence

import numpy as np
import xarray as xr

from .. import centroid, schema
from ..errors import ConfigurationError
from .holes import cutout, usable
from .strategies import PerHoleAverage

__all__ = ["defect_metrics", "robust_z", "reject_bad_holes", "metric_scale"]


#: Defect metrics (name -> meaning); large values are bad for every one of them.
DEFECT_METRICS: dict[str, str] = {
    "missing_fraction": "fraction of frames where the hole's spot is lost (no_spot, ambiguous)",
    "flux_deficit": "1 - (hole flux / median hole flux in the same frame), median over frames",
    "size_deficit": "1 - (spot RMS radius / median spot RMS radius)",
    "ellipticity": "(l1 - l2) / (l1 + l2) of the spot's second-moment matrix",
    "asymmetry": "third-moment (coma-like) asymmetry of the spot, |m3| / r^3",
    "edge_roughness": "angular harmonics 2-6 of the hole's mean spot minus the mask's median "
                      "spot (burrs, misshapen holes), relative to the mask's typical level",
    "residual_rms": "RMS of the hole's calibration residual against the commanded angles, deg",
    "scatter": "RMS of the hole's angle estimate minus the consensus of all holes, deg",
    "outlier_fraction": "fraction of frames where the hole departs from the consensus by > 5 sigma",
}


def stamp_metrics(cube: xr.Dataset, cen: xr.Dataset, *, poses=None, shot: int = 0,
                 half: int = 30, max_frames: int = 6) -> xr.Dataset:
    """Shape metrics of every hole's spot from its pixels: size, ellipticity, asymmetry.

    A stamp of ``2 * half + 1`` px is cut around each centroid in a few frames, the background
    (median of the stamp border) subtracted and pixels under 10 % of the peak zeroed; the
    moments give the RMS radius r, the ellipticity (l1 - l2) / (l1 + l2) of the second-moment
    matrix and the asymmetry ``|m3| / r^3`` from the third moments (zero for a round or
    elliptical spot; a hole partly covered by dust gives a lopsided spot). Medians over the
    frames are returned.

    Parameters
    ----------
    cube : xarray.Dataset
        Frame cube (contract ``frames/1``).
    cen : xarray.Dataset
        Its centroid table on (pose, shot, hole).
    poses : sequence of int, optional
        Poses to sample (default ``max_frames`` evenly spread).
    shot : int
        Shot to use.
    half : int
        Half-size of the stamp, px (a spot is about 35 px across on the paper bench).
    max_frames : int
        Number of poses sampled when ``poses`` is not given.

    Returns
    -------
    xarray.Dataset on ``hole``: ``radius`` (px), ``ellipticity``, ``asymmetry``.

    Examples
    --------
    >>> from sunlab import schema
    >>> yy, xx = np.indices((100, 160))
    >>> frame = 500.0 * ((xx - 40) ** 2 + (yy - 50) ** 2 < 15**2)      # a round spot
    >>> frame += 500.0 * ((xx - 120) ** 2 + (yy - 50) ** 2 < 15**2) * ~((xx > 126) & (yy < 50))
    >>> cube = schema.frames_dataset(frame.astype(np.uint16)[None, None], alpha=[0.0], beta=[0.0])
    >>> cen = schema.centroids_dataset([[[40.0, 118.0]]], [[[50.0, 51.0]]])
    >>> m = stamp_metrics(cube, cen)
    >>> bool(m.asymmetry[1] > 5 * m.asymmetry[0] and m.ellipticity[1] > m.ellipticity[0])
    True
    """
    n_p = cube.sizes["pose"]
    if poses is None:
        poses = np.unique(np.linspace(0, n_p - 1, min(max_frames, n_p)).round().astype(int))
    n_h = cen.sizes["hole"]
    res = np.full((len(poses), n_h, 3), np.nan)
    ok = usable(cen).values
    for n, (p, frame) in enumerate(_frames_of(cube, poses, shot)):
        for h in range(n_h):
            if not ok[p, shot, h]:
                continue
            st, _ = cutout(frame, cen["x"].values[p, shot, h], cen["y"].values[p, shot, h], half)
            res[n, h] = centroid.stamp_moments(st)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        med = np.nanmedian(res, axis=0)
    return xr.Dataset(
        {"radius": ("hole", med[:, 0], {"units": "px"}), "ellipticity": ("hole", med[:, 1]),
         "asymmetry": ("hole", med[:, 2])},
        coords={"hole": cen["hole"].values},
    )


def edge_roughness(cube: xr.Dataset, cen: xr.Dataset, *, shot: int = 0, max_frames: int = 100,
                   harmonics: tuple[int, int] = (2, 6), radius_px: float | None = None
                   ) -> xr.DataArray:
    """Edge roughness of every hole's spot: what a burr leaves that the mask's other holes lack.

    All holes see the Sun from the same direction, so in one frame every good hole draws the same
    spot; a burred rim or a misshapen hole adds a shape of its own that stays with the hole from
    pose to pose, while pixel noise and pixel response change. For each sampled frame the stamps
    are resampled on a common grid centred on their centroids (cubic spline) and normalised to
    unit flux; the per-frame median stamp of all holes is subtracted; the residuals are averaged
    over the frames per hole (the hole's persistent shape residual). Its angular Fourier
    amplitudes ``|c_m|`` for m in ``harmonics`` (m = 0 is flux or size, m = 1 a centroid shift;
    m >= 2 an out-of-round edge) are divided by their median over the holes, and the metric is
    their RMS: about 1 for a typical hole, several for a burred one.

    Only low harmonics carry the burr: the spot is the hole convolved with the image of the
    Sun's disk (0.045 mm across at F = 5 mm, 0.15 mm at 17 mm), which smooths a rim
    ripple of harmonic k (wavelength 2 pi r0 / k, 0.1 mm at k = 6) away; higher harmonics add
    mostly pixel-response noise. On the paper bench (quick plan of experiment I, 100 poses) the
    burred holes 37 and 85 score robust z 7.8 and 13.4 with harmonics 2-6 over 100 frames, the
    good holes at most 2.8 (2-12 over 64 frames: 4.2, 9.1 and 2.0, so hole 37 went unflagged).

    Parameters
    ----------
    cube : xarray.Dataset
        Frame cube (contract ``frames/1``) of ``cen``.
    cen : xarray.Dataset
        Its centroid table on (pose, shot, hole), with ``status``.
    shot : int
        Shot used at each pose (frames of one pose share the pixel response).
    max_frames : int
        Poses sampled (evenly spread); the noise of the metric falls as 1 / sqrt(frames)
        (about 2 s per 100 frames of 100 holes, besides rendering or reading the frames).
    harmonics : (int, int)
        Lowest and highest angular harmonic (see above for why 2-6).
    radius_px : float, optional
        Radius of the stamp, px; default 2.1 times the median RMS spot radius of ``cen``
        (``radius``) or of the stamps, capped at 0.45 times the spacing of neighbouring spots.

    Returns
    -------
    xarray.DataArray on ``hole`` (dimensionless; NaN for a hole never seen whole).

    Examples
    --------
    >>> from sunlab import schema
    >>> yy, xx = np.indices((60, 200)).astype(float)
    >>> phi = np.arctan2(yy - 30, xx)
    >>> frames, xs = [], []
    >>> for dx in (0.0, 0.3, 0.6, 0.9):                        # four frames, spots moving in x
    ...     f = np.zeros_like(xx)
    ...     for k, x in enumerate((30.0, 70.0, 110.0, 150.0)):  # hole 2 has a wavy rim
    ...         r0 = 10.0 * (1 + (0.12 * np.cos(5 * np.arctan2(yy - 30, xx - x - dx))
    ...                       if k == 2 else 0))
    ...         f += 800.0 / (1 + np.exp((np.hypot(xx - x - dx, yy - 30) - r0) / 1.5))
    ...     frames.append(f)
    >>> cube = schema.frames_dataset(np.array(frames, np.uint16)[:, None], alpha=[0.0] * 4,
    ...                              beta=[0.0] * 4)
    >>> x = [[[30 + d, 70 + d, 110 + d, 150 + d]] for d in (0.0, 0.3, 0.6, 0.9)]
    >>> cen = schema.centroids_dataset(x, np.full((4, 1, 4), 30.0).tolist())
    >>> r = edge_roughness(cube, cen, radius_px=18)
    >>> int(np.argmax(r.values)), bool(r[2] > 3 * np.median(r))
    (2, True)
    """
    ok = usable(cen).values[:, shot, :]  # (pose, hole)
    xs, ys = cen["x"].values[:, shot, :], cen["y"].values[:, shot, :]
    poses = [p for p in range(cen.sizes["pose"]) if ok[p].sum() >= 3]
    if len(poses) > max_frames:
        poses = [poses[int(k)] for k in np.linspace(0, len(poses) - 1, max_frames).round()]
    if radius_px is None:
        radius_px = _roughness_radius(cube, cen, ok, poses, shot)
    value = np.full(cen.sizes["hole"], np.nan)
    if poses and np.isfinite(radius_px) and radius_px >= 3:
        amp = _harmonic_amplitudes(cube, ok, xs, ys, poses, shot, radius_px, harmonics)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            scale = np.nanmedian(amp, axis=0)
            value = np.sqrt(np.nanmean((amp / np.where(scale > 0, scale, np.nan)) ** 2, axis=1))
    return xr.DataArray(value, dims="hole", coords={"hole": cen["hole"].values},
                        name="edge_roughness")


def _roughness_radius(cube, cen, ok, poses, shot) -> float:
    """Default stamp radius of :func:`edge_roughness`: 2.1 RMS spot radii, at most 0.45 of the
    spacing of neighbouring spots."""
    xs, ys = cen["x"].values[:, shot, :], cen["y"].values[:, shot, :]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        r_rms = float(np.nanmedian(cen["radius"].where(usable(cen)).values)) \
            if "radius" in cen else np.nan
    if not np.isfinite(r_rms) and poses:
        frame = np.asarray(cube["frames"].isel(pose=poses[0], shot=shot).values)
        hs = np.flatnonzero(ok[poses[0]])[:10]
        r_rms = float(np.nanmedian([centroid.stamp_moments(cutout(frame, xs[poses[0], h],
                                                          ys[poses[0], h], 40)[0])[0]
                                    for h in hs]))
    radius_px = 2.1 * r_rms
    if poses:
        p0 = poses[0]
        hx, hy = xs[p0][ok[p0]], ys[p0][ok[p0]]
        d = np.hypot(hx[:, None] - hx[None], hy[:, None] - hy[None])
        d[d == 0] = np.inf
        radius_px = min(radius_px, 0.45 * float(np.median(d.min(1))))
    return radius_px


def _frames_of(cube, poses, shot, batch: int = 32):
    """(pose, frame) of the given poses at one shot, computed ``batch`` frames at a time: a
    lazy cube renders or reads a batch in parallel, in one request to its scheduler (each
    request pays the scheduler's start and, on a shared scheduler, waits behind the work
    already queued there), and memory stays bounded (32 full frames are 84 MB)."""
    poses = [int(p) for p in poses]
    for k in range(0, len(poses), batch):
        part = poses[k:k + batch]
        # the shot first: one pose list then indexes one axis (an outer index on two axes of an
        # in-memory cube copies the frames many times slower)
        block = np.asarray(cube["frames"].isel(shot=shot).isel(pose=part).values)
        yield from zip(part, block, strict=True)


def _harmonic_amplitudes(cube, ok, xs, ys, poses, shot, radius_px, harmonics):
    """|c_m| (hole, harmonic) of each hole's mean over ``poses`` of its unit-flux stamp minus
    the frame's median stamp (relative to its peak), on a ring of pixels; NaN for a hole never
    seen whole.

    The stamps of a frame are resampled all at once (:func:`_cubic_stamps`), to the same values
    as ``scipy.ndimage.map_coordinates(sub, ..., order=3, mode="nearest")`` on a sub-image around
    each centroid up to float rounding."""
    n_h = ok.shape[1]
    n_r = int(np.ceil(radius_px))
    g = np.arange(-n_r, n_r + 1, dtype=float)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    rr = np.hypot(gx, gy)
    disk = rr <= radius_px
    ring = (rr > 0.5) & disk
    theta = np.arctan2(gy, gx)[ring]
    acc = np.zeros((n_h, ring.sum()))
    count = np.zeros(n_h)
    for p, frame in _frames_of(cube, poses, shot):
        hs = np.flatnonzero(ok[p])
        st = _cubic_stamps(frame, xs[p, hs], ys[p, hs], n_r)  # (hole, y, x)
        edge = np.concatenate([st[:, 0], st[:, -1], st[:, :, 0], st[:, :, -1]], axis=1)
        st -= np.median(edge, axis=1)[:, None, None]
        total = st[:, disk].sum(axis=1)
        stamps = st[:, ring] / np.where(total > 0, total, np.nan)[:, None]
        good = np.isfinite(stamps).all(axis=1)
        if good.any() and np.isnan(stamps[~good]).all():
            # NaN only in whole stamps (no flux): the median of the others
            template = _median_of_rows(stamps[good])
        else:
            template = np.nanmedian(stamps, axis=0)
        peak = np.nanmax(template)
        acc[hs[good]] += (stamps[good] - template) / peak
        count[hs[good]] += 1
    mean_res = acc / np.maximum(count, 1)[:, None]
    m = np.arange(harmonics[0], harmonics[1] + 1)
    amp = np.abs(mean_res @ np.exp(-1j * m[None, :] * theta[:, None]))  # (hole, harmonic)
    amp[count == 0] = np.nan
    return amp


def _median_of_rows(a):
    """``np.median(a, axis=0)`` of a finite 2-D array, by a sort (several times faster than
    the partition of ``np.median`` along the first axis)."""
    a = np.sort(a, axis=0)
    k = len(a) // 2
    return a[k] if len(a) % 2 else (a[k - 1] + a[k]) / 2


#: Edge padding before the spline prefilter of boundary mode "nearest", as
#: ``scipy.ndimage.map_coordinates`` pads (its ``_prepad_for_spline_filter``).
_NEAREST_PREPAD = 12


def _cubic_stamps(frame, x, y, n_r):
    """Stamps (spot, 2 n_r + 1, 2 n_r + 1) of a frame on the pixel grid -n_r..n_r around each
    centroid (x, y), by cubic spline interpolation with boundary mode "nearest".

    Each spot's sub-image (``n_r + 4`` px around its rounded centroid, clipped at the frame's
    edge) is what ``map_coordinates`` is given; :func:`_spline_grid` resamples the equal-sized
    ones together, and those clipped at the frame's edge (other shapes) one at a time."""
    m = n_r + 4
    xi, yi = np.round(x).astype(int), np.round(y).astype(int)
    full = (yi >= m) & (xi >= m) & (yi + m < frame.shape[0]) & (xi + m < frame.shape[1])
    if full.any():
        windows = np.lib.stride_tricks.sliding_window_view(frame, (2 * m + 1, 2 * m + 1))
        y0, x0 = yi[full] - m, xi[full] - m
        st = _spline_grid(windows[y0, x0], y[full] - y0, x[full] - x0, n_r)
        if full.all():
            return st
    out = np.empty((x.size, 2 * n_r + 1, 2 * n_r + 1))
    if full.any():
        out[full] = st
    for j in np.flatnonzero(~full):
        y0, x0 = max(int(yi[j]) - m, 0), max(int(xi[j]) - m, 0)
        sub = frame[y0:int(yi[j]) + m + 1, x0:int(xi[j]) + m + 1]
        out[j] = _spline_grid(sub[None], y[j:j + 1] - y0, x[j:j + 1] - x0, n_r)[0]
    return out


def _spline_grid(subs, cy, cx, n_r):
    """``map_coordinates(sub, [cy + g, cx + g], order=3, mode="nearest")`` with g = -n_r..n_r
    on rows and columns, for each of the equal-sized ``subs`` (spot, y, x) at once.

    The prefilter is that of ``map_coordinates``: pad by the edge values, cubic B-spline filter
    along y, then x. The grid is a pixel grid shifted by the spot's sub-pixel offset, so the
    interpolation is separable, with the same 4 B-spline weights for every row (column) of a
    stamp: it runs along y, then x (on the taps of all spots: spots whose first taps differ by
    d cost d more taps, one at most for the sub-images of :func:`_cubic_stamps`)."""
    from scipy.ndimage import spline_filter1d

    pad = _NEAREST_PREPAD
    n, ly, lx = subs.shape
    n_g = 2 * n_r + 1
    # padded in y (an index clipped into the sub repeats the edge row) and filtered along y;
    # the columns padded in x repeat the edge column, and so do their filtered values: they are
    # added afterwards
    c = np.take(subs, np.clip(np.arange(-pad, ly + pad), 0, ly - 1), axis=1)
    c = spline_filter1d(c, 3, axis=1, output=np.float64, mode="nearest")
    # taps from the first of all spots on (a tap off the padded sub takes its edge: "nearest")
    y0, wy = _cubic_taps(cy - n_r + pad)
    x0, wx = _cubic_taps(cx - n_r + pad)
    rows = np.clip(y0 + np.arange(n_g + wy.shape[1] - 1), 0, ly + 2 * pad - 1)
    cols = np.clip(np.arange(-pad, lx + pad), 0, lx - 1)
    # only the rows that the taps reach are filtered along x (the filter runs row by row)
    c = np.take(np.take(c, rows, axis=1), cols, axis=2)
    c = spline_filter1d(c, 3, axis=2, output=np.float64, mode="nearest")
    c = np.take(c, np.clip(x0 + np.arange(n_g + wx.shape[1] - 1), 0, lx + 2 * pad - 1), axis=2)
    t = wy[:, 0, None, None] * c[:, :n_g]
    for k in range(1, wy.shape[1]):
        t += wy[:, k, None, None] * c[:, k:k + n_g]
    out = wx[:, 0, None, None] * t[:, :, :n_g]
    for k in range(1, wx.shape[1]):
        out += wx[:, k, None, None] * t[:, :, k:k + n_g]
    return out


def _cubic_taps(cc):
    """The cubic B-spline weights at coordinates ``cc`` (spot,), as ``scipy.ndimage`` computes
    them (``get_spline_interpolation_weights``), on taps common to all spots.

    Returns
    -------
    first : int
        First tap of all spots.
    weights : numpy.ndarray (spot, tap)
        A spot's 4 weights from its first tap ``floor(cc) - 1`` on, zero on the other taps.
    """
    f = np.floor(cc)
    y = cc - f
    z = 1.0 - y
    w = np.empty((cc.size, 4))
    w[:, 1] = (y * y * (y - 2.0) * 3.0 + 4.0) / 6.0
    w[:, 2] = (z * z * (z - 2.0) * 3.0 + 4.0) / 6.0
    w[:, 0] = z * z * z / 6.0
    w[:, 3] = 1.0 - w[:, 0] - w[:, 1] - w[:, 2]
    first = f.astype(int) - 1
    shift = first - first.min()
    out = np.zeros((cc.size, 4 + shift.max()))
    for a in range(4):
        out[np.arange(cc.size), shift + a] = w[:, a]
    return int(first.min()), out


def residual_metrics(est: xr.Dataset, kappa: float = 5.0) -> xr.Dataset:
    """Metrics of each hole from its calibration residuals.

    Parameters
    ----------
    est : xarray.Dataset
        Per-hole estimates on (pose, shot, hole) (:meth:`PerHoleAverage.predict_holes`) with the
        commanded angles ``alpha_cmd``, ``beta_cmd``.
    kappa : float
        Outlier threshold in robust standard deviations of the fleet's departures.

    Returns
    -------
    xarray.Dataset on ``hole``:
        ``residual_rms`` (RMS of estimate - commanded, both angles, deg): includes the
        platform's error, common to all holes; ``scatter`` (RMS of estimate - per-frame median
        of all holes, deg): the hole-specific part; ``outlier_fraction``.

    Examples
    --------
    >>> e = xr.Dataset({"alpha": (("pose", "shot", "hole"), [[[0.0, 0.01, 0.5]]] * 4),
    ...                 "beta": (("pose", "shot", "hole"), [[[0.0, 0.0, 0.0]]] * 4)},
    ...                coords={"alpha_cmd": ("pose", np.zeros(4)),
    ...                        "beta_cmd": ("pose", np.zeros(4))})
    >>> m = residual_metrics(e)
    >>> int(np.argmax(m.scatter.values))
    2
    """
    res2 = 0.0
    dev2 = 0.0
    devs = []
    for name in ("alpha", "beta"):
        cmd = xr.DataArray(est[f"{name}_cmd"].values, dims="pose")
        res2 = res2 + (est[name] - cmd) ** 2
        d = est[name] - est[name].median("hole")
        dev2 = dev2 + d**2
        devs.append(d)
    dims = ("pose", "shot")
    rms = np.sqrt(res2.mean(dims) / 2)
    scatter = np.sqrt(dev2.mean(dims) / 2)
    scale = 1.4826 * np.nanmedian(np.abs(np.stack([d.values for d in devs])))
    scale = max(scale, 1e-12)
    out = 0.0
    for d in devs:
        out = out + (np.abs(d) > kappa * scale).where(np.isfinite(d)).mean(dims)
    # trials behind each hole's fraction (frames x 2 angles): robust_z bounds the spread of the
    # fraction below by its binomial counting noise, so that one or two tail frames of a hole
    # seen in a few frames do not make it an outlier
    n_trials = float(np.nanmedian(sum(np.isfinite(d).sum(dims).values for d in devs)))
    return xr.Dataset(
        {"residual_rms": ("hole", rms.values, {"units": "deg"}),
         "scatter": ("hole", scatter.values, {"units": "deg"}),
         "outlier_fraction": ("hole", (out / 2).values, {"n_trials": n_trials})},
        coords={"hole": est["hole"].values},
    )


def defect_metrics(cen: xr.Dataset, *, strategy: PerHoleAverage | None = None, cube=None,
                   accept: Sequence[str] = ("ok",), **spot_kw) -> xr.Dataset:
    """All defect metrics of every hole (``DEFECT_METRICS``), large = bad.

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table on (pose, shot, hole), usually the training experiment.
    strategy : PerHoleAverage, optional
        A fitted per-hole calibration; gives the residual metrics.
    cube : xarray.Dataset, optional
        The frame cube of ``cen``; gives the spot-shape metrics (:func:`stamp_metrics`) and the
        edge roughness that finds burred holes (:func:`edge_roughness`). Without
        it they come from the per-spot ``radius``, ``ellipticity``, ``asymmetry`` of the table
        when :func:`sunlab.centroid.locate` measured them.
    accept : sequence of str
        Status codes counted as present.
    **spot_kw
        Passed to :func:`stamp_metrics`.

    Returns
    -------
    xarray.Dataset on ``hole`` with the hole coordinates.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=2, layout="grid",
    ...                           defects={7: {"flux": 0.4}})
    >>> m = defect_metrics(cen)
    >>> int(np.argmax(m.flux_deficit.values)), round(float(m.flux_deficit[7]), 2)
    (7, 0.6)
    """
    ok = usable(cen, accept)
    # a lost or confused spot counts against the hole; a spot off the detector edge (clipped)
    # or touched by a hot pixel at full scale (saturated) is geometry or detector, not the hole
    lost = cen["status"].isin([schema.STATUS["no_spot"], schema.STATUS["ambiguous"]])
    missing = lost.mean(("pose", "shot"))
    flux = cen["flux"].where(ok)
    rel = flux / flux.median("hole")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        deficit = 1.0 - rel.median(("pose", "shot"))
    data = {"missing_fraction": ("hole", missing.values), "flux_deficit": ("hole", deficit.values)}
    if cube is None and all(k in cen for k in ("radius", "ellipticity", "asymmetry")):
        # per-spot shape metrics measured by the centroiding step (sunlab.centroid.locate)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            shape = {k: cen[k].where(ok).median(("pose", "shot")).values
                     for k in ("radius", "ellipticity", "asymmetry")}
        data["size_deficit"] = ("hole", 1.0 - shape["radius"] / np.nanmedian(shape["radius"]))
        data["ellipticity"] = ("hole", shape["ellipticity"])
        data["asymmetry"] = ("hole", shape["asymmetry"])
    if cube is not None:
        sm = stamp_metrics(cube, cen, **spot_kw)
        r = sm["radius"].values
        data["size_deficit"] = ("hole", 1.0 - r / np.nanmedian(r))
        data["ellipticity"] = ("hole", sm["ellipticity"].values)
        data["asymmetry"] = ("hole", sm["asymmetry"].values)
        data["edge_roughness"] = ("hole", edge_roughness(cube, cen).values)
    if strategy is not None:
        rm = residual_metrics(strategy.predict_holes(cen))
        for k in rm.data_vars:
            data[k] = ("hole", rm[k].values, rm[k].attrs)
    coords = {"hole": cen["hole"].values}
    for c in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf"):
        if c in cen.coords:
            coords[c] = ("hole", cen[c].values)
    ds = xr.Dataset(data, coords=coords)
    for k in ds.data_vars:
        ds[k].attrs["long_name"] = DEFECT_METRICS[k]
    return ds


#: Absolute floors of the robust spread of each metric, so that a perfect fleet (spread 0)
#: does not flag holes for differences far below any physical effect.
_FLOORS = {"missing_fraction": 0.02, "flux_deficit": 0.03, "size_deficit": 0.02,
           "ellipticity": 0.01, "asymmetry": 0.01, "edge_roughness": 0.25,
           "residual_rms": 0.0, "scatter": 0.0,
           "outlier_fraction": 0.01}


def robust_z(metrics: xr.Dataset) -> xr.Dataset:
    """Robust z-score of every metric: (value - median) / max(1.4826 MAD, floor).

    The floor is an absolute one per metric (``_FLOORS``), or 5 % of the median for the
    residual metrics. A fraction counted over ``n_trials`` frames (attribute of the metric, as
    ``outlier_fraction`` has) must also be improbable by counting alone: its z is at most the
    normal equivalent of the binomial tail P(K >= k | n_trials, p) at the fleet's mean rate p,
    so that one or two tail frames of a hole seen in a few frames do not make it an outlier.

    Parameters
    ----------
    metrics : xarray.Dataset
        Defect metrics on ``hole`` (:func:`defect_metrics`), large = bad.

    Returns
    -------
    xarray.Dataset
        The z-score of every metric on ``hole`` (dimensionless, positive = worse than the
        fleet), with the metrics' coordinates.

    Examples
    --------
    >>> m = xr.Dataset({"outlier_fraction": ("hole", [0.0] * 9 + [2 / 30],
    ...                                      {"n_trials": 30.0})})
    >>> round(float(robust_z(m).outlier_fraction[9]), 1)          # 2 tail frames of 30: chance
    2.1
    >>> m["outlier_fraction"].attrs["n_trials"] = 3000.0              # 200 of 3000: an outlier
    >>> bool(robust_z(m).outlier_fraction[9] > 5)
    True
    """
    out = {}
    for k in metrics.data_vars:
        v = metrics[k].values.astype(float)
        med = np.nanmedian(v)
        mad = 1.4826 * np.nanmedian(np.abs(v - med))
        floor = _FLOORS.get(k, 0.0)
        if k in ("residual_rms", "scatter"):
            floor = 0.05 * abs(med)
        z = (v - med) / max(mad, floor, 1e-15)
        n_trials = metrics[k].attrs.get("n_trials")
        if n_trials:
            from scipy.stats import binom, norm

            n = int(round(float(n_trials)))
            rate = float(np.clip(np.nanmean(v), 1e-6, 1.0))
            count = np.round(np.nan_to_num(v) * n)
            z_count = norm.isf(binom.sf(count - 1, n, rate))
            z = np.where(z > 0, np.minimum(z, np.maximum(z_count, 0.0)), z)
        out[k] = ("hole", z)
    return xr.Dataset(out, coords=metrics.coords)


def reject_bad_holes(metrics: xr.Dataset, *, kappa: float = 5.0,
                     use: Sequence[str] | None = None) -> xr.DataArray:
    """Flag bad holes: any metric more than ``kappa`` robust standard deviations above the fleet.

    Parameters
    ----------
    metrics : xarray.Dataset
        From :func:`defect_metrics`.
    kappa : float
        Threshold in robust standard deviations (one-sided: only "worse than the fleet" flags).
    use : sequence of str, optional
        Metrics to use (default all present).

    Returns
    -------
    xarray.DataArray of bool on ``hole``: True for a bad hole.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=2, layout="grid",
    ...                           defects={7: {"flux": 0.4}})
    >>> np.flatnonzero(reject_bad_holes(defect_metrics(cen)).values).tolist()
    [7]
    """
    z = robust_z(metrics)
    names = list(use) if use is not None else list(z.data_vars)
    for n in names:
        if n not in z:
            raise ConfigurationError(f"use: metric {n!r} not in {list(z.data_vars)}")
    stack = np.stack([z[n].values for n in names])
    bad = np.nanmax(np.where(np.isfinite(stack), stack, -np.inf), axis=0) > kappa
    if "missing_fraction" in metrics:
        bad |= metrics["missing_fraction"].values > 0.5
    return xr.DataArray(bad, dims="hole", coords=metrics.coords, name="bad")


def metric_scale(values) -> tuple[float, float]:
    """Colour scale (low, high) of a defect metric: its 2nd and 98th percentiles over the holes.

    One scale for every view of a metric (``sunlab.plots.plot_metric_map``, the buttons of
    :class:`sunlab.widgets.HoleExplorer`), robust to the one bad hole that would otherwise
    squeeze all good holes into one colour.

    Parameters
    ----------
    values : array_like
        The metric of every hole (NaN ignored), in the metric's units.

    Returns
    -------
    (float, float)
        (low, high), in the metric's units; (0, 1) with no finite value, and ``high`` just
        above ``low`` when all values are equal.

    Examples
    --------
    >>> [round(v, 2) for v in metric_scale([0.0, 1.0, 2.0, np.nan, 100.0])]
    [0.06, 94.12]
    >>> metric_scale([np.nan])
    (0.0, 1.0)
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if not v.size:
        return 0.0, 1.0
    lo, hi = (float(q) for q in np.percentile(v, [2, 98]))
    if hi <= lo:
        hi = lo + max(abs(lo) * 1e-6, 1e-12)
    return lo, hi
