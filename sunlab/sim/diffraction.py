"""Fresnel diffraction of a circular pinhole, broadband: the spot beyond the geometric shadow.

The renderer's default spot is geometric optics: the hole's shadow smeared by the sun disk. A hole
of radius a at a distance z from the focal plane has the Fresnel number N = a^2 / (lambda z); for
the paper's 0.2 mm hole at 550 nm N is 3.6 at F = 5 mm and 1.07 at F = 17 mm, where the pattern is
far from the shadow (edge ringing, a centre whose intensity swings with N). This module gives the
pattern and its transform; :class:`sunlab.sim.Mask` ``diffraction=True`` makes the renderer use
the transform in place of the disk's jinc for every dust-free circular or elliptical hole.

Physics (paraxial Fresnel-Kirchhoff, a plane wave of unit intensity at normal incidence, lengths in
units of a, radius rho on the focal plane):

* monochromatic intensity, I(rho) = abs(2 pi N int_0^1 exp(i pi N s^2) J0(2 pi N rho s) s ds)^2
  (the Fresnel approximation, J. W. Goodman, *Introduction to Fourier Optics*, sec. 4.2, in its
  radially symmetric form); on the axis it is 4 sin^2(pi N / 2) (the integral in closed form: the
  Fresnel-zone result, E. Hecht, *Optics*, sec. 10.3); ``tests/sim/test_diffraction.py`` checks
  the transform below against this integral through the renderer, to 1e-4 of the incident
  intensity;
* its 2-D transform, by Guigay's formula (J.-P. Guigay, Optik 49, 121 (1977): the intensity
  spectrum at distance z is the aperture's autocorrelation with the shift lambda z f, phased),
  is the transform of the lens where the disk and its copy shifted by s = lambda z f / a = q / N
  overlap, taken at the same frequency q = a f (f the frequency's modulus; cycles per radius).
  Normalised to 1 at q = 0:
  M(q) = (4 / pi) int_{s/2}^1 sqrt(1 - t^2) cos(2 pi q (t - s/2)) dt for s < 2 and 0 beyond: the
  pattern's spectrum ends at f = 2 a / (lambda z) exactly, and tends to the jinc
  2 J1(2 pi q) / (2 pi q) as N grows (s -> 0). One smooth 1-D integral per frequency
  (Gauss-Legendre in t = cos(phi)), where a Hankel transform of the ringing pattern would need
  thousands of nodes;
* broadband: the patterns averaged with the photo-electrons per unit wavelength,
  ``spectral_weights`` = source photon flux x detector QE (``spectral_weights`` gives the two
  curves and their sources).

The renderer reads M from a table (``aperture_ft``) at the same affine-mapped frequency as the
jinc; the truth (``spot_truth``) reads the same table, so a benchmark's truth is the image's.

Measured (``python benchmarks/bench_fresnel.py`` prints them; 2026-11-27), the paper's 0.2 mm
hole on ``Bench.paper_single_hole()`` and on the same bench with ``mask__distance_mm=17.0``:

* N at 550 nm: 3.64 at F = 5 mm, 1.07 at F = 17 mm;
* the spot's full width at 10 % of its peak (normal incidence): 33.1 px geometric, 30.5 px
  Fresnel at 5 mm; 42.3 and 39.9 px at 17 mm. The region of interest's 130 px is then 3.93x /
  4.27x the spot at 5 mm and 3.07x / 3.26x at 17 mm (the paper: "about 2.5x");
* algorithm B's centroid, Fresnel minus geometric: RMS 0.0011 px in x, 0.0009 px in y at 5 mm
  (9 poses), 0.0023 and 0.0011 px at 17 mm (6 poses)

(noise-free frames at (alpha, beta) in {0, 10, -15}^2 deg, the mask's play at zero; at 17 mm the
three beta = -15 deg poses leave the frame, so 6 poses there; each difference is under 0.0032
px). The Fresnel spot is narrower at 10 % of its peak, with a brighter centre and a halo: at
N ~ 1 the hole passes about one Fresnel zone, the pinhole camera's sharpest spot.

Examples
--------
>>> round(fresnel_number(0.1, 5.0, 0.55), 2)
3.64
>>> round(float(monochromatic_transform(np.array([0.0]), 2.0)[0]), 6)
1.0
"""

