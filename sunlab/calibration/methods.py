"""The calibration methods the paper compares in its Table 4, each as one fitting recipe.

A recipe is ``fit(train, validation) -> Calibration``: the ideal and optimised geometric models
fit experiment I alone; the polynomial and trigonometric orders and the networks' early stopping
are chosen on experiment II, as the paper does (docs/paper.md sec. 5), and the polynomial of the
chosen order is then fitted on I and II together (:data:`POLYNOMIAL_REFIT`); the interpolation
table is experiment I's regular grid. ``sunlab reproduce``,
the bench identification (:mod:`sunlab.studies.identification`) and the platform study
(:mod:`sunlab.studies.platform_fault`) all calibrate with these recipes.

Examples
--------
>>> from sunlab.calibration.methods import table4_methods
>>> list(table4_methods(neural=False))[:3]
['ideal model (1)', 'optimised model (3)-(4)', 'linear interp.']
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..errors import ConfigurationError
from ..stats import local_errors
from .interpolation import Interpolation
from .model import IdealModel, OptimisedModel
from .neural import NeuralNet
from .polynomial import Polynomial
from .trigonometric import Trigonometric

__all__ = ["table4_methods", "TRIGONOMETRIC_PERIOD", "POLYNOMIAL_REFIT"]

#: Whether Table 4's polynomial, its order chosen on experiment II by fits on I, is fitted
#: again on I and II together: the paper's sec. 5 says II "may also be added to I for the
#: polynomial and interpolation methods". We add it to the polynomial only, a least-squares fit
#: that takes any poses; the interpolation table stays I's regular 1-degree grid (II's
#: 1.5-degree grid does not fit in it). On the virtual bench this is what lets the polynomial
#: shed part of the inner axis's zero shift between experiment I and experiments II-III that
#: the interpolations carry whole (docs/paper.md sec. 10).
POLYNOMIAL_REFIT = True

#: Period of the trigonometric expansion of Table 4, in scaled centroid units (the calibration
#: domain is [-1, 1]): 2, the classical Fourier series whose period is the domain.
#: :class:`sunlab.calibration.Trigonometric` defaults to 4 (half a period across the domain),
#: which follows a near-linear map as well as a polynomial does; notebook 05 compares them.
TRIGONOMETRIC_PERIOD = 2.0


def table4_methods(*, neural: bool = True, hidden: int = 8, seed: int = 0,
                   reference: str = "design") -> dict[str, Callable]:
    """The calibration methods compared, as ``label: fit(train, validation) -> Calibration``.

    Labels follow the paper's Table 4 where it has the method (``linear interp.``,
    ``cubic interp.``, ``polynomial``, ``NN strategy 4``). ``reference`` is where model (1) of
    the strategy-4 network is zeroed (:class:`sunlab.calibration.NeuralNet`): ``"zero_pose"``
    re-zeroes it on each run's zero-pose centroid (the tables must carry it). Strategy 4's
    estimate is model (1) plus a learned correction, model (1) used as the sensor's model
    whose zero a lab measures with each run; strategy 2's network maps model (1)'s angles
    to the platform's, a fixed change of input variables, so its model (1) stays as fitted.

    Parameters
    ----------
    neural : bool
        Include the four neural-network strategies of Table 2 (the ``neural`` extra).
    hidden : int
        Hidden tanh neurons of each network.
    seed : int
        Seed of the networks' initial weights.

    Examples
    --------
    >>> sorted(table4_methods())[-1]
    'trigonometric'
    """
    def trigonometric(order):
        return Trigonometric(order, period=TRIGONOMETRIC_PERIOD)

    def poly(train, val):
        best, _ = Polynomial.select_order(train, val, refit=POLYNOMIAL_REFIT)
        return best

    methods: dict[str, Callable] = {
        "ideal model (1)": lambda tr, va: IdealModel().fit(tr),
        "optimised model (3)-(4)": lambda tr, va: OptimisedModel().fit(tr),
        "linear interp.": lambda tr, va: Interpolation("linear").fit(tr),
        "cubic interp.": lambda tr, va: Interpolation("cubic").fit(tr),
        "polynomial": poly,
        # the classical Fourier series of the calibration domain (one period across it); the
        # paper gives no expansion, and its "much worse" is what the series' periodicity does
        # to the near-linear map from centroid to angle (docs/paper.md sec. 4.2)
        "trigonometric": lambda tr, va: _select_on_validation(trigonometric, range(1, 5), tr,
                                                              va),
    }
    if neural:
        for s in (1, 2, 3, 4):
            methods[f"NN strategy {s}"] = (
                lambda tr, va, s=s: NeuralNet(strategy=s, hidden=hidden, seed=seed,
                                              reference=reference if s == 4 else "design"
                                              ).fit(tr, va)
            )
    return methods


def _select_on_validation(make, orders, train, validation):
    """Fit ``make(order)`` for each order the training table can support; keep the one with the
    smallest mean |error| (alpha + beta) on the validation table, as the paper picks orders."""
    best, best_err = None, np.inf
    for order in orders:
        try:
            cal = make(order).fit(train, validation)
        except ConfigurationError:  # more coefficients than training points
            break
        loc = local_errors(cal.predict(validation))
        err = float(loc["local_error"].mean())
        if err < best_err:
            best, best_err = cal, err
    if best is None:
        raise ConfigurationError(
            f"train: {train.sizes['pose']} poses support no order of {make.__name__}. "
            "Fix: calibrate on more poses"
        )
    return best
