"""The ``sunlab`` command line: :func:`main` is the ``sunlab`` entry point.

* :mod:`sunlab.cli.commands`: the parser and the subcommands that run the library
  (``reproduce``, ``simulate``, ``centroid``, ``calibrate``, ``acquire``, ``info``);
* :mod:`sunlab.cli.lab`: the lab's own bench (``import``, ``evaluate``, ``export``) and the
  readers they share (centroid tables given as CSV, image folders).

``python -m sunlab.cli`` runs the same command line.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["reproduce", "--quick"]).quick
True
"""

from .commands import build_parser, main, run

__all__ = ["build_parser", "main", "run"]
