"""The registry of calibration methods: one table, read by the library, the CLI and the docs.

Every kind a ``calibration/1`` file can carry is found here, the way xarray finds its backends:
:data:`KINDS` (single-hole methods fitted on a centroid table), :data:`FRAME_KINDS` (fitted on
frame cubes), and every calibration a package registers in the entry point group
:data:`ENTRY_POINT_GROUP` (``pyproject.toml``: ``[project.entry-points."sunlab.calibrations"]
my-kind = "mypkg.module:MyCalibration"``; sunlab's own multi-hole strategies register this
way). :func:`available_kinds` lists them, :func:`method_class` gives a kind's class, :func:`fit`
builds and fits one, and :func:`sunlab.calibration.load` restores any saved one. The paper's
Table 4 recipes are entries too (:data:`RECIPES`), fitted through :func:`fit` by
:func:`table4_methods`. This module imports nothing heavy at import time, so the command line
lists the methods without numpy.

Examples
--------
>>> sorted(KINDS)[:3]
['ideal', 'interpolation-cubic', 'interpolation-linear']
>>> RECIPES["cubic interp."]
('interpolation-cubic', {})
>>> list(table4_methods(neural=False))[:3]
['ideal model (1)', 'optimised model (3)-(4)', 'linear interp.']
"""

from __future__ import annotations

import functools
import importlib
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

from ..errors import ConfigurationError, SunlabError
from ..extras import entry_points, load_plugin, plugin_failed

if TYPE_CHECKING:
    import xarray as xr

    from .base import Calibration

__all__ = ["fit", "table4_methods"]

#: Default outlier screening of every fit (``Calibration.fit``, :func:`fit`, ``sunlab calibrate
#: --outlier-mads``), in MADs: :data:`sunlab.screening.N_MAD`, kept here so that the command line
#: shows it without importing numpy (a test checks that the two agree).
OUTLIER_MADS = 10.0

#: The single-hole calibration methods sunlab brings: ``kind`` -> ``"module:Class"`` in
#: :mod:`sunlab.calibration`.
KINDS: dict[str, str] = {
    "ideal": "model:IdealModel",
    "optimised": "model:OptimisedModel",
    "polynomial": "polynomial:Polynomial",
    "trigonometric": "trigonometric:Trigonometric",
    "interpolation-linear": "interpolation:Interpolation",
    "interpolation-cubic": "interpolation:Interpolation",
    "neural": "neural:NeuralNet",
}

#: Calibrations learned from frame cubes (``FrameNet.fit(train_cube, ...)``), not centroid
#: tables: :func:`fit` and ``sunlab calibrate`` do not offer them; ``load`` reads them.
FRAME_KINDS: dict[str, str] = {"learned-frames": "frames:FrameNet"}

#: The entry point group in which a package registers its calibration kinds.
ENTRY_POINT_GROUP = "sunlab.calibrations"

#: Short names accepted by :func:`fit` (and ``sunlab calibrate --method``) for a kind.
ALIASES: dict[str, str] = {"linear": "interpolation-linear", "cubic": "interpolation-cubic"}

#: Whether Table 4's polynomial, its order chosen on experiment II by fits on I, is fitted
#: again on I and II together (the paper's sec. 5: II "may also be added to I for the
#: polynomial and interpolation methods"; the interpolation table stays I's 1-degree grid).
POLYNOMIAL_REFIT = True

#: Period of Table 4's trigonometric expansion in scaled centroid units (the domain is
#: [-1, 1]): 2, the classical Fourier series; the class's own default is 4 (notebook 05).
TRIGONOMETRIC_PERIOD = 2.0

#: The paper's Table 4 recipes: column label -> (kind, options of :func:`fit`). The geometric
#: models and the interpolations are fitted on experiment I; the polynomial's and the
#: trigonometric expansion's orders are chosen on experiment II (``order="auto"``), as the
#: paper does (docs/paper.md sec. 5); the networks stop early on II.
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


#: What a plug-in's class must define beyond :class:`~sunlab.calibration.Calibration` (one
#: name of each group): the fit, the map, and the parameters written and read back.
PLUGIN_INTERFACE = (("_fit", "_fit_tables"), ("_predict_xy", "predict_xy"), ("_parameters",),
                    ("_from_parameters",))
_FIX = ("install the package that provides it, or repair its code (a calibration plug-in is "
        "a sunlab.calibration.Calibration subclass: help(sunlab.calibration.Calibration))")


