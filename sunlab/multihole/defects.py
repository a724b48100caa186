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
from scipy import ndimage

from .. import centroid, schema
from ..errors import ConfigurationError
from .holes import cutout, usable
from .strategies import PerHoleAverage

__all__ = ["defect_metrics", "reject_bad_holes"]


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

_SHAPE = ("radius", "ellipticity", "asymmetry")


def stamp_metrics(cube: xr.Dataset, cen: xr.Dataset, *, shot: int = 0, half: int = 30,
                  max_frames: int = 6) -> xr.Dataset:
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
    shot : int
        Shot to use.
    half : int
        Half-size of the stamp, px (a spot is about 35 px across on the paper bench).
    max_frames : int
        Number of poses sampled, evenly spread.

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
    poses = np.unique(np.linspace(0, n_p - 1, min(max_frames, n_p)).round().astype(int))
    ok, x, y = usable(cen).values[:, shot], cen["x"].values[:, shot], cen["y"].values[:, shot]
    res = np.full((len(poses), cen.sizes["hole"], 3), np.nan)
    for n, (p, frame) in enumerate(_frames_of(cube, poses, shot)):
        for h in np.flatnonzero(ok[p]):
            res[n, h] = centroid.stamp_moments(cutout(frame, x[p, h], y[p, h], half)[0])
    with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
        med = np.nanmedian(res, axis=0)
    return xr.Dataset({k: ("hole", med[:, i]) for i, k in enumerate(_SHAPE)},
                      coords={"hole": cen["hole"].values})


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
        with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
            scale = np.nanmedian(amp, axis=0)
            value = np.sqrt(np.nanmean((amp / np.where(scale > 0, scale, np.nan)) ** 2, axis=1))
    return xr.DataArray(value, dims="hole", coords={"hole": cen["hole"].values},
                        name="edge_roughness")


def _roughness_radius(cube, cen, ok, poses, shot) -> float:
    """Default stamp radius of :func:`edge_roughness`: 2.1 RMS spot radii, at most 0.45 of the
    spacing of neighbouring spots."""
    with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
        r_rms = float(np.nanmedian(cen["radius"].where(usable(cen)))) if "radius" in cen \
            else np.nan
    if not poses:
        return 2.1 * r_rms
    hs = np.flatnonzero(ok[poses[0]])
    xy = np.stack([cen["x"].values[poses[0], shot, hs], cen["y"].values[poses[0], shot, hs]], 1)
    if not np.isfinite(r_rms):
        frame = np.asarray(cube["frames"].isel(pose=poses[0], shot=shot).values)
        r_rms = float(np.nanmedian([centroid.stamp_moments(cutout(frame, *c, 40)[0])[0]
                                    for c in xy[:10]]))
    d = np.linalg.norm(xy[:, None] - xy[None], axis=-1)
    d[d == 0] = np.inf
    return min(2.1 * r_rms, 0.45 * float(np.median(d.min(1))))


def _frames_of(cube, poses, shot, batch: int = 32):
    """(pose, frame) of the given poses at one shot, computed ``batch`` frames at a time: a
    lazy cube renders or reads a batch in parallel, in one request to its scheduler (each
    request pays the scheduler's start and, on a shared scheduler, waits behind the work
    already queued there), and memory stays bounded (32 full frames are 84 MB)."""
    poses = [int(p) for p in poses]
    for k in range(0, len(poses), batch):
        # the shot first: one pose list then indexes one axis (an outer index on two axes of an
        # in-memory cube copies the frames many times slower)
        block = np.asarray(cube["frames"].isel(shot=shot).isel(pose=poses[k:k + batch]).values)
        yield from zip(poses[k:k + batch], block, strict=True)


def _cubic_stamps(frame, x, y, n_r):
    """Stamps (spot, 2 n_r + 1, 2 n_r + 1) of ``frame`` on the pixel grid -n_r..n_r about each
    (x, y) (px): ``scipy.ndimage.map_coordinates(..., order=3, mode="nearest")`` on the part of
    the frame the spots' taps reach, with the 22 px its spline prefilter sees."""
    m = n_r + 24
    y0, x0 = max(int(np.floor(y.min())) - m, 0), max(int(np.floor(x.min())) - m, 0)
    sub = np.asarray(frame[y0:int(np.floor(y.max())) + m, x0:int(np.floor(x.max())) + m], float)
    g = np.arange(-n_r, n_r + 1)
    coords = np.broadcast_arrays((y - y0)[:, None, None] + g[:, None], (x - x0)[:, None, None] + g)
    return ndimage.map_coordinates(sub, coords, order=3, mode="nearest")


