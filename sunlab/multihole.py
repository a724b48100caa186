"""The 100-hole mask: hole indexing, the paper's two strategies, defect metrics, bad-hole rejection.

With a mask of N holes every frame holds N spots. The paper (sec. 6) tries two ways to turn them
into one sun direction, both with polynomial calibration:

1. **Geometric centre** (:class:`GeometricCentre`): the mean of the N spot centroids is calibrated
   as if it were one spot.
2. **Per-hole calibration, then averaging** (:class:`PerHoleAverage`): one calibration per hole,
   and the mean of the N angle estimates.

Averaging N independent errors divides the variance by N, eq. (5); errors common to all holes
(platform pose error, mask mounting) do not average out, and "bad" holes (dust, defects) spoil the
mean. This module measures both effects: :func:`defect_metrics` scores each hole from its spots and
from its calibration residuals, :func:`reject_bad_holes` flags outliers with robust z-scores,
:func:`gain_study` compares one hole with the whole mask and splits the error into its common and
hole-specific parts (:func:`error_budget`).

Both strategies handle holes missing from some frames (off the detector, lost, flagged) without
biasing the result: the geometric centre is solved from the holes present with each hole's fitted
offset from the centre (so the centre does not jump when a hole drops out), and the average runs
over the holes present after each hole's own calibration (each is an unbiased estimate).

Conventions: pixel coordinates (x = column, y = row, centre of the first pixel = 0), angles in
degrees; centroid tables follow contract ``centroids/1`` on dims ``(pose, shot, hole)`` with the
commanded angles ``alpha``, ``beta`` as coordinates on ``pose`` and, where known, the hole's grid
row/column ``hole_i``, ``hole_j`` and design position ``hole_x_cf``, ``hole_y_cf`` (px) on ``hole``.

References
----------
.. [1] docs/paper.md, sec. 6 and Table 5 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from . import geometry, schema
from .errors import ConfigurationError, SchemaError
from .options import show_progress

__all__ = [
    "grid_layout",
    "random_layout",
    "synthetic_centroids",
    "hole_grid",
    "assign_holes",
    "usable",
    "locate_layout",
    "geometric_centre",
    "GeometricCentre",
    "PerHoleAverage",
    "combine_estimates",
    "angle_errors",
    "global_stats",
    "spot_metrics",
    "edge_roughness",
    "residual_metrics",
    "defect_metrics",
    "reject_bad_holes",
    "error_budget",
    "gain_study",
    "fig13_frame",
    "fig14_bad_holes",
    "fig15_rectangles",
    "plot_metric_map",
    "metric_scale",
    "DEFECT_METRICS",
]

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


# --------------------------------------------------------------------------------------------
# Layouts and centroid-level synthetic data
# --------------------------------------------------------------------------------------------
def grid_layout(n: int = 10, pitch_mm: float = 0.5, *, centre_px=(572.0, 375.0),
                pixel_pitch_mm: float = 0.007):
    """Design positions (x_cf, y_cf) in px of an n x n grid of holes, row-major (hole = i*n + j).

    Parameters
    ----------
    n : int
        Holes per side.
    pitch_mm : float
        Hole spacing, mm (the paper: 0.5 mm).
    centre_px : (float, float)
        Design position of the grid centre (column, row), px. The default sits off the detector
        centre so that all spots stay on the Ibis4 over the paper's test range
        (docs/paper.md sec. 8).
    pixel_pitch_mm : float
        Detector pixel pitch, mm.

    Returns
    -------
    x_cf, y_cf, i, j : numpy.ndarray, shape (n*n,)
        Design centroid (sun at zenith) and grid row/column of each hole.

    Examples
    --------
    >>> x, y, i, j = grid_layout(10)
    >>> x.shape, round(float(x[1] - x[0]), 2), int(i[10]), int(j[10])
    ((100,), 71.43, 1, 0)
    """
    if n < 1:
        raise ConfigurationError(f"n: found {n!r}, expected a positive number of holes per side")
    k = pitch_mm / pixel_pitch_mm
    i, j = np.divmod(np.arange(n * n), n)
    x = centre_px[0] + (j - (n - 1) / 2) * k
    y = centre_px[1] + (i - (n - 1) / 2) * k
    return x.astype(float), y.astype(float), i, j


def random_layout(n_holes: int = 100, *, extent_mm=(4.5, 4.5), min_sep_mm: float = 0.35,
                  centre_px=(572.0, 375.0), pixel_pitch_mm: float = 0.007, seed: int = 0):
    """Random hole positions (x_cf, y_cf) in px inside a rectangle, with a minimum separation.

    Poisson-disk sampling by rejection: holes closer than ``min_sep_mm`` would make overlapping
    spots (a spot is about 0.25 mm across at F = 5 mm), so candidates that close are redrawn.

    Parameters
    ----------
    n_holes : int
        Number of holes.
    extent_mm : (float, float)
        Width and height of the area holding hole centres, mm (the 10 x 10 grid spans 4.5 mm).
    min_sep_mm : float
        Minimum centre-to-centre distance, mm.
    centre_px, pixel_pitch_mm
        As in :func:`grid_layout`.
    seed : int
        Random seed.

    Returns
    -------
    x_cf, y_cf : numpy.ndarray, shape (n_holes,)

    Examples
    --------
    >>> x, y = random_layout(100, seed=1)
    >>> d = np.hypot(x[:, None] - x, y[:, None] - y) + 1e9 * np.eye(100)
    >>> bool(d.min() * 0.007 >= 0.35)
    True
    """
    rng = np.random.default_rng(seed)
    pts = np.empty((0, 2))
    tries = 0
    while len(pts) < n_holes:
        tries += 1
        if tries > 20000:
            raise ConfigurationError(
                f"min_sep_mm: found {min_sep_mm!r}, too large to place {n_holes} holes in "
                f"{extent_mm} mm; lower it or enlarge extent_mm"
            )
        p = rng.uniform(-0.5, 0.5, 2) * np.asarray(extent_mm, dtype=float)
        if len(pts) == 0 or np.min(((pts - p) ** 2).sum(1)) >= min_sep_mm**2:
            pts = np.vstack([pts, p])
    xy = pts / pixel_pitch_mm
    return centre_px[0] + xy[:, 0], centre_px[1] + xy[:, 1]


def _uniform(rng, sigma, size):
    """Zero-mean uniform draws of standard deviation ``sigma`` (bounded, like a stage's steps)."""
    return rng.uniform(-np.sqrt(3.0), np.sqrt(3.0), size) * sigma


def synthetic_centroids(
    alpha,
    beta,
    *,
    shots: int = 8,
    x_cf=None,
    y_cf=None,
    hole_i=None,
    hole_j=None,
    mask_distance_mm: float = 5.0,
    pixel_pitch_mm: float = 0.007,
    hole_scale=None,
    common_sigma_deg=(0.0, 0.0),
    shot_sigma_deg: float = 0.0,
    hole_sigma_px: float = 0.0,
    noise_px: float = 0.0,
    flux=None,
    defects: Mapping[int, Mapping] | None = None,
    detector_shape=(1024, 1280),
    edge_px: float = 20.0,
    seed: int = 0,
) -> xr.Dataset:
    """A multi-hole centroid table with known truth, at the level of the centroid contract.

    Every hole's spot follows the ideal model, eq. (1), from its own design position; on top come
    the errors one injects: a per-pose platform error common to all holes (uniform, standard
    deviation ``common_sigma_deg``), per-shot platform jitter, a hole-specific error that changes
    from pose to pose (``hole_sigma_px``, e.g. pixel response under the spot), centroid noise per
    frame (``noise_px``) and per-hole defects.

    Parameters
    ----------
    alpha, beta : array_like, shape (pose,)
        Commanded platform angles, deg.
    shots : int
        Frames per pose.
    x_cf, y_cf : array_like, shape (hole,), optional
        Design positions, px; default :func:`grid_layout` (10 x 10 at 0.5 mm).
    hole_i, hole_j : array_like of int, optional
        Grid row/column of each hole (default from the grid, or -1 for a free layout).
    mask_distance_mm, pixel_pitch_mm : float
        F and the pixel pitch, mm.
    hole_scale : array_like, shape (hole,), optional
        Relative scale F_h / F of each hole (a tilted mask puts holes at different heights).
    common_sigma_deg : (float, float)
        Standard deviation of the per-pose platform error on (alpha, beta), deg.
    shot_sigma_deg : float
        Standard deviation of the per-shot platform jitter, deg.
    hole_sigma_px : float
        Standard deviation of the hole-specific, pose-dependent centroid error, px.
    noise_px : float
        Standard deviation of per-frame centroid noise, px.
    flux : array_like, shape (hole,), optional
        Spot flux per hole, DN (default 2e5 each).
    defects : mapping, optional
        ``{hole: {"flux": factor, "sigma_px": extra pose-dependent error, "noise_px": extra
        per-frame noise, "missing": probability a frame loses the spot, "bias_px": (bx, by)}}``.
    detector_shape : (int, int)
        (ny, nx); spots closer than ``edge_px`` to the edge are lost (NaN, status ``clipped``).
    edge_px : float
        Margin, px (about a spot radius).
    seed : int
        Random seed; the table is deterministic in it.

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot, hole), with ``true_alpha``, ``true_beta`` on
        (pose, shot) and the hole coordinates.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0, -5.0], [0.0, 3.0], shots=2, noise_px=0.01)
    >>> dict(cen.x.sizes)
    {'pose': 2, 'shot': 2, 'hole': 100}
    """
    rng = np.random.default_rng(seed)
    alpha = np.atleast_1d(np.asarray(alpha, dtype=float))
    beta = np.atleast_1d(np.asarray(beta, dtype=float))
    if alpha.shape != beta.shape or alpha.ndim != 1:
        raise SchemaError("alpha, beta", f"shapes {alpha.shape}, {beta.shape}", "equal 1-d shapes")
    if x_cf is None:
        x_cf, y_cf, gi, gj = grid_layout(10, pixel_pitch_mm=pixel_pitch_mm)
        hole_i = gi if hole_i is None else hole_i
        hole_j = gj if hole_j is None else hole_j
    x_cf = np.asarray(x_cf, dtype=float)
    y_cf = np.asarray(y_cf, dtype=float)
    n_h = x_cf.size
    hole_i = np.full(n_h, -1) if hole_i is None else np.asarray(hole_i)
    hole_j = np.full(n_h, -1) if hole_j is None else np.asarray(hole_j)
    scale = np.ones(n_h) if hole_scale is None else np.asarray(hole_scale, dtype=float)
    n_p = alpha.size
    shape = (n_p, shots, n_h)
    ca, cb = np.broadcast_to(np.asarray(common_sigma_deg, dtype=float), (2,))
    ta = alpha[:, None] + _uniform(rng, ca, (n_p, 1)) + rng.normal(0, shot_sigma_deg, (n_p, shots))
    tb = beta[:, None] + _uniform(rng, cb, (n_p, 1)) + rng.normal(0, shot_sigma_deg, (n_p, shots))
    k = mask_distance_mm / pixel_pitch_mm
    dx, dy = geometry.ideal_centroid(ta, tb, mask_distance_mm, pixel_pitch_mm, 0.0, 0.0)
    x = x_cf + scale * dx[..., None]
    y = y_cf + scale * dy[..., None]
    del k
    hx = rng.normal(0, hole_sigma_px, (n_p, 1, n_h))
    hy = rng.normal(0, hole_sigma_px, (n_p, 1, n_h))
    x = x + hx + rng.normal(0, noise_px, shape)
    y = y + hy + rng.normal(0, noise_px, shape)
    f = np.full(n_h, 2e5) if flux is None else np.asarray(flux, dtype=float).copy()
    lost = np.zeros(shape, dtype=bool)
    for h, d in (defects or {}).items():
        h = int(h)
        f[h] *= float(d.get("flux", 1.0))
        s = float(d.get("sigma_px", 0.0))
        nz = float(d.get("noise_px", 0.0))
        x[..., h] += rng.normal(0, s, (n_p, 1)) + rng.normal(0, nz, (n_p, shots))
        y[..., h] += rng.normal(0, s, (n_p, 1)) + rng.normal(0, nz, (n_p, shots))
        bx, by = d.get("bias_px", (0.0, 0.0))
        x[..., h] += bx
        y[..., h] += by
        lost[..., h] |= rng.random((n_p, shots)) < float(d.get("missing", 0.0))
    ny, nx = detector_shape
    clipped = (x < edge_px) | (x > nx - 1 - edge_px) | (y < edge_px) | (y > ny - 1 - edge_px)
    status = np.where(clipped, schema.STATUS["clipped"], schema.STATUS["ok"])
    status = np.where(lost & ~clipped, schema.STATUS["no_spot"], status)
    bad = status != schema.STATUS["ok"]
    x = np.where(bad, np.nan, x)
    y = np.where(bad, np.nan, y)
    fl = np.where(bad, np.nan, np.broadcast_to(f, shape) * np.cos(np.deg2rad(ta))[..., None])
    cen = schema.centroids_dataset(
        x, y, flux=fl, status=status, alpha=alpha, beta=beta, method="synthetic",
        attrs={"mask_distance_mm": mask_distance_mm, "pixel_pitch_mm": pixel_pitch_mm},
        extra={
            "true_alpha": (("pose", "shot"), ta, {"units": "deg"}),
            "true_beta": (("pose", "shot"), tb, {"units": "deg"}),
        },
    )
    return cen.assign_coords(
        hole_i=("hole", hole_i), hole_j=("hole", hole_j),
        hole_x_cf=("hole", x_cf, {"units": "px"}), hole_y_cf=("hole", y_cf, {"units": "px"}),
    )


# --------------------------------------------------------------------------------------------
# Hole indexing
# --------------------------------------------------------------------------------------------
def hole_grid(cen: xr.Dataset):
    """Grid row and column of every hole of a centroid table (or frame cube).

    Uses the ``hole_i`` / ``hole_j`` coordinates when present; otherwise assumes a square,
    row-major grid.

    Returns
    -------
    i, j : numpy.ndarray of int, shape (hole,)
    n_rows, n_cols : int

    Examples
    --------
    >>> i, j, nr, nc = hole_grid(synthetic_centroids([0.0], [0.0], shots=1))
    >>> (nr, nc), int(i[57]), int(j[57])
    ((10, 10), 5, 7)
    """
    n_h = cen.sizes.get("hole", 0)
    if n_h == 0:
        raise SchemaError("hole", "no 'hole' dimension", "a multi-hole table on (pose, shot, hole)",
                          "centroid the cube with a multi-spot method")
    if "hole_i" in cen.coords and "hole_j" in cen.coords:
        i = np.asarray(cen["hole_i"].values, dtype=int)
        j = np.asarray(cen["hole_j"].values, dtype=int)
        if np.all(i >= 0) and np.all(j >= 0):
            return i, j, int(i.max()) + 1, int(j.max()) + 1
    n = math.isqrt(n_h)
    if n * n == n_h:
        i, j = np.divmod(np.arange(n_h), n)
        return i, j, n, n
    # a free layout: one row
    return np.zeros(n_h, int), np.arange(n_h), 1, n_h


def assign_holes(x, y, design_x, design_y, *, shift=None, gate_px: float = 20.0):
    """Assign the spots found in one frame to the mask's holes.

    The spots of a frame are the design pattern shifted by the sun direction (plus small
    distortions). The common shift is found by voting: every (spot - design) difference is a
    candidate and the one that brings most spots within ``gate_px`` of a design position wins
    (ties go to the candidate nearest ``shift``, the shift predicted from the commanded pose,
    which resolves the one-pitch ambiguity of a grid with missing holes). The shift is refined on
    the matched pairs and the final one-to-one assignment solves a linear sum assignment with the
    gate. Missing, extra or dim spots leave the other assignments intact.

    Parameters
    ----------
    x, y : array_like, shape (n_spots,)
        Spot centroids of one frame, px, in any order (NaN entries are ignored).
    design_x, design_y : array_like, shape (n_holes,)
        Design positions of the holes, px.
    shift : (float, float), optional
        Predicted common shift (dx, dy), px, e.g. from :func:`sunlab.geometry.ideal_centroid`.
    gate_px : float
        Largest distance between a spot and its hole's predicted position, px (less than half
        the hole pitch).

    Returns
    -------
    numpy.ndarray of int, shape (n_spots,)
        Hole index of each spot, -1 for a spot that matches no hole.

    Examples
    --------
    >>> dx, dy, _, _ = grid_layout(3)
    >>> order = np.array([4, 0, 8, 2])           # 4 of 9 spots, shuffled, moved by (30, -12) px
    >>> assign_holes(dx[order] + 30, dy[order] - 12, dx, dy).tolist()
    [4, 0, 8, 2]
    """
    from scipy.optimize import linear_sum_assignment
    from scipy.spatial import cKDTree

    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    out = np.full(x.shape, -1, dtype=int)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return out
    spots = np.column_stack([x[ok], y[ok]])
    design = np.column_stack([np.asarray(design_x, float), np.asarray(design_y, float)])
    tree = cKDTree(design)
    prior = np.zeros(2) if shift is None else np.asarray(shift, dtype=float)
    cand = (spots[:, None, :] - design[None, :, :]).reshape(-1, 2)
    if len(cand) > 4000:  # enough spots vote: use the first ones
        cand = (spots[:40, None, :] - design[None, :, :]).reshape(-1, 2)
    cand = np.vstack([prior, cand])
    # score: matched spots within the gate, ties broken by the distance to the prior
    best, best_key = prior, (-1, 0.0)
    counts = np.empty(len(cand), dtype=int)
    for n, c in enumerate(cand):
        d, _ = tree.query(spots - c, distance_upper_bound=gate_px)
        counts[n] = int(np.isfinite(d).sum())
    top = counts.max()
    for c in cand[counts == top]:
        key = (top, -float(np.hypot(*(c - prior))))
        if key > best_key:
            best, best_key = c, key
    d, idx = tree.query(spots - best, distance_upper_bound=gate_px)
    m = np.isfinite(d)
    if m.any():
        best = np.median(spots[m] - design[idx[m]], axis=0)
    cost = np.hypot(*(spots[:, None, :] - best - design[None, :, :]).transpose(2, 0, 1))
    big = 1e6
    cost = np.where(cost <= gate_px, cost, big)
    r, c = linear_sum_assignment(cost)
    keep = cost[r, c] < big
    sub = np.full(len(spots), -1, dtype=int)
    sub[r[keep]] = c[keep]
    out[np.flatnonzero(ok)] = sub
    return out


def locate_layout(cube: xr.Dataset, *, half: int = 38, progress: bool = False,
                  **options) -> xr.Dataset:
    """Centroid every hole of a free (non-grid) layout, e.g. a random mask.

    Each hole's spot is looked for in a ``2 half + 1`` px cut-out about its position predicted by
    eq. (1) from the hole's design position (``hole_x_cf``, ``hole_y_cf``) and the commanded
    pose, and centroided by :func:`sunlab.centroid.tight_window` in that cut-out. Holes must be
    at least ``half`` px plus a spot radius apart; the platform's mounting error must be small
    next to ``half`` (true on a bench with a good platform). Frames are processed one by one
    (:func:`sunlab.centroid.locate` is the parallel path for grids).

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot, hole) with the cube's hole coordinates and
        ``radius``, ``ellipticity``, ``asymmetry`` from the stamp moments.

    Examples
    --------
    >>> from sunlab import schema
    >>> yy, xx = np.mgrid[0:200, 0:300]
    >>> img = (400.0 * (np.hypot(xx - 80.3, yy - 100) < 15)
    ...        + 400.0 * (np.hypot(xx - 200, yy - 90.6) < 12))
    >>> cube = schema.frames_dataset(img.astype(np.uint16)[None, None], alpha=[0.0], beta=[0.0])
    >>> cube = cube.assign_coords(hole_x_cf=("hole", [80.0, 200.0]),
    ...                           hole_y_cf=("hole", [100.0, 90.0]))
    >>> cen = locate_layout(cube)
    >>> bool(np.allclose(cen.x[0, 0], [80.3, 200.0], atol=0.15)
    ...      and np.allclose(cen.y[0, 0], [100.0, 90.6], atol=0.15))
    True
    """
    from . import centroid

    for c in ("hole_x_cf", "hole_y_cf"):
        if c not in cube.coords:
            raise SchemaError(c, "missing", "design positions of the holes on 'hole', px",
                              "simulate a multi-hole mask or assign the coordinates")
    dx = np.asarray(cube["hole_x_cf"].values, float)
    dy = np.asarray(cube["hole_y_cf"].values, float)
    n_p, n_s, n_h = cube.sizes["pose"], cube.sizes["shot"], dx.size
    F = float(cube.attrs["mask_distance_mm"])
    pitch = float(cube.attrs["pixel_pitch_mm"])
    sx, sy = geometry.ideal_centroid(cube["alpha"].values, cube["beta"].values, F, pitch, 0.0, 0.0)
    res = np.full((n_p, n_s, n_h, 8), np.nan)
    status = np.full((n_p, n_s, n_h), schema.STATUS["no_spot"], dtype=np.int8)
    options.setdefault("saturation", 2 ** int(cube.attrs.get("bit_depth", 10)) - 1)
    it = [(p, s) for p in range(n_p) for s in range(n_s)]
    if show_progress(progress):
        from tqdm.auto import tqdm

        it = tqdm(it, desc="locate_layout")
    for p, s in it:
        frame = np.asarray(cube["frames"].isel(pose=p, shot=s).values, dtype=float)
        for h in range(n_h):
            st, (x0, y0) = _stamp(frame, dx[h] + sx[p], dy[h] + sy[p], half)
            if st.shape != (2 * half + 1, 2 * half + 1):
                status[p, s, h] = schema.STATUS["clipped"]
                continue
            c = centroid.tight_window(st, **options)
            status[p, s, h] = c.status
            if np.isfinite(c.x):
                r, e, a = _stamp_moments(st)
                res[p, s, h] = (c.x + x0, c.y + y0, c.flux, c.window[0] + x0, c.window[1] + x0,
                                r, e, a)
    ok = status == schema.STATUS["ok"]
    x = np.where(ok, res[..., 0], np.nan)
    y = np.where(ok, res[..., 1], np.nan)
    dims = ("pose", "shot", "hole")
    cen = schema.centroids_dataset(
        x, y, flux=res[..., 2], status=status, alpha=cube["alpha"].values,
        beta=cube["beta"].values, method="tight (layout)",
        attrs={k: cube.attrs[k] for k in ("pixel_pitch_mm", "mask_distance_mm", "bit_depth")
               if k in cube.attrs},
        extra={"radius": (dims, res[..., 5]), "ellipticity": (dims, res[..., 6]),
               "asymmetry": (dims, res[..., 7])},
    )
    coords = {c: ("hole", cube[c].values) for c in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf",
                                                    "hole_defect") if c in cube.coords}
    return cen.assign_coords(coords)


