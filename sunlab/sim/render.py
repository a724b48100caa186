"""The spots' geometry: from true platform angles to the sun vector, each hole's ray, the
projection of its aperture and the sun-disk kernel; and the seeds of every random draw.

Physics (docs/paper.md sec. 1-2; ``docs/nomenclature.md`` for the frames):

* The sun vector in the sensor frame, s, follows from the true axis angles, the axis geometry and
  the sensor's mounting (:func:`sunlab.sim.platform.sensor_sun_vector`).
* A hole whose centre is at Q (mm, detector frame, height Q_z above the focal plane) casts its
  *geometric ray* at Q_xy - Q_z s_xy / s_z: for a hole at height F this is the paper's eq. (1),
  F (tan alpha, tan beta / cos alpha) from the hole's zenith projection.
* The spot is the aperture projected along s onto the focal plane (an exact affine image of the
  hole's outline, with dust shadows that slide if the dust stands above the mask) convolved with
  the projected sun disk. The sun-disk kernel is the distribution of -H (d_xy / d_z - s_xy / s_z)
  over the source's directions d, weighted by radiance and by the aperture's projected area
  (d . n_mask); it is computed by quadrature and represented by the source profile stretched to
  the same mean and covariance (exact to second order, the disk being 0.0045 rad in radius).
* The irradiance is the beam's fluence times s_z; the spot's total flux is therefore
  fluence x hole area x (s . n_mask): the cosine projection of the hole.
* A pixel collects the irradiance over its sensitive rectangle (fill factor), times QE.

The spots' images and their true centroids, a product in the Fourier domain of this geometry's
aperture, kernel and pixel, live in :mod:`sunlab.sim.spots`.

Examples
--------
>>> from sunlab.sim import Bench
>>> bench = Bench.paper_single_hole().ideal_platform().ideal_mask()
>>> bench.mask.holes[0].x_mm, bench.mask.holes[0].y_mm    # off the detector centre, mm
(0.52, -0.78)
>>> x, y = ray_positions(bench, 0.0, 0.0)                  # at zenith the ray is under it
>>> round((float(x[0]) - 639.5) * 0.007, 3), round((float(y[0]) - 511.5) * 0.007, 3)
(0.52, -0.78)
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field

import numpy as np

from ..errors import ConfigurationError
from .platform import _entropy, sensor_sun_vector

__all__ = []

_TAG_FRAME = 0xF7A3E
_TAG_PLAY = 0x91A7


# --------------------------------------------------------------------------- seeding
def frame_key(seed, pose: int, shot: int) -> np.random.SeedSequence:
    """The SeedSequence of frame (pose, shot): every frame's noise stream, from (seed, pose, shot).

    Parameters
    ----------
    seed : int or sequence of int
        Seed of the experiment (non-negative).
    pose, shot : int
        Index of the pose in its plan and of the shot at that pose.

    Returns
    -------
    numpy.random.SeedSequence
        Entropy ``seed + [frame tag, pose, shot]``: the same frame gets the same noise in any
        process and in any order.

    Examples
    --------
    >>> frame_key(0, 3, 1).entropy
    [0, 1014334, 3, 1]
    """
    return np.random.SeedSequence(_entropy(seed) + [_TAG_FRAME, int(pose), int(shot)])


def mask_play(bench, seed, pose: int) -> tuple[float, float]:
    """Per-pose offset of a loosely held mask, mm: uniform within +-play (0 without play).

    Parameters
    ----------
    bench : Bench
        Its mask's ``play_x_mm`` and ``play_y_mm`` bound the offset.
    seed : int or sequence of int
        Seed of the experiment.
    pose : int
        Index of the pose: every shot of a pose shares its offset.

    Returns
    -------
    (float, float)
        The offset (x, y) of the mask in its own plane, mm.
    """
    m = bench.mask
    if m.play_x_mm == 0 and m.play_y_mm == 0:
        return (0.0, 0.0)
    u = np.random.default_rng(np.random.SeedSequence(_entropy(seed) + [_TAG_PLAY, int(pose)]))
    u = u.uniform(-1.0, 1.0, 2)
    return (float(u[0] * m.play_x_mm), float(u[1] * m.play_y_mm))


# --------------------------------------------------------------------------- geometry
@dataclass
class SpotGeometry:
    """Geometry of every spot of one frame (all lengths in px unless stated).

    Attributes
    ----------
    s : ndarray (3,)
        Sun vector in the sensor frame.
    lit : bool
        Whether the sun is in front of the mask (s . n_mask > 0).
    ray : ndarray (n, 2)
        Geometric ray through each hole centre on the focal plane (x, y).
    height_mm : ndarray (n,)
        Height of each hole centre above the focal plane, mm.
    proj : ndarray (2, 2)
        Projection of mask-plane vectors (mm) onto the focal plane along s (px).
    proj_w : ndarray (2,)
        Projection of a mask-normal offset of 1 mm (px).
    q_e : float
        Photo-electrons per px^2 of fully lit focal plane (before fill factor).
    kernel_mu, kernel_cov : ndarray
        Mean (2,) and covariance (2, 2) of the sun-disk kernel per mm of height (px, px^2/mm^2).
    limb_darkening, second_moment : float
        The source profile and its <x^2> on the unit disk.
    """

    s: np.ndarray
    lit: bool
    ray: np.ndarray
    height_mm: np.ndarray
    proj: np.ndarray
    proj_w: np.ndarray
    q_e: float
    kernel_mu: np.ndarray
    kernel_cov: np.ndarray
    limb_darkening: float
    second_moment: float
    #: the frame's hole groups (:func:`_groups`), built once per geometry: a frame and its
    #: true centroids share them
    groups: list | None = field(default=None, repr=False, compare=False)


def spot_geometry(bench, alpha_true, beta_true, play_mm=(0.0, 0.0)) -> SpotGeometry:
    """Ray positions, projections and the sun-disk kernel for true platform angles (deg).

    A frame and its true centroid need the same geometry: the last few thousand results are
    kept (keyed by the bench, which is immutable, and the angles), their arrays read-only.

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : float
        True platform angles, deg, each within +-90 (exclusive).
    play_mm : (float, float)
        The mask's per-pose offset (:func:`mask_play`), mm.

    Returns
    -------
    SpotGeometry
        Sun vector, each hole's ray (px) and height (mm), the projections and the sun-disk
        kernel of the frame.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole().ideal_platform().ideal_mask().without_lid()
    >>> g0, g = spot_geometry(b, 0.0, 0.0), spot_geometry(b, 10.0, 0.0)
    >>> round(float(g.ray[0, 0] - g0.ray[0, 0]), 2)  # F tan(10 deg) / p, F = 5 mm, p = 7 um
    125.95
    """
    key = (float(alpha_true), float(beta_true), float(play_mm[0]), float(play_mm[1]))
    try:
        return _spot_geometry_cached(bench, *key)
    except TypeError:  # a bench holding something unhashable: no cache
        return _spot_geometry_cached.__wrapped__(bench, *key)


@functools.lru_cache(maxsize=4096)
def _spot_geometry_cached(bench, a, b, px, py) -> SpotGeometry:
    s, lit, ray, height, mu, cov, q_e = _geometry(bench, [a], [b], [[px, py]], "all")
    rot = bench.mask.rotation_matrix()
    sz, p = (s[0, 2] if lit[0] else 1.0), bench.detector.pixel_pitch_mm
    proj = (rot[:2, :2] - np.outer(s[0, :2], rot[2, :2]) / sz) / p
    proj_w = (rot[:2, 2] - s[0, :2] * rot[2, 2] / sz) / p
    g = SpotGeometry(s[0], bool(lit[0]), ray[0], height, proj, proj_w, float(q_e[0]), mu[0],
                     cov[0], bench.source.limb_darkening, bench.source.second_moment())
    for v in vars(g).values():
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    return g


def _geometry(bench, alpha_true, beta_true, play_mm, kernel: str = "mean"):
    """The geometry of n frames in one pass of array arithmetic: sun vectors (n, 3), lit (n,),
    rays (n, holes, 2) px through the lid (:func:`ray_positions`), hole heights (holes,) mm;
    with ``kernel`` "mean" or "all" the sun-disk kernel's mean (n, 2) px/mm, with "all" also
    its covariance (n, 2, 2) px^2/mm^2 and the photo-electrons per px^2 q_e (n,) (None for
    what is not asked: "none" gives the rays alone).

    The kernel is the distribution of -(d_xy / d_z - s_xy / s_z) / p over the source's
    directions d (Gauss-Legendre in radius, midpoints in angle), weighted by radiance and by
    the aperture's projected area d . n_mask; q_e is the fluence times s_z, times that
    weight's share of the radiance over s . n_mask (the hole's cosine projection), times QE.
    """
    a, b = np.asarray(alpha_true, dtype=float).ravel(), np.asarray(beta_true, dtype=float).ravel()
    play = np.asarray(play_mm, dtype=float).reshape(-1, 2)
    if not (np.all(np.abs(a) < 90) and np.all(np.abs(b) < 90)):
        raise ConfigurationError(
            "alpha_true, beta_true: found an angle with |angle| >= 90 deg; expected the sun in "
            "front of the mask. Fix: pass platform angles in degrees.")
    det, mask, src = bench.detector, bench.mask, bench.source
    p = det.pixel_pitch_mm
    s = sensor_sun_vector(bench.platform, a, b)  # (n, 3)
    n_m = mask.rotation_matrix()[:, 2]
    sn = s @ n_m
    lit = (s[:, 2] > 1e-6) & (sn > 1e-6)
    sz = np.where(lit, s[:, 2], 1.0)
    # the holes' centres without play, mm (h, 3): the mask's layout placed by its offset,
    # rotation and true distance (the play shifts x and y only)
    xr, yr = det.reference_px
    origin = np.array([xr * p + mask.offset_x_mm, yr * p + mask.offset_y_mm,
                       mask.true_distance_mm])
    uv = np.array([[h.x_mm, h.y_mm] for h in mask.holes], dtype=float)
    q0 = origin[None, :] + uv @ mask.rotation_matrix()[:, :2].T
    tan = s[:, :2] / sz[:, None]
    ray = q0[None, :, :2] + play[:, None, :] - q0[None, :, 2:3] * tan[:, None, :]
    t = det.lid_thickness_mm
    if t > 0:  # Snell's law in a plane-parallel plate: the ray lands closer to the hole's foot
        r = np.hypot(s[:, 0], s[:, 1])
        safe = np.where(r > 0, r, 1.0)
        sin_t = r / np.sqrt(r * r + sz**2)
        tan_in = sin_t / np.sqrt(det.lid_index**2 - sin_t**2)
        shift = np.where(r > 0, t * (r / sz - tan_in) / safe, 0.0)
        ray = ray + (shift[:, None] * s[:, :2])[:, None, :]
    ray = ray / p
    if kernel == "none":
        return s, lit, ray, q0[:, 2], None, None, None
    n = len(a)
    mu, cov, flux = np.zeros((n, 2)), np.zeros((n, 2, 2)), np.ones(n)
    rho = src.radius_rad
    if rho > 0 and lit.any():
        x, wx = np.polynomial.legendre.leggauss(8)
        rq, wr = 0.5 * (x + 1.0), 0.5 * wx
        phi = (np.arange(16) + 0.5) * 2 * np.pi / 16
        sl = s[lit]
        e1 = np.cross([0.0, 1.0, 0.0], sl)
        e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
        e2 = np.cross(sl, e1)
        rr = rq * rho  # (r,)
        ring = (np.cos(phi)[None, None, :, None] * e1[:, None, None, :]
                + np.sin(phi)[None, None, :, None] * e2[:, None, None, :])  # (n, 1, phi, 3)
        d = (np.cos(rr)[None, :, None, None] * sl[:, None, None, :]
             + np.sin(rr)[None, :, None, None] * ring)
        radiance = src.profile(rq) * wr * np.sin(rr)
        w = radiance[None, :, None] * np.clip(d @ n_m, 0, None)
        disp = -(d[..., :2] / d[..., 2:3] - (sl[:, :2] / sl[:, 2:3])[:, None, None, :]) / p
        wsum = w.sum(axis=(1, 2))
        mu[lit] = (w[..., None] * disp).sum(axis=(1, 2)) / wsum[:, None]
        if kernel == "all":
            dd = disp - mu[lit][:, None, None, :]
            cov[lit] = np.einsum("nij,nijk,nijl->nkl", w, dd, dd) / wsum[:, None, None]
            flux[lit] = wsum / (radiance.sum() * phi.size) / sn[lit]
    if kernel != "all":
        return s, lit, ray, q0[:, 2], mu, None, None
    q_e = np.where(lit, src.fluence_photons_per_um2 * (p * 1e3) ** 2 * det.qe * sz * flux, 0.0)
    return s, lit, ray, q0[:, 2].copy(), mu, cov, q_e


def spot_centres(bench, alpha_true, beta_true, play_mm) -> tuple[np.ndarray, np.ndarray]:
    """True spot centroids of many frames at once: the ray plus the sun-disk kernel's mean.

    The same geometry as :func:`spot_geometry` (``ray + kernel_mu * height_mm``), evaluated
    for a batch of poses in one pass of array arithmetic: the surrogate needs only the
    centroid, and the per-frame call (about 0.7 ms) dominated the identification's fits.

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : array_like, shape (n,)
        True platform angles, deg, each within +-90 (exclusive).
    play_mm : array_like, shape (n, 2)
        The mask's offset of each frame (:func:`mask_play`), mm.

    Returns
    -------
    x, y : numpy.ndarray, shape (n, n_holes)
        Centroid of each hole's spot, px; a frame whose sun is behind the mask gets its rays
        and no kernel offset, as :func:`spot_geometry` gives it.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole()
    >>> x, y = spot_centres(b, [3.0], [-2.0], [[0.001, 0.0]])
    >>> g = spot_geometry(b, 3.0, -2.0, (0.001, 0.0))
    >>> bool(np.allclose(x[0], g.ray[:, 0] + g.kernel_mu[0] * g.height_mm, atol=1e-9))
    True
    """
    _, _, ray, height, mu, _, _ = _geometry(bench, alpha_true, beta_true, play_mm)
    c = ray + mu[:, None, :] * height[None, :, None]
    return c[..., 0], c[..., 1]


def ray_positions(bench, alpha_true, beta_true, play_mm=(0.0, 0.0)):
    """Geometric ray through each hole centre on the focal plane: (x, y) px arrays (n_holes,).

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : float
        True platform angles, deg.
    play_mm : (float, float)
        The mask's per-pose offset (:func:`mask_play`), mm.

    Returns
    -------
    x, y : numpy.ndarray, shape (n_holes,)
        Where the ray through each hole centre meets the focal plane, px (refracted by the
        detector's lid); the spot's centroid also carries the sun-disk kernel's mean.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole().ideal_platform().ideal_mask().without_lid()
    >>> (_, y0), (_, y) = ray_positions(b, 0.0, 0.0), ray_positions(b, 0.0, 10.0)
    >>> round(float(y[0] - y0[0]), 2)  # F tan(10 deg) / p, F = 5 mm, p = 7 um
    125.95
    """
    g = spot_geometry(bench, alpha_true, beta_true, play_mm)
    return g.ray[:, 0].copy(), g.ray[:, 1].copy()
