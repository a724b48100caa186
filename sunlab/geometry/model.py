"""Geometric models of the pinhole sun sensor: the ideal model (1), the optimised model (3)-(4),
an exact pinhole forward model with mounting errors, and sun-vector conversions.

Sign convention (``docs/nomenclature.md``): the sensor frame has z along the boresight, from the
focal plane toward the mask; x along detector columns, y along rows. The platform's outer axis sets
alpha and its inner axis sets beta; the unit vector toward the sun in the sensor frame is

.. math:: \\mathbf{s} = R_y(-\\alpha) R_x(\\beta) \\mathbf{e}_z
          = (-\\sin\\alpha\\cos\\beta,\\; -\\sin\\beta,\\; \\cos\\alpha\\cos\\beta).

Sunlight passes the hole along :math:`-\\mathbf{s}`, so the spot moves by
:math:`-F (s_x / s_z, s_y / s_z) = F(\\tan\\alpha, \\tan\\beta / \\cos\\alpha)`: +x with +alpha and
+y with +beta, which is the paper's eq. (1).

The optimised model, eqs. (3)-(4) (the source's formulas were lost; this is our reconstruction
of docs/paper.md sec. 4.1). Parameters: the mask-distance error :math:`\\delta F`, the mounting
errors :math:`\\alpha_0, \\beta_0` of the sensor on the platform, and the zero-pose centroid
:math:`(x_{zp}, y_{zp})` (where the spot falls with the platform at alpha = beta = 0). The
mounting is a rigid rotation, the one the virtual bench applies
(:meth:`sunlab.sim.Platform.mount_matrix`), so that the fit estimates the bench's own numbers:

.. math::

    M = R_y(-\\alpha_0) R_x(\\beta_0), \\qquad
    \\mathbf{s}' = M\\,\\mathbf{s}(\\alpha, \\beta), \\qquad
    x = x_{cf} - \\frac{F'}{p}\\frac{s'_x}{s'_z}, \\qquad
    y = y_{cf} - \\frac{F'}{p}\\frac{s'_y}{s'_z}                                 \\quad (3)

with :math:`F' = F + \\delta F`, and the foot of the hole :math:`(x_{cf}, y_{cf})` tied to the
zero-pose centroid by

.. math::

    x_{cf} = x_{zp} + \\frac{F'}{p}\\frac{(M\\mathbf{e}_z)_x}{(M\\mathbf{e}_z)_z}, \\qquad
    y_{cf} = y_{zp} + \\frac{F'}{p}\\frac{(M\\mathbf{e}_z)_y}{(M\\mathbf{e}_z)_z}     \\quad (4)

Inverting (3): :math:`\\mathbf{s} \\propto M^T ((x_{cf} - x)p/F', (y_{cf} - y)p/F', 1)`, and
(alpha, beta) are the platform angles of :math:`\\mathbf{s}` (:func:`sun_angles`). To first order
in the mounting angles this is the additive form ``alpha_m = a_s - alpha0``, ``beta_m = b_s -
beta0`` (``mounting="additive"``, kept for comparison); off the axes the two differ because
rotations do not commute (a roll of about beta0 sin(alpha): 0.12 deg at alpha = -17 deg), and a fit
of the additive form to a rotated mounting returns biased alpha0, beta0. The zero-pose centroid is
a fitted parameter by default (:func:`sunlab.geometry.fit_optimised_model`), not one noisy
measured frame.

References
----------
.. [1] docs/paper.md, sec. 1 and 4.1 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigurationError

__all__ = ["sun_vector", "sun_angles", "ideal_centroid", "ideal_angles", "optimised_centroid"]


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
    return np.stack(np.broadcast_arrays(-np.sin(a) * np.cos(b), -np.sin(b), np.cos(a) * np.cos(b)),
                    axis=-1)


def sun_angles(s):
    """Platform angles (alpha, beta) in degrees of a sun vector; inverse of :func:`sun_vector`.

    Parameters
    ----------
    s : array_like, shape (..., 3)
        Vectors toward the sun in the sensor frame (any length; normalised here).

    Returns
    -------
    alpha : numpy.ndarray, shape (...)
        Outer-axis angle, degrees: ``atan2(-s_x, s_z)``.
    beta : numpy.ndarray, shape (...)
        Inner-axis angle, degrees: ``asin(-s_y)`` of the unit vector.

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

    Parameters
    ----------
    x, y : array_like
        Centroid column and row, px (broadcast together).
    mask_distance_mm : float
        Mask-to-focal-plane distance F, mm.
    pixel_pitch_mm : float
        Pixel pitch p, mm.
    x_cf, y_cf : float
        Centroid with the sun at zenith, px.

    Returns
    -------
    alpha : numpy.ndarray
        Outer-axis platform angle, degrees: ``atan((x - x_cf) p / F)``.
    beta : numpy.ndarray
        Inner-axis platform angle, degrees: ``atan((y - y_cf) p cos(alpha) / F)``.

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


