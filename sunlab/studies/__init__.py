"""Studies over the paper's tables with the virtual bench, apart from the simulator itself.

:mod:`.identification` (which bench explains the tables, under a fixed protocol), with
:mod:`.evidence` (its runs, scored and written), :mod:`.profiles` (the presets and each
fitted parameter's profile likelihood) and :mod:`.ablation` (each component of the identified
bench turned off),
:mod:`.averaging` (why averaging per-hole calibrations loses to the geometric centre) and
:mod:`.platform_fault` (the inner axis's fault that makes beta worse than alpha). Each loads
on first use.
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