def usable(cen: xr.Dataset, accept: Sequence[str] = ("ok",)) -> xr.DataArray:
    """Boolean mask of centroids that may be used: finite x, y and an accepted status.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1, defects={3: {"missing": 1.0}})
    >>> int(usable(cen).sum())
    99
    """
    codes = [schema.STATUS[a] for a in accept]
    return np.isfinite(cen["x"]) & np.isfinite(cen["y"]) & cen["status"].isin(codes)


# --------------------------------------------------------------------------------------------
# Strategy 1: the geometric centre
# --------------------------------------------------------------------------------------------
def geometric_centre(cen: xr.Dataset, accept: Sequence[str] = ("ok",)) -> xr.Dataset:
    """Plain geometric centre of the spots, the paper's strategy 1: the mean of the centroids.

    .. math:: x_{gc} = \\frac{1}{N}\\sum_{ij} x_c^{ij}, \\qquad
              y_{gc} = \\frac{1}{N}\\sum_{ij} y_c^{ij}

    This is the paper's definition; it jumps by (design offset of the lost hole) / N whenever a
    hole is missing. :class:`GeometricCentre` removes that bias.

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot): ``x``, ``y`` px, ``flux`` (sum), ``n_holes``.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1)
    >>> gc = geometric_centre(cen)
    >>> round(float(gc.x[0, 0]), 6), round(float(gc.y[0, 0]), 6)
    (572.0, 375.0)
    """
    ok = usable(cen, accept)
    n = ok.sum("hole")
    x = cen["x"].where(ok).mean("hole")
    y = cen["y"].where(ok).mean("hole")
    flux = cen["flux"].where(ok).sum("hole")
    return _centre_table(cen, x.values, y.values, flux.values, n.values, "geometric_centre")


