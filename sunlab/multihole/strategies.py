"""The paper's two strategies for a mask of N holes, as calibrations (sec. 6, Table 5):
:class:`GeometricCentre` calibrates the mean of the N spot centroids as one spot,
:class:`PerHoleAverage` calibrates every hole and averages the N angle estimates
(:func:`sunlab.multihole.budget.combine_estimates`).

Both honour the protocol of :class:`sunlab.calibration.Calibration` (``fit(train,
validation=None)`` on tables on ``(pose, shot, hole)``, ``predict`` on ``(pose, shot)``,
``predict_xy(x, y)`` on arrays whose last axis is the hole, ``save`` and
:func:`sunlab.calibration.load`, contract ``calibration/1``, kinds
``multihole-geometric-centre`` and ``multihole-per-hole-average``). They are entries of the
one calibration registry, registered by entry point (group ``sunlab.calibrations`` in
``pyproject.toml``, as a lab's plug-in would be: multihole sits above calibration), so
``sunlab.calibration.fit(table, "multihole-per-hole-average", order=3)`` fits one.

Both handle holes missing from some frames without bias: the centre is solved from the holes
present with each one's fitted offset, the average runs over the holes present.

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
from ..calibration import Calibration, Polynomial
from ..calibration.artifact import from_dict
from ..errors import ConfigurationError, SchemaError
from . import _tables as _t
from .budget import combine_estimates
from .holes import usable

__all__ = ["GeometricCentre", "PerHoleAverage"]


@dataclass(repr=False)
class _HoleStrategy(Calibration):
    """What both strategies share (each documents its parameters): the calibration factory,
    the holes used and the accepted status codes; no shot screening by default, as holes
    are judged whole."""

    default_outlier_mads = None
    order: int = 5
    model: Callable | None = None
    holes: np.ndarray | None = None
    accept: Sequence[str] = ("ok",)

    def __post_init__(self):
        Calibration.__init__(self)

    def _factory(self) -> Callable:
        return self.model or (lambda: Polynomial(self.order))


@dataclass(repr=False)
class GeometricCentre(_HoleStrategy):
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
    """

    kind: ClassVar[str] = "multihole-geometric-centre"
    fill: bool = True
    min_holes: int = 3
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
        X, ok = _t._hole_frames(cen, self._ok(cen))
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
        X, ok = _t._hole_frames(cen, self._ok(cen))
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
        centre = self.centre(cen)
        if (np.isfinite(centre["x"]) & np.isfinite(centre["y"])).sum() < 3:
            raise ConfigurationError("too few usable frames to fit a calibration (fewer than 3)")
        # the strategy judges holes whole: no shot screening inside its calibrations
        self.calibration_ = self._factory()().fit(
            centre, outlier_mads=None)
        return _t._record_fit(self, cen, self._ok(cen), self.calibration_.residuals, validation)

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
        """
        if self.calibration_ is None:
            raise ConfigurationError("GeometricCentre: call fit() first")
        X, ok, shape = _t._frames(x, y)
        if self.holes is not None:
            ok = ok & np.asarray(self.holes, dtype=bool)
        c = self._solve(np.where(ok[..., None], X, 0.0), ok)
        a, b = _t._predict_arrays(self.calibration_, c[:, 0], c[:, 1])
        return a.reshape(shape), b.reshape(shape)

    def _parameters(self) -> dict:
        return {**_t._settings(self, ("order", "fill", "min_holes")),
                "A": self.A_, "M": self.M_, "calibration": self.calibration_.to_dict()}

    @classmethod
    def _from_parameters(cls, p: dict) -> GeometricCentre:
        A, M = (None if p[k] is None else np.asarray(p[k], dtype=float) for k in ("A", "M"))
        return cls(order=int(p["order"]), fill=bool(p["fill"]), min_holes=int(p["min_holes"]),
                   **_t._restore_settings(p), A_=A, M_=M, calibration_=from_dict(p["calibration"]))

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
        a, b = _t._predict_arrays(self.calibration_, gc["x"].values, gc["y"].values)
        return _t._angles_dataset(cen, a, b, ("pose", "shot"),
                               {"n_holes": (("pose", "shot"), gc["n_holes"].values)})


@dataclass(repr=False)
class PerHoleAverage(_HoleStrategy):
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
        A hole gets its own calibration only if seen at this many training poses per free
        coefficient (1.5: 15 poses for a cubic's 10); else it is left out of the average (NaN
        estimates). One seen at barely as many poses as coefficients is fitted through its
        noise: at F = 17 mm a cubic on 11 poses of a 4 x 4 grid missed by up to 8 deg.

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
    weighting: str = "equal"
    clip: float | None = None
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
                f"weighting: found {self.weighting!r}, expected 'equal' or 'inverse_variance'")
        factory = self._factory()
        n_coef = int(factory().min_poses())  # a Calibration: one pose per free coefficient
        need = max(math.ceil(self.poses_per_coef * n_coef), 3)
        ok = usable(cen, self.accept)
        # each hole's own table (centroids/1 on (pose, shot)), built directly: unusable frames
        # NaN with status no_spot
        okv, status = ok.values, cen["status"].values
        data = {"x": np.where(okv, cen["x"].values, np.nan),
                "y": np.where(okv, cen["y"].values, np.nan),
                "status": np.where(okv | (status != 0), status, schema.STATUS["no_spot"]).astype(
                    np.int8), **{v: cen[v].values for v in _t._HOLE_VARS[3:] if v in cen}}
        coords = {"pose": cen["pose"].values, "shot": cen["shot"].values,
                  "alpha": ("pose", cen["alpha"].values), "beta": ("pose", cen["beta"].values)}
        self.calibrations_ = [
            factory().fit(xr.Dataset({k: (("pose", "shot"), v[..., h]) for k, v in data.items()},
                                     coords=coords, attrs=cen.attrs), outlier_mads=None)
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
        return _t._record_fit(self, cen, ok, {a: _t._error_stats(mean[a], mean[f"{a}_cmd"])
                                           for a in ("alpha", "beta")}, validation)

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
        """
        X, _, shape = _t._frames(x, y)
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
                a[..., h], b[..., h] = _t._predict_arrays(cal, x[..., h], y[..., h])
        return a, b

    def _combine(self, est, holes=None):
        return combine_estimates(est, holes=self.holes if holes is None else holes,
                                 weights=self.weights(), clip=self.clip)

    def _parameters(self) -> dict:
        return {**_t._settings(self, ("order", "weighting", "clip", "poses_per_coef")),
                "variance": self.variance_,
                "calibrations": [None if c is None else c.to_dict() for c in self.calibrations_]}

    @classmethod
    def _from_parameters(cls, p: dict) -> PerHoleAverage:
        var = np.array([np.inf if v is None else v for v in p["variance"]], dtype=float)
        return cls(order=int(p["order"]), weighting=str(p["weighting"]), clip=p["clip"],
                   poses_per_coef=float(p["poses_per_coef"]), **_t._restore_settings(p),
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
        return _t._angles_dataset(cen, a, b, ("pose", "shot", "hole"))

    def weights(self) -> np.ndarray | None:
        """The per-hole weights of the combination: 1 / ``variance_`` (deg^-2) per hole, or None
        for equal weights (numpy.ndarray or None)."""
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
            ``alpha``, ``beta`` (deg), ``n_holes`` on (pose, shot).
        """
        (a, n), (b, _) = (self._combine(est[k], holes) for k in ("alpha", "beta"))
        return _t._angles_dataset(est, a.values, b.values, ("pose", "shot"),
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
