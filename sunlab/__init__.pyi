"""Type stub of :mod:`sunlab`: the submodules load on first use (``__getattr__``), as
scikit-image's do; this stub lets IDEs and type checkers see them."""

from . import atomic as atomic
from . import calibration as calibration
from . import centroid as centroid
from . import cli as cli
from . import errors as errors
from . import export as export
from . import extras as extras
from . import geometry as geometry
from . import hardware as hardware
from . import io as io
from . import jit as jit
from . import multihole as multihole
from . import options as options
from . import parallel as parallel
from . import plans as plans
from . import plots as plots
from . import reproduce as reproduce
from . import schema as schema
from . import sim as sim
from . import stats as stats
from . import studies as studies
from . import widgets as widgets
from .errors import ConfigurationError as ConfigurationError
from .errors import SchemaError as SchemaError
from .errors import SunlabError as SunlabError
from .options import OPTIONS as OPTIONS
from .options import set_options as set_options
from .options import show_progress as show_progress

__version__: str
__all__: list[str]
