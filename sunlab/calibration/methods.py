"""The calibration methods the paper compares in its Table 4, each as one fitting recipe.

A recipe is ``fit(train, validation) -> Calibration``, an entry of the registry
(:data:`sunlab.calibration.registry.RECIPES`: a kind and its options) fitted through
:func:`sunlab.calibration.fit`: the ideal and optimised geometric models fit experiment I alone;
the polynomial and trigonometric orders and the networks' early stopping are chosen on
experiment II, as the paper does (docs/paper.md sec. 5), and the polynomial of the chosen order
is then fitted on I and II together (:data:`POLYNOMIAL_REFIT`); the interpolation table is
experiment I's regular grid. ``sunlab reproduce``, the bench identification
(``studies.identification``) and the platform study
(:mod:`sunlab.reproduce.fault`) all calibrate with these recipes.

Examples
--------
>>> from sunlab.calibration.methods import table4_methods
>>> list(table4_methods(neural=False))[:3]
['ideal model (1)', 'optimised model (3)-(4)', 'linear interp.']
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

from .registry import POLYNOMIAL_REFIT, RECIPES, TRIGONOMETRIC_PERIOD, fit

__all__ = ["table4_methods"]


def table4_methods(*, neural: bool = True, hidden: int = 8, seed: int = 0,
                   reference: str = "design") -> dict[str, Callable]:
    """The calibration methods compared, as ``label: fit(train, validation) -> Calibration``.

    Labels follow the paper's Table 4 where it has the method (``linear interp.``,
    ``cubic interp.``, ``polynomial``, ``NN strategy 4``); each recipe is
    ``sunlab.calibration.fit(train, kind, validation, outlier_mads=None, **options)`` with the
    kind and options of :data:`~sunlab.calibration.registry.RECIPES` (the paper screens no
    shot). ``reference`` is where model (1) of the strategy-4 network is zeroed
    (:class:`sunlab.calibration.NeuralNet`): ``"zero_pose"`` re-zeroes it on each run's
    zero-pose centroid (the tables must carry it). Strategy 4's estimate is model (1) plus a
    learned correction, model (1) used as the sensor's model whose zero a lab measures with
    each run; strategy 2's network maps model (1)'s angles to the platform's, a fixed change of
    input variables, so its model (1) stays as fitted.

    Parameters
    ----------
    neural : bool
        Include the four neural-network strategies of Table 2 (the ``neural`` extra).
    hidden : int
        Hidden tanh neurons of each network.
    seed : int
        Seed of the networks' initial weights.
    reference : {"design", "zero_pose"}
        Where model (1) of NN strategy 4 is zeroed (above); strategies 1-3 use ``"design"``.

    Returns
    -------
    dict of str to callable
        Label to ``fit(train, validation) -> Calibration``, each a picklable
        ``functools.partial`` of :func:`sunlab.calibration.fit`: ``ideal model (1)``,
        ``optimised model (3)-(4)``, ``linear interp.``, ``cubic interp.``, ``polynomial``
        (order chosen on ``validation``, refitted on both tables when :data:`POLYNOMIAL_REFIT`),
        ``trigonometric`` (order 1-4 chosen on ``validation``, period
        :data:`TRIGONOMETRIC_PERIOD`) and, with ``neural``, ``NN strategy 1`` .. ``4``; the
        tables are ``centroids/1`` with commanded angles (experiments I and II).

    Examples
    --------
    >>> sorted(table4_methods())[-1]
    'trigonometric'
    """
    methods: dict[str, Callable] = {}
    for label, (kind, options) in RECIPES.items():
        if kind == "neural":
            if not neural:
                continue
            options = {**options, "hidden": hidden, "seed": seed,
                       "reference": reference if options["strategy"] == 4 else "design"}
        methods[label] = partial(_recipe, kind=kind, options=options)
    return methods


def _recipe(train, validation, *, kind: str, options: dict):
    """One recipe: ``kind`` fitted with ``options`` on I (II for its choices), unscreened."""
    return fit(train, kind, validation, outlier_mads=None, **options)
