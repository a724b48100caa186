"""Polynomial calibration functions of total degree n (docs/paper.md sec. 4.2).

.. math:: f(x, y) = \\sum_{k=0}^{n} \\sum_{l=0}^{k} a_{kl}\\, u^{k-l} v^{l}

one coefficient set per angle, fitted by linear least squares (:func:`numpy.linalg.lstsq`, SVD)
over the calibration poses. For conditioning the centroid is first scaled to [-1, 1] over the
training domain, :math:`u = (2x - x_{min} - x_{max}) / (x_{max} - x_{min})` and likewise
:math:`v` for y; the coefficients :math:`a_{kl}` refer to (u, v), the same polynomial space as the
paper's monomials in (x, y). The order is chosen on the validation experiment II with
:meth:`Polynomial.select_order`.

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, delta_f_mm=0.094,
...                                    mounting_deg=(1.864, 0.415, 0.0))
>>> cal = Polynomial(order=5).fit(cen)
>>> cal.residuals["alpha"]["max_abs"] < 1e-4
True
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from ..errors import ConfigurationError
from .artifact import COUNT, SPAN, _bad, check_parameters
from .base import Calibration, combine

__all__ = ["Polynomial"]


def monomial_exponents(order: int) -> list[tuple[int, int]]:
    """Exponents ``(k - l, l)`` of the monomials :math:`u^{k-l} v^l` in the paper's order.

    Parameters
    ----------
    order : int
        Total degree n of the polynomial.

    Returns
    -------
    list of (int, int)
        ``(n + 1)(n + 2) / 2`` pairs ``(k - l, l)`` for k = 0 .. n, l = 0 .. k: the powers
        of u and v of each coefficient :math:`a_{kl}`.

    Examples
    --------
    >>> monomial_exponents(2)
    [(0, 0), (1, 0), (0, 1), (2, 0), (1, 1), (0, 2)]
    """
    return [(k - l, l) for k in range(order + 1) for l in range(k + 1)]


def design_matrix(u, v, order: int) -> np.ndarray:
    """Matrix of the monomials :math:`u^{k-l} v^l`, shape ``u.shape + ((n + 1)(n + 2) / 2,)``.

    Parameters
    ----------
    u, v : array_like
        Scaled centroid coordinates (in [-1, 1] over the training domain), broadcast together.
    order : int
        Total degree n.

    Returns
    -------
    numpy.ndarray
        The columns in the order of :func:`monomial_exponents`: ``design_matrix(u, v, n) @ a``
        is the polynomial f(u, v) of docs/paper.md sec. 4.2.

    Examples
    --------
    >>> design_matrix(np.array([2.0]), np.array([3.0]), 1).tolist()
    [[1.0, 2.0, 3.0]]
    """
    u, v = np.broadcast_arrays(np.asarray(u, dtype=float), np.asarray(v, dtype=float))
    return np.stack([u**i * v**j for i, j in monomial_exponents(order)], axis=-1)


def _scale(values, bounds) -> np.ndarray:
    lo, hi = bounds
    return (2.0 * np.asarray(values, dtype=float) - (lo + hi)) / (hi - lo)


_METRICS = ("mean_abs", "rms", "max_abs")


class _Series(Calibration):
    """A linear series in the centroid scaled to [-1, 1] over the training range (px):
    ``basis(x, y, angle) @ coefficients[angle]``, fitted by least squares (the polynomial
    and the trigonometric expansion)."""

    scaling: dict | None = None
    coefficients: dict | None = None

    def _fit(self, data, validation) -> None:
        self.scaling = {k: [float(np.min(v)), float(np.max(v))]  # the spot moves (base fit)
                        for k, v in (("x", data.x), ("y", data.y))}
        # as many distinct poses as coefficients at least (min_poses, checked by the base fit)
        self.coefficients = {a: np.linalg.lstsq(self.basis(data.x, data.y, a), getattr(data, a),
                                                rcond=None)[0] for a in ("alpha", "beta")}

    def _predict_xy(self, x, y):
        return tuple(self.basis(x, y, a) @ self.coefficients[a] for a in ("alpha", "beta"))

    def _series(self) -> dict:
        return {"scaling": self.scaling,
                "coefficients": {a: np.asarray(c).tolist() for a, c in self.coefficients.items()}}

    @classmethod
    def select_order(cls, train, validation, orders=range(1, 9), *, metric: str = "mean_abs",
                     per_angle: bool = False, refit: bool = False, **options):
        """Pick the order on a validation table (experiment II), as the paper does; the tables
        are taken as given (``calibration.fit(train, kind, validation, order="auto")`` screens
        them first, then calls this).

        Parameters
        ----------
        train, validation : xarray.Dataset
            ``centroids/1`` tables (experiments I and II).
        orders : iterable of int
            Candidate total degrees.
        metric : {"mean_abs", "rms", "max_abs"}
            Per-shot validation error to minimise (``mean_abs`` is the paper's mu-like measure).
        per_angle : bool
            :class:`Polynomial`: choose the order of each angle separately; otherwise minimise
            the sum over both.
        refit : bool
            Refit the chosen order on ``train`` and ``validation`` together (the paper, sec.
            5: experiment II "may also be added to I for the polynomial"): the order is still
            chosen on II alone, by fits on I.
        **options
            Further keywords of the class (``average``; a trigonometric ``period``).

        Returns
        -------
        best : Polynomial or Trigonometric
            Fitted on ``train`` (with ``validation`` recorded), or on both with ``refit``, at
            the chosen order.
        scores : pandas.DataFrame
            Validation errors (deg) per candidate order: columns ``alpha_mean_abs`` ...
            ``beta_max_abs``.

        Examples
        --------
        >>> import numpy as np
        >>> from sunlab import sim
        >>> g = lambda s: np.meshgrid(np.arange(-17.0, 3.0, s), np.arange(-2.0, 18.0, s))
        >>> (a, b), (va, vb) = g(2.0), g(1.5)
        >>> kw = dict(delta_f_mm=0.1, mounting_deg=(1.8, 0.4, 0.0))
        >>> tr = sim.synthetic_centroids(a.ravel(), b.ravel(), **kw)
        >>> va = sim.synthetic_centroids(va.ravel(), vb.ravel(), **kw)
        >>> best, scores = Polynomial.select_order(tr, va, orders=[1, 2, 3])
        >>> best.orders, list(scores.index)
        ((3, 3), [1, 2, 3])
        """
        if metric not in _METRICS:
            raise ConfigurationError(f"metric: found {metric!r}, expected one of {_METRICS}")
        rows = {}
        for n in orders:
            try:
                cal = cls(order=int(n), **options).fit(train, outlier_mads=None)
            except ConfigurationError:
                continue
            res = cal._residuals(validation)
            rows[int(n)] = {f"{a}_{s}": res[a][s] for a in ("alpha", "beta") for s in _METRICS}
        if not rows:
            raise ConfigurationError(f"train: {train.sizes['pose']} poses support no order of "
                                     f"{cls.kind!r} in {list(orders)}. Fix: calibrate on more "
                                     "poses, or give lower orders")
        scores = pd.DataFrame.from_dict(rows, orient="index").astype(float)
        scores.index.name = "order"
        if per_angle:
            chosen = (int(scores[f"alpha_{metric}"].idxmin()),
                      int(scores[f"beta_{metric}"].idxmin()))
        else:
            chosen = int((scores[f"alpha_{metric}"] + scores[f"beta_{metric}"]).idxmin())
        fit_on = (combine(train, validation), None) if refit else (train, validation)
        return cls(order=chosen, **options).fit(*fit_on, outlier_mads=None), scores

    @staticmethod
    def _check_series(p: dict, n_alpha: int, n_beta: int) -> None:
        """Check a saved series' scaling and its ``n_alpha``, ``n_beta`` coefficients."""
        check_parameters(p, {"scaling": {"x": SPAN, "y": SPAN},
                             "coefficients": {"alpha": (n_alpha,), "beta": (n_beta,)}})

    def _read(self, p: dict):
        """Scaling and coefficients of a saved series (sizes checked by ``_check_parameters``)."""
        self.scaling = {k: [float(v[0]), float(v[1])] for k, v in p["scaling"].items()}
        self.coefficients = {a: np.asarray(p["coefficients"][a], dtype=float)
                             for a in ("alpha", "beta")}
        return self


class Polynomial(_Series):
    """Polynomial calibration of total degree n, one coefficient set per angle.

    Parameters
    ----------
    order : int or (int, int)
        Total degree n (the same for both angles, or ``(n_alpha, n_beta)``).
    average : {"pose", "shot"}
        Fit on pose-mean centroids (default) or on every ok shot.

    Notes
    -----
    docs/paper.md sec. 4.2: :math:`\\alpha = f_1(x_c, y_c)`, :math:`\\beta = f_2(x_c, y_c)` with
    :math:`f(x, y) = \\sum_{k=0}^{n}\\sum_{l=0}^{k} a_{kl} x^{k-l} y^l`, here in the scaled
    variables (u, v) of the module docstring. The paper picks n on experiment II.

    Examples
    --------
    >>> Polynomial(order=5).label
    'polynomial(5)'
    """

    kind = "polynomial"

    def __init__(self, order=5, average: str = "pose"):
        super().__init__()
        orders = (order, order) if np.ndim(order) == 0 else tuple(order)
        if len(orders) != 2 or any(int(n) != n or n < 0 for n in orders):
            raise ConfigurationError(
                f"order: found {order!r}, expected a non-negative integer or a pair (alpha, "
                "beta). Fix: e.g. order=5 or order=(5, 6)")
        self.orders = int(orders[0]), int(orders[1])
        self.average = average

    @property
    def label(self) -> str:
        na, nb = self.orders
        return f"polynomial({na})" if na == nb else f"polynomial({na},{nb})"

    def min_poses(self) -> int:
        """Fewest distinct training poses: one per coefficient of the larger polynomial.

        Returns
        -------
        int
            ``(n + 1)(n + 2) / 2`` for the larger order n of ``(n_alpha, n_beta)``.
        """
        return max(len(monomial_exponents(n)) for n in self.orders)

    def basis(self, x, y, angle: str = "beta") -> np.ndarray:
        """The design matrix of centroids ``x``, ``y`` (px) for one angle's polynomial: the
        monomials of the fitted calibration's scaled coordinates, so that
        ``basis(x, y, angle) @ coefficients[angle]`` is its prediction (a joint fit such as
        :func:`sunlab.reproduce.remedy.fit_correction` adds its own columns beside them).

        Parameters
        ----------
        x, y : array_like
            Centroids, px (x = column, y = row), same shape.
        angle : {"alpha", "beta"}
            Whose order (and scaling) to use.

        Returns
        -------
        numpy.ndarray
            Shape ``x.shape + ((n + 1)(n + 2) / 2,)`` for that angle's order n.

        Examples
        --------
        >>> from sunlab import sim
        >>> cal = Polynomial(2).fit(sim.synthetic_centroids([0.0, -5, -10, 0, -5, -10],
        ...                                                      [0.0, 0, 0, 5, 5, 5]))
        >>> cal.basis([100.0, 200.0], [50.0, 60.0], "alpha").shape
        (2, 6)
        """
        u, v = _scale(x, self.scaling["x"]), _scale(y, self.scaling["y"])
        return design_matrix(u, v, self.orders[("alpha", "beta").index(angle)])

    def _parameters(self) -> dict:
        return {
            "order": list(self.orders),
            "basis": "monomials u^(k-l) v^l, k = 0..n, l = 0..k, u = (2x - x_min - x_max) / "
                     "(x_max - x_min), v likewise for y",
            **self._series(),
        }

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        order = p.get("order")
        orders = order if isinstance(order, list) else [order]
        if len(orders) not in (1, 2):
            raise _bad("order", order, "an integer or [order_alpha, order_beta]")
        for n in orders:
            check_parameters({"order": n}, {"order": COUNT})
        cls._check_series(p, *((n + 1) * (n + 2) // 2 for n in orders * (3 - len(orders))))

    @classmethod
    def _from_parameters(cls, p: dict):
        return cls(order=tuple(p["order"]))._read(p)
