"""The detector's noise stream and ADC: a frame's temporal noise, saturation, rounding and
clipping (the signal chain of :mod:`sunlab.sim.detector`, steps 3-4), as compiled kernels beside
their numpy references (:mod:`sunlab.sim._jit`).

Examples
--------
>>> t = normal_table()
>>> t.dtype.name, t.size, round(float(t.std()), 3)
('float32', 65536, 1.0)
"""

from __future__ import annotations

import functools
import math

import numba
import numpy as np

from . import _jit

__all__ = []

# The noise stream: SplitMix64 (Steele, Lea & Flood 2014), counter-based: output b of a frame's
# stream is _mix64(state + b golden), and its four 16-bit fields, low bits first, index the
# 65 536 equiprobable midpoint quantiles of N(0, 1) (:func:`normal_table`) for four
# consecutive pixels (row-major). The numpy references draw the same stream on uint64 arrays
# (whose arithmetic wraps modulo 2**64 as the compiled code's does): the same frames bit for bit.
_GOLDEN = np.uint64(0x9E3779B97F4A7C15)
_M1 = np.uint64(0xBF58476D1CE4E5B9)
_M2 = np.uint64(0x94D049BB133111EB)


def _mix64_numpy(z):
    z = (z ^ (z >> np.uint64(30))) * _M1
    z = (z ^ (z >> np.uint64(27))) * _M2
    return z ^ (z >> np.uint64(31))


_mix64 = numba.njit(inline="always")(_mix64_numpy)


@functools.lru_cache(maxsize=1)
def normal_table() -> np.ndarray:
    """The 65 536 midpoint quantiles of N(0, 1), float32, read-only (variance 0.9998, tails at
    4.3 sigma).

    Returns
    -------
    numpy.ndarray of float32, shape (65536,)
    """
    from scipy.special import ndtri

    t = ndtri((np.arange(65536) + 0.5) / 65536).astype(np.float32)
    t.setflags(write=False)
    return t


@numba.njit(inline="always")
def _to_dn32(v, top):
    """floor(v + 0.5) clipped to 0 .. max_dn as uint16, for v float32 (top = max_dn + 0.5).
    Bit for bit the float64 rounding: below 2**23 the float32 sum v + 0.5 is exact or rounds to
    a neighbour never across an integer; clamping first makes truncation the floor."""
    return np.uint16(np.int32(min(max(v + np.float32(0.5), np.float32(0.0)), top)))