def _centre_table(cen, x, y, flux, n, method):
    status = np.where(n > 0, schema.STATUS["ok"], schema.STATUS["no_spot"])
    x = np.where(n > 0, x, np.nan)
    y = np.where(n > 0, y, np.nan)
    attrs = {k: v for k, v in cen.attrs.items() if k not in ("sunlab_schema", "method")}
    out = schema.centroids_dataset(
        x, y, flux=flux, status=status, alpha=cen["alpha"].values, beta=cen["beta"].values,
        method=method, attrs=attrs,
        extra={"n_holes": (("pose", "shot"), np.asarray(n, dtype=np.int16))},
    )
    for name in ("true_alpha", "true_beta"):
        if name in cen.variables:
            out[name] = (("pose", "shot"), np.asarray(cen[name].values))
    return out


def _default_model(order: int):
    def factory():
        from .calibration import Polynomial

        return Polynomial(order)

    return factory


def _hole_table(cen: xr.Dataset, h: int, ok: xr.DataArray | None = None) -> xr.Dataset:
    """The centroid table (``centroids/1``) of one hole on (pose, shot); frames that are not
    usable get NaN and status ``no_spot``. Built directly (the parent table is valid)."""
    x = np.asarray(cen["x"].values[..., h], dtype=float)
    y = np.asarray(cen["y"].values[..., h], dtype=float)
    status = np.asarray(cen["status"].values[..., h])
    if ok is not None:
        okh = np.asarray(ok.values[..., h], dtype=bool)
        x = np.where(okh, x, np.nan)
        y = np.where(okh, y, np.nan)
        status = np.where(okh, status, np.where(status == 0, schema.STATUS["no_spot"], status))
    dims = ("pose", "shot")
    data = {"x": (dims, x), "y": (dims, y), "status": (dims, status.astype(np.int8))}
    for name in ("flux", "x0", "x1", "y0", "y1"):
        if name in cen.variables:
            data[name] = (dims, np.asarray(cen[name].values[..., h]))
    attrs = {k: v for k, v in cen.attrs.items() if k != "sunlab_schema"}
    attrs["sunlab_schema"] = schema.CENTROIDS_SCHEMA
    return xr.Dataset(
        data,
        coords={"pose": cen["pose"].values, "shot": cen["shot"].values,
                "alpha": ("pose", np.asarray(cen["alpha"].values, float)),
                "beta": ("pose", np.asarray(cen["beta"].values, float))},
        attrs=attrs,
    )


def _fit_model(factory, table: xr.Dataset):
    """Fit a calibration model on the usable frames of a (pose, shot) table."""
    ok = np.isfinite(table["x"].values) & np.isfinite(table["y"].values)
    if ok.sum() < 3:
        raise ConfigurationError("too few usable frames to fit a calibration (fewer than 3)")
    return factory().fit(table)


