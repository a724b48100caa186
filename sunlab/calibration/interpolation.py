"""Calibration table + interpolation (docs/paper.md sec. 4.2): linear and cubic.

The calibration table is the set of nodes (mean centroid of the ok shots of each pose ->
commanded angles). The centroids of a pose grid do not lie on a grid (the mapping is
nonlinear and the platform errs), so the interpolation is over scattered data on the Delaunay
triangulation of the nodes: :class:`scipy.interpolate.LinearNDInterpolator` (piecewise linear)
and :class:`scipy.interpolate.CloughTocher2DInterpolator` (piecewise cubic, C1), both with the
inputs rescaled to the unit square. Outside the convex hull of the nodes the estimate is NaN
(no extrapolation), unless ``extrapolate="nearest"`` takes the nearest node's angles there.

Interpolation passes through the (noisy) nodes exactly; a smoothing polynomial averages the
pose-to-pose noise and so beats it on a test grid, as in the paper's Table 4.

Examples
--------
>>> import numpy as np
>>> from sunlab import geometry
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
>>> cen = geometry.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
>>> est = Interpolation("cubic").fit(cen).predict(cen)
>>> float(abs(est.alpha - est.alpha_cmd).max()) < 1e-9
True
"""

from __future__ import annotations

import numpy as np

from .._errors import ConfigurationError
from .base import Calibration, TrainingData

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

    Examples
    --------
    >>> Interpolation("linear").label
    'linear interp.'
    """

    kind = "interpolation-linear"

    def __init__(self, method: str = "linear", extrapolate: str | None = None):
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
        self.average = "pose"
        self.nodes: dict | None = None
        self._interp = None
        self._nearest = None

    @property
    def label(self) -> str:
        return f"{self.method} interp."

    def _build(self) -> None:
        from scipy.interpolate import (
            CloughTocher2DInterpolator,
            LinearNDInterpolator,
            NearestNDInterpolator,
        )

        pts = np.column_stack([self.nodes["x"], self.nodes["y"]])
        vals = np.column_stack([self.nodes["alpha"], self.nodes["beta"]])
        if len(pts) < 3:
            raise ConfigurationError(
                f"nodes: found {len(pts)} poses, expected at least 3 for a triangulation"
            )
        cls = LinearNDInterpolator if self.method == "linear" else CloughTocher2DInterpolator
        try:
            self._interp = cls(pts, vals, fill_value=np.nan, rescale=True)
        except Exception as err:  # qhull errors: collinear or duplicate nodes
            raise ConfigurationError(
                f"nodes: cannot triangulate the calibration table ({type(err).__name__}). Fix: "
                "calibrate on a 2-D grid of poses with distinct centroids"
            ) from err
        self._nearest = NearestNDInterpolator(pts, vals, rescale=True)

    def _fit(self, data: TrainingData, validation) -> None:
        self.nodes = {"x": data.x, "y": data.y, "alpha": data.alpha, "beta": data.beta}
        self._build()

    def _predict_xy(self, x, y):
        pts = np.column_stack([x, y])
        out = self._interp(pts)
        if self.extrapolate == "nearest":
            outside = ~np.isfinite(out[:, 0])
            if outside.any():
                out[outside] = self._nearest(pts[outside])
        return out[:, 0], out[:, 1]

    def _parameters(self) -> dict:
        return {
            "method": self.method,
            "extrapolate": self.extrapolate,
            "nodes": {k: np.asarray(v).tolist() for k, v in self.nodes.items()},
        }

    @classmethod
    def _from_parameters(cls, p: dict):
        obj = cls(method=p["method"], extrapolate=p.get("extrapolate"))
        nodes = {k: np.asarray(p["nodes"][k], dtype=float) for k in ("x", "y", "alpha", "beta")}
        if len({v.shape for v in nodes.values()}) != 1 or nodes["x"].ndim != 1:
            raise ValueError("nodes x, y, alpha, beta must be flat lists of equal length")
        obj.nodes = nodes
        obj._build()
        return obj
