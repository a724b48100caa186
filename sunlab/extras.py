"""Optional dependencies: the extras of ``pip install "sunlab[...]"`` and the error that names them.

The core of sunlab (``pip install sunlab``) reads, centroids, calibrates and evaluates with numpy,
scipy, pandas, xarray, Dask and numba. A few parts need a package that only they use; each is an
extra of pyproject.toml, and importing it through :func:`require` turns a missing package into an
ImportError that says which extra brings it.

=============  =============  ====================================================
extra          package        what needs it
=============  =============  ====================================================
neural         torch          :class:`sunlab.calibration.NeuralNet` (Table 2)
hardware       serial         the ESP300/301 stage driver (:mod:`sunlab.hardware`)
widgets        ipywidgets     :class:`sunlab.widgets.HoleExplorer`
distributed    distributed    ``sunlab.parallel.compute(address=...)``, ``local_cluster``
=============  =============  ====================================================

A lab's own code plugs in through entry points (its cameras, stages and calibrations): a
plug-in that fails is named in one line (:func:`load_plugin`, :func:`open_device`), the
commonest bench fault being a device not plugged in.

Examples
--------
>>> require("math", "neural").pi > 3
True
"""

from __future__ import annotations

import contextlib
import importlib
import importlib.metadata
import sys
import weakref

from .errors import ConfigurationError

__all__ = []

#: What each plug-in loaded or device opened came from, for the messages naming it.
_MADE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

#: The extra of pyproject.toml that brings each optional top-level package.
EXTRAS = {"torch": "neural", "serial": "hardware", "ipywidgets": "widgets",
          "distributed": "distributed"}


def require(module: str, extra: str | None = None, *, purpose: str = ""):
    """Import ``module``, or raise an ImportError naming the extra that installs it.

    Parameters
    ----------
    module : str
        The module to import (``"torch"``, ``"serial"``, ``"distributed"``, ...).
    extra : str, optional
        The extra of ``sunlab`` that brings it (default: :data:`EXTRAS` of the top-level
        package).
    purpose : str, optional
        What needs it, for the message (e.g. ``"the neural-network calibration"``).

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    ImportError
        ``module`` (or a package it needs) is not installed; the message says
        ``pip install "sunlab[EXTRA]"``. The original error is chained.

    Examples
    --------
    >>> try:
    ...     require("no_such_package_xyz", "neural")
    ... except ImportError as err:
    ...     print(str(err).split(";")[1].strip())
    install it with: pip install "sunlab[neural]" (or "sunlab[all]")
    """
    top = module.partition(".")[0]
    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise ImportError(
            f"sunlab needs the optional package {top!r}{f' for {purpose}' if purpose else ''}, "
            f"which is not installed; install it with: pip install "
            f"\"sunlab[{extra or EXTRAS.get(top, 'all')}]\" (or \"sunlab[all]\")") from err


def installed_version(distribution: str) -> str | None:
    """The installed version of a distribution (``"pyserial"``), or None when it is absent;
    for provenance records that name an extra's package without importing it.

    Parameters
    ----------
    distribution : str
        The distribution's name on PyPI (``"pyserial"``).

    Returns
    -------
    str or None
        The version string of the distribution's metadata (``"3.5"``), or None.

    Examples
    --------
    >>> installed_version("no-such-distribution-xyz") is None
    True
    """
    try:
        return importlib.metadata.version(distribution)
    except importlib.metadata.PackageNotFoundError:
        return None


def entry_points(group: str) -> dict:
    """The installed entry points of ``group``, by name."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=group)}


def plugin_failed(what: str, action: str, err: BaseException, fix: str) -> ConfigurationError:
    """A lab's code that raised, named with its error, never a traceback."""
    text = " ".join(str(err).split()) or type(err).__name__
    return ConfigurationError(f"{what}: {action} ({type(err).__name__}: {text}). Fix: {fix}")


def load_plugin(ep, what: str, fix: str):
    """The object an entry point (or a ``module:attr`` spec as one) names; one that does not
    load is named."""
    try:
        loaded = ep.load()
    except (Exception, SystemExit) as err:  # noqa: BLE001 - a broken plug-in is named
        action, module = f"{ep.value!r} does not load", getattr(ep, "module", None)
        if isinstance(err, ModuleNotFoundError) and err.name == module:
            raise ConfigurationError(f"{what}: {action}: cannot import {module!r} ({err}). "
                                     "Fix: install the package that holds it, or run from its "
                                     "folder") from err
        if isinstance(err, AttributeError) and module in sys.modules:
            raise ConfigurationError(f"{what}: {action}: {ep.module!r} has no {ep.attr!r}. "
                                     "Fix: give module:Class exactly") from err
        raise plugin_failed(what, action, err, fix) from err
    dist = f" of the distribution {ep.dist.name} {ep.dist.version}" if ep.dist else ""
    with contextlib.suppress(TypeError):
        _MADE[loaded] = (f"the plug-in {ep.name!r} ({ep.group}: {ep.value}{dist})"
                         if ep.name != ep.value else ep.value)
    return loaded


def open_device(factory, protocol, members: tuple, what: str, fix: str, /, *args, **kwargs):
    """``factory(*args, **kwargs)``, checked against ``protocol`` (a runtime-checkable
    Protocol of ``members``); a factory that raises, or an object that lacks one, is named."""
    try:
        made = factory(*args, **kwargs)
    except (Exception, SystemExit) as err:  # noqa: BLE001 - the lab's device did not open
        raise plugin_failed(what, f"{getattr(factory, '__name__', factory)!s} did not open",
                            err, fix) from err
    if not isinstance(made, protocol):
        missing = [m for m in members if not hasattr(made, m)]
        raise ConfigurationError(
            f"{what}: {type(made).__name__} lacks {missing} of the {protocol.__name__} "
            f"protocol. Fix: give the class {', '.join(members)} (docs/hardware.md)")
    with contextlib.suppress(TypeError):
        _MADE[made] = _MADE.get(factory) or (f"{getattr(factory, '__module__', '')}:"
                                             f"{getattr(factory, '__qualname__', factory)}")
    return made


def plugin_name(obj) -> str:
    """``obj``'s class and the plug-in that made it (entry point and distribution, or
    ``module:Class``): what a lab user recognises and reinstalls."""
    cls = type(obj)
    with contextlib.suppress(TypeError):  # neither hashable nor weakly referable: the class
        if obj in _MADE:
            return f"{cls.__qualname__} of {_MADE[obj]}"
    return f"{cls.__module__}.{cls.__qualname__}"
