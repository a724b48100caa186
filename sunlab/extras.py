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

import importlib
import importlib.metadata

from .errors import ConfigurationError

__all__ = []

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
    """The object an entry point names; one that does not load is named."""
    try:
        return ep.load()
    except (Exception, SystemExit) as err:  # noqa: BLE001 - a broken plug-in is named
        raise plugin_failed(what, f"the entry point {ep.value!r} does not load", err,
                            fix) from err


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
    return made
