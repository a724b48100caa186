"""Rendering: from true platform angles to spot images, their true centroids and full frames.

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

All of this is a product in the Fourier domain: aperture (a jinc for circles and ellipses, an
exact polygon transform otherwise; with ``mask.diffraction`` a circle's or an ellipse's broadband
Fresnel pattern instead of the jinc, :mod:`sunlab.sim.diffraction`) x kernel (the source
profile's transform) x the sensitive rectangle (two sincs) x a phase for the position. Pixel
values are obtained by an inverse FFT of that product folded over the neighbouring alias bands
(the Poisson summation formula), i.e. the exact pixel integrals up to the spectrum beyond 1.5
cycles/px, which is below 1e-6 of the peak.
The *true centroid* of a frame is the centroid of this noiseless expected signal, computed
directly by the same summation formula (derivative of the spectrum at the integer frequencies):
it includes the fill-factor sampling error and is exact to far better than 0.001 px; PRNU and the
other fixed patterns are detector errors and are left out of the truth on purpose.

Examples
--------
>>> from sunlab.sim import Bench
>>> bench = Bench.paper_single_hole().ideal_platform().ideal_mask()
>>> bench.mask.holes[0].x_mm, bench.mask.holes[0].y_mm    # off the detector centre, mm
(0.52, -0.78)
>>> x, y = spot_truth(bench, 0.0, 0.0)                     # at zenith the spot is under it
>>> round((float(x[0]) - 639.5) * 0.007, 3), round((float(y[0]) - 511.5) * 0.007, 3)
(0.52, -0.78)
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..errors import ConfigurationError
from . import _kernels, diffraction
from .detector import Detector
from .platform import sensor_sun_vector

__all__ = ["spot_truth", "ray_positions", "spot_image"]

_TAG_FRAME = 0xF7A3E
_TAG_PLAY = 0x91A7
#: spots folded and transformed together (:meth:`_Spectrum.images`)
_SPOTS_PER_FFT = 8
_STAMP_SIZES = (32, 40, 48, 56, 64, 80, 96, 128, 160, 192, 256, 320, 384, 512, 768, 1024)


# --------------------------------------------------------------------------- seeding
def _entropy(seed) -> list[int]:
    """Seed as a list of non-negative ints (an int or a sequence of ints)."""
    items = [seed] if isinstance(seed, int | np.integer) else list(seed)
    out = []
    for v in items:
        if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < 0:
            raise ConfigurationError(
                f"seed: found {seed!r}; expected a non-negative integer or a sequence of them. "
                "Fix: pass seed=0."
            )
        out.append(int(v))
    return out


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
    rng = np.random.default_rng(np.random.SeedSequence(_entropy(seed) + [_TAG_PLAY, int(pose)]))
    u = rng.uniform(-1.0, 1.0, 2)
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


@functools.lru_cache(maxsize=8)
def _quadrature(n_r: int = 8, n_phi: int = 16):
    x, w = np.polynomial.legendre.leggauss(n_r)
    r = 0.5 * (x + 1.0)
    wr = 0.5 * w
    phi = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    return r, wr, phi


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
    a = float(alpha_true)
    b = float(beta_true)
    if not (abs(a) < 90 and abs(b) < 90):
        raise ConfigurationError(
            f"alpha_true, beta_true: found ({a!r}, {b!r}) deg; expected |angle| < 90 deg (the sun "
            "in front of the mask). Fix: pass platform angles in degrees."
        )
    play = (float(play_mm[0]), float(play_mm[1]))
    try:
        return _spot_geometry_cached(bench, a, b, play)
    except TypeError:  # a bench holding something unhashable: no cache
        return _spot_geometry(bench, a, b, play)


@functools.lru_cache(maxsize=4096)
def _spot_geometry_cached(bench, a, b, play_mm) -> SpotGeometry:
    g = _spot_geometry(bench, a, b, play_mm)
    for v in vars(g).values():
        if isinstance(v, np.ndarray):
            v.setflags(write=False)
    return g


def _spot_geometry(bench, a, b, play_mm) -> SpotGeometry:
    det: Detector = bench.detector
    mask = bench.mask
    src = bench.source
    p = det.pixel_pitch_mm
    s = sensor_sun_vector(bench.platform, a, b)
    rot = mask.rotation_matrix()
    n_m = rot[:, 2]
    sn = float(s @ n_m)
    lit = bool(s[2] > 1e-6 and sn > 1e-6)
    sz = s[2] if lit else 1.0
    q = _hole_centres_mm(bench, play_mm)
    ray = _rays(q, s, sz, det)
    proj = (rot[:2, :2] - np.outer(s[:2], rot[2, :2]) / sz) / p
    proj_w = (rot[:2, 2] - s[:2] * rot[2, 2] / sz) / p
    # Sun-disk kernel by quadrature over the source (per mm of hole height).
    rho = src.radius_rad
    if rho > 0 and lit:
        r, wr, phi = _quadrature()
        e1 = np.cross([0.0, 1.0, 0.0], s)
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        rr = (r * rho)[:, None]
        d = np.cos(rr)[..., None] * s + np.sin(rr)[..., None] * (
            np.cos(phi)[None, :, None] * e1 + np.sin(phi)[None, :, None] * e2
        )
        w = (src.profile(r)[:, None] * wr[:, None] * np.sin(rr)) * np.clip(d @ n_m, 0, None)
        w = np.broadcast_to(w, d.shape[:2])
        disp = -(d[..., :2] / d[..., 2:3] - s[:2] / sz) / p
        wsum = w.sum()
        mu = (w[..., None] * disp).sum(axis=(0, 1)) / wsum
        dd = disp - mu
        cov = np.einsum("ij,ijk,ijl->kl", w, dd, dd) / wsum
        lsum = (src.profile(r)[:, None] * wr[:, None] * np.sin(rr) * np.ones_like(phi)).sum()
        flux_factor = wsum / lsum / sn
    else:
        mu = np.zeros(2)
        cov = np.zeros((2, 2))
        flux_factor = 1.0
    q_e = src.fluence_photons_per_um2 * (p * 1e3) ** 2 * det.qe * sz * flux_factor if lit else 0.0
    return SpotGeometry(
        s=s,
        lit=lit,
        ray=ray,
        height_mm=q[:, 2].copy(),
        proj=proj,
        proj_w=proj_w,
        q_e=float(q_e),
        kernel_mu=mu,
        kernel_cov=cov,
        limb_darkening=src.limb_darkening,
        second_moment=src.second_moment(),
    )


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
    a = np.asarray(alpha_true, dtype=float).ravel()
    b = np.asarray(beta_true, dtype=float).ravel()
    play = np.asarray(play_mm, dtype=float).reshape(-1, 2)
    if not (np.all(np.abs(a) < 90) and np.all(np.abs(b) < 90)):
        raise ConfigurationError(
            "alpha_true, beta_true: found an angle with |angle| >= 90 deg; expected the sun in "
            "front of the mask. Fix: pass platform angles in degrees."
        )
    det: Detector = bench.detector
    mask = bench.mask
    src = bench.source
    p = det.pixel_pitch_mm
    s = sensor_sun_vector(bench.platform, a, b)  # (n, 3)
    rot = mask.rotation_matrix()
    n_m = rot[:, 2]
    lit = (s[:, 2] > 1e-6) & (s @ n_m > 1e-6)
    sz = np.where(lit, s[:, 2], 1.0)
    q0 = _hole_centres_mm(bench, (0.0, 0.0))  # (h, 3); the play shifts x and y only
    qxy = q0[None, :, :2] + play[:, None, :]
    tan = s[:, :2] / sz[:, None]
    ray = qxy - q0[None, :, 2:3] * tan[:, None, :]
    t = det.lid_thickness_mm
    if t > 0:
        r = np.hypot(s[:, 0], s[:, 1])
        safe = np.where(r > 0, r, 1.0)
        sin_t = r / np.sqrt(r * r + sz**2)
        tan_in = sin_t / np.sqrt(det.lid_index**2 - sin_t**2)
        shift = np.where(r > 0, t * (r / sz - tan_in) / safe, 0.0)
        ray = ray + (shift[:, None] * s[:, :2])[:, None, :]
    ray = ray / p
    mu = np.zeros((len(a), 2))
    rho = src.radius_rad
    if rho > 0 and lit.any():
        rq, wr, phi = _quadrature()
        sl = s[lit]
        e1 = np.cross([0.0, 1.0, 0.0], sl)
        e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
        e2 = np.cross(sl, e1)
        rr = rq * rho  # (r,)
        ring = (np.cos(phi)[None, None, :, None] * e1[:, None, None, :]
                + np.sin(phi)[None, None, :, None] * e2[:, None, None, :])  # (n, 1, phi, 3)
        d = (np.cos(rr)[None, :, None, None] * sl[:, None, None, :]
             + np.sin(rr)[None, :, None, None] * ring)
        w = (src.profile(rq) * wr * np.sin(rr))[None, :, None] * np.clip(d @ n_m, 0, None)
        disp = -(d[..., :2] / d[..., 2:3] - (sl[:, :2] / sl[:, 2:3])[:, None, None, :]) / p
        mu[lit] = (w[..., None] * disp).sum(axis=(1, 2)) / w.sum(axis=(1, 2))[:, None]
    off = mu[:, None, :] * q0[None, :, 2:3]
    return ray[..., 0] + off[..., 0], ray[..., 1] + off[..., 1]


def _hole_centres_mm(bench, play_mm) -> np.ndarray:
    """Centres of the holes in the detector frame, mm (n, 3): the mask's layout placed by its
    offset, rotation, true distance and the pose's play."""
    det: Detector = bench.detector
    mask = bench.mask
    p = det.pixel_pitch_mm
    xr, yr = det.reference_px
    origin = np.array(
        [
            xr * p + mask.offset_x_mm + play_mm[0],
            yr * p + mask.offset_y_mm + play_mm[1],
            mask.true_distance_mm,
        ]
    )
    return origin[None, :] + _layout(mask).uv @ mask.rotation_matrix()[:, :2].T


