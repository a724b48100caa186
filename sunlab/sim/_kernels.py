"""Kernels of the virtual bench: the ADC of a full frame, of a spot region, the Fourier
transform of a polygon, and the spot spectra (exact, or with tabulated disk transforms).

Each is a :class:`sunlab.jit.Kernel`: compiled by Numba, with a plain numpy reference of the
same signature beside it (``_<name>_numpy``), which runs under
``sunlab.set_options(kernels="numpy")``. The references of the two ADCs draw the same random
stream and give the same frames bit for bit (vectorised SplitMix64 on uint64 arrays, whose
arithmetic wraps modulo 2**64 as the compiled code's does); those of the spectra evaluate the
transforms directly (:func:`scipy.special.j1`), so they agree with the compiled ones to the
1e-8 of the compiled Bessel approximation. Private: the public API is in
:mod:`sunlab.sim.render`.
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np
from numba.extending import overload

from .. import jit
from ..options import OPTIONS

__all__ = [
    "adc_frame",
    "adc_region",
    "normal_table",
    "polygon_ft",
    "clip_convex",
    "real_spectrum",
    "fold_phase",
    "disk_ft_table",
    "real_spectrum_tabulated",
]


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


@numba.njit(inline="always")
def _splitmix64(state):
    """One 64-bit output of SplitMix64 (Steele, Lea & Flood 2014); advances state[0]."""
    state[0] += _GOLDEN
    z = state[0]
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(inline="always")
def _mix64(z):
    """The output function of SplitMix64 applied to the counter value z."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


@numba.njit(inline="always")
def _to_dn(v, max_dn):
    """floor(v + 0.5) clipped to 0 .. max_dn, as uint16 (v float32, the sum taken in float64).

    Clamping to [0, max_dn + 0.5] first makes truncation equal to the floor, which compiles to
    one conversion instead of a libm call, an integer round trip and two branches.
    """
    w = np.float64(v) + 0.5
    w = min(max(w, 0.0), max_dn + 0.5)
    return np.uint16(np.int32(w))


@numba.njit(inline="always")
def _to_dn32(v, top):
    """floor(v + 0.5) clipped to 0 .. max_dn, as uint16, for v float32; ``top`` = max_dn + 0.5
    (float32).

    Bit for bit :func:`_to_dn`: below 2**23 the float32 sum v + 0.5 is exact, or (where it
    enters the next binade) rounds to a neighbour that is never across an integer, so its floor
    is the float64 floor; staying in float32 lets the loop run without conversions.
    """
    w = min(max(v + np.float32(0.5), np.float32(0.0)), top)
    return np.uint16(np.int32(w))


@jit.kernel(nogil=True, cache=True)
def adc_frame(mean_dn, sigma_dn, table, state, max_dn, out):
    """out = clip(rint(mean + sigma * z), 0, max_dn) over the whole frame.

    z is a standard normal deviate drawn by inverse-CDF table lookup: each 64-bit SplitMix64
    output gives four 16-bit indices into ``table`` (the 65 536 equiprobable midpoint quantiles
    of N(0, 1)), low bits first, pixels in row-major order. ``state`` (uint64[1]) is advanced by
    one step per four pixels (rounded up); an empty ``table`` means no noise. SplitMix64 is
    counter-based (output b is a fixed function of ``state + b * golden``), so the loop takes
    four pixels per output without carrying bits from one iteration to the next. The
    arithmetic is float32 throughout (mean + sigma * z as the reference computes it; the
    rounding as :func:`_to_dn32` proves exact).
    """
    ny, nx = mean_dn.shape
    n = ny * nx
    if table.shape[0] == 0:
        for i in range(ny):
            for j in range(nx):
                out[i, j] = _to_dn(mean_dn[i, j], max_dn)
        return
    m = mean_dn.reshape(n)
    s = sigma_dn.reshape(n)
    o = out.reshape(n)
    s0 = state[0]
    low = np.uint64(0xFFFF)
    top = np.float32(max_dn + 0.5)
    n4 = n // 4
    for b in range(n4):
        r = _mix64(s0 + np.uint64(b + 1) * _GOLDEN)
        k = 4 * b
        for q in range(4):
            o[k + q] = _to_dn32(m[k + q] + s[k + q] * table[(r >> np.uint64(16 * q)) & low], top)
    steps = n4 + (1 if n > 4 * n4 else 0)
    if n > 4 * n4:
        r = _mix64(s0 + np.uint64(steps) * _GOLDEN)
        for k in range(4 * n4, n):
            o[k] = _to_dn32(m[k] + s[k] * table[r & low], top)
            r = r >> np.uint64(16)
    state[0] = s0 + np.uint64(steps) * _GOLDEN