def _predict_arrays(model, x, y):
    """(alpha, beta) of a fitted calibration for centroid arrays; NaN where x or y is NaN."""
    x = np.asarray(x, dtype=float)
    y = np.asarray(y, dtype=float)
    bad = ~(np.isfinite(x) & np.isfinite(y))
    if hasattr(model, "predict_xy"):
        a, b = model.predict_xy(np.where(bad, np.nan, x), np.where(bad, np.nan, y))
    else:
        dims = ("pose", "shot")[: x.ndim] if x.ndim <= 2 else None
        tab = schema.centroids_dataset(x.reshape(x.shape[0], -1), y.reshape(x.shape[0], -1),
                                       alpha=np.zeros(x.shape[0]), beta=np.zeros(x.shape[0]))
        del dims
        pred = model.predict(tab)
        a = np.asarray(pred["alpha"].values, float).reshape(x.shape)
        b = np.asarray(pred["beta"].values, float).reshape(x.shape)
    a = np.asarray(a, float).reshape(x.shape)
    b = np.asarray(b, float).reshape(x.shape)
    return np.where(bad, np.nan, a), np.where(bad, np.nan, b)


def _predict(model, table: xr.Dataset):
    """Predicted (alpha, beta) arrays on (pose, shot), NaN where the table has no centroid."""
    return _predict_arrays(model, table["x"].values, table["y"].values)


def _angles_dataset(cen, a, b, dims, extra=None):
    """Angle estimates on ``dims`` with the commanded angles (from a centroid table's
    ``alpha``/``beta`` or an estimate's ``alpha_cmd``/``beta_cmd``) as coordinates."""
    ca = cen["alpha_cmd"] if "alpha_cmd" in cen.coords else cen["alpha"]
    cb = cen["beta_cmd"] if "beta_cmd" in cen.coords else cen["beta"]
    coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
              "alpha_cmd": ("pose", np.asarray(ca.values), {"units": "deg"}),
              "beta_cmd": ("pose", np.asarray(cb.values), {"units": "deg"})}
    if "hole" in dims:
        coords["hole"] = cen["hole"].values
        for c in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf"):
            if c in cen.coords:
                coords[c] = ("hole", cen[c].values)
    data = {"alpha": (dims, a, {"units": "deg"}), "beta": (dims, b, {"units": "deg"})}
    data.update(extra or {})
    return xr.Dataset(data, coords=coords)


@dataclass
class GeometricCentre:
    """Strategy 1 of the paper: one calibration of the geometric centre of the spots.

    When all holes are present the centre is the mean of the centroids, as in the paper. To stay
    unbiased when holes are missing, each hole h is tied to the centre c by an affine map
    :math:`\\mathbf{x}_h = \\mathbf{A}_h + \\mathbf{M}_h \\mathbf{c}` fitted on the training
    frames (:math:`\\mathbf{M}_h \\approx I`; it absorbs a mask tilt that puts holes at
    different heights), and the centre of a frame is the least-squares solution over the holes
    present, normalised so that it equals the plain mean for a complete frame.

    Parameters
    ----------
    order : int
        Polynomial order of the calibration (ignored when ``model`` is given).
    model : callable, optional
        Factory returning an unfitted calibration with ``fit(centroids)`` and
        ``predict(centroids) -> Dataset(alpha, beta)``; default
        ``sunlab.calibration.Polynomial(order)``.
    holes : array_like of bool, shape (hole,), optional
        Holes to use (default all); e.g. ``~reject_bad_holes(metrics)``.
    fill : bool
        Solve the centre with the per-hole offsets (True) or take the plain mean (False, biased
        when holes are missing).
    min_holes : int
        Fewest holes a frame needs for a centre.
    accept : sequence of str
        Status codes accepted as usable.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0, -5.0, 1.0], [0.0, 3.0, 8.0], shots=1,
    ...                           defects={0: {"missing": 1.0}})
    >>> s1 = GeometricCentre(fill=True)
    >>> c = s1.fit_centre(cen).centre(cen)   # hole 0 lost: the centre does not jump
    >>> full = geometric_centre(synthetic_centroids([0.0, -5.0, 1.0], [0.0, 3.0, 8.0], shots=1))
    >>> bool(np.allclose(c.x, full.x, atol=1e-6) and np.allclose(c.y, full.y, atol=1e-6))
    True
    """

    order: int = 5
    model: Callable | None = None
    holes: np.ndarray | None = None
    fill: bool = True
    min_holes: int = 3
    accept: Sequence[str] = ("ok",)
    A_: np.ndarray | None = field(default=None, repr=False)
    M_: np.ndarray | None = field(default=None, repr=False)
    calibration_: object | None = field(default=None, repr=False)

    def _ok(self, cen):
        ok = usable(cen, self.accept)
        if self.holes is not None:
            ok = ok & xr.DataArray(np.asarray(self.holes, dtype=bool), dims="hole")
        return ok

    def fit_centre(self, cen: xr.Dataset, n_iter: int = 4) -> GeometricCentre:
        """Fit the per-hole maps hole -> centre on a training table (no calibration)."""
        ok = self._ok(cen).values.reshape(-1, cen.sizes["hole"])
        X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, cen.sizes["hole"], 2)
        w = ok.astype(float)
        n_ok = w.sum(1)
        Xz = np.where(ok[..., None], X, 0.0)
        n_h = X.shape[1]
        # start: design offsets of the holes from the mask centre where known, else zero
        if "hole_x_cf" in cen.coords and "hole_y_cf" in cen.coords:
            d = np.column_stack([cen["hole_x_cf"].values, cen["hole_y_cf"].values]).astype(float)
            d0 = d - d.mean(0)
        else:
            d0 = np.zeros((n_h, 2))
        c = np.where(ok[..., None], X - d0, 0.0).sum(1) / np.maximum(n_ok, 1)[:, None]
        seen = ok.any(0)
        dev = np.where(ok[..., None], X - c[:, None], 0.0)
        off = np.where(seen[:, None], dev.sum(0) / np.maximum(ok.sum(0), 1)[:, None], d0)
        A = off.copy()
        M = np.tile(np.eye(2), (n_h, 1, 1))
        have = n_ok >= self.min_holes
        for _ in range(n_iter):
            D = np.column_stack([np.ones(len(c)), c])  # (F, 3)
            D = np.where(have[:, None], D, 0.0)
            for h in range(n_h):
                wh = w[:, h] * have
                if wh.sum() < 4:
                    A[h], M[h] = off[h], np.eye(2)
                    continue
                G = (D * wh[:, None]).T @ D
                R = (D * wh[:, None]).T @ Xz[:, h]
                beta = np.linalg.lstsq(G, R, rcond=None)[0]  # (3, 2)
                A[h] = beta[0]
                M[h] = beta[1:].T
            # gauge: the centre is the mean of the holes' predicted positions
            Am, Mm = A.mean(0), M.mean(0)
            Mi = np.linalg.inv(Mm)
            A = A - np.einsum("hij,j->hi", M, Mi @ Am)
            M = np.einsum("hij,jk->hik", M, Mi)
            self.A_, self.M_ = A, M
            c = self._solve(X, ok)
            c = np.where(np.isfinite(c), c, 0.0)
        self.A_, self.M_ = A, M
        return self

    def _solve(self, X, ok):
        if not self.fill:
            n = ok.sum(1)
            with np.errstate(invalid="ignore", divide="ignore"):
                c = np.where(ok[..., None], X, 0.0).sum(1) / n[:, None]
            return np.where((n >= self.min_holes)[:, None], c, np.nan)
        w = ok.astype(float)
        r = np.where(ok[..., None], X - self.A_, 0.0)
        G = np.einsum("fh,hki,hkj->fij", w, self.M_, self.M_)
        rhs = np.einsum("fh,hki,fhk->fi", w, self.M_, r)
        n = ok.sum(1)
        good = n >= self.min_holes
        G[~good] = np.eye(2)
        c = np.linalg.solve(G, rhs[..., None])[..., 0]
        return np.where(good[:, None], c, np.nan)

    def centre(self, cen: xr.Dataset) -> xr.Dataset:
        """The geometric centre of every frame, a centroid table on (pose, shot)."""
        if self.A_ is None and self.fill:
            raise ConfigurationError("GeometricCentre: call fit() or fit_centre() first")
        n_h = cen.sizes["hole"]
        if self.A_ is not None and self.A_.shape[0] != n_h:
            raise SchemaError("hole", n_h, f"{self.A_.shape[0]} holes, as in the training table")
        ok = self._ok(cen).values.reshape(-1, n_h)
        X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, n_h, 2)
        c = self._solve(X, ok).reshape(cen.sizes["pose"], cen.sizes["shot"], 2)
        n = ok.sum(1).reshape(cen.sizes["pose"], cen.sizes["shot"])
        n = np.where(np.isfinite(c[..., 0]), n, 0)
        flux = cen["flux"].where(self._ok(cen)).sum("hole").values
        return _centre_table(cen, c[..., 0], c[..., 1], flux, n, "geometric_centre")

    def fit(self, cen: xr.Dataset) -> GeometricCentre:
        """Fit the centre maps and the calibration of the centre on a training table."""
        if self.fill:
            self.fit_centre(cen)
        factory = self.model or _default_model(self.order)
        self.calibration_ = _fit_model(factory, self.centre(cen))
        return self

    def predict(self, cen: xr.Dataset) -> xr.Dataset:
        """Estimated (alpha, beta), deg, on (pose, shot), with ``n_holes`` used per frame."""
        if self.calibration_ is None:
            raise ConfigurationError("GeometricCentre: call fit() first")
        gc = self.centre(cen)
        a, b = _predict(self.calibration_, gc)
        return _angles_dataset(cen, a, b, ("pose", "shot"),
                               {"n_holes": (("pose", "shot"), gc["n_holes"].values)})


