"""Centroid-level Monte Carlo: ``centroids/1`` tables with known truth, no frames rendered.

:func:`synthetic_centroids` serves both uses of the project: one hole on ``(pose, shot)`` (the
single-hole bench of Tables 1-4: the exact pinhole model with mounting errors, a bounded per-pose
platform error, per-shot jitter and centroid noise) and a multi-hole mask on
``(pose, shot, hole)`` (Table 5 and :mod:`sunlab.multihole`: the ideal model (1) from every
hole's design position, a common per-pose error, hole-specific errors and per-hole defects).
The holes of a multi-hole table come from a :class:`HoleLayout`, in pixels, usually built from
a :class:`sunlab.sim.Mask` (which holds the layout in millimetres).

References
----------
.. [1] docs/paper.md, sec. 5, 6 and 8 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import xarray as xr

from .. import geometry, schema
from ..errors import SchemaError
from .mask import Mask
from .source import _check

__all__ = ["synthetic_centroids"]


@dataclass(frozen=True)
class HoleLayout:
    """Design positions of a mask's holes on the detector (sun at zenith), px.

    Attributes
    ----------
    x_cf, y_cf : numpy.ndarray, shape (hole,)
        Design projection of each hole, px (column, row).
    hole_i, hole_j : numpy.ndarray of int, shape (hole,)
        Grid row and column (-1 for a free layout).

    Examples
    --------
    >>> lay = HoleLayout.from_mask(Mask.grid())
    >>> lay.x_cf.shape, round(float(lay.x_cf[1] - lay.x_cf[0]), 2), int(lay.hole_i[10])
    ((100,), 71.43, 1)
    """

    x_cf: np.ndarray
    y_cf: np.ndarray
    hole_i: np.ndarray
    hole_j: np.ndarray

    @classmethod
    def from_mask(cls, mask: Mask, *, centre_px=(572.0, 375.0),
                  pixel_pitch_mm: float = 0.007) -> HoleLayout:
        """The holes of a :class:`sunlab.sim.Mask` (mm) as pixels about ``centre_px``.

        The default centre sits off the detector centre so that all spots of the paper's
        10 x 10 grid stay on the Ibis4 over the paper's test range (docs/paper.md sec. 8).

        Parameters
        ----------
        mask : sunlab.sim.Mask
            Its holes' design positions (mm) and grid indices.
        centre_px : (float, float)
            Where the mask's origin projects at zenith, (x, y) px.
        pixel_pitch_mm : float
            Pixel pitch, mm.

        Returns
        -------
        HoleLayout
            Zenith centroids (px) and grid indices (i, j) of every hole.
        """
        x, y, i, j = np.array([(h.x_mm, h.y_mm, h.i, h.j) for h in mask.holes]).T
        return cls(centre_px[0] + x / pixel_pitch_mm, centre_px[1] + y / pixel_pitch_mm,
                   i.astype(int), j.astype(int))

    @classmethod
    def of(cls, layout, pixel_pitch_mm: float = 0.007) -> HoleLayout:
        """A layout from ``"grid"`` (the paper's 10 x 10 at 0.5 mm), a Mask or a HoleLayout.

        Parameters
        ----------
        layout : {"grid"} or sunlab.sim.Mask or HoleLayout
            A HoleLayout is returned as it is; a mask goes through :meth:`from_mask`.
        pixel_pitch_mm : float
            Pixel pitch, mm.

        Returns
        -------
        HoleLayout
        """
        if isinstance(layout, HoleLayout):
            return layout
        _check(isinstance(layout, Mask) or (isinstance(layout, str) and layout == "grid"),
               "layout", layout, "None (one hole), 'grid', a sunlab.sim.Mask or a HoleLayout",
               "pass layout='grid' for the paper's 100-hole mask.")
        return cls.from_mask(Mask.grid() if isinstance(layout, str) else layout,
                             pixel_pitch_mm=pixel_pitch_mm)


def synthetic_centroids(alpha, beta, shots: int = 8, *, layout=None, seed: int = 0,
                        **errors) -> xr.Dataset:
    """A centroid table with known truth, at the level of the centroid contract.

    Parameters
    ----------
    alpha, beta : array_like, shape (pose,)
        Commanded platform angles, deg.
    shots : int
        Frames per pose (the paper: 8).
    layout : None, "grid", sunlab.sim.Mask or HoleLayout
        None: one hole, a table on ``(pose, shot)``; otherwise the mask's holes, a table on
        ``(pose, shot, hole)`` with coordinates ``hole_i``, ``hole_j``, ``hole_x_cf``,
        ``hole_y_cf``.
    seed : int
        Seed of :func:`numpy.random.default_rng`; the table is deterministic in it.
    **errors
        One hole (exact pinhole model, :func:`sunlab.geometry.model.pinhole_centroid`):
        ``mask_distance_mm`` (5), ``pixel_pitch_mm`` (0.007), ``x_cf``, ``y_cf`` (design
        projection, px: 639.5, 511.5), ``delta_f_mm``, ``mounting_deg`` (alpha0, beta0,
        gamma0), ``hole_offset_px``, ``pose_error_deg`` (half-widths of the uniform per-pose
        platform error), ``jitter_deg`` (per-shot normal jitter), ``noise_px``, ``experiment``.

        Many holes (ideal model (1) from each hole's design position): ``mask_distance_mm``,
        ``pixel_pitch_mm``, ``hole_scale`` (F_h / F per hole: a tilted mask),
        ``common_sigma_deg`` (standard deviation of the uniform per-pose error common to all
        holes, per angle), ``shot_sigma_deg``, ``hole_sigma_px`` (hole-specific, pose-dependent
        error), ``noise_px``, ``flux`` (per hole, DN, default 2e5), ``defects`` (``{hole:
        {"flux": factor, "sigma_px", "noise_px", "missing": probability, "bias_px": (bx,
        by)}}``), ``detector_shape`` ((ny, nx); spots within ``edge_px`` of the edge are lost,
        status ``clipped``).

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` with the sensor attributes and the truth ``true_alpha``,
        ``true_beta`` on (pose, shot).

    Examples
    --------
    >>> cen = synthetic_centroids([0.0, -5.0], [0.0, 3.0], shots=2)
    >>> cen.x.dims, float(cen.x[0, 0])
    (('pose', 'shot'), 639.5)
    >>> cen = synthetic_centroids([0.0, -5.0], [0.0, 3.0], shots=2, layout="grid", noise_px=0.01)
    >>> dict(cen.x.sizes)
    {'pose': 2, 'shot': 2, 'hole': 100}
    """
    if layout is None:
        return _one_hole(alpha, beta, shots, seed=seed, **errors)
    pitch = float(errors.get("pixel_pitch_mm", 0.007))
    return _many_holes(alpha, beta, shots, HoleLayout.of(layout, pitch), seed=seed, **errors)


def _one_hole(alpha, beta, shots: int = 8, *, mask_distance_mm: float = 5.0,
              pixel_pitch_mm: float = 0.007, x_cf: float = 639.5, y_cf: float = 511.5,
              delta_f_mm: float = 0.0, mounting_deg=(0.0, 0.0, 0.0), hole_offset_px=(0.0, 0.0),
              pose_error_deg=(0.0, 0.0), jitter_deg: float = 0.0, noise_px: float = 0.0,
              seed: int = 0, experiment: str = ""):
    """One hole: the bench's per-pose error, jitter, mounting and noise (see the caller)."""
    alpha, beta = np.asarray(alpha, dtype=float).ravel(), np.asarray(beta, dtype=float).ravel()
    _check(alpha.shape == beta.shape, "alpha, beta", (alpha.shape, beta.shape),
           "equal lengths (one pair per pose)", "pass flat arrays of the plan's poses.")
    _check(int(shots) >= 1, "shots", shots, ">= 1")
    rng = np.random.default_rng(seed)
    n, shape = alpha.size, (alpha.size, int(shots))
    true_a, true_b = (v[:, None] + rng.uniform(-w, w, (n, 1)) + rng.normal(0.0, jitter_deg, shape)
                      for v, w in zip((alpha, beta), pose_error_deg, strict=True))
    x, y = geometry.model.pinhole_centroid(true_a, true_b, mask_distance_mm, pixel_pitch_mm,
                                           x_cf + hole_offset_px[0], y_cf + hole_offset_px[1],
                                           delta_f_mm=delta_f_mm, mounting_deg=mounting_deg)
    x, y = (v + rng.normal(0.0, noise_px, shape) for v in (x, y))
    attrs = {"pixel_pitch_mm": float(pixel_pitch_mm), "mask_distance_mm": float(mask_distance_mm),
             "x_cf_px": float(x_cf), "y_cf_px": float(y_cf), "experiment": str(experiment)}
    return schema.centroids_dataset(x, y, alpha=alpha, beta=beta, method="synthetic", attrs=attrs,
                                    extra=_truth(true_a, true_b))


def _truth(ta, tb) -> dict:
    """The true platform angles of a table, deg, on (pose, shot)."""
    return {"true_alpha": (("pose", "shot"), ta, {"units": "deg"}),
            "true_beta": (("pose", "shot"), tb, {"units": "deg"})}


def _apply_defects(rng, x, y, f, defects: Mapping[int, Mapping] | None):
    """Add each defective hole's extra errors in place; return the frames that lose the spot."""
    n_p, shots, _ = x.shape
    lost = np.zeros(x.shape, dtype=bool)
    for h, d in (defects or {}).items():
        h = int(h)
        f[h] *= float(d.get("flux", 1.0))
        s, nz = float(d.get("sigma_px", 0.0)), float(d.get("noise_px", 0.0))
        for v, bias in zip((x, y), d.get("bias_px", (0.0, 0.0)), strict=True):
            v[..., h] += rng.normal(0, s, (n_p, 1)) + rng.normal(0, nz, (n_p, shots))
            v[..., h] += bias
        lost[..., h] |= rng.random((n_p, shots)) < float(d.get("missing", 0.0))
    return lost


def _many_holes(alpha, beta, shots: int, layout: HoleLayout, *, mask_distance_mm: float = 5.0,
                pixel_pitch_mm: float = 0.007, hole_scale=None, common_sigma_deg=(0.0, 0.0),
                shot_sigma_deg: float = 0.0, hole_sigma_px: float = 0.0, noise_px: float = 0.0,
                flux=None, defects: Mapping[int, Mapping] | None = None,
                detector_shape=(1024, 1280), edge_px: float = 20.0, seed: int = 0):
    """Many holes: common, hole-specific and per-frame errors and defects (see the caller)."""
    rng = np.random.default_rng(seed)
    alpha, beta = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (alpha, beta))
    if alpha.shape != beta.shape or alpha.ndim != 1:
        raise SchemaError("alpha, beta", f"shapes {alpha.shape}, {beta.shape}", "equal 1-d shapes")
    x_cf, y_cf = np.asarray(layout.x_cf, float), np.asarray(layout.y_cf, float)
    n_h, n_p = x_cf.size, alpha.size
    scale = np.ones(n_h) if hole_scale is None else np.asarray(hole_scale, dtype=float)
    shape = (n_p, shots, n_h)
    # the common error: zero-mean uniform of standard deviation c (bounded, like a stage's steps)
    ta, tb = (v[:, None] + rng.uniform(-np.sqrt(3.0), np.sqrt(3.0), (n_p, 1)) * c
              + rng.normal(0, shot_sigma_deg, (n_p, shots))
              for v, c in zip((alpha, beta), np.broadcast_to(common_sigma_deg, (2,)), strict=True))
    dx, dy = geometry.ideal_centroid(ta, tb, mask_distance_mm, pixel_pitch_mm, 0.0, 0.0)
    hx, hy = (rng.normal(0, hole_sigma_px, (n_p, 1, n_h)) for _ in range(2))
    x, y = (c + scale * d[..., None] + h + rng.normal(0, noise_px, shape)
            for c, d, h in ((x_cf, dx, hx), (y_cf, dy, hy)))
    f = np.full(n_h, 2e5) if flux is None else np.asarray(flux, dtype=float).copy()
    lost = _apply_defects(rng, x, y, f, defects)
    ny, nx = detector_shape
    clipped = (x < edge_px) | (x > nx - 1 - edge_px) | (y < edge_px) | (y > ny - 1 - edge_px)
    status = np.where(clipped, schema.STATUS["clipped"], schema.STATUS["ok"])
    status = np.where(lost & ~clipped, schema.STATUS["no_spot"], status)
    bad = status != schema.STATUS["ok"]
    fl = np.where(bad, np.nan, np.broadcast_to(f, shape) * np.cos(np.deg2rad(ta))[..., None])
    cen = schema.centroids_dataset(
        np.where(bad, np.nan, x), np.where(bad, np.nan, y), flux=fl, status=status, alpha=alpha,
        beta=beta, method="synthetic",
        attrs={"mask_distance_mm": mask_distance_mm, "pixel_pitch_mm": pixel_pitch_mm},
        extra=_truth(ta, tb))
    return cen.assign_coords(
        hole_i=("hole", np.asarray(layout.hole_i)), hole_j=("hole", np.asarray(layout.hole_j)),
        hole_x_cf=("hole", x_cf, {"units": "px"}), hole_y_cf=("hole", y_cf, {"units": "px"}),
    )
