"""Stub of :mod:`sunlab.plots`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import accuracy as accuracy
from . import mask as mask
from .accuracy import error_histogram as error_histogram
from .accuracy import error_maps as error_maps
from .accuracy import error_rectangles as error_rectangles
from .mask import fig13_frame as fig13_frame
from .mask import fig14_bad_holes as fig14_bad_holes
from .mask import fig15_rectangles as fig15_rectangles
from .mask import plot_metric_map as plot_metric_map

__all__: list[str]
