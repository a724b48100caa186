"""sunlab: reproduce, teach and extend the laboratory calibration of a pinhole APS sun sensor.

Submodules are loaded on first use so that ``import sunlab`` stays light (no torch, no serial
ports, no widgets until asked for); ``__init__.pyi`` lists them for IDEs and type checkers. The
optional parts are extras of ``pip install "sunlab[...]"`` (:mod:`sunlab.extras`).

Examples
--------
>>> import sunlab
>>> sunlab.schema.FRAMES_SCHEMA
'frames/1'
"""

from __future__ import annotations

import importlib

from .errors import ConfigurationError, SchemaError, SunlabError
from .options import OPTIONS, set_options, show_progress

__version__ = "0.1.0"

_SUBMODULES = {
    "schema",
    "io",
    "plans",
    "sim",
    "centroid",
    "geometry",
    "calibration",
    "stats",
    "multihole",
    "hardware",
    "parallel",
    "studies",
    "export",
    "reproduce",
    "errors",
    "options",
    "extras",
    "jit",
    "atomic",
    "plots",
    "widgets",
    "cli",
}

__all__ = [
    "SunlabError",
    "SchemaError",
    "ConfigurationError",
    "OPTIONS",
    "set_options",
    "show_progress",
    "__version__",
    *sorted(_SUBMODULES),
]


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    raise AttributeError(f"module 'sunlab' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | _SUBMODULES)
