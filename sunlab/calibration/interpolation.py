"""Calibration table + interpolation (docs/paper.md sec. 4.2): linear and cubic.

The calibration table is the set of nodes (mean centroid of the ok shots of each pose ->
commanded angles). The centroids of a pose grid do not lie on a grid (the mapping is
nonlinear and the platform errs), so the interpolation is over scattered data on the Delaunay
triangulation of the nodes: :class:`scipy.interpolate.LinearNDInterpolator` (piecewise linear)
and :class:`scipy.interpolate.CloughTocher2DInterpolator` (piecewise cubic, C1), both with the
inputs rescaled to the unit square. Outside the convex hull of the nodes the estimate is NaN
(no extrapolation), unless ``extrapolate="nearest"`` takes the nearest node's angles there.

Interpolation passes through its nodes exactly, noise included. Which wins depends on how fast
the error varies between nodes. A repeatable, spot-specific error that varies smoothly over a
grid step (a short mask distance: F = 5 mm moves the spot 12.5 px per degree) is learned by the
table, which then beats a polynomial. At F = 17 mm (42 px per degree,
``studies.surrogate_tables.interpolation_gap``; the paper's F is not identified, see
docs/identification.md, Results) the same kind of error changes
completely from node to node, so it acts like the platform's per-pose error: noise on the nodes,
which the table copies and a smoothing polynomial averages. There the polynomial wins on alpha
(polynomial < linear < cubic interpolation), as in the paper's Table 4; ``sunlab reproduce``
prints the numbers.

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
>>> est = Interpolation("cubic").fit(cen).predict(cen)
>>> float(abs(est.alpha - est.alpha_cmd).max()) < 1e-9
True
"""

from __future__ import annotations

import numpy as np
from scipy.interpolate import (
    CloughTocher2DInterpolator,
    LinearNDInterpolator,
    NearestNDInterpolator,
)
from scipy.spatial import QhullError, cKDTree

from ..errors import ConfigurationError
from .artifact import _bad, check_parameters
from .base import Calibration, _err_summary

__all__ = ["Interpolation"]

_METHODS = ("linear", "cubic")


