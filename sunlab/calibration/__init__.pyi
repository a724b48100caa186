"""Type stub of :mod:`sunlab.calibration`: its names load on first use (``__getattr__``);
this stub lets IDEs and type checkers see them."""

from .artifact import from_dict as from_dict
from .artifact import load as load
from .base import Calibration as Calibration
from .base import TrainingData as TrainingData
from .base import combine as combine
from .base import training_data as training_data
from .frames import FrameNet as FrameNet
from .interpolation import Interpolation as Interpolation
from .methods import table4_methods as table4_methods
from .model import IdealModel as IdealModel
from .model import OptimisedModel as OptimisedModel
from .neural import NeuralNet as NeuralNet
from .polynomial import Polynomial as Polynomial
from .registry import ALIASES as ALIASES
from .registry import FRAME_KINDS as FRAME_KINDS
from .registry import KINDS as KINDS
from .registry import available_kinds as available_kinds
from .registry import fit as fit
from .registry import method_class as method_class
from .summary import calibration_summary as calibration_summary
from .trigonometric import Trigonometric as Trigonometric

__all__: list[str]
