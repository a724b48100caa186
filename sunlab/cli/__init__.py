"""The ``sunlab`` command line: :func:`main` is the ``sunlab`` entry point.

One module per group of verbs, each verb a short handler around one library function:
``reproduce`` (:mod:`sunlab.reproduce`), ``simulate`` and ``acquire`` (the virtual and the real
bench), ``import``, ``centroid`` and ``info`` (frames and tables), ``calibrate``
(:func:`sunlab.calibration.fit`), ``evaluate`` (:func:`sunlab.stats.evaluate`) and ``export``,
``course``. The methods offered are read from the registry
:data:`sunlab.calibration.registry.KINDS`.
``python -m sunlab.cli`` runs the same command line.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["reproduce", "--quick"]).quick
True
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