def _mix64_numpy(z):
    """:func:`_mix64` on a uint64 array (array arithmetic wraps modulo 2**64, as uint64 does in
    compiled code; numpy scalars would warn of the overflow instead)."""
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


def _normal_deviates(table, state, n):
    """The n deviates of the noise stream at ``state`` (uint64[1], advanced past them): word b
    (b = 1, 2, ...) is the SplitMix64 output for the counter state + b golden, and its four
    16-bit fields, low bits first, index ``table`` for four consecutive pixels."""
    steps = -(-n // 4)
    counters = state + np.arange(1, steps + 1, dtype=np.uint64) * _GOLDEN
    fields = (_mix64_numpy(counters)[:, None] >> (np.uint64(16) * np.arange(4, dtype=np.uint64)))
    z = table[(fields & np.uint64(0xFFFF)).ravel()[:n]]
    state += np.array([steps], dtype=np.uint64) * _GOLDEN  # in place, wrapping
    return z


def _round_clip(v, max_dn):
    """floor(v + 0.5) clipped to 0 .. max_dn, as uint16 (the sum taken in float64)."""
    return np.clip(np.floor(np.asarray(v, dtype=np.float64) + 0.5), 0.0, max_dn).astype(np.uint16)


@adc_frame.reference
def _adc_frame_numpy(mean_dn, sigma_dn, table, state, max_dn, out):
    """numpy reference of :func:`adc_frame`: the same stream, the same frame bit for bit.

    Parameters
    ----------
    mean_dn, sigma_dn : ndarray of float32, shape (ny, nx)
        Mean and standard deviation of every pixel (DN).
    table : ndarray of float32, shape (65536,) or (0,)
        The quantile table of :func:`normal_table`; empty for no noise.
    state : ndarray of uint64, shape (1,)
        The stream's counter, advanced one step per four pixels (rounded up).
    max_dn : float
        Full scale of the ADC (DN).
    out : ndarray of uint16, shape (ny, nx)
        Written with the frame (DN).

    Returns
    -------
    None
        ``out`` and ``state`` are written in place.
    """
    if table.shape[0] == 0:
        out[...] = _round_clip(mean_dn, max_dn)
        return
    z = _normal_deviates(table, state, mean_dn.size).reshape(mean_dn.shape)
    out[...] = _round_clip(mean_dn + sigma_dn * z, max_dn)  # float32, as the kernel sums


@jit.kernel(nogil=True, cache=True)
def adc_region(
    y0,
    x0,
    signal_e,
    gain,
    dark_e,
    offset_dn,
    table,
    state,
    read_var_e,
    inv_gain,
    full_well_e,
    max_dn,
    out,
):
    """Recompute the pixels of a region holding spot signal (photo-electrons before PRNU).

    Mean electrons = gain * signal + dark; variance = mean + read noise^2 (photon and dark shot
    noise in the Gaussian limit); saturation at the full well; rounding and clipping to the ADC.
    Noise as in :func:`adc_frame`, continuing the same stream: the region's pixels, row-major,
    take four deviates per SplitMix64 output, and the state advances one step per four pixels
    (rounded up). The deviates are drawn first (the counter-based words need no carried state),
    then the pixels are computed along rows.
    """
    ny, nx = signal_e.shape
    n = ny * nx
    noisy = table.shape[0] > 0
    z = np.zeros(n if noisy else 0, dtype=np.float32)
    if noisy:
        s0 = state[0]
        low = np.uint64(0xFFFF)
        n4 = n // 4
        for b in range(n4):
            r = _mix64(s0 + np.uint64(b + 1) * _GOLDEN)
            for q in range(4):
                z[4 * b + q] = table[(r >> np.uint64(16 * q)) & low]
        steps = n4
        if n > 4 * n4:
            steps += 1
            r = _mix64(s0 + np.uint64(steps) * _GOLDEN)
            for k in range(4 * n4, n):
                z[k] = table[r & low]
                r = r >> np.uint64(16)
        state[0] = s0 + np.uint64(steps) * _GOLDEN
    top = max_dn + 0.5
    for i in range(ny):
        yy, xb = y0 + i, x0 + nx
        _adc_row(signal_e[i], gain[yy, x0:xb], dark_e[yy, x0:xb], offset_dn[yy, x0:xb],
                 z[i * nx:(i + 1) * nx] if noisy else z, noisy, read_var_e, inv_gain,
                 full_well_e, top, out[yy, x0:xb])


@numba.njit(inline="always")
def _adc_row(signal_e, gain, dark_e, offset_dn, z, noisy, read_var_e, inv_gain, full_well_e,
             top, out):
    """One row of :func:`adc_region` on contiguous 1-D slices, branch-free (clamps as min and
    max, the rounding of :func:`_to_dn` with ``top`` = max_dn + 0.5), so that the compiler
    vectorises it: the same values as the scalar loop, bit for bit, in half the time."""
    for j in range(signal_e.shape[0]):
        e = max(gain[j] * signal_e[j] + dark_e[j], 0.0)
        if noisy:
            e += math.sqrt(e + read_var_e) * z[j]
        e = min(e, full_well_e)
        w = min(max(np.float64(offset_dn[j] + e * inv_gain) + 0.5, 0.0), top)
        out[j] = np.uint16(np.int32(w))


@adc_region.reference
def _adc_region_numpy(y0, x0, signal_e, gain, dark_e, offset_dn, table, state, read_var_e,
                      inv_gain, full_well_e, max_dn, out):
    """numpy reference of :func:`adc_region`: the same stream, the same pixels bit for bit.

    Parameters
    ----------
    y0, x0 : int
        Row and column of the region's first pixel in the frame.
    signal_e : ndarray of float64, shape (ny, nx)
        Photo-electrons of the spot signal before PRNU.
    gain, dark_e, offset_dn : ndarray of float32, shape of the frame
        PRNU gain, dark electrons and offset (DN) of every pixel.
    table : ndarray of float32, shape (65536,) or (0,)
        The quantile table of :func:`normal_table`; empty for no noise.
    state : ndarray of uint64, shape (1,)
        The stream's counter, continued from the frame's.
    read_var_e : float
        Read-noise variance (e^2).
    inv_gain : float
        DN per electron.
    full_well_e : float
        Saturation (e).
    max_dn : float
        Full scale of the ADC (DN).
    out : ndarray of uint16, shape of the frame
        The frame; the region's pixels are rewritten.

    Returns
    -------
    None
        ``out`` and ``state`` are written in place.
    """
    ny, nx = signal_e.shape
    box = (slice(y0, y0 + ny), slice(x0, x0 + nx))
    e = np.maximum(gain[box] * signal_e + dark_e[box], 0.0)
    if table.shape[0] > 0:
        z = _normal_deviates(table, state, signal_e.size).reshape(signal_e.shape)
        e = e + np.sqrt(e + read_var_e) * z.astype(np.float64)
    e = np.minimum(e, full_well_e)
    out[box] = _round_clip(offset_dn[box] + e * inv_gain, max_dn)


def normal_table() -> np.ndarray:
    """The 65 536 midpoint quantiles of N(0, 1), float32 (variance 0.9998, tails at 4.3 sigma)."""
    from scipy.special import ndtri

    return ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)


