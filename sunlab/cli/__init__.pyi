"""Stub of :mod:`sunlab.cli`: its public names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from ._app import build_parser as build_parser
from ._app import main as main
from ._app import run as run

__all__: list[str]
