"""The spots' images: the expected photo-electrons of every spot as a product in the Fourier
domain, folded into stamps, and the true centroids of the noiseless signal.

The spectrum of a spot is aperture (a jinc for circles and ellipses, an exact polygon transform
otherwise; with ``mask.diffraction`` a circle's or an ellipse's broadband Fresnel pattern
instead of the jinc, :mod:`sunlab.sim.diffraction`) x kernel (the source profile's transform)
x the sensitive rectangle (two sincs) x a phase for the position (:mod:`sunlab.sim._aperture`
evaluates the factors). Pixel values are obtained by an inverse FFT of that product folded over
the neighbouring alias bands (the Poisson summation formula), i.e. the exact pixel integrals up
to the spectrum beyond 1.5 cycles/px, which is below 1e-6 of the peak. The fold is a compiled
kernel (:func:`fold_phase`), beside its numpy reference.

The *true centroid* of a frame is the centroid of this noiseless expected signal, computed
directly by the same summation formula (derivative of the spectrum at the integer frequencies):
it includes the fill-factor sampling error and is exact to far better than 0.001 px; PRNU and the
other fixed patterns are detector errors and are left out of the truth on purpose.

Examples
--------
>>> from sunlab.sim import Bench
>>> x, y = spot_truth(Bench.paper_single_hole().ideal_platform().ideal_mask(), 0.0, 0.0)
>>> round((float(x[0]) - 639.5) * 0.007, 3), round((float(y[0]) - 511.5) * 0.007, 3)  # mm
(0.52, -0.78)
"""

from __future__ import annotations

import functools
import math
from typing import NamedTuple

import numpy as np

from . import _aperture, _jit, diffraction
from .detector import Detector
from .render import SpotGeometry, spot_geometry

__all__ = []

#: spots folded and transformed together (:meth:`_Spectrum.images`)
_SPOTS_PER_FFT = 8
_STAMP_SIZES = (32, 40, 48, 56, 64, 80, 96, 128, 160, 192, 256, 320, 384, 512, 768, 1024)


# --------------------------------------------------------------------------- spectra
def _fold_phase_numpy(t4, wy, wx, ey, ex):
    """numpy reference of :func:`fold_phase`: its defining sum as two tensor contractions."""
    folded = np.einsum("aibj,nb->naij", t4, wx)
    return np.einsum("naij,na->nij", folded, wy) * ey[:, :, None] * ex[:, None, :]


@_jit.kernel(_fold_phase_numpy)
def fold_phase(t4, wy, wx, ey, ex):
    """Fold alias bands and apply each spot's position phase.

    acc[n, i, j] = ey[n, i] ex[n, j] sum_a wy[n, a] sum_b t4[a, i, b, j] wx[n, b]

    ``t4`` complex (a polygon's spectrum) or real (an affine aperture's: its imaginary parts
    are zeros, and the sums the same term by term). The loops run along j, the contiguous axis.

    Parameters
    ----------
    t4 : ndarray, shape (na, m, na, m2)
        A spectrum cut into alias bands (complex, or real for an affine aperture).
    wy, wx : ndarray of complex128, shapes (n, na)
        Each spot's band weights along y and x.
    ey, ex : ndarray of complex128, shapes (n, m) and (n, m2)
        Each spot's position phases along y and x.

    Returns
    -------
    ndarray of complex128, shape (n, m, m2)
    """
    na, m, _, m2 = t4.shape
    n = wy.shape[0]
    acc = np.empty((n, m, m2), dtype=np.complex128)
    rr, ri, sr, si = np.empty(m2), np.empty(m2), np.empty(m2), np.empty(m2)
    for q in range(n):
        for i in range(m):
            sr[:] = 0.0
            si[:] = 0.0
            for a in range(na):
                rr[:] = 0.0
                ri[:] = 0.0
                for b in range(na):
                    w = wx[q, b]
                    for j in range(m2):  # (rr + i ri) += t4[a, i, b, j] w
                        tr, ti = t4[a, i, b, j].real, t4[a, i, b, j].imag
                        rr[j] += tr * w.real - ti * w.imag
                        ri[j] += tr * w.imag + ti * w.real
                w = wy[q, a]
                for j in range(m2):  # (sr + i si) += (rr + i ri) w
                    sr[j] += rr[j] * w.real - ri[j] * w.imag
                    si[j] += rr[j] * w.imag + ri[j] * w.real
            for j in range(m2):
                acc[q, i, j] = complex(sr[j], si[j]) * ey[q, i] * ex[q, j]
    return acc