@jit.kernel(nogil=True, cache=True)
def polygon_ft(vx, vy, fx, fy):
    """Fourier transform of a polygon's indicator, F(f) = integral of exp(-2 pi i f.x) over it.

    By the divergence theorem, for a counter-clockwise polygon with edges d_k = v_{k+1} - v_k and
    midpoints m_k,

    F(f) = i / (2 pi |f|^2) sum_k (f_x d_ky - f_y d_kx) exp(-2 pi i f.m_k) sinc(f.d_k)

    with sinc(t) = sin(pi t) / (pi t); F(0) is the area. ``fx`` (nfx,) and ``fy`` (nfy,) are the
    grid's axes in cycles per unit length; returns (nfy, nfx) complex128. The exponentials are
    separable in fx and fy and are tabulated per edge, so the inner loop has no transcendental.
    """
    n = vx.shape[0]
    nfx = fx.shape[0]
    nfy = fy.shape[0]
    acc_re = np.zeros((nfy, nfx))
    acc_im = np.zeros((nfy, nfx))
    area = 0.0
    for k in range(n):
        k1 = (k + 1) % n
        area += vx[k] * vy[k1] - vx[k1] * vy[k]
    area *= 0.5
    exr = np.empty(nfx)
    exi = np.empty(nfx)
    hxr = np.empty(nfx)
    hxi = np.empty(nfx)
    tx = np.empty(nfx)
    for k in range(n):
        k1 = (k + 1) % n
        dx = vx[k1] - vx[k]
        dy = vy[k1] - vy[k]
        mx = 0.5 * (vx[k1] + vx[k])
        my = 0.5 * (vy[k1] + vy[k])
        for a in range(nfx):
            ph = -2.0 * math.pi * fx[a] * mx
            exr[a] = math.cos(ph)
            exi[a] = math.sin(ph)
            tx[a] = math.pi * fx[a] * dx
            hxr[a] = math.cos(tx[a])
            hxi[a] = math.sin(tx[a])
        for b in range(nfy):
            ph = -2.0 * math.pi * fy[b] * my
            eyr = math.cos(ph)
            eyi = math.sin(ph)
            ty = math.pi * fy[b] * dy
            hyr = math.cos(ty)
            hyi = math.sin(ty)
            for a in range(nfx):
                t = tx[a] + ty
                if abs(t) < 1e-9:
                    sc = 1.0
                else:
                    sc = (hxi[a] * hyr + hxr[a] * hyi) / t  # sin(tx + ty) / t
                w = (fx[a] * dy - fy[b] * dx) * sc
                er = exr[a] * eyr - exi[a] * eyi
                ei = exr[a] * eyi + exi[a] * eyr
                acc_re[b, a] += w * er
                acc_im[b, a] += w * ei
    out = np.empty((nfy, nfx), dtype=np.complex128)
    for b in range(nfy):
        for a in range(nfx):
            f2 = fx[a] * fx[a] + fy[b] * fy[b]
            if f2 < 1e-18:
                out[b, a] = area
            else:
                c = 1.0 / (2 * math.pi * f2)
                # i * c * (re + i im) = -c im + i c re
                out[b, a] = complex(-c * acc_im[b, a], c * acc_re[b, a])
    return out


