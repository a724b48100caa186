"""Stub of :mod:`sunlab.reproduce`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import fault as fault
from . import intervals as intervals
from . import learned as learned
from . import learned_files as learned_files
from . import pipeline as pipeline
from . import platform as platform
from . import remedy as remedy
from . import table4 as table4
from . import table5 as table5
from .platform import reproduce_platform as reproduce_platform
from .table4 import reproduce_table4 as reproduce_table4
from .table5 import reproduce_table5 as reproduce_table5

__all__: list[str]