_MOUNTINGS = ("rotation", "additive")


def _check_mounting(mounting: str) -> None:
    if mounting not in _MOUNTINGS:
        raise ConfigurationError(
            f"mounting: found {mounting!r}; expected 'rotation' (the bench's rigid mounting, "
            "default) or 'additive' (alpha0, beta0 as angle offsets)."
        )


def hole_foot(mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp, y_zp,
              mounting: str = "additive"):
    """Foot of the hole (x_cf, y_cf) that eq. (4) ties to the zero-pose centroid, px.

    Parameters
    ----------
    mask_distance_mm, pixel_pitch_mm : float
        Nominal F and the pixel pitch p, mm.
    delta_f_mm : float
        Mask-distance error dF, mm.
    alpha0, beta0 : float
        Mounting errors, degrees.
    x_zp, y_zp : float or array_like
        Zero-pose centroid, px.
    mounting : {"additive", "rotation"}
        Form of the mounting (:func:`optimised_centroid`); note the default here is the
        additive form.

    Returns
    -------
    x_cf : float or numpy.ndarray
        Column of the foot of the hole, px: ``x_zp + (F'/p) m_x / m_z`` with ``m = M e_z``
        for a rotation, ``x_zp - (F'/p) tan(alpha0)`` for the additive form
        (``F' = F + dF``).
    y_cf : float or numpy.ndarray
        Row of the foot of the hole, px: ``y_zp + (F'/p) m_y / m_z`` for a rotation,
        ``y_zp - (F'/p) tan(beta0) / cos(alpha0)`` for the additive form.

    Examples
    --------
    >>> [round(float(v), 6) for v in hole_foot(5.0, 0.007, 0.0, 0.0, 0.0, 640.0, 512.0)]
    [640.0, 512.0]
    """
    k = (mask_distance_mm + delta_f_mm) / pixel_pitch_mm
    if mounting == "rotation":
        m = mounting_matrix(alpha0, beta0)[:, 2]
        return x_zp + k * m[0] / m[2], y_zp + k * m[1] / m[2]
    a0 = np.deg2rad(alpha0)
    b0 = np.deg2rad(beta0)
    return x_zp - k * np.tan(a0), y_zp - k * np.tan(b0) / np.cos(a0)