@polygon_ft.reference
def _polygon_ft_numpy(vx, vy, fx, fy):
    """numpy reference of :func:`polygon_ft`: the edge sum evaluated on the whole grid at once.

    Parameters
    ----------
    vx, vy : ndarray of float64, shape (n,)
        The polygon's vertices, counter-clockwise (any unit of length).
    fx, fy : ndarray of float64
        The grid's axes (cycles per unit length).

    Returns
    -------
    ndarray of complex128, shape (nfy, nfx)
        The transform; the area at f = 0.
    """
    gx, gy = np.meshgrid(fx, fy)
    dx, dy = np.roll(vx, -1) - vx, np.roll(vy, -1) - vy
    mx, my = vx + 0.5 * dx, vy + 0.5 * dy
    area = 0.5 * np.sum(vx * np.roll(vy, -1) - np.roll(vx, -1) * vy)
    acc = np.zeros(gx.shape, dtype=np.complex128)
    for k in range(vx.shape[0]):
        t = gx * dx[k] + gy * dy[k]  # f . d_k
        phase = np.exp(-2j * np.pi * (gx * mx[k] + gy * my[k]))
        acc += (gx * dy[k] - gy * dx[k]) * phase * np.sinc(t)
    f2 = gx**2 + gy**2
    with np.errstate(divide="ignore", invalid="ignore"):
        out = 1j * acc / (2 * np.pi * np.where(f2 < 1e-18, 1.0, f2))
    return np.where(f2 < 1e-18, area + 0j, out)


