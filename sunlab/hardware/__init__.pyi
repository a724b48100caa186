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
from .cameras import Camera as Camera
from .cameras import ControlledCamera as ControlledCamera
from .cameras import available_cameras as available_cameras
from .cameras import capture_darks as capture_darks
from .cameras import open_camera as open_camera
from .errors import BenchError as BenchError
from .errors import CameraError as CameraError
from .errors import ControllerError as ControllerError
from .errors import ControllerLimitError as ControllerLimitError
from .errors import ErrorReplyLost as ErrorReplyLost
from .errors import LimitError as LimitError
from .errors import MotionTimeout as MotionTimeout
from .errors import StageError as StageError
from .esp import ESP300 as ESP300
from .fake import FakeESP as FakeESP
from .runner import acquire as acquire
from .runner import open_run as open_run
from .stage import Stage as Stage
from .stage import open_stage as open_stage

__all__: list[str]
