"""Transforms of the spot's factors: the aperture (a polygon, or an affine image of the unit
disk), the limb-darkened sun disk and the pixel's sensitive rectangle, and their product, the
spot's real, centred spectrum (:mod:`sunlab.sim.spots` phases and folds it into stamps).

The stamps evaluate the spectrum on thousands of frequencies per pose: there it is a compiled
kernel, :func:`spectrum_tabulated`, with the two disk transforms interpolated in tables of
:func:`scipy.special.j1` (scipy's J1 cannot be called from compiled code; a table long enough
for the grid's highest frequency). The truth's few frequencies use :func:`spectrum_direct`,
numpy with the same J1, which is also the tabulated kernel's numpy reference
(``sunlab.set_options(kernels="numpy")``). The polygon's transform is compiled too (a dusty or
burred hole's stamp); its numpy reference agrees to rounding.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from scipy import special

from . import _jit

#: Spacing and range of the tabulated disk transforms (:func:`disk_ft_table`).
TABLE_STEP = 1.0 / 64.0
TABLE_KMAX = 256.0


def _clip_convex(px, py, cx, cy):
    """Sutherland-Hodgman: the part of polygon (px, py) inside the convex CCW polygon (cx, cy).

    Parameters
    ----------
    px, py, cx, cy : ndarray of float64
        The vertices of the clipped polygon and of the convex clip.

    Returns
    -------
    x, y : ndarray of float64
        The vertices of the intersection (empty when the polygons do not meet).
    """
    ox = list(px)
    oy = list(py)
    m = cx.shape[0]
    for k in range(m):
        if len(ox) == 0:
            break
        ax, ay, bx, by = cx[k], cy[k], cx[(k + 1) % m], cy[(k + 1) % m]
        ix = ox
        iy = oy
        ox = []
        oy = []
        for i in range(len(ix)):
            x1, y1, x0, y0 = ix[i], iy[i], ix[i - 1], iy[i - 1]
            s1 = (bx - ax) * (y1 - ay) - (by - ay) * (x1 - ax)
            s0 = (bx - ax) * (y0 - ay) - (by - ay) * (x0 - ax)
            if (s1 >= 0 and s0 < 0) or (s1 < 0 and s0 >= 0):
                t = s0 / (s0 - s1)
                ox.append(x0 + t * (x1 - x0))
                oy.append(y0 + t * (y1 - y0))
            if s1 >= 0:
                ox.append(x1)
                oy.append(y1)
    return np.array(ox, dtype=np.float64), np.array(oy, dtype=np.float64)


#: compiled (a dusty hole's shadow is clipped every frame); its reference is its own source
clip_convex = _jit.kernel(_clip_convex)(_clip_convex)


def _polygon_ft_numpy(vx, vy, fx, fy):
    """numpy reference of :func:`polygon_ft`: the edge sum on the whole grid at once."""
    gx, gy = np.meshgrid(fx, fy)
    dx, dy = np.roll(vx, -1) - vx, np.roll(vy, -1) - vy
    mx, my = vx + 0.5 * dx, vy + 0.5 * dy
    area = 0.5 * np.sum(vx * np.roll(vy, -1) - np.roll(vx, -1) * vy)
    acc = np.zeros(gx.shape, dtype=np.complex128)
    for k in range(vx.shape[0]):
        phase = np.exp(-2j * np.pi * (gx * mx[k] + gy * my[k]))
        acc += (gx * dy[k] - gy * dx[k]) * phase * np.sinc(gx * dx[k] + gy * dy[k])
    f2 = gx**2 + gy**2
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 1j * acc / (2 * np.pi * np.where(f2 < 1e-18, 1.0, f2))
    return np.where(f2 < 1e-18, area + 0j, out)


@_jit.kernel(_polygon_ft_numpy)
def polygon_ft(vx, vy, fx, fy):
    """Fourier transform of a polygon's indicator, F(f) = integral of exp(-2 pi i f.x) over it.

    By the divergence theorem, for a counter-clockwise polygon with edges d_k = v_{k+1} - v_k and
    midpoints m_k, F(f) = i / (2 pi |f|^2) sum_k (f_x d_ky - f_y d_kx) exp(-2 pi i f.m_k)
    sinc(f.d_k); F(0) is the area. The exponentials are separable in fx and fy and tabulated
    per edge, so the inner loop has no transcendental.

    Parameters
    ----------
    vx, vy : ndarray of float64, shape (n,)
        The polygon's vertices, counter-clockwise.
    fx, fy : ndarray of float64
        The grid's axes (cycles per unit length).

    Returns
    -------
    ndarray of complex128, shape (nfy, nfx)
    """
    n, nfx, nfy = vx.shape[0], fx.shape[0], fy.shape[0]
    acc_re = np.zeros((nfy, nfx))
    acc_im = np.zeros((nfy, nfx))
    area = 0.5 * np.sum(vx * np.roll(vy, -1) - np.roll(vx, -1) * vy)  # the shoelace formula
    exr, exi, hxr, hxi = np.empty(nfx), np.empty(nfx), np.empty(nfx), np.empty(nfx)
    tx = np.empty(nfx)
    for k in range(n):
        k1 = (k + 1) % n
        dx, dy = vx[k1] - vx[k], vy[k1] - vy[k]
        mx, my = 0.5 * (vx[k1] + vx[k]), 0.5 * (vy[k1] + vy[k])
        for a in range(nfx):
            ph = -2.0 * math.pi * fx[a] * mx
            exr[a], exi[a] = math.cos(ph), math.sin(ph)
            tx[a] = math.pi * fx[a] * dx
            hxr[a], hxi[a] = math.cos(tx[a]), math.sin(tx[a])
        for b in range(nfy):
            ph = -2.0 * math.pi * fy[b] * my
            eyr, eyi = math.cos(ph), math.sin(ph)
            ty = math.pi * fy[b] * dy
            hyr, hyi = math.cos(ty), math.sin(ty)
            for a in range(nfx):
                t = tx[a] + ty
                sc = 1.0 if abs(t) < 1e-9 else (hxi[a] * hyr + hxr[a] * hyi) / t  # sin(t) / t
                w = (fx[a] * dy - fy[b] * dx) * sc
                acc_re[b, a] += w * (exr[a] * eyr - exi[a] * eyi)
                acc_im[b, a] += w * (exr[a] * eyi + exi[a] * eyr)
    out = np.empty((nfy, nfx), dtype=np.complex128)
    for b in range(nfy):
        for a in range(nfx):
            f2 = fx[a] * fx[a] + fy[b] * fy[b]
            if f2 < 1e-18:
                out[b, a] = area
            else:
                c = 1.0 / (2 * math.pi * f2)
                out[b, a] = complex(-c * acc_im[b, a], c * acc_re[b, a])  # i c (re + i im)
    return out


def _disk_ft(k, u):
    """Normalised transform of the unit disk with linear limb darkening u at k = 2 pi |f| r:
    the jinc 2 J1(k) / k (u = 0), else the profile's mix of it and (sin k / k - cos k) / k^2
    (the transform of sqrt(1 - r^2)); series below k = 1e-4 and 0.05."""
    k = np.asarray(k, dtype=np.float64)
    small = k < 1e-4
    ks = np.where(small, 1.0, k)
    jinc = np.where(small, 1.0 - k * k / 8.0, 2.0 * special.j1(ks) / ks)
    if u == 0.0:
        return jinc
    ld = np.where(k < 0.05, 1.0 / 3.0 - k * k / 30.0, (np.sin(ks) / ks - np.cos(ks)) / (ks * ks))
    return ((1.0 - u) * 0.5 * jinc + u * ld) / ((1.0 - u) * 0.5 + u / 3.0)


@functools.lru_cache(maxsize=8)
def disk_ft_table(u: float, n: int = round(TABLE_KMAX / TABLE_STEP)) -> np.ndarray:
    """The disk's transform at k = (i - 1) h, i = 0 .. n + 2 (h = :data:`TABLE_STEP`), read-only.

    Parameters
    ----------
    u : float
        Linear limb-darkening coefficient (0 for the aperture's jinc).
    n : int
        Steps of the table: it serves k < n h (default n h = :data:`TABLE_KMAX`).

    Returns
    -------
    ndarray of float64, shape (n + 3,)
    """
    tab = _disk_ft(np.abs(np.arange(n + 3) - 1) * TABLE_STEP, float(u))
    tab.setflags(write=False)
    return tab


@numba.njit(inline="always")
def _lookup(tab, inv_h, k):
    """Cubic (4-point Lagrange) interpolation of a :func:`disk_ft_table` at 0 <= k < n h.
    Error bound (3/128) h^4 max|f''''| < 1e-9 for h = 1/64."""
    x = k * inv_h
    i = int(x)
    if i + 3 >= tab.shape[0]:  # beyond the table (spectrum_tabulated sizes it): never silent
        return math.nan
    t = x - i
    tm1, tm2, tp1 = t - 1.0, t - 2.0, t + 1.0
    return (-tab[i] * t * tm1 * tm2 + 3.0 * tab[i + 1] * tp1 * tm1 * tm2
            - 3.0 * tab[i + 2] * tp1 * t * tm2 + tab[i + 3] * tp1 * t * tm1) / 6.0


def spectrum_direct(fx, fy, ap, area, km, u, ax, ay, diff, use_ap):
    """Real, centred spectrum on the grid fy x fx: aperture x sun-disk kernel x pixel.

    Parameters
    ----------
    fx, fy : ndarray of float64, shapes (nfx,) and (nfy,)
        The grid's axes (cycles per pixel).
    ap : ndarray, shape (2, 2)
        The affine image of the unit disk that is the aperture (px).
    area : float
        The aperture's area (px^2).
    km : ndarray, shape (2, 2)
        The symmetric matrix that stretches the unit sun disk into the kernel (px).
    u : float
        Linear limb-darkening coefficient.
    ax, ay : float
        Sides of the pixel's sensitive rectangle (px), each a sinc with its area; 0 for none.
    diff : float
        RMS of the Gaussian charge diffusion (px).
    use_ap : bool
        Whether the aperture's transform ``area * jinc(2 pi |ap^T f|)`` is a factor (else the
        caller multiplies by a polygon's or a Fresnel pattern's).

    Returns
    -------
    ndarray of float64, shape (nfy, nfx)
        The spectrum; the positions' phases are applied by the caller.
    """
    f1, f2 = np.meshgrid(fx, fy)
    v = np.outer(*(np.ones_like(f) if a <= 0.0 else a * np.sinc(a * f) for a, f in
                   ((ay, fy), (ax, fx))))
    if use_ap:
        g1, g2 = ap[0, 0] * f1 + ap[1, 0] * f2, ap[0, 1] * f1 + ap[1, 1] * f2
        v = v * area * _disk_ft(2.0 * np.pi * np.hypot(g1, g2), 0.0)
    h1, h2 = km[0, 0] * f1 + km[1, 0] * f2, km[0, 1] * f1 + km[1, 1] * f2
    v = v * _disk_ft(2.0 * np.pi * np.hypot(h1, h2), u)
    if diff > 0.0:
        v = v * np.exp(-2.0 * (np.pi * diff) ** 2 * (f1 * f1 + f2 * f2))
    return v


def _spectrum_tabulated_numpy(fx, fy, ap, area, km, u, ax, ay, diff, use_ap, tab_ap, tab_u):
    return spectrum_direct(fx, fy, ap, area, km, u, ax, ay, diff, use_ap)


@_jit.kernel(_spectrum_tabulated_numpy)
def _spectrum_tabulated(fx, fy, ap, area, km, u, ax, ay, diff, use_ap, tab_ap, tab_u):
    nfx, nfy = fx.shape[0], fy.shape[0]
    inv_h = 1.0 / TABLE_STEP
    out = np.empty((nfy, nfx))
    sx = np.empty(nfx)
    for a in range(nfx):
        t = math.pi * ax * fx[a]
        sx[a] = 1.0 if ax <= 0.0 else ax * (1.0 if abs(t) < 1e-12 else math.sin(t) / t)
    tp = 2.0 * math.pi
    for b in range(nfy):
        t = math.pi * ay * fy[b]
        sy = 1.0 if ay <= 0.0 else ay * (1.0 if abs(t) < 1e-12 else math.sin(t) / t)
        f2 = fy[b]
        for a in range(nfx):
            f1 = fx[a]
            v = sx[a] * sy
            if use_ap:
                g1, g2 = ap[0, 0] * f1 + ap[1, 0] * f2, ap[0, 1] * f1 + ap[1, 1] * f2
                v *= area * _lookup(tab_ap, inv_h, tp * math.sqrt(g1 * g1 + g2 * g2))
            h1, h2 = km[0, 0] * f1 + km[1, 0] * f2, km[0, 1] * f1 + km[1, 1] * f2
            v *= _lookup(tab_u, inv_h, tp * math.sqrt(h1 * h1 + h2 * h2))
            if diff > 0.0:
                v *= math.exp(-2.0 * (math.pi * diff) ** 2 * (f1 * f1 + f2 * f2))
            out[b, a] = v
    return out


def spectrum_tabulated(fx, fy, ap, area, km, u, ax, ay, diff, use_ap):
    """:func:`spectrum_direct` with the two disk transforms interpolated in tables (compiled).

    The interpolation error, below 2e-10 of the spectrum's peak on the paper's bench, is far
    below a photo-electron; no trigonometric call per frequency. The tables reach past the
    grid's largest k = 2 pi |f| max(norm(ap), norm(km)), doubling from :data:`TABLE_KMAX`.

    Parameters
    ----------
    fx, fy, ap, area, km, u, ax, ay, diff, use_ap
        As :func:`spectrum_direct`'s.

    Returns
    -------
    ndarray of float64, shape (nfy, nfx)
    """
    k = 2 * math.pi * math.hypot(np.abs(fx).max(), np.abs(fy).max()) * max(  # Frobenius norms:
        math.hypot(*ap.ravel()) if use_ap else 0.0, math.hypot(*km.ravel()))  # bounds, cheap
    n = round(TABLE_KMAX / TABLE_STEP)
    while n * TABLE_STEP <= k:
        n *= 2
    return _spectrum_tabulated(fx, fy, ap, area, km, u, ax, ay, diff, use_ap,
                               disk_ft_table(0.0, n), disk_ft_table(float(u), n))