@jit.kernel(cache=True)
def clip_convex(px, py, cx, cy):
    """Sutherland-Hodgman: the part of polygon (px, py) inside the convex CCW polygon (cx, cy).
    Plain Python on lists: its reference is its own source, interpreted."""
    ox = list(px)
    oy = list(py)
    m = cx.shape[0]
    for k in range(m):
        if len(ox) == 0:
            break
        ax, ay = cx[k], cy[k]
        bx, by = cx[(k + 1) % m], cy[(k + 1) % m]
        ix = ox
        iy = oy
        ox = []
        oy = []
        n = len(ix)
        for i in range(n):
            x1, y1 = ix[i], iy[i]
            x0, y0 = ix[i - 1], iy[i - 1]
            s1 = (bx - ax) * (y1 - ay) - (by - ay) * (x1 - ax)
            s0 = (bx - ax) * (y0 - ay) - (by - ay) * (x0 - ax)
            if s1 >= 0:
                if s0 < 0:
                    t = s0 / (s0 - s1)
                    ox.append(x0 + t * (x1 - x0))
                    oy.append(y0 + t * (y1 - y0))
                ox.append(x1)
                oy.append(y1)
            elif s0 >= 0:
                t = s0 / (s0 - s1)
                ox.append(x0 + t * (x1 - x0))
                oy.append(y0 + t * (y1 - y0))
    return np.array(ox, dtype=np.float64), np.array(oy, dtype=np.float64)


@numba.njit(inline="always")
def _bessel_j1(x):
    """J1(x) by the rational and asymptotic approximations of Numerical Recipes (|error| < 1e-8)."""
    ax = abs(x)
    if ax < 8.0:
        y = x * x
        a1 = x * (
            72362614232.0
            + y
            * (
                -7895059235.0
                + y * (242396853.1 + y * (-2972611.439 + y * (15704.48260 + y * (-30.16036606))))
            )
        )
        a2 = 144725228442.0 + y * (
            2300535178.0 + y * (18583304.74 + y * (99447.43394 + y * (376.9991397 + y * 1.0)))
        )
        return a1 / a2
    z = 8.0 / ax
    y = z * z
    xx = ax - 2.356194491
    a1 = 1.0 + y * (
        0.183105e-2 + y * (-0.3516396496e-4 + y * (0.2457520174e-5 + y * (-0.240337019e-6)))
    )
    a2 = 0.04687499995 + y * (
        -0.2002690873e-3 + y * (0.8449199096e-5 + y * (-0.88228987e-6 + y * 0.105787412e-6))
    )
    ans = math.sqrt(0.636619772 / ax) * (math.cos(xx) * a1 - z * math.sin(xx) * a2)
    return -ans if x < 0.0 else ans


@numba.njit(inline="always")
def _disk_ft(k, u):
    """Normalised transform of the unit disk with linear limb darkening u at k = 2 pi |f| r."""
    if k < 1e-4:
        jinc = 1.0 - k * k / 8.0
        ld = 1.0 / 3.0 - k * k / 30.0
    else:
        jinc = 2.0 * _bessel_j1(k) / k
        if u == 0.0:
            return jinc
        if k < 0.05:
            ld = 1.0 / 3.0 - k * k / 30.0
        else:
            ld = (math.sin(k) / k - math.cos(k)) / (k * k)
    if u == 0.0:
        return jinc
    return ((1.0 - u) * 0.5 * jinc + u * ld) / ((1.0 - u) * 0.5 + u / 3.0)


