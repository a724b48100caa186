"""Stub of :mod:`sunlab.io`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import calframes as calframes
from . import chunks as chunks
from . import codec as codec
from . import csvtable as csvtable
from . import describe as describe
from . import folder as folder
from . import images as images
from . import read as read
from . import sensor as sensor
from . import write as write
from .calframes import corrected_frames as corrected_frames
from .calframes import corrected_saturation as corrected_saturation
from .calframes import with_calibration_frames as with_calibration_frames
from .describe import summary as summary
from .folder import example_folder as example_folder
from .images import read_image as read_image
from .read import open_centroids as open_centroids
from .read import open_frames as open_frames
from .write import save_centroids as save_centroids
from .write import save_frames as save_frames

__all__: list[str]
