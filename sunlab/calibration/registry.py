"""The registry of calibration methods: one table, read by the library, the CLI and the docs.

:data:`KINDS` maps the ``kind`` of a calibration artifact to its class; :func:`fit` builds and
fits a method by its kind, :func:`method_class` gives the class, and
:func:`sunlab.calibration.load` restores a saved one through the same table. This module
imports nothing heavy, so the command line can list the methods without importing numpy; a
method's module is imported when it is asked for.

Examples
--------
>>> sorted(KINDS)[:3]
['ideal', 'interpolation-cubic', 'interpolation-linear']
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ..errors import ConfigurationError

if TYPE_CHECKING:
    import xarray as xr

    from .base import Calibration

__all__ = ["KINDS", "fit", "method_class"]

#: Default outlier screening of :func:`fit` (and ``sunlab calibrate --outlier-mads``): shots
#: beyond this many MADs of a robust fit are excluded. The value of
#: :data:`sunlab.screening.N_MAD`, kept here so that the command line shows it without
#: importing numpy (a test checks that the two agree).
OUTLIER_MADS = 10.0

#: The calibration methods, registered once: ``kind`` of the artifact -> ``"module:Class"`` in
#: :mod:`sunlab.calibration`. The library (:func:`fit`, :func:`load`), the command line
#: (``sunlab calibrate --method``), the reproduction and the docs all read this table. The
#: multi-hole strategies, which calibrate a whole mask, have their own registry
#: (:data:`sunlab.multihole.strategies.STRATEGY_KINDS`).
KINDS: dict[str, str] = {
    "ideal": "model:IdealModel",
    "optimised": "model:OptimisedModel",
    "polynomial": "polynomial:Polynomial",
    "trigonometric": "trigonometric:Trigonometric",
    "interpolation-linear": "interpolation:Interpolation",
    "interpolation-cubic": "interpolation:Interpolation",
    "neural": "neural:NeuralNet",
}

#: The calibrations learned from frames rather than fitted on a centroid table: ``kind`` ->
#: ``"module:Class"``. They are fitted on frame cubes (``FrameNet.fit(train_cube, ...)``), so
#: :func:`fit` and ``sunlab calibrate`` (centroid tables) do not offer them;
#: :func:`sunlab.calibration.load` reads them through this table.
FRAME_KINDS: dict[str, str] = {
    "learned-frames": "frames:FrameNet",
}

#: Short names accepted by :func:`fit` (and ``sunlab calibrate --method``) for a kind.
ALIASES: dict[str, str] = {"linear": "interpolation-linear", "cubic": "interpolation-cubic"}


def method_class(method: str) -> type[Calibration]:
    """The class of a registered calibration method (a kind of :data:`KINDS` or an alias).

    Parameters
    ----------
    method : str
        A kind (``"polynomial"``, ``"interpolation-cubic"``, ...) or an alias (``"cubic"``).

    Returns
    -------
    type
        The :class:`~sunlab.calibration.Calibration` subclass; its module is imported now.

    Raises
    ------
    ConfigurationError
        ``method`` is not registered.

    Examples
    --------
    >>> method_class("cubic").__name__
    'Interpolation'
    """
    return _class_of(ALIASES.get(method, method))


def _class_of(kind: str, kinds: dict[str, str] | None = None) -> type[Calibration]:
    registry = KINDS if kinds is None else kinds
    if kind not in registry:
        raise ConfigurationError(
            f"method: found {kind!r}, expected one of {sorted(registry)}"
            + (f" (or {sorted(ALIASES)})" if kinds is None else "")
            + ". Fix: name a registered calibration method (sunlab.calibration.KINDS)")
    module, name = registry[kind].split(":")
    if "." not in module:
        module = f"{__package__}.{module}"
    return getattr(importlib.import_module(module), name)


def fit(table: xr.Dataset, method: str, validation: xr.Dataset | None = None, *,
        outlier_mads: float | None = OUTLIER_MADS, **options) -> Calibration:
    """Fit the calibration ``method`` on a centroid table: the one entry point of the registry.

    Parameters
    ----------
    table : xarray.Dataset
        ``centroids/1`` training table on (pose, shot) with coordinates ``alpha``, ``beta``
        (deg; experiment I in the paper), e.g. from :func:`sunlab.io.open_centroids`.
    method : str
        A kind of :data:`KINDS` (``"polynomial"``, ``"trigonometric"``,
        ``"interpolation-linear"``, ``"interpolation-cubic"``, ``"neural"``, ``"ideal"``,
        ``"optimised"``) or an alias of :data:`ALIASES` (``"linear"``, ``"cubic"``).
    validation : xarray.Dataset, optional
        Validation table (experiment II): early stopping of the networks, the order of
        ``order="auto"``, the validation residuals of the artifact.
    outlier_mads : float or None
        Screen both tables first (:func:`sunlab.screening.screen_outliers`): shots whose
        centroid lies more than this many MADs from a robust fit are excluded (default
        :data:`OUTLIER_MADS`, as ``sunlab calibrate``); 0 or None keeps every shot. The
        excluded shots are listed in ``training["excluded"]`` (and
        ``training["validation_excluded"]``): pose, shot, angles (deg), centroid (px) and their
        distance in px and MADs.
    **options
        Keywords of the method's class, e.g. ``order=3`` for :class:`Polynomial`,
        ``strategy=4, hidden=8`` for :class:`NeuralNet`. ``order="auto"`` (polynomial only,
        with ``validation``): the order the validation table prefers
        (:meth:`Polynomial.select_order`); its scores are the calibration's
        ``order_scores``.

    Returns
    -------
    Calibration
        The fitted calibration (``predict``, ``predict_xy``, ``save``).

    Raises
    ------
    ConfigurationError
        ``method`` is not registered, or an option does not apply to it.
    ImportError
        The method needs an extra that is not installed (``neural``: torch), named in the
        message.
    SchemaError
        A geometric model needs a sensor attribute (mask distance, pixel pitch, design centre)
        that the table does not carry.

    Examples
    --------
    >>> from sunlab import sim
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> fit(cen, "polynomial", order=1).label
    'polynomial(1)'
    """
    kind = ALIASES.get(method, method)
    cls = _class_of(kind)
    table, excluded = _screened(table, outlier_mads)
    if validation is not None:
        validation, val_excluded = _screened(validation, outlier_mads)
    if options.get("order") == "auto":
        cal = _auto_order(kind, table, validation, options)
    else:
        try:
            cal = cls.for_kind(kind, **options)
        except TypeError as err:  # an option the class does not take
            raise ConfigurationError(
                f"{method}: {err}. Fix: pass only the keywords of {cls.__name__} "
                f"(help(sunlab.calibration.{cls.__name__}))") from err
        cal.fit(table, validation)
    if outlier_mads:
        cal.training["outlier_mads"] = float(outlier_mads)
        cal.training["excluded"] = excluded
        if validation is not None:
            cal.training["validation_excluded"] = val_excluded
    return cal


def _screened(table, n_mad):
    """``table`` with its outliers flagged ``invalid``, and their list (nothing when off)."""
    if not n_mad:
        return table, []
    from ..screening import screen_outliers

    return screen_outliers(table, n_mad)


def _auto_order(kind: str, table, validation, options: dict):
    """``order="auto"``: the polynomial whose order the validation table prefers."""
    if kind != "polynomial":
        raise ConfigurationError(f"order: 'auto' applies to method 'polynomial', not {kind!r}. "
                                 "Fix: give an integer order")
    if validation is None:
        raise ConfigurationError("order: found 'auto' without a validation table. Fix: pass "
                                 "validation= (experiment II), or an integer order")
    rest = {k: v for k, v in options.items() if k != "order"}
    cal, scores = _class_of(kind).select_order(table, validation, **rest)
    cal.order_scores = scores
    return cal
