"""The per-hole review of a multi-hole experiment: everything the hole explorer shows, computed.

:func:`review_holes` fits (or takes) the per-hole calibration, scores every hole
(:func:`~sunlab.multihole.defects.defect_metrics`), flags the bad ones
(:func:`~sunlab.multihole.defects.reject_bad_holes`) and predicts every hole's estimate of a test
table; the :class:`HoleReview` it returns answers the questions a reader asks hole by hole: the
global statistics with a chosen set of holes averaged (:meth:`HoleReview.stats`), and a hole's
residual against the average over the poses (:meth:`HoleReview.residual_map`).
:class:`sunlab.widgets.HoleExplorer` is a view over it and computes nothing of its own.

References
----------
.. [1] docs/paper.md, sec. 5 and 6 (the 2005 preprint on the Naples APS sun sensor).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr

from ..errors import ConfigurationError
from ..schema import DEFECT_FLAGS
from ..stats import error_summary
from .defects import defect_metrics, reject_bad_holes, robust_z
from .holes import hole_grid
from .strategies import PerHoleAverage

__all__ = []


@dataclass
class HoleReview:
    """Per-hole results of a multi-hole experiment (see :func:`review_holes`).

    Attributes
    ----------
    strategy : PerHoleAverage
        The fitted per-hole calibration.
    metrics : xarray.Dataset
        Defect metrics on ``hole``.
    z : xarray.Dataset
        Their robust z-scores (:func:`~sunlab.multihole.defects.robust_z`).
    flagged : numpy.ndarray of bool
        Holes flagged by the automatic rejection.
    injected : dict of int to str
        Holes the simulator gave defects, with their kinds (empty for real data).
    estimates : xarray.Dataset
        Every hole's estimate on (pose, shot, hole) of the reviewed table.
    hole_i, hole_j : numpy.ndarray of int
        Grid row and column of every hole; ``n_rows``, ``n_cols`` the grid's size.
    all_stats : dict
        :func:`sunlab.stats.error_summary` of the average of all holes.
    """

    strategy: PerHoleAverage
    metrics: xr.Dataset
    z: xr.Dataset
    flagged: np.ndarray
    injected: dict
    estimates: xr.Dataset
    hole_i: np.ndarray
    hole_j: np.ndarray
    n_rows: int
    n_cols: int
    all_stats: dict

    @property
    def n_holes(self) -> int:
        """Number of holes."""
        return int(self.estimates.sizes["hole"])

    def combined(self, included) -> xr.Dataset:
        """The strategy's average over the ``included`` holes, on (pose, shot).

        Parameters
        ----------
        included : array_like of bool, shape (hole,)
            Holes in the average.

        Returns
        -------
        xarray.Dataset
            Combined ``alpha``, ``beta`` (deg) on (pose, shot) with the commanded angles and
            ``n_holes`` (:meth:`PerHoleAverage.combine
            <sunlab.multihole.PerHoleAverage.combine>`).
        """
        return self.strategy.combine(self.estimates, holes=np.asarray(included, dtype=bool))

    def stats(self, included, hole: int) -> dict:
        """The paper's global statistics of the included holes' average, all holes and one hole.

        Parameters
        ----------
        included : array_like of bool, shape (hole,)
            Holes in the average.
        hole : int
            Index of the hole shown alone.

        Returns
        -------
        dict
            ``{"included": .., "all": .., "hole": ..}``: :func:`sunlab.stats.error_summary`
            (deg) of the average of the included holes (None when there is none), of all
            holes, and of ``hole`` alone.
        """
        inc = error_summary(self.combined(included)) if np.any(included) else None
        return {"included": inc, "all": self.all_stats,
                "hole": error_summary(self.estimates.isel(hole=int(hole)))}

    def residual_map(self, hole: int, included) -> dict:
        """The hole's estimate minus the average of the included holes, mean over the shots.

        Parameters
        ----------
        hole : int
            Index of the hole.
        included : array_like of bool, shape (hole,)
            Holes in the average.

        Returns
        -------
        dict of str to numpy.ndarray
            ``"alpha"``, ``"beta"``: the residual on ``pose``, deg (NaN where the hole or the
            average has no estimate).
        """
        comb = self.combined(included)
        return {a: (self.estimates[a].isel(hole=int(hole)) - comb[a]).mean("shot").values
                for a in ("alpha", "beta")}


def review_holes(centroids: xr.Dataset, *, strategy: PerHoleAverage | None = None, train=None,
                 metrics=None, order: int = 5, kappa: float = 5.0) -> HoleReview:
    """Review every hole of a multi-hole table: calibration, defect metrics, flags, estimates.

    Parameters
    ----------
    centroids : xarray.Dataset
        Centroid table on (pose, shot, hole): the experiment reviewed (estimates, statistics).
    strategy : PerHoleAverage, optional
        A fitted per-hole calibration (default: fitted on ``train`` with ``order``).
    train : xarray.Dataset, optional
        Training table of the calibration and of the metrics (default ``centroids``).
    metrics : xarray.Dataset, optional
        Defect metrics (default :func:`~sunlab.multihole.defects.defect_metrics` of ``train``).
    order : int
        Polynomial order when the calibration is fitted here.
    kappa : float
        Rejection threshold of :func:`~sunlab.multihole.defects.reject_bad_holes`.

    Returns
    -------
    HoleReview
        The calibration, metrics, z-scores, flags, injected defects and every hole's estimate
        of ``centroids``.

    Raises
    ------
    ConfigurationError
        ``centroids`` has no ``hole`` dimension.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> a = np.repeat(np.linspace(-8, 2, 5), 5); b = np.tile(np.linspace(-2, 8, 5), 5)
    >>> cen = synthetic_centroids(a, b, shots=2, layout="grid", noise_px=0.01,
    ...                           defects={7: {"sigma_px": 1.0}})
    >>> r = review_holes(cen, order=2)
    >>> np.flatnonzero(r.flagged).tolist(), r.stats(~r.flagged, 7)["all"]["alpha"]["n_poses"]
    ([7], 25)
    """
    if "hole" not in centroids.dims:
        raise ConfigurationError(f"centroids: found dims {tuple(centroids.dims)}, expected (pose, "
                                 "shot, hole); centroid the cube with a multi-spot method")
    base = train if train is not None else centroids
    strategy = strategy or PerHoleAverage(order=order).fit(base)
    metrics = metrics if metrics is not None else defect_metrics(base, strategy=strategy)
    estimates = strategy.predict_holes(centroids)
    i, j, nr, nc = hole_grid(centroids)
    n_h = centroids.sizes["hole"]
    return HoleReview(
        strategy=strategy, metrics=metrics, z=robust_z(metrics),
        flagged=reject_bad_holes(metrics, kappa=kappa).values,
        injected=injected_defects(centroids if "hole_defect" in centroids.coords else base),
        estimates=estimates, hole_i=i, hole_j=j, n_rows=nr, n_cols=nc,
        all_stats=error_summary(strategy.combine(estimates, holes=np.ones(n_h, bool))),
    )


def injected_defects(cen: xr.Dataset) -> dict[int, str]:
    """Holes that the simulator gave defects (``hole_defect`` bit flags), with their kinds.

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table or frame cube, with the ``hole_defect`` coordinate on ``hole`` when
        simulated.

    Returns
    -------
    dict of int to str
        Hole index -> defect kinds joined by ``+`` (names of :data:`sunlab.schema.DEFECT_FLAGS`);
        empty without ``hole_defect``.

    Examples
    --------
    >>> cen = xr.Dataset(coords={"hole_defect": ("hole", [0, 1, 0])})
    >>> list(injected_defects(cen))
    [1]
    """
    if "hole_defect" not in cen.coords:
        return {}
    flags = np.asarray(cen["hole_defect"].values, dtype=int)
    return {int(h): "+".join(k for k, bit in DEFECT_FLAGS.items() if flags[h] & bit) or "defect"
            for h in np.flatnonzero(flags)}