from __future__ import annotations

import functools
import math

import numpy as np
from scipy import constants, special

from .source import _check

__all__ = []

#: The paper's solar simulator is a 1000 W xenon arc (docs/paper.md sec. 2); no spectrum of it is
#: given, so its photon flux is a 5778 K blackbody's (a xenon arc's visible continuum is close to
#: a 6000 K one; its 800-1000 nm emission lines are left out): a stated approximation.
SOURCE_TEMPERATURE_K = 5778.0
#: Silicon's absorption coefficient at 300 K, 1/um, at 350-1100 nm every 50 nm (M. A. Green,
#: Sol. Energy Mater. Sol. Cells 92, 1305 (2008), table 1, rounded to 3 figures).
_SI_WAVELENGTH_UM = np.arange(0.35, 1.1001, 0.05)
_SI_ALPHA_PER_UM = np.array([104.0, 9.52, 2.55, 1.11, 0.639, 0.414, 0.281, 0.190, 0.130,
                             0.0850, 0.0535, 0.0306, 0.0157, 0.0064, 0.00163, 0.00035])
#: The IBIS4-1300's photodiode as a silicon slab collecting between these depths, um: a dead
#: surface layer (shallow junction) and the collection depth. The datasheet (FillFactory doc.
#: 38-05707) states QE > 50 % at 500-700 nm; its spectral-response figure was not available to us,
#: so this is a model with that anchor (the curve peaks at 560 nm and falls to a tenth of its peak
#: at 960 nm), not the datasheet's curve. Only the shape matters here: the weights are normalised.
QE_DEAD_UM = 0.2
QE_DEPTH_UM = 6.0
#: The halo's energy fraction left outside the renderer's stamps (:attr:`FresnelHole.reach`):
#: wrapped round a stamp, it pulls a spot's centroid toward the stamp's centre by about this
#: fraction of the spot's sub-pixel offset from it, under 0.003 px.
HALO_FRACTION = 0.005
#: Wavelength grid of the broadband average, um (silicon responds from 350 to 1100 nm).
_GRID_UM = np.linspace(0.35, 1.10, 76)
#: The transform table's step in k = 2 pi q: the cubic spline through it is within 1e-6 of the
#: peak of the direct sum at F = 5 and 17 mm (the cutoffs' (2 - s)^(3/2) kinks limit it).
_TABLE_STEP = 1.0 / 16.0
#: Tables are kept per Fresnel number rounded to this relative step: a hole's height changes by
#: microns from pose to pose (the mask's tilt and play), which must not rebuild the table (about
#: 2 s); the pattern changes by about that fraction between neighbours.
_KEY_STEP = 1e-4
#: Above this Fresnel number (at 550 nm) the table would be large and the shadow is within a few
#: 1 / (pi^2 N) of the truth: geometric optics (diffraction=False) is the right model there.
_MAX_FRESNEL = 100.0


def fresnel_number(radius_mm: float, distance_mm: float, wavelength_um: float = 0.55) -> float:
    """The Fresnel number N = a^2 / (lambda z) of a circular hole.

    Parameters
    ----------
    radius_mm : float
        Hole radius a, mm.
    distance_mm : float
        Propagation distance z (hole to focal plane), mm.
    wavelength_um : float
        Wavelength, um.

    Returns
    -------
    float
        N (dimensionless): about the number of Fresnel zones the hole spans.
    """
    return float(radius_mm) ** 2 / (float(wavelength_um) * 1e-3 * float(distance_mm))