@jit.kernel(nogil=True, cache=True)
def real_spectrum(fx, fy, ap, area, km, u, ax, ay, diff, use_ap):
    """Real, centred spectrum on the grid fy (nfy,) x fx (nfx,): aperture x kernel x pixel.

    aperture: ``area * jinc(2 pi |ap^T f|)`` (an affine image ``ap`` of the unit disk) when
    ``use_ap``, else 1; kernel: the limb-darkened disk stretched by the symmetric matrix ``km``;
    pixel: the sensitive rectangle ``ax`` x ``ay`` (two sincs, area included; 0 for none) and a
    Gaussian
    diffusion of RMS ``diff``. Phases (positions) are applied by the caller.
    """
    nfx = fx.shape[0]
    nfy = fy.shape[0]
    out = np.empty((nfy, nfx))
    sx = np.empty(nfx)
    for a in range(nfx):
        t = math.pi * ax * fx[a]
        sx[a] = 1.0 if ax <= 0.0 else ax * (1.0 if abs(t) < 1e-12 else math.sin(t) / t)
    for b in range(nfy):
        t = math.pi * ay * fy[b]
        sy = 1.0 if ay <= 0.0 else ay * (1.0 if abs(t) < 1e-12 else math.sin(t) / t)
        for a in range(nfx):
            f1 = fx[a]
            f2 = fy[b]
            v = sx[a] * sy
            if use_ap:
                g1 = ap[0, 0] * f1 + ap[1, 0] * f2
                g2 = ap[0, 1] * f1 + ap[1, 1] * f2
                v *= area * _disk_ft(2.0 * math.pi * math.sqrt(g1 * g1 + g2 * g2), 0.0)
            h1 = km[0, 0] * f1 + km[1, 0] * f2
            h2 = km[0, 1] * f1 + km[1, 1] * f2
            v *= _disk_ft(2.0 * math.pi * math.sqrt(h1 * h1 + h2 * h2), u)
            if diff > 0.0:
                v *= math.exp(-2.0 * (math.pi * diff) ** 2 * (f1 * f1 + f2 * f2))
            out[b, a] = v
    return out


@jit.kernel(nogil=True, cache=True)
def fold_phase(t4, wy, wx, ey, ex):
    """Fold alias bands and apply each spot's position phase.

    acc[n, i, j] = ey[n, i] ex[n, j] sum_a wy[n, a] sum_b t4[a, i, b, j] wx[n, b]

    ``t4`` complex (a polygon's spectrum) or real (an affine aperture's: compiled apart, half
    the arithmetic, the same sums term by term, a real t times w being what the complex
    product computes for t + 0i). The loops run along j, the contiguous axis of ``t4``.
    """
    na, m, _, m2 = t4.shape
    n = wy.shape[0]
    acc = np.empty((n, m, m2), dtype=np.complex128)
    rr = np.empty(m2)
    ri = np.empty(m2)
    sr = np.empty(m2)
    si = np.empty(m2)
    for q in range(n):
        for i in range(m):
            sr[:] = 0.0
            si[:] = 0.0
            for a in range(na):
                rr[:] = 0.0
                ri[:] = 0.0
                for b in range(na):
                    _accumulate_row(t4, a, i, b, wx[q, b], rr, ri)
                _rotate_add(rr, ri, wy[q, a], sr, si)
            _phase_out(sr, si, ey[q, i], ex[q], acc[q, i])
    return acc


def _disk_ft_numpy(k, u):
    """Normalised transform of the unit disk with linear limb darkening u, at k = 2 pi |f| r
    (an array), with the exact Bessel function J1."""
    from scipy.special import j1

    k = np.asarray(k, dtype=np.float64)
    small = k < 1e-4
    ks = np.where(small, 1.0, k)
    jinc = np.where(small, 1.0 - k * k / 8.0, 2.0 * j1(ks) / ks)
    if u == 0.0:
        return jinc
    ld = np.where(k < 0.05, 1.0 / 3.0 - k * k / 30.0, (np.sin(ks) / ks - np.cos(ks)) / (ks * ks))
    return ((1.0 - u) * 0.5 * jinc + u * ld) / ((1.0 - u) * 0.5 + u / 3.0)


