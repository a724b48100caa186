"""The paper's two strategies for a mask of N holes, as calibrations (sec. 6, Table 5).

1. **Geometric centre** (:class:`GeometricCentre`): the mean of the N spot centroids is calibrated
   as if it were one spot.
2. **Per-hole calibration, then averaging** (:class:`PerHoleAverage`): one calibration per hole,
   and the mean of the N angle estimates (:func:`combine_estimates`).

Both honour the protocol of :class:`sunlab.calibration.Calibration`: ``fit(train,
validation=None)`` on tables on ``(pose, shot, hole)``, ``predict`` an estimate on
``(pose, shot)``, ``predict_xy(x, y)`` on centroid arrays whose last axis is the hole,
``to_dict`` / :func:`sunlab.calibration.from_dict` and ``save`` /
:func:`sunlab.calibration.load` (contract ``calibration/1``, kinds
``multihole-geometric-centre`` and ``multihole-per-hole-average``, the fitted per-hole or
centre calibrations nested as their own documents). They are entries of the one calibration
registry, registered by entry point (group ``sunlab.calibrations`` in ``pyproject.toml``, as a
lab's plug-in would be: multihole sits above calibration), so ``sunlab.calibration.fit(table,
"multihole-per-hole-average", order=3)`` fits one and ``sunlab.calibration.load`` reads one.

Both handle holes missing from some frames (off the detector, lost, flagged) without biasing
the result: the geometric centre is solved from the holes present with each hole's fitted
offset from the centre (so the centre does not jump when a hole drops out), and the average
runs over the holes present after each hole's own calibration (each is an unbiased estimate).
Averaging N independent errors divides the variance by N, eq. (5); errors common to all holes
do not average out (:mod:`sunlab.multihole.budget`).

References
----------
.. [1] docs/paper.md, sec. 6 and Table 5 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import xarray as xr

from ..calibration import Calibration, from_dict
from ..errors import ConfigurationError, SchemaError
from ._tables import (
    _angles_dataset,
    _centre_table,
    _default_model,
    _error_stats,
    _fit_model,
    _frames,
    _hole_table,
    _predict,
    _predict_arrays,
    _record_fit,
    _restore_settings,
    _settings,
    _validation_residuals,
)
from .holes import usable

__all__ = ["GeometricCentre", "PerHoleAverage"]


def geometric_centre(cen: xr.Dataset, accept: Sequence[str] = ("ok",)) -> xr.Dataset:
    """Plain geometric centre of the spots, the paper's strategy 1: the mean of the centroids.

    .. math:: x_{gc} = \\frac{1}{N}\\sum_{ij} x_c^{ij}, \\qquad
              y_{gc} = \\frac{1}{N}\\sum_{ij} y_c^{ij}

    This is the paper's definition; it jumps by (design offset of the lost hole) / N whenever a
    hole is missing. :class:`GeometricCentre` removes that bias.

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table on (pose, shot, hole), px.
    accept : sequence of str
        Status names counted as usable.

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot): ``x``, ``y`` px, ``flux`` (sum), ``n_holes``.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1, layout="grid")
    >>> gc = geometric_centre(cen)
    >>> round(float(gc.x[0, 0]), 6), round(float(gc.y[0, 0]), 6)
    (572.0, 375.0)
    """
    ok = usable(cen, accept)
    n = ok.sum("hole")
    x = cen["x"].where(ok).mean("hole")
    y = cen["y"].where(ok).mean("hole")
    flux = cen["flux"].where(ok).sum("hole")
    return _centre_table(cen, x.values, y.values, flux.values, n.values, "geometric_centre")


@dataclass(repr=False)
class GeometricCentre(Calibration):
    """Strategy 1 of the paper: one calibration of the geometric centre of the spots.

    When all holes are present the centre is the mean of the centroids, as in the paper. To stay
    unbiased when holes are missing, each hole h is tied to the centre c by an affine map
    :math:`\\mathbf{x}_h = \\mathbf{A}_h + \\mathbf{M}_h \\mathbf{c}` fitted on the training
    frames (:math:`\\mathbf{M}_h \\approx I`; it absorbs a mask tilt that puts holes at
    different heights), and the centre of a frame is the least-squares solution over the holes
    present, normalised so that it equals the plain mean for a complete frame.

    Parameters
    ----------
    order : int
        Polynomial order of the calibration (ignored when ``model`` is given).
    model : callable, optional
        Factory returning an unfitted :class:`sunlab.calibration.Calibration`; default
        ``sunlab.calibration.Polynomial(order)``. Not saved: a loaded strategy holds the
        fitted calibration itself.
    holes : array_like of bool, shape (hole,), optional
        Holes to use (default all); e.g. ``~reject_bad_holes(metrics)``.
    fill : bool
        Solve the centre with the per-hole offsets (True) or take the plain mean (False, biased
        when holes are missing).
    min_holes : int
        Fewest holes a frame needs for a centre.
    accept : sequence of str
        Status codes accepted as usable.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0, -5.0, 1.0], [0.0, 3.0, 8.0], shots=1, layout="grid",
    ...                           defects={0: {"missing": 1.0}})
    >>> s1 = GeometricCentre(fill=True)
    >>> c = s1.fit_centre(cen).centre(cen)   # hole 0 lost: the centre does not jump
    >>> full = geometric_centre(synthetic_centroids([0.0, -5.0, 1.0], [0.0, 3.0, 8.0], shots=1,
    ...                                          layout="grid"))
    >>> bool(np.allclose(c.x, full.x, atol=1e-6) and np.allclose(c.y, full.y, atol=1e-6))
    True

    Saved and loaded like every calibration (JSON, contract ``calibration/1``):

    >>> import os, tempfile
    >>> from sunlab import calibration
    >>> s1 = GeometricCentre(order=1).fit(cen)
    >>> back = calibration.load(s1.save(os.path.join(tempfile.mkdtemp(), "gc.json")))
    >>> bool(np.array_equal(back.predict(cen).alpha, s1.predict(cen).alpha, equal_nan=True))
    True
    """

    default_outlier_mads = None  # no shot screening by default: holes are judged whole
    kind: ClassVar[str] = "multihole-geometric-centre"
    order: int = 5
    model: Callable | None = None
    holes: np.ndarray | None = None
    fill: bool = True
    min_holes: int = 3
    accept: Sequence[str] = ("ok",)
    A_: np.ndarray | None = field(default=None, repr=False)
    M_: np.ndarray | None = field(default=None, repr=False)
    calibration_: object | None = field(default=None, repr=False)

    def _ok(self, cen):
        ok = usable(cen, self.accept)
        if self.holes is not None:
            ok = ok & xr.DataArray(np.asarray(self.holes, dtype=bool), dims="hole")
        return ok

    def fit_centre(self, cen: xr.Dataset, n_iter: int = 4) -> GeometricCentre:
        """Fit the per-hole maps hole -> centre on a training table (no calibration).

        Parameters
        ----------
        cen : xarray.Dataset
            Training table on (pose, shot, hole), px.
        n_iter : int
            Alternations of the map fit and the centre solve.

        Returns
        -------
        GeometricCentre
            ``self``, with the maps ``A_`` (hole, 2), px, and ``M_`` (hole, 2, 2) set.
        """
        ok = self._ok(cen).values.reshape(-1, cen.sizes["hole"])
        X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, cen.sizes["hole"], 2)
        w = ok.astype(float)
        n_ok = w.sum(1)
        Xz = np.where(ok[..., None], X, 0.0)
        n_h = X.shape[1]
        # start: design offsets of the holes from the mask centre where known, else zero
        if "hole_x_cf" in cen.coords and "hole_y_cf" in cen.coords:
            d = np.column_stack([cen["hole_x_cf"].values, cen["hole_y_cf"].values]).astype(float)
            d0 = d - d.mean(0)
        else:
            d0 = np.zeros((n_h, 2))
        c = np.where(ok[..., None], X - d0, 0.0).sum(1) / np.maximum(n_ok, 1)[:, None]
        seen = ok.any(0)
        dev = np.where(ok[..., None], X - c[:, None], 0.0)
        off = np.where(seen[:, None], dev.sum(0) / np.maximum(ok.sum(0), 1)[:, None], d0)
        A = off.copy()
        M = np.tile(np.eye(2), (n_h, 1, 1))
        have = n_ok >= self.min_holes
        for _ in range(n_iter):
            D = np.column_stack([np.ones(len(c)), c])  # (F, 3)
            D = np.where(have[:, None], D, 0.0)
            for h in range(n_h):
                wh = w[:, h] * have
                if wh.sum() < 4:
                    A[h], M[h] = off[h], np.eye(2)
                    continue
                G = (D * wh[:, None]).T @ D
                R = (D * wh[:, None]).T @ Xz[:, h]
                beta = np.linalg.lstsq(G, R, rcond=None)[0]  # (3, 2)
                A[h] = beta[0]
                M[h] = beta[1:].T
            # gauge: the centre is the mean of the holes' predicted positions
            Am, Mm = A.mean(0), M.mean(0)
            Mi = np.linalg.inv(Mm)
            A = A - np.einsum("hij,j->hi", M, Mi @ Am)
            M = np.einsum("hij,jk->hik", M, Mi)
            self.A_, self.M_ = A, M
            c = self._solve(X, ok)
            c = np.where(np.isfinite(c), c, 0.0)
        self.A_, self.M_ = A, M
        return self

    def _solve(self, X, ok):
        if not self.fill:
            n = ok.sum(1)
            with np.errstate(invalid="ignore", divide="ignore"):
                c = np.where(ok[..., None], X, 0.0).sum(1) / n[:, None]
            return np.where((n >= self.min_holes)[:, None], c, np.nan)
        w = ok.astype(float)
        r = np.where(ok[..., None], X - self.A_, 0.0)
        G = np.einsum("fh,hki,hkj->fij", w, self.M_, self.M_)
        rhs = np.einsum("fh,hki,fhk->fi", w, self.M_, r)
        n = ok.sum(1)
        good = n >= self.min_holes
        G[~good] = np.eye(2)
        c = np.linalg.solve(G, rhs[..., None])[..., 0]
        return np.where(good[:, None], c, np.nan)

    def centre(self, cen: xr.Dataset) -> xr.Dataset:
        """The geometric centre of every frame.

        Parameters
        ----------
        cen : xarray.Dataset
            Centroid table on (pose, shot, hole), px, with the holes of the training table.

        Returns
        -------
        xarray.Dataset
            Contract ``centroids/1`` on (pose, shot): ``x``, ``y`` px (NaN with fewer than
            ``min_holes`` holes), ``flux`` (sum), ``n_holes``.
        """
        if self.A_ is None and self.fill:
            raise ConfigurationError("GeometricCentre: call fit() or fit_centre() first")
        n_h = cen.sizes["hole"]
        if self.A_ is not None and self.A_.shape[0] != n_h:
            raise SchemaError("hole", n_h, f"{self.A_.shape[0]} holes, as in the training table")
        ok = self._ok(cen).values.reshape(-1, n_h)
        X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, n_h, 2)
        c = self._solve(X, ok).reshape(cen.sizes["pose"], cen.sizes["shot"], 2)
        n = ok.sum(1).reshape(cen.sizes["pose"], cen.sizes["shot"])
        n = np.where(np.isfinite(c[..., 0]), n, 0)
        flux = cen["flux"].where(self._ok(cen)).sum("hole").values
        return _centre_table(cen, c[..., 0], c[..., 1], flux, n, "geometric_centre")

    def _fit_tables(self, cen: xr.Dataset, validation: xr.Dataset | None = None
                    ) -> GeometricCentre:
        """Fit the centre maps and the calibration of the centre on a training table.

        Parameters
        ----------
        cen : xarray.Dataset
            Training table on (pose, shot, hole) with the commanded angles (experiment I).
        validation : xarray.Dataset, optional
            A validation table (experiment II): the artifact's validation residuals.

        Returns
        -------
        GeometricCentre
            ``self``, fitted.
        """
        if self.fill:
            self.fit_centre(cen)
        factory = self.model or _default_model(self.order)
        self.calibration_ = _fit_model(factory, self.centre(cen))
        _record_fit(self, cen, self._ok(cen), self.calibration_.residuals)
        _validation_residuals(self, validation)
        return self

    def __post_init__(self):
        Calibration.__init__(self)

    def predict_xy(self, x, y):
        """Angles (alpha, beta), deg, of frames given as centroid arrays ``x``, ``y`` (px)
        whose last axis is the hole (NaN: hole missing).

        Parameters
        ----------
        x, y : array_like, shape (..., hole)
            Centroids of every hole of each frame, px.

        Returns
        -------
        alpha, beta : numpy.ndarray, shape (...)
            Angles of the frames, deg.

        Examples
        --------
        >>> from sunlab.sim import synthetic_centroids
        >>> cen = synthetic_centroids([0.0, -5.0, 1.0, 3.0], [0.0, 3.0, 8.0, -2.0], shots=1,
        ...                           layout="grid")
        >>> s1 = GeometricCentre(order=1).fit(cen)
        >>> a, b = s1.predict_xy(cen.x.values, cen.y.values)
        >>> bool(np.allclose(a, s1.predict(cen).alpha.values))
        True
        """
        if self.calibration_ is None:
            raise ConfigurationError("GeometricCentre: call fit() first")
        X, ok, shape = _frames(x, y)
        if self.holes is not None:
            ok = ok & np.asarray(self.holes, dtype=bool)
        c = self._solve(np.where(ok[..., None], X, 0.0), ok)
        a, b = _predict_arrays(self.calibration_, c[:, 0], c[:, 1])
        return a.reshape(shape), b.reshape(shape)

    def _parameters(self) -> dict:
        return {**_settings(self, ("order", "fill", "min_holes")),
                "A": self.A_, "M": self.M_, "calibration": self.calibration_.to_dict()}

    @classmethod
    def _from_parameters(cls, p: dict) -> GeometricCentre:
        A, M = (None if p[k] is None else np.asarray(p[k], dtype=float) for k in ("A", "M"))
        return cls(order=int(p["order"]), fill=bool(p["fill"]), min_holes=int(p["min_holes"]),
                   **_restore_settings(p), A_=A, M_=M, calibration_=from_dict(p["calibration"]))

    def predict(self, cen: xr.Dataset) -> xr.Dataset:
        """Estimated (alpha, beta) of every frame from the calibrated centre.

        Parameters
        ----------
        cen : xarray.Dataset
            Centroid table on (pose, shot, hole), px.

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) on (pose, shot), ``n_holes`` used per frame, commanded
            angles ``alpha_cmd``, ``beta_cmd`` as coordinates.
        """
        if self.calibration_ is None:
            raise ConfigurationError("GeometricCentre: call fit() first")
        gc = self.centre(cen)
        a, b = _predict(self.calibration_, gc)
        return _angles_dataset(cen, a, b, ("pose", "shot"),
                               {"n_holes": (("pose", "shot"), gc["n_holes"].values)})


# --------------------------------------------------------------------------------------------
# Strategy 2: per-hole calibration, then the average
# --------------------------------------------------------------------------------------------
def combine_estimates(est, *, holes=None, weights=None, clip: float | None = None,
                      n_iter: int = 3, dim: str = "hole"):
    """Combine per-hole angle estimates of each frame into one: mean, weighted and/or clipped.

    Parameters
    ----------
    est : xarray.DataArray
        Angle estimates, deg, with a ``hole`` dimension; NaN for a hole missing in a frame.
    holes : array_like of bool, shape (hole,), optional
        Holes allowed in the combination.
    weights : array_like, shape (hole,), optional
        Non-negative weights, e.g. 1 / (hole's residual variance); default equal.
    clip : float, optional
        Sigma-clipping threshold: in every frame, estimates further than ``clip`` robust standard
        deviations from the median of the kept ones are dropped, ``n_iter`` times (the scale is
        1.4826 MAD, bounded below by the standard deviation of the survivors after the first
        pass).
    dim : str
        Dimension to combine.

    Returns
    -------
    mean, n : xarray.DataArray
        The combined estimate and the number of holes used in each frame.

    Notes
    -----
    Averaging N independent estimates of equal variance divides the variance by N, eq. (5):

    .. math:: \\sigma^2_N = \\sigma^2 / N.

    The mean over the holes present is unbiased as long as each hole's estimate is.

    Examples
    --------
    >>> e = xr.DataArray([[1.0, 1.1, 0.9, 5.0, np.nan]], dims=("pose", "hole"))
    >>> float(combine_estimates(e)[0][0])
    2.0
    >>> round(float(combine_estimates(e, clip=4.0)[0][0]), 6)
    1.0
    """
    ok = np.isfinite(est)
    if holes is not None:
        ok = ok & xr.DataArray(np.asarray(holes, dtype=bool), dims=dim)
    w = xr.ones_like(est) if weights is None else xr.DataArray(np.asarray(weights, float), dims=dim)
    w = w.where(ok, 0.0)
    if clip is not None:
        for it in range(n_iter):
            cur = est.where(w > 0)
            med = cur.median(dim)
            scale = 1.4826 * np.abs(cur - med).median(dim)
            if it > 0:  # a few survivors can have MAD 0: their standard deviation bounds it
                scale = np.maximum(scale, cur.std(dim))
            keep = np.abs(est - med) <= clip * scale
            w = w.where(keep, 0.0)
    wsum = w.sum(dim)
    mean = (est.fillna(0.0) * w).sum(dim) / wsum.where(wsum > 0)
    return mean, (w > 0).sum(dim)


@dataclass(repr=False)
class PerHoleAverage(Calibration):
    """Strategy 2 of the paper: a calibration per hole (f1_ij, f2_ij), then the average.

    .. math:: \\alpha = \\frac{1}{N}\\sum_{ij} f_1^{ij}(x_c^{ij}, y_c^{ij}), \\qquad
              \\beta = \\frac{1}{N}\\sum_{ij} f_2^{ij}(x_c^{ij}, y_c^{ij})

    The average runs over the holes present in each frame, which is unbiased: every hole's own
    calibration already maps its spot to the sun direction. With ``weighting="inverse_variance"``
    each hole counts by the inverse of its hole-specific residual variance on the training set
    (its scatter about the consensus of all holes); ``clip`` adds per-frame sigma clipping.

    Parameters
    ----------
    order : int
        Polynomial order of every hole's calibration.
    model : callable, optional
        Calibration factory, as in :class:`GeometricCentre`.
    holes : array_like of bool, optional
        Holes allowed in the average (the calibration is still fitted for every hole, so the
        selection can change without refitting).
    weighting : {"equal", "inverse_variance"}
        How the holes are weighted.
    clip : float, optional
        Per-frame sigma-clipping threshold (robust standard deviations).
    accept : sequence of str
        Status codes accepted as usable.
    poses_per_coef : float
        A hole gets its own calibration only if it was seen at no fewer than this many
        training poses per free coefficient (1.5: 15 poses for a cubic's 10). A hole seen at
        barely as many poses as coefficients is fitted almost exactly, through its noise, and
        swings between the poses: at a long F (17 mm) the corner holes leave the detector at
        many poses, and a cubic on 11 of a 4 x 4 grid missed by up to 8 deg. Such a hole is left out
        of the average (its estimates are NaN).

    Examples
    --------
    >>> from sunlab.calibration import Polynomial
    >>> from sunlab.sim import synthetic_centroids
    >>> a = np.repeat(np.arange(-4.0, 5.0, 2.0), 5); b = np.tile(np.arange(-4.0, 5.0, 2.0), 5)
    >>> cen = synthetic_centroids(a, b, shots=1, layout="grid", noise_px=0.01)
    >>> s2 = PerHoleAverage(model=lambda: Polynomial(2)).fit(cen)
    >>> err = s2.predict(cen).alpha - cen.alpha
    >>> bool(abs(err).max() < 0.005)
    True
    """

    default_outlier_mads = None  # no shot screening by default: holes are judged whole
    kind: ClassVar[str] = "multihole-per-hole-average"
    order: int = 5
    model: Callable | None = None
    holes: np.ndarray | None = None
    weighting: str = "equal"
    clip: float | None = None
    accept: Sequence[str] = ("ok",)
    poses_per_coef: float = 1.5
    calibrations_: list | None = field(default=None, repr=False)
    variance_: np.ndarray | None = field(default=None, repr=False)

    def _fit_tables(self, cen: xr.Dataset, validation: xr.Dataset | None = None
                    ) -> PerHoleAverage:
        """Fit one calibration per hole on a training table; estimate each hole's variance.

        Parameters
        ----------
        cen : xarray.Dataset
            Training table on (pose, shot, hole) with the commanded angles (experiment I).
        validation : xarray.Dataset, optional
            A validation table (experiment II): the artifact's validation residuals.

        Returns
        -------
        PerHoleAverage
            ``self``, with ``calibrations_`` (None for a hole seen too rarely) and
            ``variance_`` (deg^2 per hole) set.
        """
        if self.weighting not in ("equal", "inverse_variance"):
            raise ConfigurationError(
                f"weighting: found {self.weighting!r}, expected 'equal' or 'inverse_variance'"
            )
        factory = self.model or _default_model(self.order)
        ok = usable(cen, self.accept)
        self.calibrations_ = []
        probe = factory()
        if hasattr(probe, "min_poses"):
            n_coef = int(probe.min_poses())
        else:
            order = getattr(probe, "order", self.order)
            n_coef = (order + 1) * (order + 2) // 2
        need = max(math.ceil(self.poses_per_coef * n_coef), 3)
        for h in range(cen.sizes["hole"]):
            table = _hole_table(cen, h, ok)
            n_poses = int(np.isfinite(table["x"].values).any(axis=1).sum())
            # a hole seen at too few poses cannot carry its own calibration: it is left out
            self.calibrations_.append(_fit_model(factory, table) if n_poses >= need else None)
        if all(c is None for c in self.calibrations_):
            raise ConfigurationError(
                f"centroids: no hole was seen at {need} or more training poses, the fewest for "
                f"its own calibration ({n_coef} coefficients x poses_per_coef = "
                f"{self.poses_per_coef}); use more calibration poses or a lower order")
        est = self.predict_holes(cen)
        dev2 = 0.0
        for name in ("alpha", "beta"):
            cons = est[name].median("hole")
            dev2 = dev2 + (est[name] - cons) ** 2
        var = dev2.mean(("pose", "shot")).values / 2
        med = np.nanmedian(var)
        self.variance_ = np.where(np.isfinite(var), np.maximum(var, 1e-3 * med), np.inf)
        mean = self.combine(est)
        _record_fit(self, cen, ok, {a: _error_stats(mean[a].values, mean[f"{a}_cmd"].values)
                                    for a in ("alpha", "beta")})
        _validation_residuals(self, validation)
        return self

    def __post_init__(self):
        Calibration.__init__(self)

    def predict_xy(self, x, y):
        """Angles (alpha, beta), deg, of frames given as centroid arrays ``x``, ``y`` (px)
        whose last axis is the hole (NaN: hole missing): every hole's own estimate, combined
        by this strategy's rule.

        Parameters
        ----------
        x, y : array_like, shape (..., hole)
            Centroids of every hole of each frame, px.

        Returns
        -------
        alpha, beta : numpy.ndarray, shape (...)
            Angles of the frames, deg.

        Examples
        --------
        >>> from sunlab.calibration import Polynomial
        >>> from sunlab.sim import synthetic_centroids
        >>> a = np.repeat(np.arange(-4.0, 5.0, 2.0), 5); b = np.tile(np.arange(-4.0, 5.0, 2.0), 5)
        >>> cen = synthetic_centroids(a, b, shots=1, layout="grid", noise_px=0.01)
        >>> s2 = PerHoleAverage(model=lambda: Polynomial(2)).fit(cen)
        >>> alpha, _ = s2.predict_xy(cen.x.values, cen.y.values)
        >>> bool(np.allclose(alpha, s2.predict(cen).alpha.values))
        True
        """
        if self.calibrations_ is None:
            raise ConfigurationError("PerHoleAverage: call fit() first")
        X, ok, shape = _frames(x, y)
        if X.shape[1] != len(self.calibrations_):
            raise SchemaError("hole", X.shape[1], f"{len(self.calibrations_)} holes (the last "
                              "axis of x, y), as in training")
        est = np.full(X.shape, np.nan)
        for h, cal in enumerate(self.calibrations_):
            if cal is not None:
                est[:, h, 0], est[:, h, 1] = _predict_arrays(cal, X[:, h, 0], X[:, h, 1])
        out = []
        for k in range(2):
            m, _ = combine_estimates(xr.DataArray(est[..., k], dims=("frame", "hole")),
                                     holes=self.holes, weights=self.weights(), clip=self.clip)
            out.append(m.values.reshape(shape))
        return out[0], out[1]

    def _parameters(self) -> dict:
        return {**_settings(self, ("order", "weighting", "clip", "poses_per_coef")),
                "variance": self.variance_,
                "calibrations": [None if c is None else c.to_dict() for c in self.calibrations_]}

    @classmethod
    def _from_parameters(cls, p: dict) -> PerHoleAverage:
        var = np.array([np.inf if v is None else v for v in p["variance"]], dtype=float)
        return cls(order=int(p["order"]), weighting=str(p["weighting"]), clip=p["clip"],
                   poses_per_coef=float(p["poses_per_coef"]), **_restore_settings(p),
                   variance_=var, calibrations_=[None if d is None else from_dict(d)
                                                 for d in p["calibrations"]])

    def predict_holes(self, cen: xr.Dataset) -> xr.Dataset:
        """Every hole's own estimate of every frame.

        Parameters
        ----------
        cen : xarray.Dataset
            Centroid table on (pose, shot, hole), px, with the holes of the training table.

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) on (pose, shot, hole), NaN where a hole is unusable.
        """
        if self.calibrations_ is None:
            raise ConfigurationError("PerHoleAverage: call fit() first")
        n_h = cen.sizes["hole"]
        if n_h != len(self.calibrations_):
            raise SchemaError("hole", n_h, f"{len(self.calibrations_)} holes, as in training")
        ok = usable(cen, self.accept).values
        x = np.where(ok, cen["x"].values, np.nan)
        y = np.where(ok, cen["y"].values, np.nan)
        a = np.full(x.shape, np.nan)
        b = np.full(x.shape, np.nan)
        for h, cal in enumerate(self.calibrations_):
            if cal is None:
                continue
            a[..., h], b[..., h] = _predict_arrays(cal, x[..., h], y[..., h])
        return _angles_dataset(cen, a, b, ("pose", "shot", "hole"))

    def weights(self) -> np.ndarray | None:
        """The per-hole weights of the combination.

        Returns
        -------
        numpy.ndarray or None
            1 / ``variance_`` (deg^-2) per hole; None for equal weights.
        """
        if self.weighting == "equal":
            return None
        return 1.0 / self.variance_

    def combine(self, est: xr.Dataset, holes=None) -> xr.Dataset:
        """Combine per-hole estimates with this strategy's rule (weights, clipping).

        Parameters
        ----------
        est : xarray.Dataset
            Per-hole estimates from :meth:`predict_holes`, deg.
        holes : array_like of bool, shape (hole,), optional
            Holes in the average (default ``self.holes``).

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) and ``n_holes`` on (pose, shot).
        """
        holes = self.holes if holes is None else holes
        out = {}
        n = None
        for name in ("alpha", "beta"):
            m, n = combine_estimates(est[name], holes=holes, weights=self.weights(),
                                     clip=self.clip)
            out[name] = m.values
        return _angles_dataset(est, out["alpha"], out["beta"], ("pose", "shot"),
                               {"n_holes": (("pose", "shot"), n.values)})

    def predict(self, cen: xr.Dataset) -> xr.Dataset:
        """Combined estimate of every frame: :meth:`predict_holes`, then :meth:`combine`.

        Parameters
        ----------
        cen : xarray.Dataset
            Centroid table on (pose, shot, hole), px.

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) and ``n_holes`` on (pose, shot).
        """
        return self.combine(self.predict_holes(cen))


def angle_errors(pred: xr.Dataset, cen: xr.Dataset | None = None) -> xr.Dataset:
    """Estimated minus commanded angles, deg (the paper's test protocol, sec. 5).

    ``pred`` carries the commanded angles as ``alpha_cmd``/``beta_cmd`` (as returned by the
    strategies) or they come from ``cen``'s ``alpha``/``beta``.

    Parameters
    ----------
    pred : xarray.Dataset
        Estimates ``alpha``, ``beta`` (deg) on (pose, shot) or (pose, shot, hole).
    cen : xarray.Dataset, optional
        Centroid table whose ``alpha``, ``beta`` are the commanded angles.

    Returns
    -------
    xarray.Dataset
        ``alpha``, ``beta``: estimated minus commanded, deg, on ``pred``'s dims.

    Examples
    --------
    >>> p = xr.Dataset({"alpha": (("pose", "shot"), [[1.5]]), "beta": (("pose", "shot"), [[0.0]])},
    ...                coords={"alpha_cmd": ("pose", [1.0]), "beta_cmd": ("pose", [0.5])})
    >>> float(angle_errors(p).alpha[0, 0]), float(angle_errors(p).beta[0, 0])
    (0.5, -0.5)
    """
    if cen is not None:
        ca, cb = cen["alpha"], cen["beta"]
    else:
        ca, cb = pred["alpha_cmd"], pred["beta_cmd"]
    return xr.Dataset({"alpha": pred["alpha"] - ca.values[:, None] if pred["alpha"].ndim == 2
                       else pred["alpha"] - xr.DataArray(ca.values, dims="pose"),
                       "beta": pred["beta"] - cb.values[:, None] if pred["beta"].ndim == 2
                       else pred["beta"] - xr.DataArray(cb.values, dims="pose")})
