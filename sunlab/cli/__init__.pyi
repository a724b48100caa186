"""Stub of :mod:`sunlab.cli`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import commands as commands
from . import lab as lab
from . import study as study
from .commands import build_parser as build_parser
from .commands import main as main
from .commands import run as run

__all__: list[str]