#: The methods sunlab calls on a calibration: those a plug-in's class (one defined outside
#: sunlab) defines have their exceptions turned into one line naming the class.
_CALLS = ("fit", "predict", "predict_xy", "_fit", "_fit_tables", "_predict_xy", "_parameters",
          "_check_parameters", "_from_parameters", "min_poses", "inside")


def name_plugin_errors(cls) -> None:
    """Wrap the :data:`_CALLS` that a class defined outside sunlab defines, so that an
    exception in its code (not a :class:`~sunlab.errors.SunlabError`) becomes one
    :class:`~sunlab.errors.ConfigurationError` naming the class (``Calibration`` calls it on
    every subclass)."""
    if cls.__module__.partition(".")[0] == "sunlab":
        return
    for name in set(_CALLS) & set(vars(cls)):
        method = vars(cls)[name]
        func = getattr(method, "__func__", method)  # a classmethod's function

        @functools.wraps(func)
        def call(*args, _func=func, _name=name, **kwargs):
            try:
                return _func(*args, **kwargs)
            except SunlabError:
                raise
            except Exception as err:  # noqa: BLE001 - a plug-in's fault, named in one line
                raise plugin_failed(f"calibration plug-in {cls.__module__}:{cls.__qualname__}",
                                    f"{_name} raised", err, "repair the plug-in's code, or "
                                    "calibrate with a built-in kind") from err
        setattr(cls, name, classmethod(call) if isinstance(method, classmethod) else call)


def _plugin_class(ep) -> type[Calibration]:
    """The class of a calibration entry point, checked against :data:`PLUGIN_INTERFACE` when it
    is loaded (not by an AttributeError in the middle of a fit)."""
    from .base import Calibration

    what = f"calibration plug-in {ep.name!r} ({ep.value})"
    cls = load_plugin(ep, what, _FIX)
    if not (isinstance(cls, type) and issubclass(cls, Calibration)):
        raise ConfigurationError(f"{what}: {cls!r} is not a Calibration subclass. Fix: {_FIX}")
    own = set().union(*(vars(k) for k in cls.__mro__[:cls.__mro__.index(Calibration)]))
    missing = [" or ".join(names) for names in PLUGIN_INTERFACE if own.isdisjoint(names)]
    if missing:
        raise ConfigurationError(f"{what}: {cls.__name__} lacks {missing} of the Calibration "
                                 f"interface. Fix: {_FIX}")
    return cls


def available_kinds(*, frames: bool = True) -> dict[str, str]:
    """Every calibration kind sunlab can fit or load: the built-ins and the entry points.

    Parameters
    ----------
    frames : bool
        Include :data:`FRAME_KINDS` (fitted on frame cubes, not centroid tables).

    Returns
    -------
    dict of str to str
        ``kind`` -> where its class comes from (``"module:Class"``); a built-in kind is never
        shadowed by an entry point.

    Examples
    --------
    >>> kinds = available_kinds()
    >>> "polynomial" in kinds and "learned-frames" in kinds
    True
    """
    found = {**KINDS, **(FRAME_KINDS if frames else {})}
    return found | {k: ep.value for k, ep in entry_points(ENTRY_POINT_GROUP).items()
                    if k not in KINDS and k not in FRAME_KINDS}