# --------------------------------------------------------------------------------------------
# Strategy 2: per-hole calibration, then the average
# --------------------------------------------------------------------------------------------
def combine_estimates(est, *, holes=None, weights=None, clip: float | None = None,
                      n_iter: int = 3, dim: str = "hole"):
    """Combine per-hole angle estimates of each frame into one: mean, weighted and/or clipped.

    Parameters
    ----------
    est : xarray.DataArray
        Angle estimates, deg, with a ``hole`` dimension; NaN for a hole missing in a frame.
    holes : array_like of bool, shape (hole,), optional
        Holes allowed in the combination.
    weights : array_like, shape (hole,), optional
        Non-negative weights, e.g. 1 / (hole's residual variance); default equal.
    clip : float, optional
        Sigma-clipping threshold: in every frame, estimates further than ``clip`` robust standard
        deviations from the median of the kept ones are dropped, ``n_iter`` times (the scale is
        1.4826 MAD, bounded below by the standard deviation of the survivors after the first
        pass).
    dim : str
        Dimension to combine.

    Returns
    -------
    mean, n : xarray.DataArray
        The combined estimate and the number of holes used in each frame.

    Notes
    -----
    Averaging N independent estimates of equal variance divides the variance by N, eq. (5):

    .. math:: \\sigma^2_N = \\sigma^2 / N.

    The mean over the holes present is unbiased as long as each hole's estimate is.

    Examples
    --------
    >>> e = xr.DataArray([[1.0, 1.1, 0.9, 5.0, np.nan]], dims=("pose", "hole"))
    >>> float(combine_estimates(e)[0][0])
    2.0
    >>> round(float(combine_estimates(e, clip=4.0)[0][0]), 6)
    1.0
    """
    ok = np.isfinite(est)
    if holes is not None:
        ok = ok & xr.DataArray(np.asarray(holes, dtype=bool), dims=dim)
    w = xr.ones_like(est) if weights is None else xr.DataArray(np.asarray(weights, float), dims=dim)
    w = w.where(ok, 0.0)
    if clip is not None:
        for it in range(n_iter):
            cur = est.where(w > 0)
            med = cur.median(dim)
            scale = 1.4826 * np.abs(cur - med).median(dim)
            if it > 0:  # a few survivors can have MAD 0: their standard deviation bounds it
                scale = np.maximum(scale, cur.std(dim))
            keep = np.abs(est - med) <= clip * scale
            w = w.where(keep, 0.0)
    wsum = w.sum(dim)
    mean = (est.fillna(0.0) * w).sum(dim) / wsum.where(wsum > 0)
    return mean, (w > 0).sum(dim)


@dataclass
class PerHoleAverage:
    """Strategy 2 of the paper: a calibration per hole (f1_ij, f2_ij), then the average.

    .. math:: \\alpha = \\frac{1}{N}\\sum_{ij} f_1^{ij}(x_c^{ij}, y_c^{ij}), \\qquad
              \\beta = \\frac{1}{N}\\sum_{ij} f_2^{ij}(x_c^{ij}, y_c^{ij})

    The average runs over the holes present in each frame, which is unbiased: every hole's own
    calibration already maps its spot to the sun direction. With ``weighting="inverse_variance"``
    each hole counts by the inverse of its hole-specific residual variance on the training set
    (its scatter about the consensus of all holes); ``clip`` adds per-frame sigma clipping.

    Parameters
    ----------
    order : int
        Polynomial order of every hole's calibration.
    model : callable, optional
        Calibration factory, as in :class:`GeometricCentre`.
    holes : array_like of bool, optional
        Holes allowed in the average (the calibration is still fitted for every hole, so the
        selection can change without refitting).
    weighting : {"equal", "inverse_variance"}
        How the holes are weighted.
    clip : float, optional
        Per-frame sigma-clipping threshold (robust standard deviations).
    accept : sequence of str
        Status codes accepted as usable.
    poses_per_coef : float
        A hole gets its own calibration only if it was seen at no fewer than this many
        training poses per free coefficient (1.5: 15 poses for a cubic's 10). A hole seen at
        barely as many poses as coefficients is fitted almost exactly, through its noise, and
        swings between the poses: at F = 17 mm the corner holes leave the detector at many
        poses, and a cubic on 11 of a 4 x 4 grid missed by up to 8 deg. Such a hole is left out
        of the average (its estimates are NaN).

    Examples
    --------
    >>> from sunlab.multihole import _LstsqPolynomial
    >>> a = np.repeat(np.arange(-4.0, 5.0, 2.0), 5); b = np.tile(np.arange(-4.0, 5.0, 2.0), 5)
    >>> cen = synthetic_centroids(a, b, shots=1, noise_px=0.01)
    >>> s2 = PerHoleAverage(model=lambda: _LstsqPolynomial(2)).fit(cen)
    >>> err = s2.predict(cen).alpha - cen.alpha
    >>> bool(abs(err).max() < 0.005)
    True
    """

    order: int = 5
    model: Callable | None = None
    holes: np.ndarray | None = None
    weighting: str = "equal"
    clip: float | None = None
    accept: Sequence[str] = ("ok",)
    poses_per_coef: float = 1.5
    calibrations_: list | None = field(default=None, repr=False)
    variance_: np.ndarray | None = field(default=None, repr=False)

    def fit(self, cen: xr.Dataset) -> PerHoleAverage:
        """Fit one calibration per hole on a training table; estimate each hole's variance."""
        if self.weighting not in ("equal", "inverse_variance"):
            raise ConfigurationError(
                f"weighting: found {self.weighting!r}, expected 'equal' or 'inverse_variance'"
            )
        factory = self.model or _default_model(self.order)
        ok = usable(cen, self.accept)
        self.calibrations_ = []
        probe = factory()
        if hasattr(probe, "min_poses"):
            n_coef = int(probe.min_poses())
        else:
            order = getattr(probe, "order", self.order)
            n_coef = (order + 1) * (order + 2) // 2
        need = max(math.ceil(self.poses_per_coef * n_coef), 3)
        for h in range(cen.sizes["hole"]):
            table = _hole_table(cen, h, ok)
            n_poses = int(np.isfinite(table["x"].values).any(axis=1).sum())
            # a hole seen at too few poses cannot carry its own calibration: it is left out
            self.calibrations_.append(_fit_model(factory, table) if n_poses >= need else None)
        if all(c is None for c in self.calibrations_):
            raise ConfigurationError(
                f"centroids: no hole was seen at {need} or more training poses, the fewest for "
                f"its own calibration ({n_coef} coefficients x poses_per_coef = "
                f"{self.poses_per_coef}); use more calibration poses or a lower order")
        est = self.predict_holes(cen)
        dev2 = 0.0
        for name in ("alpha", "beta"):
            cons = est[name].median("hole")
            dev2 = dev2 + (est[name] - cons) ** 2
        var = dev2.mean(("pose", "shot")).values / 2
        med = np.nanmedian(var)
        self.variance_ = np.where(np.isfinite(var), np.maximum(var, 1e-3 * med), np.inf)
        return self

    def predict_holes(self, cen: xr.Dataset) -> xr.Dataset:
        """Every hole's own estimate (alpha, beta), deg, on (pose, shot, hole)."""
        if self.calibrations_ is None:
            raise ConfigurationError("PerHoleAverage: call fit() first")
        n_h = cen.sizes["hole"]
        if n_h != len(self.calibrations_):
            raise SchemaError("hole", n_h, f"{len(self.calibrations_)} holes, as in training")
        ok = usable(cen, self.accept).values
        x = np.where(ok, cen["x"].values, np.nan)
        y = np.where(ok, cen["y"].values, np.nan)
        a = np.full(x.shape, np.nan)
        b = np.full(x.shape, np.nan)
        for h, cal in enumerate(self.calibrations_):
            if cal is None:
                continue
            a[..., h], b[..., h] = _predict_arrays(cal, x[..., h], y[..., h])
        return _angles_dataset(cen, a, b, ("pose", "shot", "hole"))

    def weights(self) -> np.ndarray | None:
        """The per-hole weights of the combination (None for equal weights)."""
        if self.weighting == "equal":
            return None
        return 1.0 / self.variance_

    def combine(self, est: xr.Dataset, holes=None) -> xr.Dataset:
        """Combine per-hole estimates (from :meth:`predict_holes`) with this strategy's rule."""
        holes = self.holes if holes is None else holes
        out = {}
        n = None
        for name in ("alpha", "beta"):
            m, n = combine_estimates(est[name], holes=holes, weights=self.weights(),
                                     clip=self.clip)
            out[name] = m.values
        return _angles_dataset(est, out["alpha"], out["beta"], ("pose", "shot"),
                               {"n_holes": (("pose", "shot"), n.values)})

    def predict(self, cen: xr.Dataset) -> xr.Dataset:
        """Combined estimate (alpha, beta), deg, on (pose, shot), with ``n_holes`` used."""
        return self.combine(self.predict_holes(cen))


