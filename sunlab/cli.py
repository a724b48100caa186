"""The ``sunlab`` command line.

Each subcommand has an ``_add_<name>(subparsers)`` function that declares its arguments and sets
``func`` to a ``_run_<name>(args)`` handler; handlers import what they need lazily so that
``sunlab --help`` stays fast.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["info", "cube.zarr"]).path
'cube.zarr'
"""

from __future__ import annotations

import argparse
import sys

from ._errors import SunlabError

__all__ = ["build_parser", "main"]


def _add_info(sub) -> None:
    p = sub.add_parser("info", help="print a summary of a frame cube or centroid table")
    p.add_argument("path", help="a .zarr store, a .nc file")
    p.set_defaults(func=_run_info)


def _run_info(args) -> int:
    from . import io

    print(io.summary(io.open_dataset(args.path)))
    return 0


# One adder per subcommand, in the order `sunlab --help` lists them.
_ADDERS = [_add_info]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``sunlab`` command."""
    from . import __version__

    parser = argparse.ArgumentParser(
        prog="sunlab",
        description="Reproduce, teach and extend the lab calibration of a pinhole APS sun sensor.",
    )
    parser.add_argument("--version", action="version", version=f"sunlab {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for adder in _ADDERS:
        adder(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sunlab`` console script; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except SunlabError as err:
        print(f"sunlab {args.command}: error: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"sunlab {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