def method_class(method: str, *, frames: bool = False) -> type[Calibration]:
    """The class of a registered calibration method: a kind of :func:`available_kinds` or an
    alias.

    Parameters
    ----------
    method : str
        A kind (``"polynomial"``, ``"multihole-per-hole-average"``, ...) or an alias.
    frames : bool
        Also look in :data:`FRAME_KINDS` (what :func:`sunlab.calibration.load` does).

    Returns
    -------
    type
        The :class:`~sunlab.calibration.Calibration` subclass; its module is imported now.

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
    eps = entry_points(ENTRY_POINT_GROUP)
    if kind not in eps:
        raise ConfigurationError(
            f"method: found {method!r}, expected one of "
            f"{sorted(available_kinds(frames=frames))} (or {sorted(ALIASES)}). Fix: name a "
            f"registered calibration method (sunlab.calibration.registry.available_kinds(); the "
            f"multi-hole strategies are entry points of {ENTRY_POINT_GROUP!r}: if they are "
            "missing, reinstall sunlab, e.g. pip install -e .)")
    return _plugin_class(eps[kind])


def fit(table: xr.Dataset, method: str, validation: xr.Dataset | None = None, *,
        outlier_mads: float | str | None = "default", **options) -> Calibration:
    """Fit the calibration ``method`` on a centroid table: ``method_class(method)(**options)
    .fit(table, validation, outlier_mads=outlier_mads)``, the same result as the class's own
    ``fit``.

    Parameters
    ----------
    table : xarray.Dataset
        ``centroids/1`` training table on (pose, shot) with coordinates ``alpha``, ``beta``
        (deg; experiment I), e.g. from :func:`sunlab.io.open_centroids`; on (pose, shot, hole)
        for a multi-hole strategy.
    method : str
        A kind of :data:`KINDS`, an alias of :data:`ALIASES` (``"linear"``, ``"cubic"``), or a
        kind of the entry point group :data:`ENTRY_POINT_GROUP` (the multi-hole strategies
        ``"multihole-geometric-centre"``, ``"multihole-per-hole-average"``).
    validation : xarray.Dataset, optional
        Validation table (experiment II): early stopping of the networks, the order of
        ``order="auto"``, the validation residuals of the artifact.
    outlier_mads : float or None
        Outlier screening of both tables (:meth:`Calibration.fit`); ``"default"`` is the
        class's, :data:`OUTLIER_MADS` for the single-hole methods; 0 or None keeps every shot.
    **options
        Keywords of the method's class, e.g. ``order=3``. ``order="auto"`` (with
        ``validation``, a polynomial or trigonometric method): the order the validation table
        prefers (:meth:`Polynomial.select_order`, whose keywords ``orders``, ``per_angle``,
        ``refit`` apply); its scores are ``order_scores``.

    Returns
    -------
    Calibration
        The fitted calibration.

    Examples
    --------
    >>> from sunlab import sim
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> fit(cen, "polynomial", order=1).label
    'polynomial(1)'
    """
    kind = ALIASES.get(method, method)
    cls = method_class(kind)
    if kind.startswith("interpolation-"):
        options = {"method": kind.removeprefix("interpolation-"), **options}
    if options.get("order") == "auto":  # the order the validation table prefers
        from .base import _screen

        if not hasattr(cls, "select_order"):
            raise ConfigurationError(f"order: 'auto' applies to the methods that choose their "
                                     f"order (select_order: 'polynomial', 'trigonometric'), not "
                                     f"{kind!r}. Fix: drop order, or give an integer")
        if validation is None:
            raise ConfigurationError("order: found 'auto' without a validation table. Fix: "
                                     "pass validation= (experiment II), or an integer order")
        table, validation, screened = _screen(table, validation, outlier_mads,
                                              cls.default_outlier_mads)  # once, for all orders
        cal, cal.order_scores = cls.select_order(
            table, validation, **{k: v for k, v in options.items() if k != "order"})
        cal.training.update(screened)
        return cal
    try:
        cal = cls(**options)
    except TypeError as err:  # an option the class does not take
        raise ConfigurationError(f"{method}: {err}. Fix: pass only the keywords of "
                                 f"{cls.__name__} (help(sunlab.calibration.{cls.__name__}))"
                                 ) from err
    return cal.fit(table, validation, outlier_mads=outlier_mads)


def table4_methods(*, neural: bool = True, hidden: int = 8, seed: int = 0,
                   reference: str = "design") -> dict[str, Callable]:
    """The calibration methods the paper compares in its Table 4, as
    ``label: fit(train, validation) -> Calibration``.

    Each recipe is ``fit(train, kind, validation, outlier_mads=None, **options)`` with the kind
    and options of :data:`RECIPES` (the paper screens no shot). ``reference`` is where model (1)
    of the strategy-4 network is zeroed (:class:`sunlab.calibration.NeuralNet`): ``"zero_pose"``
    re-zeroes it on each run's zero-pose centroid; strategies 1-3 keep ``"design"``.
    ``sunlab reproduce``, the bench identification and the platform study calibrate with these.

    Parameters
    ----------
    neural : bool
        Include the four neural-network strategies of Table 2 (the ``neural`` extra).
    hidden : int
        Hidden tanh neurons of each network.
    seed : int
        Seed of the networks' initial weights.
    reference : {"design", "zero_pose"}
        Where model (1) of NN strategy 4 is zeroed.

    Returns
    -------
    dict of str to callable
        Label to a picklable ``functools.partial`` of :func:`fit`: ``ideal model (1)``,
        ``optimised model (3)-(4)``, ``linear interp.``, ``cubic interp.``, ``polynomial``
        (order chosen on ``validation``, refitted on both tables when :data:`POLYNOMIAL_REFIT`),
        ``trigonometric`` and, with ``neural``, ``NN strategy 1`` .. ``4``.

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