def _pixel_sinc(a, f):
    """The pixel's rectangle of side ``a`` in frequency: a sinc(a f), area included; 1 for none."""
    return np.ones_like(f) if a <= 0.0 else a * np.sinc(a * f)


@real_spectrum.reference
def _real_spectrum_numpy(fx, fy, ap, area, km, u, ax, ay, diff, use_ap):
    """numpy reference of :func:`real_spectrum`, on the whole grid at once.

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
        Sides of the pixel's sensitive rectangle (px); 0 for none.
    diff : float
        RMS of the Gaussian charge diffusion (px).
    use_ap : bool
        Whether the aperture's transform is a factor.

    Returns
    -------
    ndarray of float64, shape (nfy, nfx)
        The real, centred spectrum.
    """
    f1, f2 = np.meshgrid(fx, fy)
    v = np.outer(_pixel_sinc(ay, fy), _pixel_sinc(ax, fx))
    if use_ap:
        g1, g2 = ap[0, 0] * f1 + ap[1, 0] * f2, ap[0, 1] * f1 + ap[1, 1] * f2
        v = v * area * _disk_ft_numpy(2.0 * np.pi * np.hypot(g1, g2), 0.0)
    h1, h2 = km[0, 0] * f1 + km[1, 0] * f2, km[0, 1] * f1 + km[1, 1] * f2
    v = v * _disk_ft_numpy(2.0 * np.pi * np.hypot(h1, h2), u)
    if diff > 0.0:
        v = v * np.exp(-2.0 * (np.pi * diff) ** 2 * (f1 * f1 + f2 * f2))
    return v


def _accumulate_row(t4, a, i, b, w, rr, ri):
    """(rr + i ri) += t4[a, i, b, :] w, for a real or complex ``t4``."""


@overload(_accumulate_row, inline="always")
def _accumulate_row_impl(t4, a, i, b, w, rr, ri):
    if isinstance(t4.dtype, numba.types.Complex):

        def impl_complex(t4, a, i, b, w, rr, ri):
            wr = w.real
            wi = w.imag
            for j in range(rr.shape[0]):
                tr = t4[a, i, b, j].real
                ti = t4[a, i, b, j].imag
                rr[j] += tr * wr - ti * wi
                ri[j] += tr * wi + ti * wr

        return impl_complex

    def impl_real(t4, a, i, b, w, rr, ri):
        wr = w.real
        wi = w.imag
        for j in range(rr.shape[0]):
            t = t4[a, i, b, j]
            rr[j] += t * wr
            ri[j] += t * wi

    return impl_real


@numba.njit(inline="always")
def _rotate_add(rr, ri, w, sr, si):
    """(sr + i si) += (rr + i ri) w, elementwise."""
    wr = w.real
    wi = w.imag
    for j in range(rr.shape[0]):
        sr[j] += rr[j] * wr - ri[j] * wi
        si[j] += rr[j] * wi + ri[j] * wr


@numba.njit(inline="always")
def _phase_out(sr, si, e, ex, out):
    """out = (sr + i si) e ex, elementwise."""
    for j in range(sr.shape[0]):
        out[j] = complex(sr[j], si[j]) * e * ex[j]


@fold_phase.reference
def _fold_phase_numpy(t4, wy, wx, ey, ex):
    """numpy reference of :func:`fold_phase`: its defining sum as two tensor contractions.

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
        acc[n, i, j] = ey[n, i] ex[n, j] sum_a wy[n, a] sum_b t4[a, i, b, j] wx[n, b].
    """
    folded = np.einsum("aibj,nb->naij", t4, wx)
    return np.einsum("naij,na->nij", folded, wy) * ey[:, :, None] * ex[:, None, :]


#: Spacing and range of the tabulated disk transforms (:func:`disk_ft_table`).
TABLE_STEP = 1.0 / 64.0
TABLE_KMAX = 256.0


@jit.kernel(nogil=True, cache=True)
def _build_table(u, h, n):
    tab = np.empty(n + 3)
    for i in range(n + 3):
        tab[i] = _disk_ft(abs(i - 1) * h, u)
    return tab


