"""The ``sunlab`` command line: :func:`main` is the ``sunlab`` entry point.

* :mod:`sunlab.cli.commands`: the parser and the subcommands that run the library
  (``reproduce``, ``simulate``, ``centroid``, ``calibrate``, ``acquire``, ``info``);
* :mod:`sunlab.cli.lab`: the lab's own bench (``import``, ``evaluate``, ``export``) and what
  they share (a CSV table's ``sensor.json``, image folders).

Every verb wraps one library function (``calibrate``: :func:`sunlab.calibration.fit`,
``evaluate``: :func:`sunlab.stats.evaluate`, tables: :func:`sunlab.io.open_centroids`); the
methods offered are read from the registry :data:`sunlab.calibration.KINDS`.

``python -m sunlab.cli`` runs the same command line.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["reproduce", "--quick"]).quick
True
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