def _rays(q, s, sz, det):
    """The geometric ray of each hole centre q (n, 3) mm for the sun vector s: px (n, 2).

    Through the detector's glass lid (thickness t, index n, :class:`~sunlab.sim.Detector`) the
    ray travels at the refracted angle, sin(theta') = sin(theta) / n, so it lands closer to the
    hole's foot by t (tan(theta) - tan(theta')) along the sun's azimuth (Snell's law for a
    plane-parallel plate; docs/paper.md sec. 10).
    """
    ray = q[:, :2] - q[:, 2:3] * (s[:2] / sz)[None, :]
    t = det.lid_thickness_mm
    if t > 0:
        r = math.hypot(float(s[0]), float(s[1]))
        if r > 0:
            sin_t = r / math.sqrt(r * r + float(sz) ** 2)
            tan_in = sin_t / math.sqrt(det.lid_index**2 - sin_t**2)
            ray = ray + t * (r / float(sz) - tan_in) * (s[:2] / r)[None, :]
    return ray / det.pixel_pitch_mm


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


# --------------------------------------------------------------------------- spectra
def _axes(f):
    return np.ascontiguousarray(np.ravel(f), dtype=float)


class _Group:
    """Holes of one frame sharing an aperture design (identical affine holes, or one polygon
    hole). Spectrum of hole h relative to its ray: ``common(f) * exp(-2 pi i f . shift_h)``, so
    the expected photo-electrons are ``q_e * common(f) * exp(-2 pi i f . centre_h)`` with
    ``centre_h = ray_h + shift_h``; ``common`` holds the aperture (px^2), the sun-disk kernel
    (unit integral) and the pixel's sensitive area, ``shift_h`` the kernel's centroid (which
    scales with the hole's height) minus the sensitive area's offset."""

    def __init__(self, geom: SpotGeometry, det: Detector, ap: _Aperture, fresnel: bool = False):
        self.idx = ap.idx
        self.ray = geom.ray[self.idx]
        h = geom.height_mm[self.idx]
        # the spot's centre relative to its ray: the kernel's centroid, which scales with the
        # hole's height, minus the sensitive area's offset
        self.shift = geom.kernel_mu[None, :] * h[:, None] - np.asarray(
            det.sensitive_offset_px)[None, :]
        self.centre = self.ray + self.shift
        hbar = float(np.mean(h))
        cov = geom.kernel_cov * hbar * hbar
        if np.any(cov):
            w, v = np.linalg.eigh(cov / geom.second_moment)
            self.kernel_m = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
        else:
            self.kernel_m = np.zeros((2, 2))
        self.u = float(geom.limb_darkening)
        self.ax, self.ay = det.sensitive_size_px
        self.diff = float(det.diffusion_px)
        self.cut = []
        self.fresnel = None
        if ap.affine is not None:
            self.affine = geom.proj @ ap.affine
            self.area = math.pi * abs(float(np.linalg.det(self.affine)))
            self.poly = None
            r_ap = float(np.linalg.norm(self.affine, 2))
            # mask.diffraction, paraxial: the pattern of normal incidence projected like the
            # shadow (at the jinc's frequency); the lid's glass counts t / n of the optical path
            if fresnel:
                self.fresnel = diffraction.FresnelHole(ap.affine, hbar - det.lid_height_loss_mm)
        else:
            self.affine = np.zeros((2, 2))
            self.area = 0.0
            self.poly = ap.outline @ geom.proj.T
            for poly, hd in ap.occluders:
                shadow = poly @ geom.proj.T + geom.proj_w * hd
                cx, cy = _kernels.clip_convex(
                    self.poly[:, 0].copy(),
                    self.poly[:, 1].copy(),
                    shadow[:, 0].copy(),
                    shadow[:, 1].copy(),
                )
                if cx.size >= 3:
                    self.cut.append(np.stack([cx, cy], axis=-1))
            r_ap = float(np.max(np.hypot(self.poly[:, 0], self.poly[:, 1])))
        self.radius = (
            r_ap
            + 1.05 * float(np.linalg.norm(self.kernel_m, 2))
            + float(np.max(np.hypot(*(self.centre - self.ray).T)))
            + 0.5 * math.hypot(self.ax, self.ay)
            + 4 * self.diff
        )

    def common(self, fx, fy, pixel: bool = True, tabulated: bool = False):
        """Centred spectrum on the grid fy x fx (1-D axes, cycles/px); (nfy, nfx).

        ``tabulated``: interpolate the disk transforms in tables (images; error below 2e-10 of
        the peak); the truth uses the direct evaluation."""
        fx = _axes(fx)
        fy = _axes(fy)
        ax, ay = (self.ax, self.ay) if pixel else (0.0, 0.0)
        args = (fx, fy, self.affine, self.area, self.kernel_m, self.u, ax, ay,
                self.diff if pixel else 0.0, self.poly is None and self.fresnel is None)
        if tabulated:
            out = _kernels.real_spectrum_tabulated(
                *args, _kernels.disk_ft_table(0.0), _kernels.disk_ft_table(self.u))
        else:
            out = _kernels.real_spectrum(*args)
        if self.poly is not None:
            ap = _kernels.polygon_ft(self.poly[:, 0].copy(), self.poly[:, 1].copy(), fx, fy)
            for c in self.cut:
                ap = ap - _kernels.polygon_ft(c[:, 0].copy(), c[:, 1].copy(), fx, fy)
            out = out * ap
        elif self.fresnel is not None:  # the Fresnel spot's transform where the jinc was
            out = out * (self.area * self.fresnel.ft(fx, fy, self.affine))
        return out

    def centroids(self, n_alias: int = 2, h: float = 1e-5):
        """Centroids (x, y) of the sampled spots by the Poisson summation formula, and the total
        signal sum(S) / q_e (px^2 x fill factor)."""
        k = np.arange(-n_alias, n_alias + 1, dtype=float)
        t = self.common(k, k)
        tx = (self.common(k + h, k) - self.common(k - h, k)) / (2 * h)
        ty = (self.common(k, k + h) - self.common(k, k - h)) / (2 * h)
        px = np.exp(-2j * np.pi * self.centre[:, 0:1] * k[None, :])  # (n, K)
        py = np.exp(-2j * np.pi * self.centre[:, 1:2] * k[None, :])
        den = np.einsum("nb,ba,na->n", py, t, px)
        nx_ = np.einsum("nb,ba,na->n", py, tx, px)
        ny_ = np.einsum("nb,ba,na->n", py, ty, px)
        cx = self.centre[:, 0] + np.real(1j / (2 * np.pi) * nx_ / den)
        cy = self.centre[:, 1] + np.real(1j / (2 * np.pi) * ny_ / den)
        return cx, cy, np.real(den)

    def stamp_size(self) -> int:
        need = 2 * self.radius + 4
        if self.fresnel is not None:  # the halo: its energy beyond the stamp wraps round it
            need += 2 * float(np.linalg.norm(self.affine, 2)) * (self.fresnel.reach - 1.0)
        return next((n for n in _STAMP_SIZES if n >= need), int(2 ** math.ceil(math.log2(need))))

    def stamps(
        self,
        q_e: float,
        size: int | None = None,
        oversample: int = 1,
        pixel: bool = True,
        n_alias: int = 1,
        members=None,
    ):
        """Expected photo-electrons on a size x size grid around each spot of the group.

        Yields (k, image, x0, y0, step): image[i, j] is at x = x0 + j * step, y = y0 + i * step;
        k indexes the group's holes.
        """
        members = np.arange(len(self.idx)) if members is None else np.asarray(members, dtype=int)
        if members.size == 0:
            return
        spec = self.spectrum(size, oversample, pixel, n_alias)
        imgs, x0, y0 = spec.images(self.ray[members], self.centre[members], q_e)
        for n, k in enumerate(members):
            yield int(k), imgs[n], int(x0[n]), int(y0[n]), spec.step

    def spectrum(self, size=None, oversample: int = 1, pixel: bool = True, n_alias: int = 1):
        """The group's centred spectrum on a stamp's frequency grid, folded and phased by
        :meth:`_Spectrum.images` for any spot positions (one evaluation serves every shot of a
        pose, :func:`sunlab.sim.frame.render_pose`)."""
        size = self.stamp_size() if size is None else int(size)
        step = 1.0 / oversample
        m = size * oversample
        fxb = np.arange(m // 2 + 1) / size
        fyb = np.fft.fftfreq(m, d=step)
        al = np.arange(-n_alias, n_alias + 1) * oversample
        fx = (al[:, None] + fxb[None, :]).ravel()
        fy = (al[:, None] + fyb[None, :]).ravel()
        t = self.common(fx, fy, pixel=pixel, tabulated=True)  # real for an affine aperture
        t4 = np.ascontiguousarray(t.reshape(al.size, m, al.size, m // 2 + 1))
        return _Spectrum(t4, al, fxb, fyb, size, m, step)


class _Spectrum(NamedTuple):
    """A group's spectrum on a stamp grid: t4[a, i, b, j] at fy = al[a] + fyb[i],
    fx = al[b] + fxb[j] (cycles/px), for stamps of ``size`` px sampled every ``step`` px."""

    t4: np.ndarray
    al: np.ndarray
    fxb: np.ndarray
    fyb: np.ndarray
    size: int
    m: int
    step: float

    def images(self, ray, centre, q_e):
        """Stamps (n, m, m) of spots centred at ``centre`` (n, 2) px, each placed round its
        ``ray`` (n, 2): (images, x0, y0), image[n, i, j] at x = x0[n] + j step, y = y0[n] + i
        step; ``q_e`` a scalar or one value per spot."""
        x0 = np.floor(ray[:, 0]).astype(int) - self.size // 2 + 1
        y0 = np.floor(ray[:, 1]).astype(int) - self.size // 2 + 1
        dx = centre[:, 0] - x0
        dy = centre[:, 1] - y0
        # Phase of hole n at alias (a, b) and base frequency (i, j) factorises:
        # exp(-2 pi i (al_a + fy_i) dy_n) exp(-2 pi i (al_b + fx_j) dx_n).
        al = self.al
        wy = np.exp(-2j * np.pi * al[None, :] * dy[:, None])
        wx = np.exp(-2j * np.pi * al[None, :] * dx[:, None])
        ey = np.exp(-2j * np.pi * self.fyb[None, :] * dy[:, None])
        ex = np.exp(-2j * np.pi * self.fxb[None, :] * dx[:, None])
        m = self.m
        scale = np.broadcast_to(np.asarray(q_e, dtype=float) / self.step**2, (len(x0),))
        imgs = np.empty((len(x0), m, m))
        # a few spots at a time, so that the folded spectra and their images stay in cache
        for c in range(0, len(x0), _SPOTS_PER_FFT):
            sl = slice(c, c + _SPOTS_PER_FFT)
            acc = _kernels.fold_phase(self.t4, wy[sl], wx[sl], ey[sl], ex[sl])
            imgs[sl] = np.fft.irfft2(acc, s=(m, m), axes=(-2, -1))
            imgs[sl] *= scale[sl, None, None]
        return imgs, x0, y0


class _Aperture(NamedTuple):
    """Holes sharing one aperture design, in the mask frame (mm): ``affine`` maps the unit disk
    onto a dust-free circle or ellipse (None otherwise); ``outline`` and ``occluders`` (dust as
    (polygon, height)) describe any other hole."""

    idx: np.ndarray
    affine: np.ndarray | None
    outline: np.ndarray | None
    occluders: tuple


class _Layout(NamedTuple):
    uv: np.ndarray
    apertures: tuple


def _aperture(hole, idx) -> _Aperture:
    aff = hole.affine()
    occ = tuple(hole.occluders())
    idx = np.atleast_1d(np.asarray(idx, dtype=int))
    if aff is not None and not occ:
        return _Aperture(idx, aff, None, ())
    return _Aperture(idx, None, hole.outline(), occ)


def _layout(mask) -> _Layout:
    """The mask's hole positions (n, 2) mm and apertures grouped by design (affine holes without
    dust share a spectrum); a mask is immutable, so this is built once per mask."""
    try:
        return _layout_cached(mask)
    except TypeError:  # a mask holding something unhashable: no cache
        return _make_layout(mask)


@functools.lru_cache(maxsize=16)
def _layout_cached(mask) -> _Layout:
    lay = _make_layout(mask)
    lay.uv.setflags(write=False)
    return lay


def _make_layout(mask) -> _Layout:
    holes = mask.holes
    keyed: dict = {}
    out = []
    for k, h in enumerate(holes):
        aff = h.affine()
        if aff is not None and not h.occluders():
            keyed.setdefault(tuple(np.round(aff, 12).ravel()), []).append(k)
        else:
            out.append(_aperture(h, [k]))
    for idx in keyed.values():
        out.append(_aperture(holes[idx[0]], idx))
    uv = np.array([[h.x_mm, h.y_mm] for h in holes], dtype=float)
    return _Layout(uv, tuple(out))


def _groups(bench, geom: SpotGeometry) -> list[_Group]:
    """The frame's hole groups; built once per geometry (a frame and its truth share them)."""
    if geom.groups is None:
        det = bench.detector
        on = bench.mask.diffraction
        geom.groups = [_Group(geom, det, ap, on) for ap in _layout(bench.mask).apertures]
    return geom.groups


def _on_detector(group: _Group, det: Detector) -> np.ndarray:
    r = group.radius
    x, y = group.ray[:, 0], group.ray[:, 1]
    return (x - r >= -0.5) & (y - r >= -0.5) & (x + r <= det.nx - 0.5) & (y + r <= det.ny - 0.5)


def _truth(bench, geom: SpotGeometry):
    n = len(bench.mask.holes)
    x = np.full(n, np.nan)
    y = np.full(n, np.nan)
    if not geom.lit:
        return x, y
    for g in _groups(bench, geom):
        ok = _on_detector(g, bench.detector)
        if np.any(ok):
            cx, cy, _ = g.centroids()
            x[g.idx[ok]] = cx[ok]
            y[g.idx[ok]] = cy[ok]
    return x, y


def spot_truth(bench, alpha_true, beta_true, *, play_mm=(0.0, 0.0)):
    """True centroids of the noiseless expected spots, px: (x, y) arrays of shape (n_holes,).

    The centroid of the expected photo-signal sampled by the pixels' sensitive areas (fill factor
    included, PRNU excluded), computed exactly by the Poisson summation formula. NaN for a spot
    that is not entirely on the detector or not lit.

    Parameters
    ----------
    bench : Bench
        The virtual bench.
    alpha_true, beta_true : float
        True platform angles, deg.
    play_mm : (float, float)
        The mask's per-pose offset (see :func:`mask_play`), mm.

    Returns
    -------
    x, y : numpy.ndarray, shape (n_holes,)
        True centroid of each spot, px (NaN where the spot is clipped or not lit).

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> from sunlab.geometry import ideal_centroid
    >>> b = Bench.paper_single_hole().ideal_platform().ideal_mask().without_lid()
    >>> x_cf, y_cf = ray_positions(b, 0.0, 0.0)               # the zero-pose spot
    >>> x, y = spot_truth(b, -12.0, 7.0)
    >>> xi, yi = ideal_centroid(-12.0, 7.0, 5.0, 0.007, x_cf[0], y_cf[0])    # eq. (1)
    >>> bool(abs(x[0] - xi) < 0.01 and abs(y[0] - yi) < 0.01)
    True
    """
    return _truth(bench, spot_geometry(bench, alpha_true, beta_true, play_mm))


def spot_image(
    bench,
    alpha_true,
    beta_true,
    *,
    hole: int = 0,
    oversample: int = 1,
    pixel: bool = True,
    size: int | None = None,
    play_mm=(0.0, 0.0),
):
    """The noiseless expected image of one spot, photo-electrons (before PRNU).

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : float
        True platform angles, deg.
    hole : int
        Index of the hole.
    oversample : int
        Samples per pixel along each axis (1: one value per pixel).
    pixel : bool
        True: integrate over each pixel's sensitive area (what pixels record); False: the
        irradiance itself, photo-electrons per px^2 of a fully sensitive surface.
    size : int, optional
        Side of the stamp, px (default: just large enough for the spot).

    Returns
    -------
    image : ndarray (m, m)
    x0, y0 : float
        Coordinates (px) of ``image[0, 0]``.
    step : float
        Sample spacing, px.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> img, x0, y0, step = spot_image(Bench.paper_single_hole(), 0.0, 0.0)
    >>> img.shape, step
    ((48, 48), 1.0)
    """
    geom = spot_geometry(bench, alpha_true, beta_true, play_mm)
    g = _Group(geom, bench.detector, _aperture(bench.mask.holes[hole], [hole]),
               bench.mask.diffraction)
    _, img, x0, y0, step = next(
        g.stamps(geom.q_e, size=size, oversample=int(oversample), pixel=pixel)
    )
    return img, x0, y0, step
