"""Stub of :mod:`sunlab.sim`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import bench as bench
from . import centroids as centroids
from . import cube as cube
from . import detector as detector
from . import diffraction as diffraction
from . import frame as frame
from . import holes as holes
from . import mask as mask
from . import platform as platform
from . import render as render
from . import source as source
from . import spots as spots
from . import surrogate as surrogate
from .bench import Bench as Bench
from .centroids import synthetic_centroids as synthetic_centroids
from .cube import simulate as simulate
from .detector import Detector as Detector
from .frame import render_frame as render_frame
from .mask import Mask as Mask
from .platform import Platform as Platform
from .source import Source as Source

__all__: list[str]
