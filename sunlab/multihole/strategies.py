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

from .. import schema
from ..calibration import Calibration, Polynomial, from_dict
from ..errors import ConfigurationError, SchemaError
from .holes import usable

__all__ = ["GeometricCentre", "PerHoleAverage"]


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
        Solve the centre with the per-hole offsets (True) or take the plain mean of the
        centroids, the paper's definition (False: it jumps by the lost hole's design offset / N
        whenever a hole is missing).
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
    >>> full = GeometricCentre(fill=False).centre(synthetic_centroids(
    ...     [0.0, -5.0, 1.0], [0.0, 3.0, 8.0], shots=1, layout="grid"))  # the plain mean
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
        return ok if self.holes is None else ok & xr.DataArray(np.asarray(self.holes, bool),
                                                               dims="hole")

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
        X, ok = _hole_frames(cen, self._ok(cen))
        n_ok, Xz = ok.sum(1), np.where(ok[..., None], X, 0.0)
        # start: design offsets of the holes from the mask centre where known, else zero
        d0 = np.zeros((X.shape[1], 2))
        if "hole_x_cf" in cen.coords and "hole_y_cf" in cen.coords:
            d0 = np.column_stack([cen["hole_x_cf"].values, cen["hole_y_cf"].values]).astype(float)
            d0 -= d0.mean(0)
        c = np.where(ok[..., None], X - d0, 0.0).sum(1) / np.maximum(n_ok, 1)[:, None]
        dev = np.where(ok[..., None], X - c[:, None], 0.0).sum(0)
        off = np.where(ok.any(0)[:, None], dev / np.maximum(ok.sum(0), 1)[:, None], d0)
        W = ok * (n_ok >= self.min_holes)[:, None]  # (frame, hole)
        few = W.sum(0) < 4  # a hole seen in too few frames keeps its offset
        for _ in range(n_iter):
            # each hole's weighted least-squares affine map from the centre: x_h = A + M c
            D = np.column_stack([np.ones(len(c)), c])
            G = np.einsum("fh,fi,fj->hij", W, D, D, optimize=True)
            beta = np.linalg.pinv(G) @ np.einsum("fh,fi,fhk->hik", W, D, Xz, optimize=True)
            A = np.where(few[:, None], off, beta[:, 0])
            M = np.where(few[:, None, None], np.eye(2), beta[:, 1:].transpose(0, 2, 1))
            # gauge: the centre is the mean of the holes' predicted positions
            Mi = np.linalg.inv(M.mean(0))
            self.A_ = A - np.einsum("hij,j->hi", M, Mi @ A.mean(0))
            self.M_ = np.einsum("hij,jk->hik", M, Mi)
            c = np.nan_to_num(self._solve(X, ok))
        return self

    def _solve(self, X, ok):
        n = ok.sum(1)
        if not self.fill:
            with np.errstate(invalid="ignore", divide="ignore"):
                c = np.where(ok[..., None], X, 0.0).sum(1) / n[:, None]
        else:
            r = np.where(ok[..., None], X - self.A_, 0.0)
            G = np.einsum("fh,hki,hkj->fij", ok.astype(float), self.M_, self.M_)
            G[n < self.min_holes] = np.eye(2)
            rhs = np.einsum("fh,hki,fhk->fi", ok.astype(float), self.M_, r)
            c = np.linalg.solve(G, rhs[..., None])[..., 0]
        return np.where((n >= self.min_holes)[:, None], c, np.nan)

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
        if self.A_ is not None and self.A_.shape[0] != cen.sizes["hole"]:
            raise SchemaError("hole", cen.sizes["hole"],
                              f"{self.A_.shape[0]} holes, as in the training table")
        X, ok = _hole_frames(cen, self._ok(cen))
        c = self._solve(X, ok)
        n = np.where(np.isfinite(c[:, 0]), ok.sum(1), 0).reshape(cen["x"].shape[:2])
        x, y = (c[:, k].reshape(n.shape) for k in (0, 1))
        flux = cen["flux"].where(self._ok(cen)).sum("hole").values
        status = np.where(n > 0, schema.STATUS["ok"], schema.STATUS["no_spot"])
        attrs = {k: v for k, v in cen.attrs.items() if k not in ("sunlab_schema", "method")}
        out = schema.centroids_dataset(
            np.where(n > 0, x, np.nan), np.where(n > 0, y, np.nan), flux=flux, status=status,
            alpha=cen["alpha"].values, beta=cen["beta"].values, method="geometric_centre",
            attrs=attrs, extra={"n_holes": (("pose", "shot"), n.astype(np.int16))})
        for name in ("true_alpha", "true_beta"):
            if name in cen.variables:
                out[name] = (("pose", "shot"), np.asarray(cen[name].values))
        return out

    def fit(self, cen: xr.Dataset, validation: xr.Dataset | None = None) -> GeometricCentre:
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
        centre = self.centre(cen)
        if (np.isfinite(centre["x"]) & np.isfinite(centre["y"])).sum() < 3:
            raise ConfigurationError("too few usable frames to fit a calibration (fewer than 3)")
        self.calibration_ = (self.model or (lambda: Polynomial(self.order)))().fit(centre)
        return _record_fit(self, cen, self._ok(cen), self.calibration_.residuals, validation)

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
        a, b = _predict_arrays(self.calibration_, gc["x"].values, gc["y"].values)
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

    def fit(self, cen: xr.Dataset, validation: xr.Dataset | None = None) -> PerHoleAverage:
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
                f"weighting: found {self.weighting!r}, expected 'equal' or 'inverse_variance'")
        factory = self.model or (lambda: Polynomial(self.order))
        probe = factory()
        order = getattr(probe, "order", self.order)
        n_coef = int(probe.min_poses()) if hasattr(probe, "min_poses") else \
            (order + 1) * (order + 2) // 2
        need = max(math.ceil(self.poses_per_coef * n_coef), 3)
        ok = usable(cen, self.accept)
        # each hole's own table (centroids/1 on (pose, shot)), built directly: unusable frames
        # NaN with status no_spot
        okv, status = ok.values, cen["status"].values
        data = {"x": np.where(okv, cen["x"].values, np.nan),
                "y": np.where(okv, cen["y"].values, np.nan),
                "status": np.where(okv | (status != 0), status, schema.STATUS["no_spot"]).astype(
                    np.int8), **{v: cen[v].values for v in _HOLE_VARS[3:] if v in cen}}
        coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
                  "alpha": ("pose", cen["alpha"].values), "beta": ("pose", cen["beta"].values)}
        self.calibrations_ = [
            factory().fit(xr.Dataset({k: (("pose", "shot"), v[..., h]) for k, v in data.items()},
                                     coords=coords, attrs=cen.attrs))
            # a hole seen at too few poses cannot carry its own calibration: it is left out
            if okv[..., h].any(1).sum() >= need else None for h in range(cen.sizes["hole"])]
        if all(c is None for c in self.calibrations_):
            raise ConfigurationError(
                f"centroids: no hole was seen at {need} or more training poses, the fewest for "
                f"its own calibration ({n_coef} coefficients x poses_per_coef = "
                f"{self.poses_per_coef}); use more calibration poses or a lower order")
        est = self.predict_holes(cen)
        dev2 = sum((est[a] - est[a].median("hole")) ** 2 for a in ("alpha", "beta"))
        var = dev2.mean(("pose", "shot")).values / 2
        self.variance_ = np.where(np.isfinite(var), np.maximum(var, 1e-3 * np.nanmedian(var)),
                                  np.inf)
        mean = self.combine(est)
        return _record_fit(self, cen, ok, {a: _error_stats(mean[a], mean[f"{a}_cmd"])
                                           for a in ("alpha", "beta")}, validation)

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
        X, _, shape = _frames(x, y)
        a, b = self._hole_estimates(X[..., 0], X[..., 1], "the last axis of x, y")
        return tuple(self._combine(xr.DataArray(v, dims=("frame", "hole")))[0].values.reshape(
            shape) for v in (a, b))

    def _hole_estimates(self, x, y, where="the table's hole dimension"):
        """Every hole's own (alpha, beta) of centroid arrays (..., hole), NaN where missing."""
        if self.calibrations_ is None:
            raise ConfigurationError("PerHoleAverage: call fit() first")
        if x.shape[-1] != len(self.calibrations_):
            raise SchemaError("hole", x.shape[-1],
                              f"{len(self.calibrations_)} holes ({where}), as in training")
        a, b = np.full(x.shape, np.nan), np.full(x.shape, np.nan)
        for h, cal in enumerate(self.calibrations_):
            if cal is not None:
                a[..., h], b[..., h] = _predict_arrays(cal, x[..., h], y[..., h])
        return a, b

    def _combine(self, est, holes=None):
        return combine_estimates(est, holes=self.holes if holes is None else holes,
                                 weights=self.weights(), clip=self.clip)

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
        ok = usable(cen, self.accept).values
        a, b = self._hole_estimates(np.where(ok, cen["x"].values, np.nan),
                                    np.where(ok, cen["y"].values, np.nan))
        return _angles_dataset(cen, a, b, ("pose", "shot", "hole"))

    def weights(self) -> np.ndarray | None:
        """The per-hole weights of the combination.

        Returns
        -------
        numpy.ndarray or None
            1 / ``variance_`` (deg^-2) per hole; None for equal weights.
        """
        return None if self.weighting == "equal" else 1.0 / self.variance_

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
        (a, n), (b, _) = (self._combine(est[k], holes) for k in ("alpha", "beta"))
        return _angles_dataset(est, a.values, b.values, ("pose", "shot"),
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


def angle_errors(pred: xr.Dataset) -> xr.Dataset:
    """Estimated minus commanded angles, deg (the paper's test protocol, sec. 5).

    ``pred`` carries the commanded angles as ``alpha_cmd``/``beta_cmd``, as the strategies return
    them.

    Parameters
    ----------
    pred : xarray.Dataset
        Estimates ``alpha``, ``beta`` (deg) on (pose, shot) or (pose, shot, hole).

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
    return xr.Dataset({a: pred[a] - pred[f"{a}_cmd"] for a in ("alpha", "beta")})


# --------------------------------------------------------------------------------------------
# Tables and arrays shared by the two strategies
# --------------------------------------------------------------------------------------------
#: the variables of one hole's own centroid table (``centroids/1`` on (pose, shot))
_HOLE_VARS = ("x", "y", "status", "flux", "x0", "x1", "y0", "y1")


def _hole_frames(cen, ok):
    """A table's centroids as (frame, hole, 2) and its usable mask (frame, hole)."""
    n_h = cen.sizes["hole"]
    X = np.stack([cen["x"].values, cen["y"].values], -1).reshape(-1, n_h, 2)
    return X, ok.values.reshape(-1, n_h)


def _frames(x, y):
    """Centroid arrays (..., hole) as (frames, hole, 2), their usable mask and leading shape."""
    x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
    if x.ndim < 1:
        raise ConfigurationError(
            "x, y: found scalars; a multi-hole strategy needs every hole's centroid of a frame "
            "(arrays whose last axis is the hole)")
    X = np.stack([x, y], -1).reshape(-1, x.shape[-1], 2)
    return X, np.isfinite(X).all(-1), x.shape[:-1]


def _predict_arrays(model, x, y):
    """(alpha, beta) of a fitted calibration for centroid arrays; NaN where x or y is NaN."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    bad = ~(np.isfinite(x) & np.isfinite(y))
    a, b = model.predict_xy(np.where(bad, np.nan, x), np.where(bad, np.nan, y))
    return tuple(np.where(bad, np.nan, np.reshape(v, x.shape)) for v in (a, b))


def _error_stats(est, cmd) -> dict:
    """Statistics of estimated - commanded (deg) over the finite estimates, as ``calibration/1``
    writes residuals."""
    e = (est - cmd).values
    e = e[np.isfinite(e)]
    if e.size == 0:
        return dict.fromkeys(("mean", "mean_abs", "rms", "std", "max_abs"), None) | {"n": 0}
    return {"mean": float(e.mean()), "mean_abs": float(np.abs(e).mean()),
            "rms": float(np.sqrt(np.mean(e**2))), "std": float(e.std()),
            "max_abs": float(np.abs(e).max()), "n": int(e.size)}


def _record_fit(strategy, cen, ok, residuals: dict, validation):
    """The training summary, domain and residuals (with the validation table's) every fitted
    calibration carries; returns the strategy."""
    ok = np.asarray(ok.values, dtype=bool)
    strategy.training = {
        "experiment": str(cen.attrs.get("experiment", "")),
        "centroid_method": str(cen.attrs.get("method", "")),
        "n_samples": int(ok.sum()), "n_poses": int(ok.any(axis=(1, 2)).sum()),
        "n_shots": int(cen.sizes["shot"]), "n_holes": int(cen.sizes["hole"])}
    values = {"alpha": cen["alpha"].values, "beta": cen["beta"].values,
              "x": cen["x"].values[ok], "y": cen["y"].values[ok]}
    strategy.domain = {k: [float(v.min()), float(v.max())] if v.size else [0.0, 0.0]
                       for k, v in values.items()}
    strategy.residuals = {"alpha": residuals["alpha"], "beta": residuals["beta"],
                          "validation": None}
    if validation is not None:
        est = strategy.predict(validation)
        strategy.residuals["validation"] = {a: _error_stats(est[a], est[f"{a}_cmd"])
                                            for a in ("alpha", "beta")}
    return strategy


def _settings(strategy, names) -> dict:
    """The strategy's settings (``names`` plus the shared ones) for its saved parameters."""
    holes = None if strategy.holes is None else np.asarray(strategy.holes, bool).tolist()
    return {**{k: getattr(strategy, k) for k in names}, "holes": holes,
            "accept": list(strategy.accept)}


def _restore_settings(p: dict) -> dict:
    return {"holes": None if p["holes"] is None else np.asarray(p["holes"], dtype=bool),
            "accept": tuple(str(s) for s in p["accept"])}


def _angles_dataset(cen, a, b, dims, extra=None):
    """Angle estimates on ``dims`` with the commanded angles (from a centroid table's
    ``alpha``/``beta`` or an estimate's ``alpha_cmd``/``beta_cmd``) as coordinates."""
    cmd = {k: (cen[f"{k}_cmd"] if f"{k}_cmd" in cen.coords else cen[k]).values
           for k in ("alpha", "beta")}
    coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
              **{f"{k}_cmd": ("pose", v, {"units": "deg"}) for k, v in cmd.items()}}
    if "hole" in dims:
        coords.update({c: ("hole", cen[c].values) for c in
                       ("hole", "hole_i", "hole_j", "hole_x_cf", "hole_y_cf") if c in cen.coords})
    return xr.Dataset({"alpha": (dims, a, {"units": "deg"}), "beta": (dims, b, {"units": "deg"}),
                       **(extra or {})}, coords=coords)
