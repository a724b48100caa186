"""The Cramér–Rao lower bound of a spot centroid (pixel-integrated Poisson + read noise).

Examples
--------
>>> from sunlab.centroid import crlb
>>> b = crlb(385000.0, 30.0, 2.5, gain=4.0)
>>> bool(b.sigma_x < 0.02)
True
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..errors import ConfigurationError
from .result import _check_positive

__all__ = ["crlb", "disk_profile"]


class CRLB(NamedTuple):
    """Cramér–Rao lower bound of the centroid standard deviation, px."""

    sigma_x: float
    sigma_y: float


def disk_profile(dx, dy, radius: float = 17.5, edge: float = 3.25):
    """Surface brightness (0..1) of a uniform disk spot blurred by a uniform source disk.

    The spot of a round hole of radius ``radius`` lit by a uniform disk source whose image has
    radius ``edge`` (F tan of the sun's angular radius: 5 mm x tan(0.26 deg) = 3.24 px for the
    paper's bench) is the hole convolved with that disk. For ``radius >> edge`` its edge profile
    is the fraction of the source disk inside a half-plane at distance ``d = r - radius``:

    .. math:: f(d) = \\frac{1}{\\pi}\\left[\\arccos u - u\\sqrt{1 - u^2}\\right],
              \\quad u = \\operatorname{clip}(d / \\rho, -1, 1),\\ \\rho = \\text{edge}

    ``edge = 0`` is a hard edge.

    Parameters
    ----------
    dx, dy : array_like
        Offset from the spot's centre along x (columns) and y (rows), px; broadcast together.
    radius : float
        Radius of the spot (the hole's image before the source's blur), px.
    edge : float
        Radius rho of the source disk's image, px; 0 for a hard edge.

    Returns
    -------
    numpy.ndarray
        Brightness relative to the spot's flat top, 0 .. 1, of the broadcast shape: 1 inside
        ``radius - edge``, 0 beyond ``radius + edge``, 0.5 at ``radius`` (edge > 0).

    Examples
    --------
    >>> [float(disk_profile(r, 0.0)) for r in (0.0, 17.5, 30.0)]
    [1.0, 0.5, 0.0]
    """
    r = np.hypot(dx, dy)
    if edge <= 0:
        return np.where(r <= radius, 1.0, 0.0)
    u = np.clip((r - radius) / edge, -1.0, 1.0)
    return (np.arccos(u) - u * np.sqrt(1.0 - u * u)) / np.pi


def crlb(
    flux: float, background: float, read_noise: float, *, gain: float = 1.0,
    radius: float = 17.5, edge: float = 3.25, model: Callable | None = None,
    half_size: float | None = None, position: tuple[float, float] = (0.3, 0.2),
    quantisation: bool = True, supersample: int = 16,
) -> CRLB:
    """Cramér–Rao lower bound of a spot centroid for pixel-integrated Poisson + read noise.

    The expected value of pixel ``i`` is ``mu_i = flux * P_i + background`` where ``P_i`` is the
    spot's surface brightness integrated over the pixel (normalised to 1 over the cutout); its
    variance is ``mu_i / gain + read_noise^2 (+ 1/12 for quantisation to integer DN)``. The
    Fisher information of the centre is

    .. math:: I_{ab} = \\sum_i \\frac{1}{\\operatorname{var}_i}
              \\frac{\\partial \\mu_i}{\\partial a}\\frac{\\partial \\mu_i}{\\partial b},
              \\qquad a, b \\in \\{x, y\\}

    and the bound is ``sqrt(diag(I^-1))``. The derivative of a pixel-integrated value with
    respect to the centre is computed exactly as the difference of line integrals of the surface
    brightness along the pixel's two edges, so hard-edged spots work too. The variance model is
    the Gaussian (shifted-Poisson) approximation of the Poisson + Gaussian likelihood, exact in
    the pure-Poisson and pure-Gaussian limits. Flux, background and spot shape are taken as
    known; for a centrally symmetric spot the centre decouples from them, so the bound holds
    when they are fitted too.

    Parameters
    ----------
    flux : float
        Total spot flux above the background, DN.
    background : float
        Background level per pixel (dark + stray light), DN.
    read_noise : float
        Read noise, DN rms.
    gain : float
        Conversion gain, electrons per DN (Poisson variance in DN^2 is ``mu / gain``).
    radius, edge : float
        Spot radius and edge half-width, px, of the default model :func:`disk_profile`.
    model : callable, optional
        Surface brightness ``model(dx, dy)`` (any scale) of the spot about its centre, for
        array offsets dx (column) and dy (row) in px; replaces the default disk.
    half_size : float, optional
        Half-size of the cutout, px (default ``radius + edge + 3``; give it with ``model``).
    position : tuple of 2 float
        Sub-pixel position of the centre (the bound depends on it weakly).
    quantisation : bool
        Add the quantisation variance 1/12 DN^2.
    supersample : int
        Sub-samples per pixel side (and line-integral samples per pixel edge x 4).

    Returns
    -------
    CRLB
        ``(sigma_x, sigma_y)``, px.

    Examples
    --------
    >>> b = crlb(385000.0, 30.0, 2.5, gain=4.0)
    >>> 0.002 < b.sigma_x < 0.02
    True
    """
    _check_positive("flux", flux)
    _check_positive("gain", gain)
    if not (background >= 0 and read_noise >= 0):
        raise ConfigurationError(
            f"background, read_noise: found {background!r}, {read_noise!r}, expected >= 0 DN"
        )
    prof = model if model is not None else (lambda dx, dy: disk_profile(dx, dy, radius, edge))
    h = float(half_size) if half_size is not None else float(radius + max(edge, 0) + 3)
    noise = (gain, read_noise**2, 1.0 / 12.0 if quantisation else 0.0)
    fisher = _fisher(prof, flux, background, noise, h, position, int(supersample))
    cov = np.linalg.inv(fisher)
    return CRLB(float(math.sqrt(cov[0, 0])), float(math.sqrt(cov[1, 1])))


def _fisher(prof, flux, background, noise, h, position, s):
    """Fisher information (2 x 2) of the centre of the spot ``prof`` (see :func:`crlb`):
    ``noise`` is (gain, read noise^2, quantisation variance), ``h`` the cutout's half-size,
    ``s`` the sub-samples per pixel side."""
    gain, read_var, quant_var = noise
    n = int(math.ceil(h))
    px0, py0 = position
    cols = np.arange(-n, n + 1)
    off = (np.arange(s) + 0.5) / s - 0.5
    # Pixel integrals of the surface brightness.
    sx = (cols[:, None] + off[None, :]).ravel() - px0
    sy = (cols[:, None] + off[None, :]).ravel() - py0
    sub = prof(sx[None, :], sy[:, None])
    pint = sub.reshape(cols.size, s, cols.size, s).mean(axis=(1, 3))
    total = pint.sum()
    if not total > 0:
        raise ConfigurationError("model: found a spot of zero brightness on the cutout")
    scale = flux / total
    mu = scale * pint + background
    var = mu / gain + read_var + quant_var
    # d mu / d x0 = -(line integral on the right edge - on the left edge), and likewise for y0.
    t = 4 * s
    lo = (np.arange(t) + 0.5) / t - 0.5
    ly = (cols[:, None] + lo[None, :]).ravel() - py0  # rows, finely sampled
    edges = np.concatenate([cols - 0.5, [cols[-1] + 0.5]]) - px0
    line = prof(edges[None, :], ly[:, None]).reshape(cols.size, t, edges.size).mean(axis=1)
    dmu_dx = -scale * (line[:, 1:] - line[:, :-1])
    lx = (cols[:, None] + lo[None, :]).ravel() - px0
    edges_y = np.concatenate([cols - 0.5, [cols[-1] + 0.5]]) - py0
    line_y = prof(lx[None, :], edges_y[:, None]).reshape(edges_y.size, cols.size, t).mean(axis=2)
    dmu_dy = -scale * (line_y[1:, :] - line_y[:-1, :])
    return np.array([
        [np.sum(dmu_dx**2 / var), np.sum(dmu_dx * dmu_dy / var)],
        [np.sum(dmu_dx * dmu_dy / var), np.sum(dmu_dy**2 / var)],
    ])
