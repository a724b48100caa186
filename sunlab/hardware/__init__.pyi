"""Stub of :mod:`sunlab.hardware`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import camera as camera
from . import cameras as cameras
from . import errors as errors
from . import esp as esp
from . import fake as fake
from . import runner as runner
from . import stage as stage
from .camera import FolderCamera as FolderCamera
from .camera import SimCamera as SimCamera
from .cameras import open_camera as open_camera
from .errors import BenchError as BenchError
from .errors import MotionTimeout as MotionTimeout
from .esp import ESP300 as ESP300
from .runner import acquire as acquire
from .runner import open_run as open_run
from .stage import open_stage as open_stage

__all__: list[str]