class _LstsqPolynomial:
    """Minimal least-squares polynomial f(x, y) = sum a_kl x^(k-l) y^l (for doctests and tests).

    The project's calibration is :class:`sunlab.calibration.Polynomial`; this one exists so that
    the strategies can be exercised without it. Inputs are centred and scaled before the fit.
    """

    def __init__(self, order: int = 2):
        self.order = order

    def _design(self, x, y):
        u = (x - self.c_[0]) / self.s_[0]
        v = (y - self.c_[1]) / self.s_[1]
        return np.column_stack([u ** (k - l) * v**l for k in range(self.order + 1)
                                for l in range(k + 1)])

    def fit(self, cen):
        x = cen["x"].values.ravel()
        y = cen["y"].values.ravel()
        a = np.broadcast_to(cen["alpha"].values[:, None], cen["x"].shape).ravel()
        b = np.broadcast_to(cen["beta"].values[:, None], cen["x"].shape).ravel()
        m = np.isfinite(x) & np.isfinite(y)
        self.c_ = (x[m].mean(), y[m].mean())
        self.s_ = (x[m].std() or 1.0, y[m].std() or 1.0)
        D = self._design(x[m], y[m])
        self.coef_ = np.linalg.lstsq(D, np.column_stack([a[m], b[m]]), rcond=None)[0]
        return self

    def predict_xy(self, x, y):
        x = np.asarray(x, float)
        y = np.asarray(y, float)
        p = self._design(np.nan_to_num(x.ravel()), np.nan_to_num(y.ravel())) @ self.coef_
        a = np.where(np.isfinite(x), p[:, 0].reshape(x.shape), np.nan)
        b = np.where(np.isfinite(x), p[:, 1].reshape(x.shape), np.nan)
        return a, b

    def predict(self, cen):
        a, b = self.predict_xy(cen["x"].values, cen["y"].values)
        return xr.Dataset({"alpha": (cen["x"].dims, a), "beta": (cen["x"].dims, b)})


# --------------------------------------------------------------------------------------------
# Errors and statistics
# --------------------------------------------------------------------------------------------
def angle_errors(pred: xr.Dataset, cen: xr.Dataset | None = None) -> xr.Dataset:
    """Estimated minus commanded angles, deg (the paper's test protocol, sec. 5).

    ``pred`` carries the commanded angles as ``alpha_cmd``/``beta_cmd`` (as returned by the
    strategies) or they come from ``cen``'s ``alpha``/``beta``.

    Examples
    --------
    >>> p = xr.Dataset({"alpha": (("pose", "shot"), [[1.5]]), "beta": (("pose", "shot"), [[0.0]])},
    ...                coords={"alpha_cmd": ("pose", [1.0]), "beta_cmd": ("pose", [0.5])})
    >>> float(angle_errors(p).alpha[0, 0]), float(angle_errors(p).beta[0, 0])
    (0.5, -0.5)
    """
    if cen is not None:
        ca, cb = cen["alpha"], cen["beta"]
    else:
        ca, cb = pred["alpha_cmd"], pred["beta_cmd"]
    return xr.Dataset({"alpha": pred["alpha"] - ca.values[:, None] if pred["alpha"].ndim == 2
                       else pred["alpha"] - xr.DataArray(ca.values, dims="pose"),
                       "beta": pred["beta"] - cb.values[:, None] if pred["beta"].ndim == 2
                       else pred["beta"] - xr.DataArray(cb.values, dims="pose")})


def global_stats(est: xr.Dataset) -> dict:
    """The paper's global statistics of each angle: mu, sigma, M, sigma_M (deg), plus the RMS.

    Local error = mean over the shots of |error|, maximum error = max over the shots; mu and
    sigma are the mean and (sample) standard deviation of the local errors over the poses, M and
    sigma_M those of the maximum errors (docs/paper.md sec. 5), computed by :mod:`sunlab.stats`.
    ``rms`` is the root mean square of the per-shot errors and ``n_poses`` the number of poses
    with at least one usable estimate. A hole never seen (no usable estimate: off the detector
    over the whole plan, or left without a calibration) gives NaN statistics with
    ``n_poses = 0``, not a warning.

    Parameters
    ----------
    est : xarray.Dataset
        Estimates ``alpha``, ``beta`` on (pose, shot) with the commanded angles ``alpha_cmd``,
        ``beta_cmd`` as coordinates (the strategies' output), or signed errors (no ``*_cmd``).

    Examples
    --------
    >>> e = xr.Dataset({"alpha": (("pose", "shot"), [[0.1, -0.3], [0.2, 0.2]]),
    ...                 "beta": (("pose", "shot"), [[0.0, 0.0], [0.0, 0.0]])})
    >>> s = global_stats(e)
    >>> round(s["alpha"]["mu"], 6), round(s["alpha"]["M"], 6), s["alpha"]["n_poses"]
    (0.2, 0.25, 2)
    >>> global_stats(e * np.nan)["beta"]["n_poses"]                   # a hole never seen
    0
    """
    from . import stats

    ref = None
    if "alpha_cmd" not in est.variables or "beta_cmd" not in est.variables:
        ref = {"alpha": xr.DataArray(0.0), "beta": xr.DataArray(0.0)}
    loc = stats.local_errors(est[["alpha", "beta"]], ref)
    table = stats.global_stats({"m": loc})["m"]
    err = stats.shot_errors(est[["alpha", "beta"]], ref)
    out = {}
    for name in ("alpha", "beta"):
        e = np.asarray(err[name].values, dtype=float)
        e = e[np.isfinite(e)]
        n_poses = int(np.isfinite(loc["local_error"].sel(angle=name).values).sum())
        out[name] = {k: float(table.loc[(name, k)]) if n_poses else math.nan
                     for k in stats.STATS}
        out[name]["rms"] = float(np.sqrt(np.mean(e**2))) if e.size else math.nan
        out[name]["n_poses"] = n_poses
    return out


# --------------------------------------------------------------------------------------------
# Defect metrics and rejection
# --------------------------------------------------------------------------------------------
def _stamp_moments(img):
    """Second and third moments of a background-subtracted stamp (threshold at 10 % of peak)."""
    img = np.asarray(img, dtype=float)
    border = np.concatenate([img[0], img[-1], img[:, 0], img[:, -1]])
    bg = np.median(border)
    w = img - bg
    peak = w.max()
    if not np.isfinite(peak) or peak <= 0:
        return np.nan, np.nan, np.nan
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
    return r, ell, asym


def _stamp(frame, x, y, half):
    ny, nx = frame.shape
    xi, yi = int(round(x)), int(round(y))
    x0, x1 = max(xi - half, 0), min(xi + half + 1, nx)
    y0, y1 = max(yi - half, 0), min(yi + half + 1, ny)
    return np.asarray(frame[y0:y1, x0:x1], dtype=float), (x0, y0)


