"""Stub of :mod:`sunlab.course`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import batch as batch
from . import capstone as capstone
from . import editions as editions
from . import grading as grading
from . import hidden as hidden
from . import kernel as kernel
from . import probe as probe
from . import wire as wire
from .editions import write_course as write_course
from .grading import grade as grade
from .grading import write_gradebook as write_gradebook

__all__: list[str]