def optimised_centroid(alpha, beta, mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0,
                       x_zp, y_zp, *, mounting: str = "rotation"):
    r"""Spot centroid predicted by the optimised model, eqs. (3)-(4), for platform angles.

    The forward direction of :func:`optimised_angles`: the platform's sun vector is rotated by
    the mounting ``M = R_y(-alpha0) R_x(beta0)`` into the sensor frame and projected through a
    hole at ``F + delta_f_mm``; the foot of the hole is set so that the zero pose lands on
    ``(x_zp, y_zp)`` (module notes).

    Parameters
    ----------
    alpha, beta : array_like
        Platform angles, degrees.
    mask_distance_mm : float
        Nominal mask-to-focal-plane distance F, mm.
    pixel_pitch_mm : float
        Pixel pitch p, mm.
    delta_f_mm : float
        Mask-distance error dF, mm.
    alpha0, beta0 : float
        Mounting errors of the sensor on the platform, degrees.
    x_zp, y_zp : float
        Centroid at the zero pose (alpha = beta = 0), px.
    mounting : {"rotation", "additive"}
        The mounting as a rigid rotation (default, as the bench) or as additive angle offsets
        (``alpha + alpha0``, ``beta + beta0`` through eq. (1)).

    Returns
    -------
    x, y : numpy.ndarray
        Centroid column and row, px.

    Notes
    -----
    .. math:: \mathbf{s}' = R_y(-\alpha_0) R_x(\beta_0)\,\mathbf{s}(\alpha, \beta), \qquad
              x = x_{cf} - \frac{F'}{p}\frac{s'_x}{s'_z}, \qquad
              y = y_{cf} - \frac{F'}{p}\frac{s'_y}{s'_z}  \qquad (3)

    Examples
    --------
    >>> x, y = optimised_centroid(0.0, 0.0, 5.0, 0.007, 0.094, 1.864, 0.415, 600.0, 500.0)
    >>> round(float(x), 9), round(float(y), 9)  # the zero pose maps to the zero-pose centroid
    (600.0, 500.0)
    """
    _check_mounting(mounting)
    x_cf, y_cf = hole_foot(mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp,
                           y_zp, mounting)
    if mounting == "rotation":
        return pinhole_centroid(alpha, beta, mask_distance_mm, pixel_pitch_mm, x_cf, y_cf,
                                delta_f_mm=delta_f_mm, mounting_deg=(alpha0, beta0, 0.0))
    return ideal_centroid(np.asarray(alpha, dtype=float) + alpha0,
                          np.asarray(beta, dtype=float) + beta0, mask_distance_mm + delta_f_mm,
                          pixel_pitch_mm, x_cf, y_cf)


def optimised_angles(x, y, mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp,
                     y_zp, *, mounting: str = "rotation"):
    r"""Platform angles from a spot centroid by the optimised model, eqs. (3)-(4).

    Parameters
    ----------
    x, y : array_like
        Centroid column and row, px.
    mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp, y_zp
        As in :func:`optimised_centroid` (mm, mm, mm, deg, deg, px, px).
    mounting : {"rotation", "additive"}
        As in :func:`optimised_centroid`.

    Returns
    -------
    alpha, beta : numpy.ndarray
        Platform angles, degrees.

    Notes
    -----
    .. math:: \mathbf{s} \propto M^T \left(\frac{(x_{cf} - x)p}{F'},
              \frac{(y_{cf} - y)p}{F'}, 1\right), \qquad
              (\alpha_m, \beta_m) = \mathrm{angles}(\mathbf{s})  \quad (3)

    with :math:`F' = F + \delta F`, :math:`M = R_y(-\alpha_0) R_x(\beta_0)` and
    :math:`(x_{cf}, y_{cf})` from eq. (4).

    Examples
    --------
    >>> p = (5.0, 0.007, 0.094, 1.864, 0.415, 600.0, 500.0)
    >>> a, b = optimised_angles(*optimised_centroid(-12.0, 9.0, *p), *p)
    >>> round(float(a), 9), round(float(b), 9)
    (-12.0, 9.0)
    """
    _check_mounting(mounting)
    x_cf, y_cf = hole_foot(mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp,
                           y_zp, mounting)
    if mounting == "rotation":
        k = (mask_distance_mm + delta_f_mm) / pixel_pitch_mm
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        sp = np.stack([(x_cf - x) / k, (y_cf - y) / k, np.ones_like(x)], axis=-1)
        return sun_angles(sp @ mounting_matrix(alpha0, beta0))
    a_s, b_s = ideal_angles(x, y, mask_distance_mm + delta_f_mm, pixel_pitch_mm, x_cf, y_cf)
    return a_s - alpha0, b_s - beta0