def jinc(k):
    """The geometric disk's normalised transform 2 J1(k) / k, 1 at k = 0.

    k = 2 pi f a, with f the frequency's modulus and a the disk's radius.

    Parameters
    ----------
    k : array_like
        Angular frequency times the radius, rad.

    Returns
    -------
    numpy.ndarray
        2 J1(k) / k, the limit of ``monochromatic_transform`` as N grows.
    """
    k = np.maximum(np.abs(np.asarray(k, dtype=float)), 1e-30)
    return 2.0 * special.j1(k) / k


@functools.lru_cache(maxsize=1)
def spectral_weights() -> tuple[np.ndarray, np.ndarray]:
    """Photo-electrons per unit wavelength on the grid (source photon flux x QE), normalised.

    The source: a :data:`SOURCE_TEMPERATURE_K` blackbody's photon flux,
    lambda^-4 / (exp(hc / lambda k T) - 1) (the xenon arc approximated, see the constant). The
    detector: exp(-alpha d0) - exp(-alpha d1), the fraction of photons absorbed between the dead
    layer d0 = :data:`QE_DEAD_UM` and the collection depth d1 = :data:`QE_DEPTH_UM`, alpha
    silicon's absorption coefficient (Green 2008) interpolated in log; the fill factor and the
    lid's transmission do not depend on wavelength to first order and cancel in the normalisation.

    Returns
    -------
    wavelength_um : numpy.ndarray, shape (76,)
        350 to 1100 nm, um.
    weight : numpy.ndarray, shape (76,)
        Trapezoid quadrature weights of the normalised electron spectrum; they sum to 1.
    """
    lam = _GRID_UM
    x = constants.h * constants.c / (lam * 1e-6 * constants.k * SOURCE_TEMPERATURE_K)
    photons = lam**-4 / np.expm1(x)
    alpha = np.exp(np.interp(lam, _SI_WAVELENGTH_UM, np.log(_SI_ALPHA_PER_UM)))
    qe = np.exp(-alpha * QE_DEAD_UM) - np.exp(-alpha * QE_DEPTH_UM)
    w = photons * qe * np.gradient(lam)
    w.setflags(write=False)
    lam = lam.copy()
    lam.setflags(write=False)
    return lam, w / w.sum()