class _Group:
    """Holes of one frame sharing an aperture design (identical affine holes, or one polygon
    hole). Spectrum of hole h relative to its ray: ``common(f) * exp(-2 pi i f . shift_h)``, so
    the expected photo-electrons are ``q_e * common(f) * exp(-2 pi i f . centre_h)`` with
    ``centre_h = ray_h + shift_h``; ``common`` holds the aperture (px^2), the sun-disk kernel
    (unit integral) and the pixel's sensitive area, ``shift_h`` the kernel's centroid (which
    scales with the hole's height) minus the sensitive area's offset."""

    def __init__(self, geom: SpotGeometry, det: Detector, ap: _Aperture, fresnel: bool = False):
        self.idx, self.ray, h = ap.idx, geom.ray[ap.idx], geom.height_mm[ap.idx]
        # the spot's centre relative to its ray: the kernel's centroid, which scales with the
        # hole's height, minus the sensitive area's offset
        self.shift = (geom.kernel_mu[None, :] * h[:, None]
                      - np.asarray(det.sensitive_offset_px)[None, :])
        self.centre = self.ray + self.shift
        hbar = float(np.mean(h))
        # the symmetric square root of the kernel's covariance over the profile's <x^2>
        w, v = np.linalg.eigh(geom.kernel_cov * hbar * hbar / geom.second_moment)
        self.kernel_m = (v * np.sqrt(np.clip(w, 0, None))) @ v.T
        self.u, self.diff = float(geom.limb_darkening), float(det.diffusion_px)
        self.ax, self.ay = det.sensitive_size_px
        self.cut, self.fresnel, self.poly = [], None, None
        if ap.affine is not None:
            self.affine = geom.proj @ ap.affine
            self.area = math.pi * abs(float(np.linalg.det(self.affine)))
            r_ap = float(np.linalg.norm(self.affine, 2))
            # mask.diffraction, paraxial: the pattern of normal incidence projected like the
            # shadow (at the jinc's frequency); the lid's glass counts t / n of the optical path
            if fresnel:
                self.fresnel = diffraction.FresnelHole(ap.affine, hbar - det.lid_height_loss_mm)
        else:
            self.affine, self.area, self.poly = np.zeros((2, 2)), 0.0, ap.outline @ geom.proj.T
            for poly, hd in ap.occluders:
                shadow = poly @ geom.proj.T + geom.proj_w * hd
                cx, cy = _aperture.clip_convex(self.poly[:, 0], self.poly[:, 1], shadow[:, 0],
                                               shadow[:, 1])
                if cx.size >= 3:
                    self.cut.append(np.stack([cx, cy], axis=-1))
            r_ap = float(np.max(np.hypot(self.poly[:, 0], self.poly[:, 1])))
        self.radius = (r_ap + 1.05 * float(np.linalg.norm(self.kernel_m, 2))
                       + float(np.max(np.hypot(*(self.centre - self.ray).T)))
                       + 0.5 * math.hypot(self.ax, self.ay) + 4 * self.diff)

    def common(self, fx, fy, pixel: bool = True, tabulated: bool = False):
        """Centred spectrum on the grid fy x fx (1-D axes, cycles/px); (nfy, nfx).

        ``tabulated``: interpolate the disk transforms in tables (images; error below 2e-10 of
        the peak); the truth uses the direct evaluation."""
        fx, fy = (np.ascontiguousarray(np.ravel(f), dtype=float) for f in (fx, fy))
        ax, ay = (self.ax, self.ay) if pixel else (0.0, 0.0)
        args = (fx, fy, self.affine, self.area, self.kernel_m, self.u, ax, ay,
                self.diff if pixel else 0.0, self.poly is None and self.fresnel is None)
        out = (_aperture.spectrum_tabulated if tabulated else _aperture.spectrum_direct)(*args)
        if self.poly is not None:
            ap = _aperture.polygon_ft(self.poly[:, 0].copy(), self.poly[:, 1].copy(), fx, fy)
            for c in self.cut:
                ap = ap - _aperture.polygon_ft(c[:, 0].copy(), c[:, 1].copy(), fx, fy)
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

    def spectrum(self, size=None, oversample: int = 1, pixel: bool = True, n_alias: int = 1):
        """The group's centred spectrum on a stamp's frequency grid, folded and phased by
        :meth:`_Spectrum.images` for any spot positions (one evaluation serves every shot of a
        pose, :func:`sunlab.sim.frame.render_pose`)."""
        size = self.stamp_size() if size is None else int(size)
        step, m = 1.0 / oversample, size * oversample
        fxb, fyb = np.arange(m // 2 + 1) / size, np.fft.fftfreq(m, d=step)
        al = np.arange(-n_alias, n_alias + 1) * oversample
        fx, fy = ((al[:, None] + f[None, :]).ravel() for f in (fxb, fyb))
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

    def images(self, ray, centre, q_e, out=None):
        """Stamps (n, m, m) of spots centred at ``centre`` (n, 2) px, each placed round its
        ``ray`` (n, 2): (images, x0, y0), image[n, i, j] at x = x0[n] + j step, y = y0[n] + i
        step; ``q_e`` a scalar or one value per spot; written into ``out`` when given."""
        x0, y0 = (np.floor(ray[:, i]).astype(int) - self.size // 2 + 1 for i in (0, 1))
        dx, dy = centre[:, 0] - x0, centre[:, 1] - y0
        # Phase of hole n at alias (a, b) and base frequency (i, j) factorises:
        # exp(-2 pi i (al_a + fy_i) dy_n) exp(-2 pi i (al_b + fx_j) dx_n).
        wy, wx, ey, ex = (np.exp(-2j * np.pi * f[None, :] * d[:, None]) for f, d in (
            (self.al, dy), (self.al, dx), (self.fyb, dy), (self.fxb, dx)))
        m = self.m
        scale = np.broadcast_to(np.asarray(q_e, dtype=float) / self.step**2, (len(x0),))
        imgs = np.empty((len(x0), m, m)) if out is None else out
        # a few spots at a time, so that the folded spectra and their images stay in cache
        for c in range(0, len(x0), _SPOTS_PER_FFT):
            sl = slice(c, c + _SPOTS_PER_FFT)
            acc = fold_phase(self.t4, wy[sl], wx[sl], ey[sl], ex[sl])
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


@functools.lru_cache(maxsize=16)
def _apertures(mask) -> tuple:
    """The mask's apertures grouped by design (affine holes without dust share a spectrum):
    each other hole alone, in order, then the shared designs; built once per mask."""
    keyed, out = {}, []
    for k, h in enumerate(mask.holes):
        aff, occ = h.affine(), tuple(h.occluders())
        if aff is not None and not occ:
            keyed.setdefault(tuple(np.round(aff, 12).ravel()), (aff, []))[1].append(k)
        else:
            out.append(_Aperture(np.array([k]), None, h.outline(), occ))
    return tuple(out + [_Aperture(np.array(idx), aff, None, ()) for aff, idx in keyed.values()])


def _groups(bench, geom: SpotGeometry) -> list[_Group]:
    """The frame's hole groups; built once per geometry (a frame and its truth share them)."""
    if geom.groups is None:
        det = bench.detector
        on = bench.mask.diffraction
        geom.groups = [_Group(geom, det, ap, on) for ap in _apertures(bench.mask)]
    return geom.groups


def _truth(bench, geom: SpotGeometry):
    """True centroids (x, y) of a frame's spots, NaN for a spot not wholly on the detector."""
    xy, det = np.full((2, len(bench.mask.holes)), np.nan), bench.detector
    for g in _groups(bench, geom) if geom.lit else ():
        r, (x, y) = g.radius, g.ray.T
        ok = (x - r >= -0.5) & (y - r >= -0.5) & (x + r <= det.nx - 0.5) & (y + r <= det.ny - 0.5)
        if np.any(ok):
            xy[:, g.idx[ok]] = np.array(g.centroids()[:2])[:, ok]
    return xy[0], xy[1]


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
        The mask's per-pose offset (see :func:`sunlab.sim.render.mask_play`), mm.

    Returns
    -------
    x, y : numpy.ndarray, shape (n_holes,)
        True centroid of each spot, px (NaN where the spot is clipped or not lit).

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> from sunlab.geometry import ideal_centroid
    >>> from sunlab.sim.render import ray_positions
    >>> b = Bench.paper_single_hole().ideal_platform().ideal_mask().without_lid()
    >>> x_cf, y_cf = ray_positions(b, 0.0, 0.0)               # the zero-pose spot
    >>> x, y = spot_truth(b, -12.0, 7.0)
    >>> xi, yi = ideal_centroid(-12.0, 7.0, 5.0, 0.007, x_cf[0], y_cf[0])    # eq. (1)
    >>> bool(abs(x[0] - xi) < 0.01 and abs(y[0] - yi) < 0.01)
    True
    """
    return _truth(bench, spot_geometry(bench, alpha_true, beta_true, play_mm))


def spot_image(bench, alpha_true, beta_true, *, hole: int = 0, oversample: int = 1,
               pixel: bool = True, size: int | None = None, play_mm=(0.0, 0.0)):
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
    ap = next(a for a in _apertures(bench.mask) if hole in a.idx)._replace(idx=np.array([hole]))
    g = _Group(geom, bench.detector, ap, bench.mask.diffraction)
    spec = g.spectrum(size, int(oversample), pixel)
    imgs, x0, y0 = spec.images(g.ray, g.centre, geom.q_e)
    return imgs[0], int(x0[0]), int(y0[0]), spec.step
