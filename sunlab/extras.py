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

Examples
--------
>>> require("math", "neural").pi > 3
True
"""

from __future__ import annotations

import importlib
import importlib.metadata

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
