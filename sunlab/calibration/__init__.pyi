"""Stub of :mod:`sunlab.calibration`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import artifact as artifact
from . import base as base
from . import frames as frames
from . import interpolation as interpolation
from . import model as model
from . import neural as neural
from . import plausibility as plausibility
from . import polynomial as polynomial
from . import registry as registry
from . import summary as summary
from . import trigonometric as trigonometric
from . import windows as windows
from .artifact import load as load
from .base import Calibration as Calibration
from .frames import FrameNet as FrameNet
from .interpolation import Interpolation as Interpolation
from .model import IdealModel as IdealModel
from .model import OptimisedModel as OptimisedModel
from .neural import NeuralNet as NeuralNet
from .polynomial import Polynomial as Polynomial
from .registry import fit as fit
from .registry import table4_methods as table4_methods
from .trigonometric import Trigonometric as Trigonometric

__all__: list[str]
