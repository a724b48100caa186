"""Stub of :mod:`sunlab.reproduce`: its public submodules and names. ``__init__.py`` reads it with
``lazy_loader.attach_stub`` (scikit-image's pattern) to load each on first use, and IDEs
and type checkers read it as the package's interface."""

from . import fault as fault
from . import intervals as intervals
from . import learned as learned
from . import learned_files as learned_files
from . import pipeline as pipeline
from . import platform as platform
from . import remedy as remedy
from . import table4 as table4
from . import table5 as table5
from .pipeline import QUICK as QUICK
from .pipeline import experiment_plans as experiment_plans
from .pipeline import locate_runs as locate_runs
from .pipeline import mounting_offset_px as mounting_offset_px
from .pipeline import simulate_and_locate as simulate_and_locate
from .platform import ROWS as ROWS
from .platform import format_platform as format_platform
from .platform import reproduce_platform as reproduce_platform
from .table4 import format_table as format_table
from .table4 import reproduce_table4 as reproduce_table4
from .table5 import COLUMNS as COLUMNS
from .table5 import REJECTION_COLUMN as REJECTION_COLUMN
from .table5 import format_table5 as format_table5
from .table5 import reproduce_table5 as reproduce_table5

__all__: list[str]
