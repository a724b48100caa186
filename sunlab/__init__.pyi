"""Stub of :mod:`sunlab`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import atomic as atomic
from . import calibration as calibration
from . import centroid as centroid
from . import cli as cli
from . import course as course
from . import errors as errors
from . import export as export
from . import extras as extras
from . import geometry as geometry
from . import hardware as hardware
from . import integrity as integrity
from . import io as io
from . import multihole as multihole
from . import options as options
from . import parallel as parallel
from . import plans as plans
from . import plots as plots
from . import report as report
from . import reproduce as reproduce
from . import schema as schema
from . import screening as screening
from . import sim as sim
from . import stats as stats
from . import widgets as widgets
from .errors import ConfigurationError as ConfigurationError
from .errors import SchemaError as SchemaError
from .errors import SunlabError as SunlabError
from .options import set_options as set_options

__version__: str
__all__: list[str]