def _normal_deviates(table, state, n):
    """The n deviates of the stream at ``state`` (uint64[1]), advanced past them (numpy)."""
    steps = -(-n // 4)
    counters = state + np.arange(1, steps + 1, dtype=np.uint64) * _GOLDEN
    fields = _mix64_numpy(counters)[:, None] >> (np.uint64(16) * np.arange(4, dtype=np.uint64))
    state += np.array([steps], dtype=np.uint64) * _GOLDEN  # in place, wrapping
    return table[(fields & np.uint64(0xFFFF)).ravel()[:n]]


def _round_clip(v, max_dn):
    return np.clip(np.floor(np.asarray(v, dtype=np.float64) + 0.5), 0.0, max_dn).astype(np.uint16)


def _adc_frame_numpy(mean_dn, sigma_dn, table, state, max_dn, out):
    """numpy reference of :func:`adc_frame`."""
    if table.shape[0] == 0:
        out[...] = _round_clip(mean_dn, max_dn)
        return
    z = _normal_deviates(table, state, mean_dn.size).reshape(mean_dn.shape)
    out[...] = _round_clip(mean_dn + sigma_dn * z, max_dn)  # float32, as the kernel sums


@_jit.kernel(_adc_frame_numpy)
def adc_frame(mean_dn, sigma_dn, table, state, max_dn, out):
    """out = clip(rint(mean + sigma z), 0, max_dn) over a whole frame (float32 arithmetic).

    Parameters
    ----------
    mean_dn, sigma_dn : ndarray of float32, shape (ny, nx)
        Mean and standard deviation of every pixel (DN).
    table : ndarray of float32, shape (65536,) or (0,)
        :func:`normal_table`; empty for no noise.
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
    n = mean_dn.size
    m, s, o = mean_dn.reshape(n), sigma_dn.reshape(n), out.reshape(n)
    top = np.float32(max_dn + 0.5)
    if table.shape[0] == 0:
        for k in range(n):
            o[k] = _to_dn32(m[k], top)
        return
    s0, low, n4 = state[0], np.uint64(0xFFFF), n // 4
    for b in range(n4):  # four pixels per output: no bits carried between iterations
        r = _mix64(s0 + np.uint64(b + 1) * _GOLDEN)
        k = 4 * b
        for q in range(4):
            o[k + q] = _to_dn32(m[k + q] + s[k + q] * table[(r >> np.uint64(16 * q)) & low], top)
    r = _mix64(s0 + np.uint64(n4 + 1) * _GOLDEN)  # the last pixels' output, if any
    for k in range(4 * n4, n):
        o[k] = _to_dn32(m[k] + s[k] * table[r & low], top)
        r = r >> np.uint64(16)
    state[0] = s0 + np.uint64((n + 3) // 4) * _GOLDEN


def _clipped(box, shape):
    """A stamp's box (offset, y0, x0, ny, nx) clipped to a frame: its rows and columns in the
    frame and in the stamp, or None off the frame."""
    _, y0, x0, ny, nx = (int(v) for v in box)
    ya, yb, xa, xb = max(y0, 0), min(y0 + ny, shape[0]), max(x0, 0), min(x0 + nx, shape[1])
    if ya >= yb or xa >= xb:
        return None
    return (slice(ya, yb), slice(xa, xb)), (slice(ya - y0, yb - y0), slice(xa - x0, xb - x0))


def stamp_signal(boxes, signal_e, shape):
    """Every stamp added over a frame of ``shape`` in order, clipped to it (float64)."""
    full = np.zeros(shape)
    for o, y0, x0, ny, nx in boxes:
        if (cut := _clipped((o, y0, x0, ny, nx), shape)) is not None:
            full[cut[0]] += signal_e[o : o + ny * nx].reshape(ny, nx)[cut[1]]
    return full


def _adc_stamps_numpy(boxes, signal_e, gain, dark_e, offset_dn, table, state, read_var_e,
                      inv_gain, full_well_e, max_dn, out):
    """numpy reference of :func:`adc_stamps`."""
    full = stamp_signal(boxes, signal_e, out.shape)
    for box in boxes:
        if (cut := _clipped(box, out.shape)) is None:
            continue
        box, sig = cut[0], full[cut[0]]
        e = np.maximum(gain[box] * sig + dark_e[box], 0.0)
        if table.shape[0] > 0:
            z = _normal_deviates(table, state, sig.size).reshape(sig.shape)
            e = e + np.sqrt(e + read_var_e) * z.astype(np.float64)
        out[box] = _round_clip(offset_dn[box] + np.minimum(e, full_well_e) * inv_gain, max_dn)


@_jit.kernel(_adc_stamps_numpy)
def adc_stamps(boxes, signal_e, gain, dark_e, offset_dn, table, state, read_var_e, inv_gain,
               full_well_e, max_dn, out):
    """Recompute the pixels under a frame's spot stamps, continuing the frame's stream.

    Stamp by stamp, in order, over its box clipped to the frame (a box wholly off the frame
    draws nothing): the signal is the sum of every stamp over each pixel, in stamp order (so
    overlapping stamps add); electrons e = max(gain signal + dark, 0), plus sqrt(e + read
    noise^2) z (photon and dark shot noise in the Gaussian limit), saturated at the full well,
    rounded and clipped by the ADC. The box's deviates are drawn first, then each row is
    computed branch-free (the compiler vectorises it).

    Parameters
    ----------
    boxes : ndarray of int64, shape (stamps, 5)
        Each stamp's offset in ``signal_e``, its first row and column in the frame and its rows
        and columns (offset, y0, x0, ny, nx).
    signal_e : ndarray of float64, shape (n,)
        The stamps' photo-electrons before PRNU, each row-major at its offset.
    gain, dark_e, offset_dn : ndarray of float32, shape of the frame
        PRNU gain, dark electrons and offset (DN) of every pixel.
    table, state
        As :func:`adc_frame`'s.
    read_var_e, inv_gain, full_well_e, max_dn : float
        Read-noise variance (e^2), DN per electron, saturation (e), full scale (DN).
    out : ndarray of uint16, shape of the frame
        The frame; the stamps' pixels are rewritten.

    Returns
    -------
    None
        ``out`` and ``state`` are written in place.
    """
    n_s, (fy, fx), noisy = boxes.shape[0], out.shape, table.shape[0] > 0
    clip = np.empty((n_s, 4), dtype=np.int64)  # each box on the frame: ya, yb, xa, xb
    for k in range(n_s):
        y0, x0, ny, nx = boxes[k, 1], boxes[k, 2], boxes[k, 3], boxes[k, 4]
        clip[k] = max(y0, 0), min(y0 + ny, fy), max(x0, 0), min(x0 + nx, fx)
    size = max(0, np.max((clip[:, 1] - clip[:, 0]) * (clip[:, 3] - clip[:, 2]))) if n_s else 0
    z, row = np.zeros(size if noisy else 1, dtype=np.float32), np.empty(fx)
    meet, top = np.empty(n_s, dtype=np.int64), max_dn + 0.5
    for k in range(n_s):
        ya, yb, xa, xb = clip[k, 0], clip[k, 1], clip[k, 2], clip[k, 3]
        if ya >= yb or xa >= xb:
            continue
        n_meet = 0  # the stamps over this one's pixels (itself included), in stamp order
        for j in range(n_s):
            if clip[j, 0] < yb and ya < clip[j, 1] and clip[j, 2] < xb and xa < clip[j, 3]:
                meet[n_meet] = j
                n_meet += 1
        nx, n = xb - xa, (yb - ya) * (xb - xa)
        if noisy:
            s0, low, steps = state[0], np.uint64(0xFFFF), (n + 3) // 4
            for b in range(steps):
                r = _mix64(s0 + np.uint64(b + 1) * _GOLDEN)
                for q in range(4 * b, min(4 * b + 4, n)):
                    z[q] = table[r & low]
                    r = r >> np.uint64(16)
            state[0] = s0 + np.uint64(steps) * _GOLDEN
        for yy in range(ya, yb):
            if n_meet == 1:  # the stamp alone: its own row
                start = boxes[k, 0] + (yy - boxes[k, 1]) * boxes[k, 4] + xa - boxes[k, 2]
                sig = signal_e[start:start + nx]
            else:
                sig = row[:nx]
                sig[:] = 0.0
            for j in meet[:n_meet] if n_meet > 1 else meet[:0]:
                if clip[j, 0] <= yy < clip[j, 1]:
                    start = boxes[j, 0] + (yy - boxes[j, 1]) * boxes[j, 4] - boxes[j, 2]
                    for c in range(max(xa, clip[j, 2]), min(xb, clip[j, 3])):
                        sig[c - xa] += signal_e[start + c]
            g, d, off, ob = gain[yy, xa:xb], dark_e[yy, xa:xb], offset_dn[yy, xa:xb], out[yy, xa:xb]
            zi = z[(yy - ya) * nx:(yy - ya + 1) * nx] if noisy else z
            for c in range(nx):
                e = max(g[c] * sig[c] + d[c], 0.0)
                if noisy:
                    e += math.sqrt(e + read_var_e) * zi[c]
                e = min(e, full_well_e)
                ob[c] = np.uint16(np.int32(min(max(np.float64(off[c] + e * inv_gain) + 0.5, 0.0),
                                               top)))
