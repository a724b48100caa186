"""Stub of :mod:`sunlab.geometry`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import model as model
from ._fit import OptimisedFit as OptimisedFit
from ._fit import fit_optimised_model as fit_optimised_model
from .model import ideal_angles as ideal_angles
from .model import ideal_centroid as ideal_centroid
from .model import optimised_centroid as optimised_centroid
from .model import sun_angles as sun_angles
from .model import sun_vector as sun_vector

__all__: list[str]