def spot_metrics(cube: xr.Dataset, cen: xr.Dataset, *, poses=None, shot: int = 0,
                 half: int = 30, max_frames: int = 6) -> xr.Dataset:
    """Shape metrics of every hole's spot from its pixels: size, ellipticity, asymmetry.

    A stamp of ``2 * half + 1`` px is cut around each centroid in a few frames, the background
    (median of the stamp border) subtracted and pixels under 10 % of the peak zeroed; the
    moments give the RMS radius r, the ellipticity (l1 - l2) / (l1 + l2) of the second-moment
    matrix and the asymmetry |m3| / r^3 from the third moments (zero for a round or
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
    >>> m = spot_metrics(cube, cen)
    >>> bool(m.asymmetry[1] > 5 * m.asymmetry[0] and m.ellipticity[1] > m.ellipticity[0])
    True
    """
    n_p = cube.sizes["pose"]
    if poses is None:
        poses = np.unique(np.linspace(0, n_p - 1, min(max_frames, n_p)).round().astype(int))
    n_h = cen.sizes["hole"]
    res = np.full((len(poses), n_h, 3), np.nan)
    ok = usable(cen).values
    for n, p in enumerate(poses):
        frame = np.asarray(cube["frames"].isel(pose=int(p), shot=shot).values)
        for h in range(n_h):
            if not ok[p, shot, h]:
                continue
            st, _ = _stamp(frame, cen["x"].values[p, shot, h], cen["y"].values[p, shot, h], half)
            res[n, h] = _stamp_moments(st)
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
    amplitudes |c_m| for m in ``harmonics`` (m = 0 is flux or size, m = 1 a centroid shift;
    m >= 2 an out-of-round edge) are divided by their median over the holes, and the metric is
    their RMS: about 1 for a typical hole, several for a burred one.

    Only low harmonics carry the burr: the spot is the hole convolved with the image of the
    Sun's disk (0.27 mm across at F = 17 mm, wider than the 0.2 mm hole), which smooths a rim
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
        (about 20 s per 100 frames of 100 holes).
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
    from scipy.ndimage import map_coordinates

    n_p, n_h = cen.sizes["pose"], cen.sizes["hole"]
    ok = usable(cen).values[:, shot, :]
    xs, ys = cen["x"].values[:, shot, :], cen["y"].values[:, shot, :]
    poses = [p for p in range(n_p) if ok[p].sum() >= 3]
    if len(poses) > max_frames:
        poses = [poses[int(k)] for k in np.linspace(0, len(poses) - 1, max_frames).round()]
    if radius_px is None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            r_rms = float(np.nanmedian(cen["radius"].where(usable(cen)).values)) \
                if "radius" in cen else np.nan
        if not np.isfinite(r_rms) and poses:
            frame = np.asarray(cube["frames"].isel(pose=poses[0], shot=shot).values)
            hs = np.flatnonzero(ok[poses[0]])[:10]
            r_rms = float(np.nanmedian([_stamp_moments(_stamp(frame, xs[poses[0], h],
                                                              ys[poses[0], h], 40)[0])[0]
                                        for h in hs]))
        radius_px = 2.1 * r_rms
        if poses:
            p0 = poses[0]
            hx, hy = xs[p0][ok[p0]], ys[p0][ok[p0]]
            d = np.hypot(hx[:, None] - hx[None], hy[:, None] - hy[None])
            d[d == 0] = np.inf
            radius_px = min(radius_px, 0.45 * float(np.median(d.min(1))))
    if not poses or not np.isfinite(radius_px) or radius_px < 3:
        return xr.DataArray(np.full(n_h, np.nan), dims="hole", coords={"hole": cen["hole"].values},
                            name="edge_roughness")
    n_r = int(np.ceil(radius_px))
    g = np.arange(-n_r, n_r + 1, dtype=float)
    gy, gx = np.meshgrid(g, g, indexing="ij")
    rr = np.hypot(gx, gy)
    disk = rr <= radius_px
    ring = (rr > 0.5) & disk
    theta = np.arctan2(gy, gx)[ring]
    acc = np.zeros((n_h, ring.sum()))
    count = np.zeros(n_h)
    for p in poses:
        frame = np.asarray(cube["frames"].isel(pose=int(p), shot=shot).values, dtype=float)
        hs = np.flatnonzero(ok[p])
        stamps = np.empty((hs.size, ring.sum()))
        for n, h in enumerate(hs):
            # cut a stamp with a margin first: the spline prefilter then runs on it, not on the
            # whole frame
            xi, yi = int(round(xs[p, h])), int(round(ys[p, h]))
            m = n_r + 4
            y0, x0 = max(yi - m, 0), max(xi - m, 0)
            sub = frame[y0:yi + m + 1, x0:xi + m + 1]
            st = map_coordinates(sub, [ys[p, h] - y0 + gy, xs[p, h] - x0 + gx], order=3,
                                 mode="nearest")
            edge = np.concatenate([st[0], st[-1], st[:, 0], st[:, -1]])
            st = st - np.median(edge)
            total = st[disk].sum()
            stamps[n] = st[ring] / total if total > 0 else np.nan
        template = np.nanmedian(stamps, axis=0)
        peak = np.nanmax(template)
        good = np.isfinite(stamps).all(axis=1)
        acc[hs[good]] += (stamps[good] - template) / peak
        count[hs[good]] += 1
    mean_res = acc / np.maximum(count, 1)[:, None]
    m = np.arange(harmonics[0], harmonics[1] + 1)
    amp = np.abs(mean_res @ np.exp(-1j * m[None, :] * theta[:, None]))  # (hole, harmonic)
    amp[count == 0] = np.nan
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        scale = np.nanmedian(amp, axis=0)
        value = np.sqrt(np.nanmean((amp / np.where(scale > 0, scale, np.nan)) ** 2, axis=1))
    return xr.DataArray(value, dims="hole", coords={"hole": cen["hole"].values},
                        name="edge_roughness")


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
    """All defect metrics of every hole (:data:`DEFECT_METRICS`), large = bad.

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table on (pose, shot, hole), usually the training experiment.
    strategy : PerHoleAverage, optional
        A fitted per-hole calibration; gives the residual metrics.
    cube : xarray.Dataset, optional
        The frame cube of ``cen``; gives the spot-shape metrics (:func:`spot_metrics`) and the
        edge roughness that finds burred holes (:func:`edge_roughness`). Without
        it they come from the per-spot ``radius``, ``ellipticity``, ``asymmetry`` of the table
        when :func:`sunlab.centroid.locate` measured them.
    accept : sequence of str
        Status codes counted as present.
    **spot_kw
        Passed to :func:`spot_metrics`.

    Returns
    -------
    xarray.Dataset on ``hole`` with the hole coordinates.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=2, defects={7: {"flux": 0.4}})
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
        sm = spot_metrics(cube, cen, **spot_kw)
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
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=2, defects={7: {"flux": 0.4}})
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


# --------------------------------------------------------------------------------------------
# The gain of N holes over one, and its error budget
# --------------------------------------------------------------------------------------------
def error_budget(est: xr.Dataset, holes=None) -> dict:
    """Split the per-hole test errors into a part common to all holes and a hole-specific part.

    With e_h the error of hole h's estimate in a frame, the common part is the mean over holes
    e_bar and the specific part e_h - e_bar. For N holes with independent specific errors of
    variance s^2 and a common error of variance c^2, one hole has variance c^2 + s^2 and the
    average c^2 + s^2 / N, so the gain in standard deviation is at most
    sqrt((c^2 + s^2) / (c^2 + s^2 / N)), which tends to sqrt(N) (eq. 5) only when c -> 0.

    Returns
    -------
    dict per angle: ``single`` (RMS of one hole's error), ``common`` (RMS of the common part,
    corrected for the specific part's leftover s/sqrt(N)), ``specific`` (RMS of the specific
    part), ``n_holes``, ``gain_limit`` (the predicted gain) and ``sqrt_n``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> e = rng.normal(0, 1, (400, 1, 100)) + rng.normal(0, 0.3, (400, 1, 1))
    >>> dims = ("pose", "shot", "hole")
    >>> est = xr.Dataset({"alpha": (dims, e), "beta": (dims, e)},
    ...                  coords={"alpha_cmd": ("pose", np.zeros(400)),
    ...                          "beta_cmd": ("pose", np.zeros(400))})
    >>> b = error_budget(est)["alpha"]
    >>> round(b["specific"], 1), round(b["common"], 1)
    (1.0, 0.3)
    """
    err = angle_errors(est)
    out = {}
    for name in ("alpha", "beta"):
        e = err[name]
        if holes is not None:
            e = e.where(xr.DataArray(np.asarray(holes, bool), dims="hole"))
        n = float(np.isfinite(e).sum("hole").mean())
        mean = e.mean("hole")
        spec = e - mean
        s2 = float((spec**2).mean()) * n / max(n - 1, 1)
        m2 = float((mean**2).mean())
        c2 = max(m2 - s2 / n, 0.0)
        single = float(np.sqrt((e**2).mean()))
        out[name] = {"single": single, "common": math.sqrt(c2), "specific": math.sqrt(s2),
                     "n_holes": n, "gain_limit": math.sqrt((c2 + s2) / (c2 + s2 / n)),
                     "sqrt_n": math.sqrt(n)}
    return out


def gain_study(train: xr.Dataset, test: xr.Dataset, *, order: int = 5, model=None,
               cube=None, kappa: float = 5.0, clip: float = 4.0) -> dict:
    """How far 100 holes get toward the sqrt(N) of eq. (5), with and without bad-hole rejection.

    Fits both strategies and the per-hole calibrations on ``train``; on ``test`` compares one
    hole (every good hole alone: the median of their statistics, and the best single hole), the
    geometric centre, the plain average, and the average after rejection with inverse-variance
    weights and sigma clipping. Adds the error budget of :func:`error_budget`.

    Returns
    -------
    dict with ``stats`` (strategy -> angle -> stat -> value, deg), ``gain`` (strategy -> angle
    -> sigma and rms gain over one hole), ``budget``, ``bad`` (indices of rejected holes) and
    ``metrics`` (the defect metrics).

    Examples
    --------
    >>> a = np.repeat(np.linspace(-8, 2, 6), 6); b = np.tile(np.linspace(-2, 8, 6), 6)
    >>> kw = dict(shots=2, hole_sigma_px=0.1, noise_px=0.01)
    >>> tr = synthetic_centroids(a, b, seed=1, **kw)
    >>> te = synthetic_centroids(a + 0.5, b + 0.5, seed=2, **kw)
    >>> g = gain_study(tr, te, order=4)
    >>> bool(g["gain"]["averaging"]["alpha"]["rms"] > 5)
    True
    """
    s2 = PerHoleAverage(order=order, model=model).fit(train)
    metrics = defect_metrics(train, strategy=s2, cube=cube)
    bad = reject_bad_holes(metrics, kappa=kappa).values
    good = ~bad
    s1 = GeometricCentre(order=order, model=model).fit(train)
    s1r = GeometricCentre(order=order, model=model, holes=good).fit(train)
    est = s2.predict_holes(test)
    # one hole: each good hole alone
    # (a hole never on the detector during the test, or without a calibration, has no statistics)
    singles = [s for s in (global_stats(est.isel(hole=h)) for h in np.flatnonzero(good))
               if s["alpha"]["n_poses"] and s["beta"]["n_poses"]]
    if not singles:
        raise ConfigurationError("test: no good hole has a usable estimate at any test pose")
    stats = {
        "one_hole_median": {a: {k: float(np.median([s[a][k] for s in singles]))
                                for k in singles[0][a]} for a in ("alpha", "beta")},
        "geometric_centre": global_stats(s1.predict(test)),
        "geometric_centre_rejected": global_stats(s1r.predict(test)),
        "averaging": global_stats(s2.combine(est)),
        "averaging_rejected": global_stats(
            PerHoleAverage(order=order, model=model, holes=good, weighting="inverse_variance",
                           clip=clip, calibrations_=s2.calibrations_, variance_=s2.variance_
                           ).combine(est)),
    }
    one = stats["one_hole_median"]
    gain = {k: {a: {"sigma": one[a]["sigma"] / v[a]["sigma"], "mu": one[a]["mu"] / v[a]["mu"],
                    "rms": one[a]["rms"] / v[a]["rms"]} for a in ("alpha", "beta")}
            for k, v in stats.items() if k != "one_hole_median"}
    return {"stats": stats, "gain": gain, "budget": error_budget(est, holes=good),
            "budget_all": error_budget(est), "bad": np.flatnonzero(bad).tolist(),
            "metrics": metrics}


# --------------------------------------------------------------------------------------------
# Figures 13-15 and the metric map
# --------------------------------------------------------------------------------------------
def fig13_frame(frame, cen_frame=None, *, ax=None, bad=None):
    """Fig. 13: a frame of the 100-hole mask, with the centroids and bad holes marked.

    Parameters
    ----------
    frame : array_like, shape (ny, nx)
        One detector frame, DN.
    cen_frame : xarray.Dataset, optional
        The frame's centroids on ``hole`` (``cen.isel(pose=p, shot=s)``).
    ax : matplotlib Axes, optional
    bad : array_like of bool, optional
        Bad holes, circled in red.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = fig13_frame(np.zeros((64, 80)))
    >>> fig.axes[0].get_xlabel()
    'x (column), px'
    """
    import matplotlib.pyplot as plt

    fig = ax.figure if ax is not None else plt.figure(figsize=(7, 5.6))
    ax = ax or fig.add_subplot()
    im = ax.imshow(np.asarray(frame), cmap="gray", origin="upper", interpolation="nearest")
    fig.colorbar(im, ax=ax, label="DN", shrink=0.8)
    if cen_frame is not None:
        ax.plot(cen_frame["x"].values, cen_frame["y"].values, "+", color="tab:orange", ms=5,
                label="centroids")
        if bad is not None:
            b = np.asarray(bad, bool)
            ax.plot(cen_frame["x"].values[b], cen_frame["y"].values[b], "o", mfc="none",
                    color="red", ms=14, label="rejected holes")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_xlabel("x (column), px")
    ax.set_ylabel("y (row), px")
    ax.set_title("100-hole mask: one frame (Fig. 13)")
    return fig


def fig14_bad_holes(frame, cen_frame, holes, *, reference=None, half: int = 30, metrics=None):
    """Fig. 14: stamps of bad holes' spots beside a good one.

    Parameters
    ----------
    frame : array_like, shape (ny, nx)
    cen_frame : xarray.Dataset
        Centroids of that frame on ``hole``.
    holes : sequence of int
        The bad holes to show.
    reference : int, optional
        A good hole shown first.
    half : int
        Stamp half-size, px.
    metrics : xarray.Dataset, optional
        Defect metrics, printed under each stamp.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1).isel(pose=0, shot=0)
    >>> fig = fig14_bad_holes(np.zeros((1024, 1280)), cen, [3, 4], reference=0)
    >>> len(fig.axes)
    3
    """
    import matplotlib.pyplot as plt

    show = ([reference] if reference is not None else []) + [int(h) for h in holes]
    if not show:
        raise ConfigurationError("holes: no hole to show; pass at least one hole index")
    fig, axes = plt.subplots(1, len(show), figsize=(2.6 * len(show), 3.4), squeeze=False,
                             layout="constrained")
    frame = np.asarray(frame)
    for ax, h in zip(axes[0], show, strict=True):
        x, y = float(cen_frame["x"].values[h]), float(cen_frame["y"].values[h])
        if np.isfinite(x):
            st, (x0, y0) = _stamp(frame, x, y, half)
            ax.imshow(st, cmap="magma", origin="upper",
                      extent=(x0 - 0.5, x0 + st.shape[1] - 0.5, y0 + st.shape[0] - 0.5, y0 - 0.5))
            ax.plot(x, y, "+", color="cyan")
        else:
            ax.text(0.5, 0.5, "no spot", ha="center", transform=ax.transAxes)
        title = f"hole {h}" + (" (good)" if h == reference else "")
        if metrics is not None:
            m = metrics.sel(hole=h) if "hole" in metrics.dims else metrics
            short = {"flux_deficit": "flux deficit", "ellipticity": "ellipticity",
                     "asymmetry": "asymmetry", "edge_roughness": "edge roughness"}
            bits = [f"{name} {float(m[k]):.2g}" for k, name in short.items() if k in m]
            title += "".join(("\n" if n % 2 == 0 else ", ") + b for n, b in enumerate(bits))
        ax.set_title(title, fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle("Spots of bad holes (Fig. 14)", fontsize=10)  # constrained layout: no overlap
    return fig


def fig15_rectangles(table: Mapping[str, Mapping], *, ax=None):
    """Fig. 15: the paper's rectangles [M - 3 sigma_M, M + 3 sigma_M] in alpha and beta.

    Parameters
    ----------
    table : mapping
        ``{label: {"alpha": {"M": .., "sigma_M": ..}, "beta": {...}}}`` in deg, e.g. the
        ``stats`` of :func:`gain_study` or the columns of :func:`sunlab.reproduce_table5`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> t = {"1 hole": {"alpha": {"M": 0.0099, "sigma_M": 0.0054},
    ...                 "beta": {"M": 0.0178, "sigma_M": 0.0080}}}
    >>> len(fig15_rectangles(t).axes[0].patches)
    1
    """
    import matplotlib.pyplot as plt

    from .plots import draw_rectangles

    fig = ax.figure if ax is not None else plt.figure(figsize=(6, 5.8), layout="constrained")
    ax = ax or fig.add_subplot()
    boxes = [(label, s["alpha"]["M"] - 3 * s["alpha"]["sigma_M"],
              s["alpha"]["M"] + 3 * s["alpha"]["sigma_M"],
              s["beta"]["M"] - 3 * s["beta"]["sigma_M"], s["beta"]["M"] + 3 * s["beta"]["sigma_M"])
             for label, s in table.items()]
    # numbered rectangles, a shared tag where they coincide, the legend below the axes
    draw_rectangles(ax, boxes)
    ax.set_xlabel(r"$\alpha$ error, deg: $M \pm 3\sigma_M$")
    ax.set_ylabel(r"$\beta$ error, deg: $M \pm 3\sigma_M$")
    ax.set_title("One hole vs 100 holes (Fig. 15)")
    return fig


def metric_scale(values) -> tuple[float, float]:
    """Colour scale (low, high) of a defect metric: its 2nd and 98th percentiles over the holes.

    One scale for every view of a metric (:func:`plot_metric_map`, the buttons of
    :class:`sunlab.widgets.HoleExplorer`), robust to the one bad hole that would otherwise
    squeeze all good holes into one colour.

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


