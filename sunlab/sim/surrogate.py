"""The centroid-level surrogate of the virtual bench: centroids of a plan without rendering.

A rendered experiment takes minutes; the surrogate gives the same plan's centroid table in
seconds, so that a parameter of the bench can be scanned (the studies of ``studies/``
do) and the chosen values then confirmed on rendered frames by ``sunlab reproduce``.

The surrogate, :func:`surrogate_centroids`, keeps every mechanism of the rendered bench that moves
a centroid by more than a few thousandths of a pixel, computed the same way as the renderer:

* **Geometry**: the ray through each hole centre for the *true* platform angles, from
  :func:`sunlab.sim.render.spot_geometry` (mounting rotation, mask distance F + dF, mask tilt,
  offset and play), plus the mean of the sun-disk kernel (the spot's centre of light is not
  exactly on the ray under an oblique, extended source).
* **Platform**: the true angles of every shot from the bench's own platform table (the per-pose
  error, its shape per axis, the wobble, the per-shot jitter), identical to the rendered cube's
  ``true_alpha``/``true_beta`` for the same seed and plan.
* **Spot-specific error**: the shift of the centre of mass that the detector's gain pattern
  (PRNU) gives a spot of the bench's shape at each position. For a spot profile ``S`` centred
  at ``c`` on a gain map ``g`` the centroid is

  .. math:: \\bar{x}(c) = c + \\frac{\\sum_u u\\,S(u)\\,g(c + u)}{\\sum_u S(u)\\,g(c + u)}
            - \\frac{\\sum_u u\\,S(u)}{\\sum_u S(u)},

  two correlations of the gain map with the spot (FFT, once per detector and F), sampled at the
  spot's position by bilinear interpolation. This error is repeatable (the same pixel pattern
  under the same spot) but varies over the correlation length of the pattern; at a large F a
  1-degree calibration step moves the spot by several correlation lengths, so neither an
  interpolation table nor a polynomial can learn it: it acts as a per-pose error in experiment I
  (noisy calibration nodes) and again in experiment III.
* **Per-shot centroid noise**: photon, dark and read noise of the window, normal, RMS
  ``noise_px`` (measured on rendered frames of the same spot, see
  ``studies.surrogate_tables.centroid_noise_px``).

What the surrogate leaves out (all below 0.01 px on the default bench): the fill factor's
pixel-phase bias, quantisation, and the window of the centroid algorithm.

Examples
--------
>>> from sunlab import plans
>>> from sunlab.sim import Bench
>>> bench = Bench.paper_single_hole()
>>> round(spot_diameter_px(bench), 1)  # the hole plus the sun's penumbra, px
35.4
>>> cen = surrogate_centroids(bench, plans.experiment("III").thin(6), seed=0)
>>> dict(cen.x.sizes)
{'pose': 16, 'shot': 8}

"""

from __future__ import annotations

import functools

import numpy as np
import xarray as xr

__all__ = []


def spot_diameter_px(bench) -> float:
    """Diameter of the spot at zenith, px: the hole plus the sun's penumbra, (d + F' theta) / p.

    The spot of a pinhole of diameter d under a source of angular diameter theta at height F'
    is d + F' theta across (the umbra shrinks and the penumbra grows with F'). The paper's
    algorithm A takes a 130 px ROI that is "about 2.5 times the spot" (docs/paper.md sec. 1),
    which would put the spot at about 52 px and F at about 17 mm; the presets' F = 5 mm
    (``studies.identification``) gives a 35 px spot, 1/3.7 of the ROI.

    Parameters
    ----------
    bench : sunlab.sim.Bench
        Its largest hole, the mask's true height F' = F + dF, the source and the pixel pitch.

    Returns
    -------
    float
        Spot diameter, px.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole()
    >>> round(130 / spot_diameter_px(b), 2)
    3.67
    """
    theta = 2.0 * bench.source.radius_rad
    d = max(h.diameter_mm for h in bench.mask.holes)
    return (d + bench.mask.true_distance_mm * theta) / bench.detector.pixel_pitch_mm


@functools.lru_cache(maxsize=8)
def _maps(bench):
    from scipy.signal import fftconvolve

    from .detector import fixed_pattern
    from .spots import spot_image

    # the expected single-spot image at zenith (electrons, before PRNU), a centred stamp
    one = bench.replace(mask=bench.mask.replace(holes=bench.mask.holes[:1]),
                        platform=bench.platform.ideal()).ideal_mask()
    s = np.asarray(spot_image(one, 0.0, 0.0)[0], dtype=float)
    m = s.shape[0]
    u = np.arange(m) - (m - 1) / 2.0
    ux, uy = np.broadcast_to(u[None, :], s.shape), np.broadcast_to(u[:, None], s.shape)
    mx, my = float((ux * s).sum() / s.sum()), float((uy * s).sum() / s.sum())
    g = fixed_pattern(bench.detector).gain.astype(float)
    # correlation = convolution with the flipped kernel
    # (an even stamp puts the map half a pixel off the spot's centre: far below the pattern's
    # 6 px correlation length)
    den = fftconvolve(g, s[::-1, ::-1], mode="same")
    return tuple((fftconvolve(g, (uu * s)[::-1, ::-1], mode="same") / den - mc).astype(np.float32)
                 for uu, mc in ((ux, mx), (uy, my)))


