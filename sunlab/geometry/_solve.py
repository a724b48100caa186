"""The optimised model's least squares (docs/paper.md sec. 4.1): the residuals of eqs. (3)-(4)
with their analytic Jacobian, the trust-region solve, and the standard errors (Jacobian or block
bootstrap) of :func:`sunlab.geometry.fit_optimised_model`. Private to :mod:`sunlab.geometry`.
"""

from __future__ import annotations

import numpy as np

from .model import hole_foot, optimised_angles, rotation_x, rotation_y

__all__: list[str] = []


def _least_squares(xs, ys, al, be, start, F, p, fixed_zp, mounting, weights=None, *,
                   analytic: bool = True):
    """Least-squares fit of the optimised model's parameters (zero pose free if not fixed).

    ``weights`` (optional, one per point) multiply each point's two residuals; an integer
    multiplicity ``k`` enters as ``sqrt(k)``, the same objective as ``k`` copies of the point.
    ``analytic``: the Jacobian of :class:`_AngleResiduals` (True, the bootstrap replicas) or
    two-point finite differences of :func:`optimised_angles` (False, the full-data fit, whose
    numbers stay those it always gave: the differences' truncation error stops it about 1e-8
    relative from the exact minimiser the analytic Jacobian reaches).
    """
    from scipy.optimize import least_squares

    if analytic:
        model = _AngleResiduals(xs, ys, al, be, F, p, fixed_zp, mounting, weights)
        fun, jac = model.residuals, model.jacobian
    else:
        ww = None if weights is None else np.concatenate([weights, weights])

        def fun(q):
            zp = (q[3], q[4]) if fixed_zp is None else fixed_zp
            am, bm = optimised_angles(xs, ys, F, p, q[0], q[1], q[2], *zp, mounting=mounting)
            res = np.concatenate([am - al, bm - be])
            return res if ww is None else res * ww

        jac = "2-point"
    return least_squares(
        fun, start, jac=jac, method="trf", x_scale="jac", xtol=1e-14, ftol=1e-14, gtol=1e-14,
        max_nfev=2000,
    )


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
