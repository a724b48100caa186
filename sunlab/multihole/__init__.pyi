"""Stub of :mod:`sunlab.multihole`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import budget as budget
from . import defects as defects
from . import holes as holes
from . import review as review
from . import strategies as strategies
from .budget import error_budget as error_budget
from .budget import gain_study as gain_study
from .defects import defect_metrics as defect_metrics
from .defects import reject_bad_holes as reject_bad_holes
from .holes import centroid_free_layout as centroid_free_layout
from .strategies import GeometricCentre as GeometricCentre
from .strategies import PerHoleAverage as PerHoleAverage

__all__: list[str]
