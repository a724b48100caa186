"""Geometric models of the pinhole sun sensor: the ideal model (1) and sun-vector conversions.

Sign convention (``docs/nomenclature.md``): the sensor frame has z along the boresight, from the
focal plane toward the mask; x along detector columns, y along rows. The platform's outer axis sets
alpha and its inner axis sets beta; the unit vector toward the sun in the sensor frame is

.. math:: \\mathbf{s} = R_y(-\\alpha) R_x(\\beta) \\mathbf{e}_z
          = (-\\sin\\alpha\\cos\\beta,\\; -\\sin\\beta,\\; \\cos\\alpha\\cos\\beta).

Sunlight passes the hole along :math:`-\\mathbf{s}`, so the spot moves by
:math:`-F (s_x / s_z, s_y / s_z) = F(\\tan\\alpha, \\tan\\beta / \\cos\\alpha)`: +x with +alpha and
+y with +beta, which is the paper's eq. (1).

References
----------
.. [1] PAPER.md, sec. 1 and 4.1 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import numpy as np

__all__ = ["sun_vector", "sun_angles", "ideal_centroid", "ideal_angles"]


def sun_vector(alpha, beta):
    """Unit vector toward the sun in the sensor frame for platform angles (alpha, beta).

    Parameters
    ----------
    alpha, beta : array_like
        Outer- and inner-axis angles, degrees.

    Returns
    -------
    numpy.ndarray, shape (..., 3)

    Examples
    --------
    >>> sun_vector(0.0, 0.0).tolist() == [0.0, 0.0, 1.0]
    True
    >>> bool(np.allclose(sun_vector(90.0, 0.0), [-1.0, 0.0, 0.0]))
    True
    """
    a = np.deg2rad(np.asarray(alpha, dtype=float))
    b = np.deg2rad(np.asarray(beta, dtype=float))
    return np.stack(
        np.broadcast_arrays(-np.sin(a) * np.cos(b), -np.sin(b), np.cos(a) * np.cos(b)), axis=-1
    )


def sun_angles(s):
    """Platform angles (alpha, beta) in degrees of a sun vector; inverse of :func:`sun_vector`.

    Examples
    --------
    >>> a, b = sun_angles(sun_vector(-12.0, 7.5))
    >>> round(float(a), 9), round(float(b), 9)
    (-12.0, 7.5)
    """
    s = np.asarray(s, dtype=float)
    s = s / np.linalg.norm(s, axis=-1, keepdims=True)
    beta = np.arcsin(np.clip(-s[..., 1], -1.0, 1.0))
    alpha = np.arctan2(-s[..., 0], s[..., 2])
    return np.rad2deg(alpha), np.rad2deg(beta)


def ideal_centroid(alpha, beta, mask_distance_mm, pixel_pitch_mm, x_cf, y_cf):
    """Spot centroid predicted by the ideal model, eq. (1), for platform angles (alpha, beta).

    .. math:: x = x_{cf} + \\frac{F}{p}\\tan\\alpha, \\qquad
              y = y_{cf} + \\frac{F}{p}\\frac{\\tan\\beta}{\\cos\\alpha}

    Parameters
    ----------
    alpha, beta : array_like
        Platform angles, degrees.
    mask_distance_mm : float
        Mask-to-focal-plane distance F, mm.
    pixel_pitch_mm : float
        Pixel pitch p, mm.
    x_cf, y_cf : float
        Centroid with the sun at zenith, px.

    Returns
    -------
    x, y : numpy.ndarray
        Centroid column and row, px.

    Examples
    --------
    >>> x, y = ideal_centroid(45.0, 0.0, 5.0, 0.007, 640.0, 512.0)
    >>> round(float(x - 640.0), 6)  # F / p * tan(45 deg)
    714.285714
    """
    a = np.deg2rad(np.asarray(alpha, dtype=float))
    b = np.deg2rad(np.asarray(beta, dtype=float))
    k = mask_distance_mm / pixel_pitch_mm
    return x_cf + k * np.tan(a), y_cf + k * np.tan(b) / np.cos(a)


def ideal_angles(x, y, mask_distance_mm, pixel_pitch_mm, x_cf, y_cf):
    """Platform angles from a spot centroid by the ideal model, eq. (1).

    .. math:: \\tan\\alpha = \\frac{(x - x_{cf})\\,p}{F}, \\qquad
              \\tan\\beta = \\frac{(y - y_{cf})\\,p\\cos\\alpha}{F}

    Examples
    --------
    >>> a, b = ideal_angles(*ideal_centroid(-10.0, 5.0, 5.0, 0.007, 640, 512), 5.0, 0.007, 640, 512)
    >>> round(float(a), 9), round(float(b), 9)
    (-10.0, 5.0)
    """
    k = mask_distance_mm / pixel_pitch_mm
    a = np.arctan((np.asarray(x, dtype=float) - x_cf) / k)
    b = np.arctan((np.asarray(y, dtype=float) - y_cf) * np.cos(a) / k)
    return np.rad2deg(a), np.rad2deg(b)