def _harmonic_amplitudes(cube, ok, xs, ys, poses, shot, radius_px, harmonics):
    """|c_m| (hole, harmonic) of each hole's mean over ``poses`` of its unit-flux stamp minus
    the frame's median stamp (relative to its peak), on a ring of pixels; NaN for a hole never
    seen whole. The stamps of a frame are resampled at once by ``scipy.ndimage`` (cubic
    B-spline, boundary mode "nearest") on the part of the frame the spots cover."""
    n_r = int(np.ceil(radius_px))
    g = np.arange(-n_r, n_r + 1, dtype=float)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    rr = np.hypot(gx, gy)
    disk, ring = rr <= radius_px, (rr > 0.5) & (rr <= radius_px)
    acc, count = np.zeros((ok.shape[1], ring.sum())), np.zeros(ok.shape[1])
    for p, frame in _frames_of(cube, poses, shot):
        hs = np.flatnonzero(ok[p])
        st = _cubic_stamps(frame, xs[p, hs], ys[p, hs], n_r)
        st -= np.median(np.concatenate([st[:, 0], st[:, -1], st[:, :, 0], st[:, :, -1]], 1),
                        axis=1)[:, None, None]
        total = st[:, disk].sum(axis=1)
        good = total > 0
        if good.any():
            stamps = st[good][:, ring] / total[good, None]
            template = np.median(stamps.T, axis=1)
            acc[hs[good]] += (stamps - template) / template.max()
            count[hs[good]] += 1
    m = np.arange(harmonics[0], harmonics[1] + 1)
    amp = np.abs(acc / np.maximum(count, 1)[:, None]
                 @ np.exp(-1j * m[None, :] * np.arctan2(gy, gx)[ring][:, None]))
    amp[count == 0] = np.nan
    return amp


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
    angle = xr.DataArray(["alpha", "beta"], dims="angle")
    e = xr.concat([est["alpha"], est["beta"]], angle)
    res = e - xr.concat([est["alpha_cmd"], est["beta_cmd"]], angle)
    dev = e - e.median("hole")
    dims = ("angle", "pose", "shot")
    scale = max(1.4826 * float(np.nanmedian(np.abs(dev))), 1e-12)
    # trials behind each hole's fraction (frames x 2 angles): robust_z bounds the spread of the
    # fraction below by its binomial counting noise, so that one or two tail frames of a hole
    # seen in a few frames do not make it an outlier
    n_trials = float(np.nanmedian(np.isfinite(dev).sum(dims)))
    out = (np.abs(dev) > kappa * scale).where(np.isfinite(dev)).mean(("pose", "shot")).mean("angle")
    return xr.Dataset(
        {"residual_rms": ("hole", np.sqrt((res**2).mean(dims)).values, {"units": "deg"}),
         "scatter": ("hole", np.sqrt((dev**2).mean(dims)).values, {"units": "deg"}),
         "outlier_fraction": ("hole", out.values, {"n_trials": n_trials})},
        coords={"hole": est["hole"].values})


def defect_metrics(cen: xr.Dataset, *, strategy: PerHoleAverage | None = None, cube=None,
                   accept: Sequence[str] = ("ok",)) -> xr.Dataset:
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
    flux = cen["flux"].where(ok)
    with warnings.catch_warnings(action="ignore", category=RuntimeWarning):
        rel = (flux / flux.median("hole")).median(("pose", "shot"))
        ds = xr.Dataset({"missing_fraction": lost.mean(("pose", "shot")), "flux_deficit": 1 - rel})
        if cube is not None:  # from the frames
            ds.update(stamp_metrics(cube, cen).drop_vars("hole"))
            ds["edge_roughness"] = ("hole", edge_roughness(cube, cen).values)
        elif all(k in cen for k in _SHAPE):  # per spot, by the centroiding (centroid.locate)
            ds.update({k: cen[k].where(ok).median(("pose", "shot")) for k in _SHAPE})
        if "radius" in ds:
            ds["size_deficit"] = 1.0 - ds["radius"] / float(np.nanmedian(ds["radius"]))
    if strategy is not None:
        ds.update(residual_metrics(strategy.predict_holes(cen)).drop_vars("hole"))
    keep = [k for k in DEFECT_METRICS if k in ds]  # in the table's order
    coords = [c for c in ("hole", "hole_i", "hole_j", "hole_x_cf", "hole_y_cf") if c in cen.coords]
    ds = ds[keep].drop_vars(list(ds.coords)).assign_coords({c: cen[c] for c in coords})
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
    from scipy.stats import binom, median_abs_deviation, norm

    out = {}
    for k in metrics.data_vars:
        v = metrics[k].values.astype(float)
        med = np.nanmedian(v)
        floor = 0.05 * abs(med) if k in ("residual_rms", "scatter") else _FLOORS.get(k, 0.0)
        mad = median_abs_deviation(v, scale="normal", nan_policy="omit")
        z = (v - med) / max(mad, floor, 1e-15)
        if n := round(float(metrics[k].attrs.get("n_trials", 0))):
            rate = float(np.clip(np.nanmean(v), 1e-6, 1.0))
            z_count = norm.isf(binom.sf(np.round(np.nan_to_num(v) * n) - 1, n, rate))
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
    if missing := set(use or ()) - set(z.data_vars):
        raise ConfigurationError(f"use: metric {sorted(missing)[0]!r} not in {list(z.data_vars)}")
    bad = (z[list(use or z.data_vars)].to_array() > kappa).any("variable")
    if "missing_fraction" in metrics:
        bad |= metrics["missing_fraction"] > 0.5
    return bad.rename("bad")


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
    if not np.isfinite(v).any():
        return 0.0, 1.0
    lo, hi = (float(q) for q in np.nanpercentile(v, [2, 98]))
    return lo, hi if hi > lo else lo + max(abs(lo) * 1e-6, 1e-12)
