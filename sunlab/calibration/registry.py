"""The registry of calibration methods: one table, read by the library, the CLI and the docs.

Every kind a ``calibration/1`` file can carry is found here, the way xarray finds its backends:

* :data:`KINDS`, the single-hole methods sunlab brings (fitted on a centroid table:
  :func:`fit`, ``sunlab calibrate --method``), and :data:`FRAME_KINDS` (fitted on frame cubes);
* every calibration a package registers in the entry point group :data:`ENTRY_POINT_GROUP`
  (``pyproject.toml``: ``[project.entry-points."sunlab.calibrations"] my-kind =
  "mypkg.module:MyCalibration"``). sunlab's own multi-hole strategies, which sit in a layer
  above calibration (:mod:`sunlab.multihole`), register this way, as a lab's plug-in would.

:func:`available_kinds` lists them all, :func:`method_class` gives a kind's class, :func:`fit`
builds and fits one, and :func:`sunlab.calibration.load` restores any saved one. The paper's
Table 4 recipes are entries too (:data:`RECIPES`: a kind and its options), fitted through
:func:`fit` by :func:`sunlab.calibration.methods.table4_methods`. This module imports nothing
heavy, so the command line can list the methods without importing numpy; a method's module is
imported when it is asked for.

Examples
--------
>>> sorted(KINDS)[:3]
['ideal', 'interpolation-cubic', 'interpolation-linear']
>>> RECIPES["cubic interp."]
('interpolation-cubic', {})
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

from ..errors import ConfigurationError

if TYPE_CHECKING:
    import xarray as xr

    from .base import Calibration

__all__ = ["KINDS", "available_kinds", "fit", "method_class"]

#: Default outlier screening of :func:`fit` (and ``sunlab calibrate --outlier-mads``): shots
#: beyond this many MADs of a robust fit are excluded. The value of
#: :data:`sunlab.screening.N_MAD`, kept here so that the command line shows it without
#: importing numpy (a test checks that the two agree).
OUTLIER_MADS = 10.0

#: The single-hole calibration methods sunlab brings: ``kind`` of the artifact ->
#: ``"module:Class"`` in :mod:`sunlab.calibration`. The library (:func:`fit`, :func:`load`), the
#: command line (``sunlab calibrate --method``), the reproduction and the docs all read this
#: table; kinds from other packages (the multi-hole strategies among them) come from the entry
#: point group :data:`ENTRY_POINT_GROUP`.
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

#: The entry point group in which a package registers its calibration kinds (``kind`` ->
#: ``"module:Class"``, a :class:`~sunlab.calibration.Calibration` subclass whose ``kind`` is
#: that name). sunlab registers its multi-hole strategies here (``pyproject.toml``).
ENTRY_POINT_GROUP = "sunlab.calibrations"

#: Short names accepted by :func:`fit` (and ``sunlab calibrate --method``) for a kind.
ALIASES: dict[str, str] = {"linear": "interpolation-linear", "cubic": "interpolation-cubic"}

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

#: The paper's Table 4 recipes: column label -> (kind, options of :func:`fit`), each fitted as
#: ``fit(train, kind, validation, **options)`` (:func:`sunlab.calibration.methods.table4_methods`
#: adds the networks' size and seed). The geometric models and the interpolations are fitted on
#: experiment I; the polynomial's and the trigonometric expansion's orders are chosen on
#: experiment II (``order="auto"``), as the paper does (docs/paper.md sec. 5); the networks stop
#: early on II. The trigonometric expansion is the classical Fourier series of the calibration
#: domain (one period across it): the paper gives no expansion, and its "much worse" is what the
#: series' periodicity does to the near-linear map from centroid to angle (docs/paper.md sec.
#: 4.2).
RECIPES: dict[str, tuple[str, dict]] = {
    "ideal model (1)": ("ideal", {}),
    "optimised model (3)-(4)": ("optimised", {}),
    "linear interp.": ("interpolation-linear", {}),
    "cubic interp.": ("interpolation-cubic", {}),
    "polynomial": ("polynomial", {"order": "auto", "refit": POLYNOMIAL_REFIT}),
    "trigonometric": ("trigonometric", {"order": "auto", "orders": (1, 2, 3, 4),
                                        "period": TRIGONOMETRIC_PERIOD}),
    **{f"NN strategy {s}": ("neural", {"strategy": s}) for s in (1, 2, 3, 4)},
}


def _entry_points() -> dict:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_kinds(*, frames: bool = True) -> dict[str, str]:
    """Every calibration kind sunlab can fit or load: the built-ins and the entry points.

    Parameters
    ----------
    frames : bool
        Include :data:`FRAME_KINDS` (fitted on frame cubes, not centroid tables).

    Returns
    -------
    dict of str to str
        ``kind`` -> where its class comes from (``"module:Class"``); each loads with
        :func:`method_class`. A built-in kind is never shadowed by an entry point.

    Examples
    --------
    >>> kinds = available_kinds()
    >>> "polynomial" in kinds and "learned-frames" in kinds
    True
    """
    found = {**KINDS, **(FRAME_KINDS if frames else {})}
    found.update({name: ep.value for name, ep in _entry_points().items()
                  if name not in KINDS and name not in FRAME_KINDS})
    return found


def method_class(method: str, *, frames: bool = False) -> type[Calibration]:
    """The class of a registered calibration method: a kind of :func:`available_kinds` or an
    alias.

    Parameters
    ----------
    method : str
        A kind (``"polynomial"``, ``"interpolation-cubic"``, ``"multihole-per-hole-average"``,
        ...) or an alias (``"cubic"``).
    frames : bool
        Also look in :data:`FRAME_KINDS` (what :func:`sunlab.calibration.load` does).

    Returns
    -------
    type
        The :class:`~sunlab.calibration.Calibration` subclass; its module is imported now.

    Raises
    ------
    ConfigurationError
        ``method`` is not registered, or its entry point does not load.

    Examples
    --------
    >>> method_class("cubic").__name__
    'Interpolation'
    """
    kind = ALIASES.get(method, method)
    builtin = {**KINDS, **(FRAME_KINDS if frames else {})}
    if kind in builtin:
        module, name = builtin[kind].split(":")
        return getattr(importlib.import_module(f"{__package__}.{module}"), name)
    eps = _entry_points()
    if kind not in eps:
        raise ConfigurationError(
            f"method: found {method!r}, expected one of "
            f"{sorted(available_kinds(frames=frames))} (or {sorted(ALIASES)}). Fix: name a "
            f"registered calibration method (sunlab.calibration.available_kinds(); the "
            f"multi-hole strategies are entry points of {ENTRY_POINT_GROUP!r}: if they are "
            "missing, reinstall sunlab, e.g. pip install -e .)")
    try:
        return eps[kind].load()
    except Exception as err:  # noqa: BLE001 - a broken plug-in is named, not a traceback
        raise ConfigurationError(
            f"method {kind!r}: the entry point {eps[kind].value!r} of {ENTRY_POINT_GROUP!r} does "
            f"not load ({type(err).__name__}: {err}). Fix: install the package that provides "
            "it, or repair its code") from err


def fit(table: xr.Dataset, method: str, validation: xr.Dataset | None = None, *,
        outlier_mads: float | None = OUTLIER_MADS, **options) -> Calibration:
    """Fit the calibration ``method`` on a centroid table: the one entry point of the registry.

    Parameters
    ----------
    table : xarray.Dataset
        ``centroids/1`` training table on (pose, shot) with coordinates ``alpha``, ``beta``
        (deg; experiment I in the paper), e.g. from :func:`sunlab.io.open_centroids`; on
        (pose, shot, hole) for a multi-hole strategy.
    method : str
        A kind of :data:`KINDS` (``"polynomial"``, ``"trigonometric"``,
        ``"interpolation-linear"``, ``"interpolation-cubic"``, ``"neural"``, ``"ideal"``,
        ``"optimised"``), an alias of :data:`ALIASES` (``"linear"``, ``"cubic"``), or a kind
        of the entry point group :data:`ENTRY_POINT_GROUP` (``"multihole-geometric-centre"``,
        ``"multihole-per-hole-average"``: the paper's two strategies of sec. 6).
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
        ``strategy=4, hidden=8`` for :class:`NeuralNet`. ``order="auto"`` (a method that
        takes an ``order``, with ``validation``): the order the validation table prefers, as
        the paper chooses its orders (:meth:`Polynomial.select_order`; for another method the
        order, of ``orders`` (default 1 to 8), whose mean local error on the validation table,
        alpha + beta, is smallest); its scores are the calibration's ``order_scores``.

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
    cls = method_class(kind)
    table, excluded = _screened(table, outlier_mads)
    if validation is not None:
        validation, val_excluded = _screened(validation, outlier_mads)
    if options.get("order") == "auto":
        cal = _auto_order(cls, kind, table, validation, options)
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


def _auto_order(cls, kind: str, table, validation, options: dict):
    """``order="auto"``: the order the validation table prefers (scores in ``order_scores``)."""
    import inspect

    if "order" not in inspect.signature(cls.__init__).parameters:
        raise ConfigurationError(f"order: 'auto' applies to the methods that take an order "
                                 f"(e.g. 'polynomial', 'trigonometric'), not {kind!r}. Fix: "
                                 "drop order")
    if validation is None:
        raise ConfigurationError("order: found 'auto' without a validation table. Fix: pass "
                                 "validation= (experiment II), or an integer order")
    rest = {k: v for k, v in options.items() if k != "order"}
    if hasattr(cls, "select_order"):
        cal, scores = cls.select_order(table, validation, **rest)
    else:
        cal, scores = _select_on_validation(cls, kind, table, validation, **rest)
    cal.order_scores = scores
    return cal


def _select_on_validation(cls, kind: str, train, validation, orders=range(1, 9), **options):
    """Fit ``kind`` at each order the training table supports; keep the one with the smallest
    mean local error (alpha + beta, deg) on the validation table, as the paper picks orders.
    Returns the calibration and the error of every order tried (a DataFrame on ``order``)."""
    import pandas as pd

    from ..stats import local_errors

    best, best_err, rows = None, float("inf"), {}
    for order in orders:
        try:
            cal = cls.for_kind(kind, order=int(order), **options).fit(train, validation)
        except ConfigurationError:  # more coefficients than training points
            break
        rows[int(order)] = float(local_errors(cal.predict(validation))["local_error"].mean())
        if rows[int(order)] < best_err:
            best, best_err = cal, rows[int(order)]
    if best is None:
        raise ConfigurationError(
            f"train: {train.sizes['pose']} poses support no order of {kind!r} in "
            f"{list(orders)}. Fix: calibrate on more poses, or give lower orders")
    scores = pd.DataFrame({"mean_local_error": rows}).rename_axis("order")
    return best, scores
