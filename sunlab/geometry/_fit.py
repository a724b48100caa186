"""The fit of the optimised model (docs/paper.md sec. 4.1): :func:`fit_optimised_model` and its
result :class:`OptimisedFit`; the residuals of eqs. (3)-(4) with their analytic Jacobian, the
trust-region solve (:func:`scipy.optimize.least_squares`), and the standard errors (Jacobian or
block bootstrap). The models themselves are :mod:`sunlab.geometry.model`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
from scipy.optimize import least_squares

from ..errors import ConfigurationError
from .model import _check_mounting, hole_foot, optimised_angles, rotation_x, rotation_y

__all__ = ["OptimisedFit", "fit_optimised_model"]


@dataclass(frozen=True)
class OptimisedFit:
    """Result of :func:`fit_optimised_model`.

    Attributes
    ----------
    delta_f_mm : float
        Mask-distance error dF, mm.
    alpha0, beta0 : float
        Mounting errors, degrees.
    x_zp, y_zp : float
        Zero-pose centroid, px (measured, or fitted when ``zero_pose_fitted``).
    x_cf, y_cf : float
        Foot of the hole implied by eq. (4), px.
    mask_distance_mm, pixel_pitch_mm : float
        The nominal F and the pixel pitch used, mm.
    stderr : dict
        One-sigma standard errors of the fitted parameters (same units), by ``stderr_method``.
    rms_alpha, rms_beta : float
        RMS residual of the fit per angle, degrees.
    n_points : int
        Number of centroids used.
    zero_pose_fitted : bool
        True when (x_zp, y_zp) were free parameters.
    success : bool
        Whether the optimiser reported convergence.
    message : str
        The optimiser's message.
    mounting : str
        ``"rotation"`` or ``"additive"`` (:func:`optimised_centroid`).
    stderr_method : str
        ``"jacobian"`` (white residuals) or ``"block bootstrap"`` (see
        :func:`fit_optimised_model`).
    """

    delta_f_mm: float
    alpha0: float
    beta0: float
    x_zp: float
    y_zp: float
    x_cf: float
    y_cf: float
    mask_distance_mm: float
    pixel_pitch_mm: float
    stderr: dict
    rms_alpha: float
    rms_beta: float
    n_points: int
    zero_pose_fitted: bool
    success: bool
    message: str
    mounting: str = "rotation"
    stderr_method: str = "jacobian"

    @property
    def params(self) -> tuple:
        """``(mask_distance_mm, pixel_pitch_mm, delta_f_mm, alpha0, beta0, x_zp, y_zp)``, the
        trailing arguments of :func:`optimised_angles` and :func:`optimised_centroid` (pass
        ``mounting=fit.mounting`` with them, or use :meth:`angles`)."""
        return (self.mask_distance_mm, self.pixel_pitch_mm, self.delta_f_mm, self.alpha0,
                self.beta0, self.x_zp, self.y_zp)

    def angles(self, x, y):
        """Platform angles (deg) of centroids (px) by the fitted model.

        Parameters
        ----------
        x, y : array_like
            Centroid column and row, px (broadcast together).

        Returns
        -------
        alpha : numpy.ndarray
            Outer-axis platform angle, degrees.
        beta : numpy.ndarray
            Inner-axis platform angle, degrees (both by :func:`optimised_angles` with
            :attr:`params` and :attr:`mounting`).
        """
        return optimised_angles(x, y, *self.params, mounting=self.mounting)

    def to_dict(self) -> dict:
        """Plain-Python dictionary (JSON-ready).

        Returns
        -------
        dict
            Every field by name (``stderr`` a nested dict), as ``calibration/1`` files store the
            optimised model; :func:`sunlab.calibration.model.optimised_fit_from_dict` reverses it.
        """
        return asdict(self)


def fit_optimised_model(x, y, alpha, beta, mask_distance_mm, pixel_pitch_mm, x_zp=None,
                        y_zp=None, *, initial=(0.0, 0.0, 0.0), mounting: str = "rotation",
                        blocks=None, n_boot: int = 0, seed: int = 0) -> OptimisedFit:
    """Fit dF, alpha0, beta0 (and the zero-pose centroid) of the optimised model (3)-(4).

    Minimises
    :math:`\\sum_i (\\alpha_m(x_i, y_i) - \\alpha_i)^2 + (\\beta_m(x_i, y_i) - \\beta_i)^2`
    over the calibration centroids with :func:`scipy.optimize.least_squares` (trust-region
    reflective, Jacobian-scaled), as in docs/paper.md sec. 4.1.

    Parameters
    ----------
    x, y : array_like
        Centroids, px. Non-finite entries are ignored.
    alpha, beta : array_like
        Platform angles of each centroid (broadcast against x), degrees.
    mask_distance_mm, pixel_pitch_mm : float
        Nominal F and pixel pitch, mm.
    x_zp, y_zp : float, optional
        Measured zero-pose centroid, px. When either is None (default), both are free
        parameters fitted jointly with the others from every pose, rather than anchored on the
        few noisy frames of one pose.
    initial : tuple of 3 float
        Starting ``(delta_f_mm, alpha0, beta0)``, mm and degrees.
    mounting : {"rotation", "additive"}
        Form of the mounting (:func:`optimised_centroid`).
    blocks : array_like of int, optional
        A block label per centroid for the block bootstrap (e.g. poses grouped into
        2 x 2-degree squares of the grid): residuals inside a block may be correlated
        (shots of one pose share the platform's pose error; neighbouring poses share the
        pixel pattern under the spot), different blocks are taken as independent.
    n_boot : int
        Bootstrap replicas; 0 (default) gives the Jacobian standard errors, which assume
        white residuals. Replicas start at the full-data solution.
    seed : int
        Seed of the bootstrap's resampling.

    Returns
    -------
    OptimisedFit

    Raises
    ------
    ConfigurationError
        If fewer usable centroids than parameters remain.

    Examples
    --------
    >>> from sunlab.geometry import optimised_centroid
    >>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
    >>> x, y = optimised_centroid(a, b, 5.0, 0.007, 0.094, 1.864, 0.415, 640.0, 512.0)
    >>> fit = fit_optimised_model(x, y, a, b, 5.0, 0.007)
    >>> round(fit.delta_f_mm, 6), round(fit.alpha0, 6), round(fit.beta0, 6)
    (0.094, 1.864, 0.415)
    >>> round(fit.x_zp, 6), round(fit.y_zp, 6)
    (640.0, 512.0)
    """
    _check_mounting(mounting)
    free_zp = x_zp is None or y_zp is None
    n_par = 5 if free_zp else 3
    x, y, alpha, beta, blocks = _usable_points(x, y, alpha, beta, blocks, n_par)
    F, p = float(mask_distance_mm), float(pixel_pitch_mm)
    p0 = [float(v) for v in initial]
    p0 += _zero_pose_start(x, y, alpha, beta, F / p) if free_zp else []
    fixed_zp = None if free_zp else (x_zp, y_zp)

    def solve(xs, ys, al, be, start, weights=None):
        return _least_squares(xs, ys, al, be, start, F, p, fixed_zp, mounting, weights)

    res = solve(x, y, alpha, beta, p0)
    boot = bool(n_boot and n_boot > 1)
    err = (_bootstrap_stderr(solve, x, y, alpha, beta, res.x, blocks, n_boot, seed) if boot
           else _jacobian_stderr(res, n_par))
    names = ["delta_f_mm", "alpha0", "beta0", "x_zp", "y_zp"][:n_par]
    zp = (float(res.x[3]), float(res.x[4])) if free_zp else (float(x_zp), float(y_zp))
    return _fit_result(res, zp, F, p, mounting, dict(zip(names, err, strict=True)),
                       "block bootstrap" if boot else "jacobian")


def _fit_result(res, zp, F, p, mounting, err: dict, method: str) -> OptimisedFit:
    """The :class:`OptimisedFit` of a least-squares solution ``res``."""
    q, n = res.x, res.fun.size // 2
    x_cf, y_cf = hole_foot(F, p, q[0], q[1], q[2], *zp, mounting)
    return OptimisedFit(
        delta_f_mm=float(q[0]), alpha0=float(q[1]), beta0=float(q[2]), x_zp=zp[0], y_zp=zp[1],
        x_cf=float(x_cf), y_cf=float(y_cf), mask_distance_mm=F, pixel_pitch_mm=p,
        stderr={k: float(v) for k, v in err.items()},
        rms_alpha=float(np.sqrt(np.mean(res.fun[:n] ** 2))),
        rms_beta=float(np.sqrt(np.mean(res.fun[n:] ** 2))), n_points=int(n),
        zero_pose_fitted=len(q) == 5, success=bool(res.success), message=str(res.message),
        mounting=mounting, stderr_method=method)


def _usable_points(x, y, alpha, beta, blocks, n_par: int):
    """The finite calibration points (and their bootstrap blocks); at least ``n_par``."""
    x, y, alpha, beta = np.broadcast_arrays(*(np.asarray(v, float) for v in (x, y, alpha, beta)))
    ok = np.isfinite(x) & np.isfinite(y) & np.isfinite(alpha) & np.isfinite(beta)
    if blocks is not None:
        blocks = np.broadcast_to(np.asarray(blocks), x.shape)[ok]
    x, y, alpha, beta = x[ok], y[ok], alpha[ok], beta[ok]
    if x.size < n_par:
        raise ConfigurationError(
            f"centroids: found {x.size} usable centroids, expected at least {n_par} for the "
            "optimised model. Fix: pass a calibration table with more poses of status ok"
        )
    return x, y, alpha, beta, blocks


def _zero_pose_start(x, y, alpha, beta, k: float) -> list:
    """Starting zero-pose centroid: the median of the centroids moved back by eq. (1)."""
    a = np.deg2rad(alpha)
    return [float(np.median(x - k * np.tan(a))),
            float(np.median(y - k * np.tan(np.deg2rad(beta)) / np.cos(a)))]


def _least_squares(xs, ys, al, be, start, F, p, fixed_zp, mounting, weights=None):
    """Least-squares fit of the optimised model's parameters (zero pose free if not fixed),
    with the analytic Jacobian of :class:`_AngleResiduals`.

    ``weights`` (optional, one per point) multiply each point's two residuals; an integer
    multiplicity ``k`` enters as ``sqrt(k)``, the same objective as ``k`` copies of the point.
    """
    model = _AngleResiduals(xs, ys, al, be, F, p, fixed_zp, mounting, weights)
    return least_squares(model.residuals, start, jac=model.jacobian, method="trf",
                         x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14, max_nfev=2000)


#: Cross-product matrices of the x and y axes: dR_x(t)/dt = R_x(t) K_x, dR_y(t)/dt = K_y R_y(t).
_K_X = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
_K_Y = np.array([[0.0, 0.0, 1.0], [0.0, 0.0, 0.0], [-1.0, 0.0, 0.0]])


class _AngleResiduals:
    r"""Residuals :math:`(\alpha_m - \alpha_i, \beta_m - \beta_i)` of the optimised model (3)-(4),
    as :func:`optimised_angles` computes them, and their analytic Jacobian in the parameters
    ``q = (dF, alpha0, beta0[, x_zp, y_zp])`` (mm, deg, px).

    Rotation mounting: with :math:`k = F'/p`, :math:`\mathbf{m} = M\mathbf{e}_z` and the foot
    (4), the inverted ray is :math:`\mathbf{u} = ((x_{cf} - x)/k, (y_{cf} - y)/k, 1)`, i.e.
    :math:`u_0 = (x_{zp} - x)/k + m_0/m_2`, :math:`u_1 = (y_{zp} - y)/k + m_1/m_2`, and
    :math:`\mathbf{s} = M^T\mathbf{u}` (eq. (3) inverted). Every derivative is linear in
    :math:`\mathbf{u}`, :math:`\partial\mathbf{s}/\partial q_j = G_j^T\mathbf{u}` with a
    constant 3 x 3 :math:`G_j` whose last row holds the terms free of the point (:math:`u_2 = 1`):

    .. math::

        G_{\delta F} = -\frac{1}{kp}\begin{pmatrix} M_{0\cdot} \\ M_{1\cdot} \\
            -\frac{m_0}{m_2}M_{0\cdot} - \frac{m_1}{m_2}M_{1\cdot}\end{pmatrix}, \quad
        G_{\theta} = M_\theta + \mathbf{e}_2\Big(
            \big(\tfrac{m_0}{m_2}\big)_\theta M_{0\cdot}
            + \big(\tfrac{m_1}{m_2}\big)_\theta M_{1\cdot}\Big), \quad
        G_{x_{zp}} = \mathbf{e}_2\frac{M_{0\cdot}}{k}, \quad
        G_{y_{zp}} = \mathbf{e}_2\frac{M_{1\cdot}}{k}

    for :math:`\theta \in \{\alpha_0, \beta_0\}`, with :math:`M_{\alpha_0} = -K_y M`,
    :math:`M_{\beta_0} = M K_x` per radian (:math:`K` the cross-product matrices of the axes).
    Then, with :math:`h^2 = s_0^2 + s_2^2` and :math:`r^2 = h^2 + s_1^2` (:func:`sun_angles`),

    .. math:: d\alpha = \frac{s_0\,ds_2 - s_2\,ds_0}{h^2}, \qquad
              d\beta = -\frac{r^2\,ds_1 - s_1\,(\mathbf{s}\cdot d\mathbf{s})}{r^2 h}.

    Additive mounting: :math:`\tan a = (x - x_{zp})/k + \tan\alpha_0`, :math:`\tan b = w\cos a`
    with :math:`w = (y - y_{zp})/k + \tan\beta_0/\cos\alpha_0`, :math:`\alpha_m = a - \alpha_0`,
    :math:`\beta_m = b - \beta_0` (eq. (1) through the foot (4)), by the chain rule.

    Optional ``weights`` multiply each point's two residuals and Jacobian rows. What
    :meth:`residuals` computed is kept for :meth:`jacobian` at the same point (where the
    trust-region solver asks for it).
    """

    def __init__(self, xs, ys, al, be, F, p, fixed_zp, mounting, weights=None):
        self.x, self.y, self.al, self.be = xs, ys, al, be
        self.F, self.p, self.fixed_zp, self.mounting = F, p, fixed_zp, mounting
        self.w = None if weights is None else np.concatenate([weights, weights])
        self._q = None
        self._u = np.ones((np.size(xs), 3))

    def residuals(self, q):
        """Residuals, deg: the alpha ones, then the beta ones (weighted)."""
        q = np.array(q, dtype=float)
        x_zp, y_zp = (q[3], q[4]) if self.fixed_zp is None else self.fixed_zp
        k = (self.F + q[0]) / self.p
        if self.mounting == "rotation":
            M = rotation_y(-np.deg2rad(q[1])) @ rotation_x(np.deg2rad(q[2]))  # mounting_matrix
            u = self._u
            u[:, 0] = (x_zp + k * M[0, 2] / M[2, 2] - self.x) / k  # (x_cf - x) / k, eq. (4)
            u[:, 1] = (y_zp + k * M[1, 2] / M[2, 2] - self.y) / k
            s = [u[:, 0] * M[0, i] + u[:, 1] * M[1, i] + M[2, i] for i in range(3)]
            h2 = s[0] ** 2 + s[2] ** 2
            r2 = h2 + s[1] ** 2
            am = np.rad2deg(np.arctan2(-s[0], s[2]))
            bm = np.rad2deg(np.arcsin(np.clip(-s[1] / np.sqrt(r2), -1.0, 1.0)))
            self._cache = (k, M, s, h2, r2)
        else:
            x_cf, y_cf = hole_foot(self.F, self.p, q[0], q[1], q[2], x_zp, y_zp, "additive")
            ta = (self.x - x_cf) / k
            w = (self.y - y_cf) / k
            cos_a = 1.0 / np.sqrt(1.0 + ta**2)
            tb = w * cos_a
            am = np.rad2deg(np.arctan(ta)) - q[1]
            bm = np.rad2deg(np.arctan(tb)) - q[2]
            self._cache = (k, ta, w, cos_a, tb)
        self._q = q
        res = np.concatenate([am - self.al, bm - self.be])
        return res if self.w is None else res * self.w

    def jacobian(self, q):
        """Jacobian of :meth:`residuals`, shape (2 n, len(q)), deg per mm, deg and px."""
        q = np.asarray(q, dtype=float)
        if self._q is None or not np.array_equal(q, self._q):
            self.residuals(q)
        n_par = q.size
        rad = np.pi / 180.0
        if self.mounting == "rotation":
            k, M, s, h2, r2 = self._cache
            m = M[:, 2]
            g = np.zeros((5, 3, 3))  # g[j, l, c] = d s_c / d q_j per unit u_l
            g[0, :2] = M[:2]
            g[0, 2] = -(m[0] / m[2]) * M[0] - (m[1] / m[2]) * M[1]
            g[0] *= -1.0 / (k * self.p)
            for j, dM in ((1, -rad * _K_Y @ M), (2, rad * M @ _K_X)):
                dm = dM[:, 2]
                g[j] = dM
                g[j, 2] += ((dm[0] * m[2] - m[0] * dm[2]) * M[0]
                            + (dm[1] * m[2] - m[1] * dm[2]) * M[1]) / m[2] ** 2
            g[3, 2] = M[0] / k
            g[4, 2] = M[1] / k
            ds = [self._u @ g[:n_par, :, c].T for c in range(3)]
            s0, s1, s2 = (v[:, None] for v in s)
            da = (s0 * ds[2] - s2 * ds[0]) / (h2[:, None] * rad)
            db = (s1 * (s0 * ds[0] + s1 * ds[1] + s2 * ds[2]) - r2[:, None] * ds[1]) / (
                (r2 * np.sqrt(h2) * rad)[:, None])
        else:
            k, ta, w, cos_a, tb = self._cache
            a0, b0 = np.deg2rad(q[1]), np.deg2rad(q[2])
            dta = np.zeros((ta.size, n_par))  # d tan(a) / d q_j
            dw = np.zeros((ta.size, n_par))
            dta[:, 0] = (np.tan(a0) - ta) / (k * self.p)
            dw[:, 0] = (np.tan(b0) / np.cos(a0) - w) / (k * self.p)
            dta[:, 1] = rad / np.cos(a0) ** 2
            dw[:, 1] = rad * np.tan(b0) * np.sin(a0) / np.cos(a0) ** 2
            dw[:, 2] = rad / (np.cos(b0) ** 2 * np.cos(a0))
            if n_par == 5:
                dta[:, 3] = -1.0 / k
                dw[:, 4] = -1.0 / k
            da = dta / (1.0 + ta**2)[:, None]
            db = (dw * cos_a[:, None] - (w * ta * cos_a)[:, None] * da) / (1.0 + tb**2)[:, None]
            da, db = da / rad, db / rad
            da[:, 1] -= 1.0
            db[:, 2] -= 1.0
        jac = np.concatenate([da, db])
        return jac if self.w is None else jac * self.w[:, None]


def _bootstrap_stderr(solve, x, y, alpha, beta, q, blocks, n_boot: int, seed: int):
    """Standard errors from a block bootstrap: whole blocks are resampled with replacement.

    A block drawn ``k`` times enters its replica once with weight ``sqrt(k)`` on its residuals
    (the same sum of squares, hence the same minimiser, as ``k`` copies, with fewer points);
    blocks not drawn are left out. The draws are those of ``k`` copies, in the same order.
    """
    labels = np.arange(x.size) if blocks is None else np.asarray(blocks)
    uniq, inv = np.unique(labels, return_inverse=True)
    rng = np.random.default_rng(seed)
    reps = []
    for _ in range(int(n_boot)):
        count = np.bincount(rng.integers(0, uniq.size, uniq.size), minlength=uniq.size)[inv]
        use = count > 0
        reps.append(solve(x[use], y[use], alpha[use], beta[use], q, np.sqrt(count[use])).x)
    return np.std(np.array(reps), axis=0, ddof=1)


def _jacobian_stderr(res, n_par: int):
    """Standard errors from the Jacobian at the solution (white residuals assumed)."""
    dof = max(res.fun.size - n_par, 1)
    s2 = 2.0 * res.cost / dof
    try:
        cov = np.linalg.inv(res.jac.T @ res.jac) * s2
        return np.sqrt(np.clip(np.diag(cov), 0.0, None))
    except np.linalg.LinAlgError:
        return np.full(n_par, np.nan)