class Interpolation(Calibration):
    """Linear or cubic interpolation of the calibration table.

    Parameters
    ----------
    method : {"linear", "cubic"}
        Piecewise-linear (Delaunay) or Clough-Tocher piecewise-cubic interpolation.
    extrapolate : {None, "nearest"}
        Outside the convex hull of the nodes: NaN (default) or the nearest node's angles.
    leave_one_out : bool
        Record :meth:`leave_one_out`'s errors in ``residuals`` when fitted (default; seconds
        per table); the predictions do not depend on it.

    Examples
    --------
    >>> Interpolation("linear").label
    'linear interp.'
    """

    kind = "interpolation-linear"

    def __init__(self, method: str = "linear", extrapolate: str | None = None, *,
                 leave_one_out: bool = True):
        super().__init__()
        if method not in _METHODS:
            raise ConfigurationError(f"method: found {method!r}, expected one of {_METHODS}")
        if extrapolate not in (None, "nearest"):
            raise ConfigurationError(
                f"extrapolate: found {extrapolate!r}, expected None (NaN outside the hull) or "
                "'nearest'"
            )
        self.method = method
        self.kind = f"interpolation-{method}"
        self.extrapolate = extrapolate
        # a diagnostic of the artifact, seconds per table: a study that refits thousands of
        # tables and reads only their predictions turns it off
        self.with_leave_one_out = bool(leave_one_out)
        self.average = "pose"
        self.nodes: dict | None = None
        self._interp = self._nearest = None  # scipy interpolants of the nodes (_build)

    @property
    def label(self) -> str:
        return f"{self.method} interp."

    def _build(self) -> None:
        pts = np.column_stack([self.nodes["x"], self.nodes["y"]])
        vals = np.column_stack([self.nodes["alpha"], self.nodes["beta"]])
        cls = LinearNDInterpolator if self.method == "linear" else CloughTocher2DInterpolator
        try:
            self._interp = cls(pts, vals, fill_value=np.nan, rescale=True)
        except Exception as err:  # qhull errors: collinear or duplicate nodes
            raise ConfigurationError(
                f"nodes: cannot triangulate the calibration table ({type(err).__name__}). Fix: "
                "calibrate on a 2-D grid of poses with distinct centroids"
            ) from err
        self._nearest = NearestNDInterpolator(pts, vals, rescale=True)

    def min_poses(self) -> int:
        """Fewest distinct training poses: three nodes make one Delaunay triangle.

        Returns
        -------
        int
            3.
        """
        return 3  # one triangle

    def _fit(self, data, validation) -> None:
        self.nodes = {"x": data.x, "y": data.y, "alpha": data.alpha, "beta": data.beta}
        self._build()

    def inside(self, x, y) -> np.ndarray:
        """True inside the convex hull of the nodes (where the interpolant is defined).

        Parameters
        ----------
        x, y : array_like
            Centroids, px (x = column, y = row), broadcast together.

        Returns
        -------
        numpy.ndarray of bool
            Of the broadcast shape; False where x or y is not finite.
        """
        self.check_fitted()
        x, y = np.broadcast_arrays(np.asarray(x, dtype=float), np.asarray(y, dtype=float))
        ok = np.isfinite(x) & np.isfinite(y)
        pts = np.column_stack([np.where(ok, x, 0.0).ravel(), np.where(ok, y, 0.0).ravel()])
        scaled = (pts - self._interp.offset) / self._interp.scale
        return (self._interp.tri.find_simplex(scaled) >= 0).reshape(x.shape) & ok

    def leave_one_out(self, neighbours: int = 24) -> dict:
        """Leave-one-out errors of the table: each node predicted without it, deg.

        An interpolant passes through its nodes, so its training residuals say nothing; the
        leave-one-out error is the honest estimate of its error between nodes. Each node is
        predicted by the same interpolation built on its ``neighbours`` nearest other nodes
        (in the rescaled centroid plane): removing a node changes the Delaunay triangulation
        only around it, so for linear interpolation this equals the global leave-one-out;
        cubic gradients are estimated from the neighbourhood. Nodes outside the hull of their
        neighbours (the rim of the table) are left out of the statistics.

        Parameters
        ----------
        neighbours : int
            Nearest other nodes each left-out node is interpolated from (default 24: the two
            rings of a square grid around it).

        Returns
        -------
        dict
            Per angle the statistics of ``residuals`` (``mean_abs``, ``rms``, ``max_abs``, ...).

        Examples
        --------
        >>> import numpy as np
        >>> from sunlab import sim
        >>> a, b = np.meshgrid(np.arange(-6.0, 3.0), np.arange(-2.0, 7.0), indexing="ij")
        >>> cen = sim.synthetic_centroids(a.ravel(), b.ravel())
        >>> loo = Interpolation("linear").fit(cen).residuals["leave_one_out"]
        >>> 49 <= loo["alpha"]["n"] < 81, 0 < loo["alpha"]["max_abs"] < 0.05  # 7 x 7 inner nodes
        (True, True)
        """
        pts = np.column_stack([self.nodes["x"], self.nodes["y"]])
        vals = np.column_stack([self.nodes["alpha"], self.nodes["beta"]])
        lo, span = pts.min(axis=0), np.ptp(pts, axis=0)
        span = np.where(span > 0, span, 1.0)
        z = (pts - lo) / span
        k = min(int(neighbours) + 1, len(z))
        _, idx = cKDTree(z).query(z, k=k)
        est = np.full(vals.shape, np.nan)
        cls = LinearNDInterpolator if self.method == "linear" else CloughTocher2DInterpolator
        for i, near in enumerate(np.atleast_2d(idx)):
            near = near[near != i]
            if len(near) < 3:
                continue
            try:  # the same interpolant on the node's neighbours (rescaled plane)
                est[i] = cls(z[near], vals[near], fill_value=np.nan)(z[i:i + 1])[0]
            except QhullError:  # degenerate neighbourhood (collinear nodes): skip the node
                continue
        return {"alpha": _err_summary(est[:, 0], vals[:, 0]),
                "beta": _err_summary(est[:, 1], vals[:, 1])}

    def _extra_residuals(self, data) -> dict:
        return {"leave_one_out": self.leave_one_out()} if self.with_leave_one_out else {}

    def _predict_xy(self, x, y):
        pts = np.column_stack([x, y])
        out = self._interp(pts)
        if self.extrapolate == "nearest":
            outside = ~np.isfinite(out[:, 0])
            if outside.any():
                out[outside] = self._nearest(pts[outside])
        return out[:, 0], out[:, 1]

    def _parameters(self) -> dict:
        return {"method": self.method, "extrapolate": self.extrapolate,
                "nodes": {k: np.asarray(v).tolist() for k, v in self.nodes.items()}}

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        nodes = p.get("nodes")
        n = len(nodes["x"]) if isinstance(nodes, dict) and isinstance(nodes.get("x"), list) else 0
        if n < 3:
            raise _bad("nodes.x", f"{n} nodes", "at least 3 nodes (one triangle)")
        check_parameters(p, {"nodes": dict.fromkeys(("x", "y", "alpha", "beta"), (n,))})

    @classmethod
    def _from_parameters(cls, p: dict):
        obj = cls(method=p["method"], extrapolate=p.get("extrapolate"))
        obj.nodes = {k: np.asarray(p["nodes"][k], dtype=float)
                     for k in ("x", "y", "alpha", "beta")}
        obj._build()
        return obj
