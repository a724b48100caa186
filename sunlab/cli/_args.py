r"""What the verbs share: a subcommand with the common options, argument types whose message
names the value found and the one expected, the check of an output path before the work, and
the escaping of text read from a file before a terminal shows it.

Examples
--------
>>> import argparse
>>> POSITIVE("3"), SECONDS("0.5")
(3, 0.5)
>>> try:
...     WORKERS("0")
... except argparse.ArgumentTypeError as err:
...     print(err)
found 0, expected an integer >= 1 and <= 1024
>>> printable("mask \x1b[2J 100 holes")
'mask \\x1b[2J 100 holes'
"""

from __future__ import annotations

import argparse
import math

__all__: list[str] = []

#: ``--debug`` on every subcommand (``sunlab info X --debug`` as ``sunlab --debug info X``).
_DEBUG = argparse.ArgumentParser(add_help=False)
_DEBUG.add_argument("--debug", action="store_true", default=argparse.SUPPRESS,
                    help="show the Python traceback of an error")


def verb(sub, name: str, run, help: str, description: str | None = None, *,
         progress: bool = False, overwrite: str | None = None) -> argparse.ArgumentParser:
    """Add the subcommand ``name`` whose handler is ``run(args)``; with ``progress`` it takes
    ``--no-progress``, with ``overwrite`` (what it replaces) ``--overwrite``."""
    p = sub.add_parser(name, help=help, description=description, parents=[_DEBUG])
    if progress:
        p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    if overwrite:
        p.add_argument("--overwrite", action="store_true", help=f"replace {overwrite}")
    p.set_defaults(func=run)
    return p


def typed(kind, ok, expected: str):
    """An argparse type: ``kind(text)`` if ``ok`` holds for it, else an error ``found X,
    expected EXPECTED`` (argparse prefixes the option)."""

    def parse(text: str):
        try:
            value = kind(text)
        except ValueError:
            value = None
        if value is None or not ok(value):
            shown = value if kind is int and value is not None else repr(text)
            raise argparse.ArgumentTypeError(f"found {shown}, expected {expected}")
        return value

    return parse


def integer(low: int, high: int | None = None):
    """An argparse type: an integer >= ``low`` (and <= ``high``)."""
    return typed(int, lambda v: low <= v <= (math.inf if high is None else high),
                 f"an integer >= {low}" + ("" if high is None else f" and <= {high}"))


POSITIVE = integer(1)
SEED = integer(0, 2**32 - 1)  # what numpy, Dask and torch all take
SHOTS = integer(1, 10_000)  # frames per pose, threads, processes: bounded so that a typo
WORKERS = integer(1, 1024)  # cannot exhaust the machine (outputs: check_out's nbytes)
SECONDS = typed(float, lambda v: 0 <= v < math.inf, "finite seconds >= 0")


def check_out(path, overwrite: bool, kind: str = "auto", nbytes: int = 0) -> None:
    """Check an output path before the work starts (its folder, permissions, an existing
    output, its size of ``nbytes`` uncompressed against the free space); ``kind`` ``"auto"``:
    a NetCDF file by its suffix, else a Zarr store."""
    from pathlib import Path

    from .. import atomic, io

    if kind == "auto":
        kind = "file" if Path(path).suffix.lower() in io.write.NETCDF_SUFFIXES else "zarr"
    atomic.check_target(path, overwrite=overwrite, kind=kind, flag="--overwrite", nbytes=nbytes)


def printable(text: str, keep: str = "") -> str:
    r"""``text`` with every control character but those in ``keep`` escaped (ESC as ``\x1b``):
    what a file holds is shown to a terminal, never run by it."""
    return "".join(c if c.isprintable() or c in keep
                   else c.encode("unicode_escape").decode("ascii") for c in text)