def rotation_x(t) -> np.ndarray:
    """Right-handed rotation by ``t`` rad about x.

    Parameters
    ----------
    t : float
        Angle, rad.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``[[1, 0, 0], [0, cos t, -sin t], [0, sin t, cos t]]``.

    Examples
    --------
    >>> np.round(rotation_x(np.pi / 2) @ [0.0, 1.0, 0.0], 12).tolist()
    [0.0, 0.0, 1.0]
    """
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rotation_y(t) -> np.ndarray:
    """Right-handed rotation by ``t`` rad about y.

    Parameters
    ----------
    t : float
        Angle, rad.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``[[cos t, 0, sin t], [0, 1, 0], [-sin t, 0, cos t]]``.

    Examples
    --------
    >>> np.round(rotation_y(np.pi / 2) @ [0.0, 0.0, 1.0], 12).tolist()
    [1.0, 0.0, 0.0]
    """
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rotation_z(t) -> np.ndarray:
    """Right-handed rotation by ``t`` rad about z.

    Parameters
    ----------
    t : float
        Angle, rad.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``[[cos t, -sin t, 0], [sin t, cos t, 0], [0, 0, 1]]``.

    Examples
    --------
    >>> np.round(rotation_z(np.pi / 2) @ [1.0, 0.0, 0.0], 12).tolist()
    [0.0, 1.0, 0.0]
    """
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def mounting_matrix(alpha0=0.0, beta0=0.0, gamma0=0.0):
    """Rotation from the platform frame to the sensor frame for a misaligned mounting.

    .. math:: M = R_z(\\gamma_0)\\, R_y(-\\alpha_0)\\, R_x(\\beta_0)

    so that a sun vector on the platform's boresight appears in the sensor frame at the angles
    (alpha0, beta0), rotated by gamma0 about the boresight (an in-plane rotation the optimised
    model does not describe).

    Parameters
    ----------
    alpha0, beta0, gamma0 : float
        Mounting rotations about the sensor's y, x and z axes, degrees.

    Returns
    -------
    numpy.ndarray, shape (3, 3)

    Examples
    --------
    >>> M = mounting_matrix(1.864, 0.415)
    >>> a, b = sun_angles(M @ sun_vector(0.0, 0.0))
    >>> round(float(a), 9), round(float(b), 9)
    (1.864, 0.415)
    """
    a0, b0, g0 = np.deg2rad([alpha0, beta0, gamma0])
    return rotation_z(g0) @ rotation_y(-a0) @ rotation_x(b0)


def pinhole_centroid(alpha, beta, mask_distance_mm, pixel_pitch_mm, x_cf, y_cf, *,
                     delta_f_mm=0.0, mounting_deg=(0.0, 0.0, 0.0)):
    """Exact pinhole forward model: centroid of the spot for platform angles (alpha, beta).

    The sun vector of the platform, :func:`sun_vector`, is rotated into the sensor frame by the
    rigid mounting rotation :func:`mounting_matrix`, and the ray through the hole at height
    :math:`F + \\delta F` above the focal plane (above pixel ``(x_cf, y_cf)``) is intersected
    with the focal plane:

    .. math:: \\mathbf{s}' = M\\,\\mathbf{s}(\\alpha, \\beta), \\qquad
              x = x_{cf} - \\frac{F + \\delta F}{p}\\frac{s'_x}{s'_z}, \\qquad
              y = y_{cf} - \\frac{F + \\delta F}{p}\\frac{s'_y}{s'_z}

    With no mounting error this is eq. (1); with (alpha0, beta0) only it agrees with the
    optimised model (3)-(4) along the axes and differs by second-order cross terms elsewhere.

    Parameters
    ----------
    alpha, beta : array_like
        Platform angles, degrees.
    mask_distance_mm, pixel_pitch_mm : float
        Nominal F and pixel pitch, mm.
    x_cf, y_cf : float
        Foot of the hole on the focal plane (true, not design), px.
    delta_f_mm : float
        Mask-distance error, mm.
    mounting_deg : tuple of 3 float
        ``(alpha0, beta0, gamma0)`` of :func:`mounting_matrix`, degrees.

    Returns
    -------
    x, y : numpy.ndarray
        Centroid column and row, px.

    Examples
    --------
    >>> x, y = pinhole_centroid(-10.0, 5.0, 5.0, 0.007, 640.0, 512.0)
    >>> xi, yi = ideal_centroid(-10.0, 5.0, 5.0, 0.007, 640.0, 512.0)
    >>> bool(np.allclose([x, y], [xi, yi], atol=1e-9))
    True
    """
    s = sun_vector(alpha, beta) @ mounting_matrix(*mounting_deg).T
    k = (mask_distance_mm + delta_f_mm) / pixel_pitch_mm
    return x_cf - k * s[..., 0] / s[..., 2], y_cf - k * s[..., 1] / s[..., 2]