def plot_metric_map(metrics: xr.Dataset, name: str, *, bad=None, ax=None):
    """The mask's holes as a map coloured by one defect metric; rejected holes crossed.

    Examples
    --------
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=1, defects={7: {"flux": 0.4}})
    >>> fig = plot_metric_map(defect_metrics(cen), "flux_deficit")
    >>> fig.axes[0].get_title()
    'flux_deficit'
    """
    import matplotlib.pyplot as plt

    if name not in metrics:
        raise ConfigurationError(f"name: metric {name!r} not in {list(metrics.data_vars)}")
    i, j, nr, nc = hole_grid(metrics)
    grid = np.full((nr, nc), np.nan)
    grid[i, j] = metrics[name].values
    fig = ax.figure if ax is not None else plt.figure(figsize=(4.8, 4))
    ax = ax or fig.add_subplot()
    lo, hi = metric_scale(metrics[name].values)
    im = ax.imshow(grid, cmap="viridis", origin="upper", vmin=lo, vmax=hi)
    fig.colorbar(im, ax=ax, label=metrics[name].attrs.get("units", ""), extend="both")
    if bad is not None:
        b = np.asarray(bad, bool)
        ax.plot(j[b], i[b], "x", color="red", ms=12, mew=2)
    ax.set_xlabel("hole column j")
    ax.set_ylabel("hole row i")
    ax.set_title(name)
    return fig