def spot_error_maps(bench):
    """Centroid shift (dx, dy) px of a spot centred on each pixel, from the gain pattern (PRNU).

    Parameters
    ----------
    bench : sunlab.sim.Bench
        Its detector's fixed pattern and its spot shape (F, hole, source) are used.

    Returns
    -------
    dx, dy : numpy.ndarray, shape (ny, nx), float32
        Shift of the spot's centre of mass, px, for a spot centred on pixel (y, x).

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> dx, dy = spot_error_maps(Bench.paper_single_hole())
    >>> dx.shape
    (1024, 1280)
    >>> bool(0.01 < float(np.std(dx[200:800, 200:1000])) < 0.04)  # 1.22 % PRNU over 2.8 px
    True
    """
    try:
        return _maps(bench)
    except TypeError:  # a bench holding something unhashable: no cache
        return _maps.__wrapped__(bench)



def surrogate_centroids(bench, plan, seed=0, *, noise_px: float = 0.004,
                        spot_error: bool = True, edge_px: float | None = None) -> xr.Dataset:
    """Centroids of a plan on the bench without rendering: true centroid + modelled errors.

    The platform table (true angles per shot), the mask play and the seed entropy are those of
    :func:`sunlab.sim.simulate` for the same ``(plan, bench, seed)``, so the surrogate and the
    rendered cube share their platform errors; see the module notes for the error terms.

    Parameters
    ----------
    bench : sunlab.sim.Bench
    plan : sunlab.plans.Plan
    seed : int
        Seed of the experiment (as :func:`sunlab.sim.simulate`).
    noise_px : float
        Per-shot centroid noise, px RMS per axis
        (``studies.surrogate_tables.centroid_noise_px``).
    spot_error : bool
        Add the gain-pattern (PRNU) centroid shift of :func:`spot_error_maps`.
    edge_px : float, optional
        Spots whose centre is closer than this to the frame's edge are lost (NaN, status
        ``clipped``); default the spot's radius plus 4 px.

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot) for one hole, (pose, shot, hole) for several,
        with ``true_alpha``, ``true_beta`` and the sensor attributes.

    Examples
    --------
    >>> from sunlab import plans
    >>> from sunlab.sim import Bench
    >>> cen = surrogate_centroids(Bench.paper_single_hole(), plans.experiment("III").thin(6))
    >>> dict(cen.x.sizes), int((cen.status != 0).sum())
    ({'pose': 16, 'shot': 8}, 0)
    """
    from scipy import ndimage

    from .platform import _entropy, _platform_table
    from .render import mask_play, spot_centres

    key = _entropy(seed) + [plan.crc32()]
    ta, tb = _platform_table(bench, plan, key)
    n_p, n_s, n_h = len(plan), plan.shots, bench.n_holes
    play = np.repeat([mask_play(bench, key, p) for p in range(n_p)], n_s, axis=0)
    x, y = (v.reshape(n_p, n_s, n_h)
            for v in spot_centres(bench, np.ravel(ta), np.ravel(tb), play.reshape(-1, 2)))
    ny, nx = bench.detector.shape
    edge = spot_diameter_px(bench) / 2 + 4.0 if edge_px is None else float(edge_px)
    clipped = (x < edge) | (x > nx - 1 - edge) | (y < edge) | (y > ny - 1 - edge)
    if spot_error:
        c = np.stack([np.clip(y, 0, ny - 1).ravel(), np.clip(x, 0, nx - 1).ravel()])
        x, y = (v + ndimage.map_coordinates(d, c, order=1).reshape(v.shape)
                for v, d in zip((x, y), spot_error_maps(bench), strict=True))
    rng = np.random.default_rng(np.random.SeedSequence(key + [0x5B26]))
    x, y = (v + rng.normal(0.0, noise_px, v.shape) for v in (x, y))
    return _surrogate_table(bench, plan, x, y, clipped, ta, tb)


def _surrogate_table(bench, plan, x, y, clipped, ta, tb):
    """The surrogate's ``centroids/1`` table: clipped spots NaN, the true angles beside,
    and for a multi-hole mask the holes' coordinates."""
    from .. import schema
    from .centroids import _truth

    status = np.where(clipped, schema.STATUS["clipped"], schema.STATUS["ok"])
    x, y = np.where(clipped, np.nan, x), np.where(clipped, np.nan, y)
    xd, yd = bench.hole_design_px()
    attrs = {"pixel_pitch_mm": bench.detector.pixel_pitch_mm,
             "mask_distance_mm": bench.mask_distance_mm, "x_cf_px": float(np.mean(xd)),
             "y_cf_px": float(np.mean(yd)), "experiment": plan.name}
    kw = dict(alpha=plan.alpha, beta=plan.beta, method="surrogate", attrs=attrs,
              extra=_truth(ta, tb))
    if x.shape[-1] == 1:
        return schema.centroids_dataset(x[..., 0], y[..., 0], status=status[..., 0], **kw)
    cen = schema.centroids_dataset(x, y, status=status, flux=np.where(clipped, np.nan, 1.0), **kw)
    return cen.assign_coords(
        hole_i=("hole", np.array([h.i for h in bench.mask.holes])),
        hole_j=("hole", np.array([h.j for h in bench.mask.holes])),
        hole_x_cf=("hole", xd, {"units": "px"}), hole_y_cf=("hole", yd, {"units": "px"}),
    )
