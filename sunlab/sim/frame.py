"""Frames: the expected spot stamps of a frame exposed on the detector, with its noise and ADC.

A frame is the sensor's dark frame (bias, column pattern, dark signal and its non-uniformity,
read and dark shot noise, rounding: :mod:`sunlab.sim.detector`) with the pixels under the spots
recomputed from their expected photo-electrons (:mod:`sunlab.sim.render`) times the pixels'
response, with photon noise, saturation at the full well and the ADC's rounding and clipping.
Every frame is deterministic in (seed, pose, shot): its noise is a counter-based stream keyed by
:func:`sunlab.sim.render.frame_key`.

The shots of one pose share the spots' shape (:func:`render_pose`): the aperture's projection
and the sun-disk kernel are evaluated once per pose, at its first shot, and each shot places the
spots at its own rays with its own flux. The platform's jitter between shots (0.0005 deg RMS)
changes the shape by parts in 1e5, below one photo-electron (``tests/sim/test_render.py``).

Examples
--------
>>> from sunlab.sim import Bench
>>> f = render_frame(Bench.paper_single_hole(), -5.0, 5.0, seed=1)
>>> f.dtype.name, f.shape
('uint16', (1024, 1280))
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigurationError
from ._adc import adc_frame, adc_stamps, normal_table, stamp_signal
from .detector import fixed_pattern
from .render import _geometry, frame_key, mask_play, spot_geometry
from .spots import _groups

__all__ = ["render_frame"]


def _pose_stamps(bench, alphas, betas, play_mm, shape_angles):
    """The expected photo-electron stamps of several shots of one pose, the spots' shapes
    evaluated once: one flat buffer, and per shot the boxes (offset, y0, x0, ny, nx) of its
    stamps in order (int64, (stamps, 5): :func:`sunlab.sim._adc.adc_stamps`).

    Every shot's spots sit at their own rays (the sun vector of the shot's true angles) with the
    flux of their own obliquity; their shape (aperture projection, sun-disk kernel, the
    kernel's centroid offset) is that of the angles ``shape_angles``, the pose's first shot in
    a cube. The jitter between the shots of a pose (0.0005 deg RMS on the paper's bench)
    changes the shape by parts in 1e5; ``tests/sim/test_render.py`` bounds the difference
    from the exact stamps.
    """
    geom = spot_geometry(bench, shape_angles[0], shape_angles[1], play_mm)
    if not geom.lit:  # no shared shape: each shot on its own (the sun at the mask's horizon)
        bufs, boxes, o = [], [], 0
        for a, b in zip(alphas, betas, strict=True):
            buf, (box,) = (_pose_stamps(bench, [a], [b], play_mm, (a, b))
                           if (a, b) != tuple(shape_angles) else (np.empty(0), [_NO_STAMPS]))
            bufs.append(buf)
            boxes.append(box + np.array([o, 0, 0, 0, 0]))
            o += buf.size
        return np.concatenate(bufs), boxes
    det = bench.detector
    sv, lit, ray_k, *_ = _geometry(bench, alphas, betas, [play_mm] * len(alphas), "none")
    q_k = geom.q_e * (sv[:, 2] / geom.s[2])  # the flux's cosine factor, per shot
    todo = []
    for g in _groups(bench, geom):  # every lit shot's spots that reach the detector, in order
        (x, y), r = ray_k[:, g.idx].transpose(2, 0, 1), g.radius
        kk, mm = np.nonzero(lit[:, None] & (x + r >= -0.5) & (y + r >= -0.5)
                            & (x - r <= det.nx - 0.5) & (y - r <= det.ny - 0.5))
        if kk.size:
            todo.append((g, g.spectrum(), kk, mm))
    starts = np.cumsum([0] + [kk.size * spec.m**2 for _, spec, kk, _ in todo])
    buf, rows, shot = np.empty(starts[-1]), [], []
    for (g, spec, kk, mm), o in zip(todo, starts, strict=False):
        ray, m = ray_k[kk, g.idx[mm]], spec.m
        _, x0, y0 = spec.images(ray, ray + g.shift[mm], q_k[kk],
                                out=buf[o : o + kk.size * m * m].reshape(-1, m, m))
        rows.append(np.stack([o + m * m * np.arange(kk.size), y0, x0, np.full_like(x0, m),
                              np.full_like(x0, m)], axis=1))
        shot.append(kk)
    rows = np.concatenate(rows or [_NO_STAMPS]).astype(np.int64)
    shot = np.concatenate(shot or [np.empty(0, int)])
    return buf, [rows[shot == k] for k in range(len(alphas))]


#: no stamps: the boxes of a shot whose spots all miss the detector
_NO_STAMPS = np.empty((0, 5), dtype=np.int64)


def expected_frame(bench, alpha_true, beta_true, *, play_mm=(0.0, 0.0)):
    """The model's mean (DN, before rounding) and variance (DN^2) of every pixel of a frame.

    The mean is bias + column pattern + (dark + PRNU x signal) / gain; the variance is
    (dark + PRNU x signal + read noise^2) / gain^2 (without the 1/12 DN^2 of rounding and without
    clipping). For testing the noise model and for teaching.

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : float
        True platform angles, deg.
    play_mm : (float, float)
        The mask's per-pose offset (:func:`sunlab.sim.mask_play`), mm.

    Returns
    -------
    mean, var : numpy.ndarray, shape (ny, nx)
        Expected value (DN) and variance (DN^2) of each pixel.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> mean, var = expected_frame(Bench.paper_single_hole(), 0.0, 0.0)
    >>> mean.shape, bool(mean.max() > 300)
    ((1024, 1280), True)
    """
    det, fp, g = bench.detector, fixed_pattern(bench.detector), bench.detector.gain_e_per_dn
    buf, (boxes,) = _pose_stamps(bench, [alpha_true], [beta_true], play_mm,
                                 (alpha_true, beta_true))
    e = np.clip(fp.dark_e + fp.gain * stamp_signal(boxes, buf, det.shape), 0, None)
    mean = fp.offset_dn + e / g
    var = (e + det.read_noise_e**2) / g**2 if det.temporal_noise else np.zeros_like(mean)
    return mean, var


def render_frame(bench, alpha_true, beta_true, *, seed, pose: int = 0, shot: int = 0,
                 play_mm=None, out=None, shape_angles=None) -> np.ndarray:
    """One full detector frame, uint16 (ny, nx), deterministic in (seed, pose, shot).

    Parameters
    ----------
    bench : Bench
        The virtual bench.
    alpha_true, beta_true : float
        True platform angles (see :func:`sunlab.sim.platform.platform_pose`), deg.
    seed : int or sequence of int
        Seed of the experiment.
    pose, shot : int
        Indices of the frame: the noise stream is derived from (seed, pose, shot); a loosely held
        mask's offset from (seed, pose).
    play_mm : (float, float), optional
        Override the mask's per-pose offset, mm.
    out : numpy.ndarray of uint16, shape (ny, nx), optional
        Write the frame here (e.g. one shot of a pose's block) instead of a new array.
    shape_angles : (float, float), optional
        True angles (deg) at which the spot's *shape* is evaluated; its position and flux are
        always those of ``alpha_true``, ``beta_true`` (the default, exact). A simulated cube
        renders every shot of a pose with the shape of the pose's first shot
        (:func:`render_pose`), so frame (p, s) of a cube is ``render_frame(..., pose=p,
        shot=s, shape_angles=(true_alpha[p, 0], true_beta[p, 0]))``.

    Returns
    -------
    numpy.ndarray of uint16, shape (ny, nx)
        ``out`` when given.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> bench = Bench.paper_single_hole()
    >>> f1 = render_frame(bench, -5.0, 5.0, seed=1, pose=0, shot=0)
    >>> f2 = render_frame(bench, -5.0, 5.0, seed=1, pose=0, shot=0)
    >>> f1.dtype.name, f1.shape, bool((f1 == f2).all())
    ('uint16', (1024, 1280), True)
    """
    out = _output(out, bench.detector.shape)
    play = mask_play(bench, seed, pose) if play_mm is None else play_mm
    ref = (alpha_true, beta_true) if shape_angles is None else shape_angles
    buf, (boxes,) = _pose_stamps(bench, [alpha_true], [beta_true], play, ref)
    _expose(bench, buf, boxes, seed, pose, shot, out)
    return out


def render_pose(bench, alpha_true, beta_true, *, seed, pose: int = 0, out=None) -> np.ndarray:
    """Every shot of one pose, uint16 (shots, ny, nx): the frames of a simulated cube.

    Shot s is ``render_frame(bench, alpha_true[s], beta_true[s], seed=seed, pose=pose, shot=s,
    shape_angles=(alpha_true[0], beta_true[0]))``: the spots' shape is evaluated once for the
    pose (their positions and fluxes per shot), which makes a multi-hole pose several times
    cheaper to render than its shots one by one.

    Parameters
    ----------
    bench : Bench
    alpha_true, beta_true : array_like, shape (shots,)
        True platform angles of each shot, deg.
    seed : int or sequence of int
        Seed of the experiment: shot s gets the noise stream ``frame_key(seed, pose, s)``.
    pose : int
        Index of the pose in its plan.
    out : numpy.ndarray of uint16, shape (shots, ny, nx), optional
        Written in place when given (a cube's chunk).

    Returns
    -------
    numpy.ndarray of uint16, shape (shots, ny, nx)
        The frames, DN (``out`` when given).

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> bench = Bench.paper_single_hole()
    >>> frames = render_pose(bench, [-5.0, -5.0004], [5.0, 5.0003], seed=1, pose=0)
    >>> one = render_frame(bench, -5.0004, 5.0003, seed=1, pose=0, shot=1,
    ...                    shape_angles=(-5.0, 5.0))
    >>> frames.shape, bool((frames[1] == one).all())
    ((2, 1024, 1280), True)
    """
    a = np.atleast_1d(np.asarray(alpha_true, dtype=float))
    b = np.atleast_1d(np.asarray(beta_true, dtype=float))
    if a.shape != b.shape or a.ndim != 1:
        raise ConfigurationError(
            f"alpha_true, beta_true: found shapes {a.shape} and {b.shape}; expected two 1-D "
            "arrays of the same length (one angle per shot).")
    out = _output(out, (a.size,) + bench.detector.shape)
    play_mm = mask_play(bench, seed, pose)
    buf, boxes = _pose_stamps(bench, a, b, play_mm, (a[0], b[0]))
    for k, box in enumerate(boxes):
        _expose(bench, buf, box, seed, pose, k, out[k])
    return out


def _output(out, shape):
    """``out``, checked, or a new uint16 array of ``shape``."""
    if out is not None and (out.shape, out.dtype, out.flags.c_contiguous) != (shape, "u2", True):
        raise ConfigurationError(
            f"out: found {out.dtype} {out.shape}; expected a C-contiguous uint16 array of shape "
            f"{shape}. Fix: pass numpy.empty({shape}, dtype=numpy.uint16) or omit out.")
    return np.empty(shape, dtype=np.uint16) if out is None else out


def _expose(bench, buf, boxes, seed, pose, shot, out):
    """The ADC of a frame: the dark frame's noise and rounding everywhere, then the pixels under
    the spot stamps (``buf``, ``boxes``: :func:`_pose_stamps`) recomputed with their photon
    noise."""
    det, fp, max_dn = bench.detector, fixed_pattern(bench.detector), float(bench.detector.max_dn)
    table = normal_table() if det.temporal_noise else np.empty(0, dtype=np.float32)
    state = frame_key(seed, pose, shot).generate_state(1, dtype=np.uint64)
    adc_frame(fp.bg_mean_dn, fp.bg_sigma_dn, table, state, max_dn, out)
    read_var = float(det.read_noise_e**2) if det.temporal_noise else 0.0
    adc_stamps(boxes, buf, fp.gain, fp.dark_e, fp.offset_dn, table, state, read_var,
               1.0 / det.gain_e_per_dn, float(det.full_well_e), max_dn, out)
