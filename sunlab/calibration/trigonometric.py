"""Trigonometric (2-D Fourier) calibration functions (docs/paper.md sec. 4.2, "much worse").

.. math:: f(u, v) = \\sum_{i=0}^{2n} \\sum_{j=0}^{2n} c_{ij}\\, \\phi_i(u)\\, \\phi_j(v), \\qquad
          \\phi \\in \\{1, \\cos(k\\omega u), \\sin(k\\omega u)\\}_{k=1..n}, \\quad
          \\omega = 2\\pi / P

a tensor-product Fourier series of order n in the centroid scaled to [-1, 1] over the training
domain (as for :mod:`~sunlab.calibration.polynomial`), fitted by linear least squares. The
paper does not give its expansion; we use the period P = 4 (the domain spans half a period), so
the fitted function need not repeat across the domain; ``period=2`` is the classical periodic
series, which forces equal values on opposite edges and is worse still.

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
>>> cal = Trigonometric(order=3).fit(cen)
>>> cal.residuals["alpha"]["mean_abs"] < 0.05
True
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigurationError
from .artifact import COUNT, POSITIVE, check_parameters
from .polynomial import _scale, _Series

__all__ = ["Trigonometric"]


def fourier_basis(u, order: int, period: float = 4.0) -> np.ndarray:
    """1-D Fourier basis ``[1, cos(w u), sin(w u), ..., cos(n w u), sin(n w u)]``, w = 2 pi / P.

    Parameters
    ----------
    u : array_like
        Scaled centroid coordinate (the training domain is [-1, 1]).
    order : int
        Highest harmonic n.
    period : float
        Period P, in scaled units.

    Returns
    -------
    numpy.ndarray
        Shape ``u.shape + (2n + 1,)``.

    Examples
    --------
    >>> fourier_basis(np.array([0.0]), 2).tolist()
    [[1.0, 1.0, 0.0, 1.0, 0.0]]
    """
    u = np.asarray(u, dtype=float)
    w = 2.0 * np.pi / period
    cols = [np.ones_like(u)]
    for k in range(1, order + 1):
        cols += [np.cos(k * w * u), np.sin(k * w * u)]
    return np.stack(cols, axis=-1)


class Trigonometric(_Series):
    """2-D Fourier-series calibration, one coefficient set per angle.

    Parameters
    ----------
    order : int
        Highest harmonic n per axis; ``(2n + 1)**2`` coefficients per angle.
    period : float
        Period P in scaled units (the training domain is [-1, 1]).
    average : {"pose", "shot"}
        Fit on pose-mean centroids (default) or on every ok shot.

    Examples
    --------
    >>> Trigonometric(order=4).label
    'trigonometric(4)'
    """

    kind = "trigonometric"

    def __init__(self, order: int = 4, period: float = 4.0, average: str = "pose"):
        super().__init__()
        if int(order) != order or order < 0:
            raise ConfigurationError(f"order: found {order!r}, expected a non-negative integer")
        if not float(period) > 0:
            raise ConfigurationError(f"period: found {period!r}, expected > 0 (scaled units)")
        self.order = int(order)
        self.period = float(period)
        self.average = average

    @property
    def label(self) -> str:
        return f"trigonometric({self.order})"

    def basis(self, x, y, angle: str = "beta") -> np.ndarray:
        """The design matrix of centroids ``x``, ``y`` (px): the tensor products of the 1-D
        bases (:func:`fourier_basis`) of the scaled coordinates, the same for both angles.

        Returns
        -------
        numpy.ndarray
            Shape ``(x.size, (2n + 1)**2)``.
        """
        bu = fourier_basis(_scale(x, self.scaling["x"]), self.order, self.period)
        bv = fourier_basis(_scale(y, self.scaling["y"]), self.order, self.period)
        return (bu[:, :, None] * bv[:, None, :]).reshape(len(bu), -1)

    def min_poses(self) -> int:
        """Fewest distinct training poses: one per coefficient of the 2-D series.

        Returns
        -------
        int
            ``(2n + 1)**2``, the tensor product of two 1-D bases of order n.
        """
        return (2 * self.order + 1) ** 2

    def _parameters(self) -> dict:
        return {
            "order": self.order,
            "period": self.period,
            "basis": "tensor product of [1, cos(k w u), sin(k w u)] k=1..n in u and v, "
                     "w = 2 pi / period, u, v scaled to [-1, 1]",
            **self._series(),
        }

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        check_parameters(p, {"order": COUNT, "period": (POSITIVE,)})
        cls._check_series(p, (2 * p["order"] + 1) ** 2, (2 * p["order"] + 1) ** 2)

    @classmethod
    def _from_parameters(cls, p: dict):
        return cls(order=int(p["order"]), period=float(p["period"]))._read(p)
