"""Stub of :mod:`sunlab.studies`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import ablation as ablation
from . import averaging as averaging
from . import evidence as evidence
from . import identification as identification
from . import platform_fault as platform_fault
from . import profiles as profiles
from . import surrogate_tables as surrogate_tables

__all__: list[str]
