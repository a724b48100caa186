"""Stub of :mod:`sunlab.centroid`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import cube as cube
from . import estimators as estimators
from . import lattice as lattice
from . import moments as moments
from . import result as result
from . import sources as sources
from ._paper import border_mean as border_mean
from ._paper import first_hit as first_hit
from ._paper import projection_profiles as projection_profiles
from ._paper import projection_window as projection_window
from ._paper import threshold_window as threshold_window
from .crlb import crlb as crlb
from .crlb import disk_profile as disk_profile
from .cube import default_method as default_method
from .cube import locate as locate
from .cube import locate_all as locate_all
from .estimators import METHODS as METHODS
from .estimators import disk_fit as disk_fit
from .estimators import tight_window as tight_window
from .lattice import locate_spots as locate_spots
from .moments import stamp_moments as stamp_moments
from .result import Centroid as Centroid
from .sources import centroid_sources as centroid_sources

__all__: list[str]