@functools.lru_cache(maxsize=64)
def _gauss(nodes: int):
    """Gauss-Legendre nodes and weights on [-1, 1], at least ``nodes`` of them (a multiple of
    16, so that nearby requests share one)."""
    return np.polynomial.legendre.leggauss(16 * -(-int(nodes) // 16))


def monochromatic_intensity(rho, n_fresnel: float):
    """Fresnel intensity of a circular hole, relative to the incident intensity.

    Parameters
    ----------
    rho : array_like
        Radius on the focal plane, in hole radii.
    n_fresnel : float
        Fresnel number N = a^2 / (lambda z).

    Returns
    -------
    numpy.ndarray
        I(rho) / I0 = abs(2 pi N int_0^1 exp(i pi N s^2) J0(2 pi N rho s) s ds)^2, by Gauss-Legendre
        quadrature with enough nodes for the integrand's pi N (1 + 2 rho) radians of phase.
    """
    rho = np.asarray(rho, dtype=float)
    n = float(n_fresnel)
    x, w = _gauss(64 + int(2.0 * math.pi * n * (1.0 + 2.0 * float(np.max(rho, initial=0.0)))))
    s, w = 0.5 * (x + 1.0), 0.5 * w
    out = np.empty(rho.shape)
    flat, res = rho.ravel(), out.reshape(-1)
    for c in range(0, flat.size, 512):
        r = flat[c:c + 512, None]
        u = (w * s * np.exp(1j * math.pi * n * s * s) * special.j0(2 * math.pi * n * r * s)).sum(-1)
        res[c:c + 512] = np.abs(2.0 * math.pi * n * u) ** 2
    return out


def _lens_ft(q, n_fresnel: float, nodes: int):
    """M(q) of the module notes on an array of q >= 0 (cycles per radius)."""
    q = np.asarray(q, dtype=float)
    half = np.clip(0.5 * q / float(n_fresnel), 0.0, 1.0)  # s / 2
    phi1 = np.arccos(half)
    x, w = _gauss(nodes)
    # t = cos(phi) on [0, phi1]: sqrt(1 - t^2) dt = sin^2(phi) dphi, a smooth integrand
    phi = 0.5 * phi1[..., None] * (x + 1.0)
    shifted = np.cos(phi) - half[..., None]
    integrand = np.sin(phi) ** 2 * np.cos(2.0 * math.pi * q[..., None] * shifted)
    return (4.0 / math.pi) * 0.5 * phi1 * (integrand @ w)


def monochromatic_transform(q, n_fresnel: float):
    """The monochromatic Fresnel pattern's 2-D transform, normalised to 1 at f = 0.

    Parameters
    ----------
    q : array_like
        f a: the frequency's modulus times the hole radius, cycles per radius (>= 0).
    n_fresnel : float
        Fresnel number N = a^2 / (lambda z).

    Returns
    -------
    numpy.ndarray
        M(q) of the module notes (Guigay's lens), 0 for q >= 2 N.
    """
    q = np.abs(np.asarray(q, dtype=float))
    return _lens_ft(q, n_fresnel, 32 + int(2.0 * math.pi * float(np.max(q, initial=0.0))))


def broadband_transform(q, radius_mm: float, distance_mm: float):
    """The broadband Fresnel pattern's transform: M averaged over ``spectral_weights``.

    Parameters
    ----------
    q : array_like
        f a: the frequency's modulus times the hole radius, cycles per radius (>= 0).
    radius_mm, distance_mm : float
        Hole radius a and propagation distance z, mm.

    Returns
    -------
    numpy.ndarray
        sum_lambda w(lambda) M(q; a^2 / (lambda z)), 1 at q = 0 (each M is; the weights sum to 1).
    """
    q = np.abs(np.asarray(q, dtype=float))
    nodes = 32 + int(2.0 * math.pi * float(np.max(q, initial=0.0)))
    return _spectral_sum(lambda n: _lens_ft(q, n, nodes),
                         fresnel_number(radius_mm, distance_mm, 1.0))


def broadband_intensity(rho, radius_mm: float, distance_mm: float):
    """The broadband Fresnel pattern, relative to the incident intensity.

    Parameters
    ----------
    rho : array_like
        Radius on the focal plane, in hole radii.
    radius_mm, distance_mm : float
        Hole radius a and propagation distance z, mm.

    Returns
    -------
    numpy.ndarray
        sum_lambda w(lambda) I(rho; a^2 / (lambda z)) (:func:`monochromatic_intensity`).
    """
    return _spectral_sum(lambda n: monochromatic_intensity(rho, n),
                         fresnel_number(radius_mm, distance_mm, 1.0))


def _spectral_sum(fn, n1: float):
    """sum_lambda w(lambda) fn(N1 / lambda) over :func:`spectral_weights` (lambda in um), for
    N1 the Fresnel number at 1 um."""
    lam, w = spectral_weights()
    return sum(w_k * fn(n1 / lam_k) for lam_k, w_k in zip(lam, w, strict=True))


@functools.lru_cache(maxsize=32)
def _table(key: int):
    """The broadband transform against k = 2 pi q for the Fresnel number at 1 um
    N1 = exp(key * :data:`_KEY_STEP`), as (k_end, spline); zero beyond k_end."""
    from scipy.interpolate import CubicSpline

    n1 = math.exp(key * _KEY_STEP)
    # the shortest wavelength's cutoff, and the table's points up to it
    k_end = 2.0 * math.pi * 2.0 * n1 / float(spectral_weights()[0].min())
    k = np.arange(0.0, k_end + 4 * _TABLE_STEP, _TABLE_STEP)
    val = _spectral_sum(lambda n: _lens_ft(k / (2.0 * math.pi), n, 32 + int(k_end)), n1)
    return float(k[-1]), CubicSpline(k, val)


def aperture_ft(k, radius_mm: float, distance_mm: float):
    """:func:`broadband_transform` from a cached table: the renderer's replacement of the jinc.

    Parameters
    ----------
    k : array_like
        2 pi f a (f the frequency's modulus), the jinc's argument, rad; >= 0.
    radius_mm, distance_mm : float
        Hole radius a and propagation distance z, mm.

    Returns
    -------
    numpy.ndarray
        The transform (1 at k = 0), a cubic spline through exact values every 1/16 rad (N
        rounded to :data:`_KEY_STEP`), 0 beyond the shortest wavelength's cutoff
        4 pi a^2 / (lambda_min z).
    """
    n1 = fresnel_number(radius_mm, distance_mm, 1.0)
    k_end, spline = _table(int(round(math.log(n1) / _KEY_STEP)))
    k = np.abs(np.asarray(k, dtype=float))
    return np.where(k < k_end, spline(np.minimum(k, k_end)), 0.0)


class FresnelHole:
    """One circular (or elliptical) hole design's broadband Fresnel spot, for the renderer.

    Paraxial: the pattern is that of normal incidence for the circle of the hole's area, mapped
    like the shadow (the renderer evaluates it at the affine-mapped frequency of the jinc). At an
    incidence theta the beam sees the hole foreshortened to a cos(theta) along the tilt and
    travels z / cos(theta), so the true Fresnel numbers are N cos(theta) across the tilt and
    N cos^3(theta) along it (-9 % and -24 % at the paper's largest 24 deg): left out here.

    Parameters
    ----------
    affine_mm : numpy.ndarray, shape (2, 2)
        The map of the unit disk onto the hole, mm (:meth:`sunlab.sim.holes.Hole.affine`).
    distance_mm : float
        Optical distance from the hole to the focal plane, mm (a glass lid of thickness t and
        index n counts t / n).

    Attributes
    ----------
    radius_mm : float
        The equal-area radius sqrt(abs(det A)), mm.
    reach : float
        Radius, in hole radii, outside which the pattern holds :data:`HALO_FRACTION` of its
        energy (the Airy tail 1 - EE(rho) ~ 1 / (pi^2 N rho) averaged over the spectrum, within
        4 % of the pattern's own at rho >= 10): the renderer's stamps reach this far beyond the
        shadow; the rest wraps round the stamp as a nearly flat pedestal.
    """

    def __init__(self, affine_mm, distance_mm: float):
        self.radius_mm = math.sqrt(abs(float(np.linalg.det(np.asarray(affine_mm, dtype=float)))))
        self.distance_mm = float(distance_mm)
        n = fresnel_number(self.radius_mm, self.distance_mm) if self.distance_mm > 0 else math.inf
        _check(self.radius_mm > 0 and 0 < n <= _MAX_FRESNEL, "mask.diffraction",
               f"the hole of radius {self.radius_mm:g} mm at {distance_mm:g} mm: N = {n:g} at 550 "
               "nm", f"0 < N <= {_MAX_FRESNEL:g}, beyond which the geometric shadow holds",
               "mask.diffraction=False.")
        lam, w = spectral_weights()
        n1 = fresnel_number(self.radius_mm, self.distance_mm, 1.0)
        self.reach = max(1.0, float(w @ lam) / (math.pi**2 * n1 * HALO_FRACTION))

    def ft(self, fx, fy, affine_px):
        """The normalised transform on the grid fy x fx (cycles/px): (nfy, nfx).

        Parameters
        ----------
        fx, fy : numpy.ndarray
            The grid's axes, cycles/px.
        affine_px : numpy.ndarray, shape (2, 2)
            The hole's shadow on the focal plane as the image of the unit disk, px.

        Returns
        -------
        numpy.ndarray, shape (nfy, nfx)
            ``aperture_ft`` at k = 2 pi norm(A^T f), where the jinc is evaluated.
        """
        g1 = affine_px[0, 0] * fx[None, :] + affine_px[1, 0] * fy[:, None]
        g2 = affine_px[0, 1] * fx[None, :] + affine_px[1, 1] * fy[:, None]
        return aperture_ft(2.0 * math.pi * np.hypot(g1, g2), self.radius_mm, self.distance_mm)