@_build_table.reference
def _build_table_numpy(u, h, n):
    """numpy reference of :func:`_build_table`: the exact transform at k = (i - 1) h."""
    return _disk_ft_numpy(np.abs(np.arange(n + 3) - 1) * h, u)


def disk_ft_table(u: float) -> np.ndarray:
    """``_disk_ft(k, u)`` at k = (i - 1) h, i = 0 .. n + 2 (h = :data:`TABLE_STEP`, n h =
    :data:`TABLE_KMAX`), read-only: the samples of :func:`real_spectrum_tabulated`.

    Parameters
    ----------
    u : float
        Linear limb-darkening coefficient (0 for the aperture's jinc).

    Returns
    -------
    ndarray of float64, shape (n + 3,)
        The table, built by the kernels the option ``kernels`` selects (kept per option).
    """
    return _disk_ft_table(float(u), OPTIONS["kernels"])


@functools.lru_cache(maxsize=8)
def _disk_ft_table(u: float, kernels: str) -> np.ndarray:
    tab = _build_table(u, TABLE_STEP, int(round(TABLE_KMAX / TABLE_STEP)))
    tab.setflags(write=False)
    return tab


@numba.njit(inline="always")
def _lookup(tab, inv_h, k, u):
    """Cubic (4-point Lagrange) interpolation of a :func:`disk_ft_table` at k >= 0, or the exact
    transform beyond the table. Error bound (3/128) h^4 max|f''''| < 1e-9 for h = 1/64."""
    x = k * inv_h
    i = int(x)
    if i + 3 >= tab.shape[0]:
        return _disk_ft(k, u)
    t = x - i
    tm1 = t - 1.0
    tm2 = t - 2.0
    tp1 = t + 1.0
    return (
        -tab[i] * t * tm1 * tm2
        + 3.0 * tab[i + 1] * tp1 * tm1 * tm2
        - 3.0 * tab[i + 2] * tp1 * t * tm2
        + tab[i + 3] * tp1 * t * tm1
    ) / 6.0


@jit.kernel(nogil=True, cache=True)
def real_spectrum_tabulated(fx, fy, ap, area, km, u, ax, ay, diff, use_ap, tab_ap, tab_u):
    """:func:`real_spectrum` with the two disk transforms interpolated in tables.

    ``tab_ap`` = ``disk_ft_table(0.0)`` (the aperture's jinc) and ``tab_u`` =
    ``disk_ft_table(u)`` (the sun disk). The interpolation error, below 2e-10 of the spectrum's
    peak on the paper's bench (``tests/sim/test_kernels.py`` measures it), is smaller than the
    1e-8 of the Bessel approximation both paths share; the evaluation is 3-4x faster (no
    trigonometric call per frequency).
    """
    nfx = fx.shape[0]
    nfy = fy.shape[0]
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
                g1 = ap[0, 0] * f1 + ap[1, 0] * f2
                g2 = ap[0, 1] * f1 + ap[1, 1] * f2
                v *= area * _lookup(tab_ap, inv_h, tp * math.sqrt(g1 * g1 + g2 * g2), 0.0)
            h1 = km[0, 0] * f1 + km[1, 0] * f2
            h2 = km[0, 1] * f1 + km[1, 1] * f2
            v *= _lookup(tab_u, inv_h, tp * math.sqrt(h1 * h1 + h2 * h2), u)
            if diff > 0.0:
                v *= math.exp(-2.0 * (math.pi * diff) ** 2 * (f1 * f1 + f2 * f2))
            out[b, a] = v
    return out


@real_spectrum_tabulated.reference
def _real_spectrum_tabulated_numpy(fx, fy, ap, area, km, u, ax, ay, diff, use_ap, tab_ap,
                                   tab_u):
    """numpy reference of :func:`real_spectrum_tabulated`: the transforms evaluated directly
    (:func:`_real_spectrum_numpy`; the tables ``tab_ap``, ``tab_u`` unused), which the kernel
    interpolates to 2e-10 of the peak."""
    return _real_spectrum_numpy(fx, fy, ap, area, km, u, ax, ay, diff, use_ap)
