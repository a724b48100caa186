"""The ``sunlab`` command: its parser, and the one place where what ends a command (an error,
a signal, a closed pipe) becomes one line on stderr and an exit status.

Each verb's module adds its subcommands (``add(sub)``), each with ``func`` set to a
``run_<verb>(args)`` handler that imports what it needs lazily (``sunlab --help`` stays fast).
``--debug`` (anywhere on the line) shows the Python traceback instead of the line.

Examples
--------
>>> build_parser().parse_args(["info", "cube.zarr", "--debug"]).debug
True
"""

from __future__ import annotations

import argparse
import contextlib
import os
import sys

from ..errors import SunlabError
from . import _bench, _calibrate, _course, _files, _reproduce, _signals
from ._args import printable

__all__ = ["build_parser", "main", "run"]

#: Set when a command met a closed stdout pipe: :func:`run` then silences stdout.
_PIPE_CLOSED = False

#: What an operating-system error's message tells the user to check, by its type.
_OS_FIX = {
    PermissionError: "check the permissions of the file or folder, or choose a path you can "
                     "write to",
    FileNotFoundError: "check the path (relative paths start at the current folder)",
    IsADirectoryError: "give a file, not a folder",
    NotADirectoryError: "check the path: a part of it is a file, not a folder",
}


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``sunlab`` command.

    Returns
    -------
    argparse.ArgumentParser
        One subcommand per verb, each with ``func`` set to its handler."""
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="sunlab",
        description="Reproduce, teach and extend the lab calibration of a pinhole APS sun sensor.")
    parser.add_argument("--version", action="version", version=f"sunlab {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of an error (also after the command)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for verbs in (_reproduce, _bench, _files, _calibrate, _course):
        verbs._add(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sunlab`` console script.

    Parameters
    ----------
    argv : list of str, optional
        Arguments after ``sunlab`` (default ``sys.argv[1:]``); ``--debug`` re-raises errors.

    Returns
    -------
    int
        Exit status: 0 success, 1 an error in the inputs, files or settings (one stderr line
        naming it and the fix), 2 a bad command line, 3 an internal error, 130, 143, 129 on
        SIGINT, SIGTERM, SIGHUP (one line, temporary outputs removed, workers stopped)."""
    with contextlib.suppress(AttributeError, ValueError):  # a path that is not UTF-8 is
        sys.stdout.reconfigure(errors="backslashreplace")  # shown escaped, as on stderr
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    try:
        with _signals.interrupting(quiet=not args.debug):
            status = int(args.func(args) or 0)
            sys.stdout.flush()  # a closed pipe is reported here, not at the interpreter's exit
        return status
    except (Exception, KeyboardInterrupt) as err:  # noqa: BLE001 - never a traceback
        if args.debug:
            raise
        status, line = _ending(err)
        with contextlib.suppress(OSError):  # the terminal may be gone (SIGHUP)
            print(f"sunlab {args.command}: {line}", file=sys.stderr)
        return status


def _ending(err: BaseException) -> tuple[int, str]:
    """The exit status and the one line that say how a command ended on ``err``."""
    global _PIPE_CLOSED
    if isinstance(err, KeyboardInterrupt):
        name, status = _signals.ended_by(err)
        return status, f"interrupted by {name}"
    if isinstance(err, BrokenPipeError) and err.filename is None:  # `sunlab info X | head`
        _PIPE_CLOSED = True
        return 1, ("error: the output pipe was closed before the command finished (its reader "
                   "stopped). Fix: read the whole output, or redirect it to a file")
    text = str(err) or type(err).__name__
    if isinstance(err, OSError) and not isinstance(err, SunlabError):
        fix = _OS_FIX.get(type(err), "check the path, the free disk space and the permissions")
        text = f"{err.strerror or text}. Fix: {fix}"
        text = text if err.filename is None else f"{err.filename}: {text}"
    text = printable(" ".join(text.split()))
    if isinstance(err, SunlabError | OSError):
        return 1, f"error: {text}"
    if isinstance(err, MemoryError):  # a size the user asked for, not a bug
        return 1, (f"error: not enough memory ({text}). Fix: ask for less (a smaller frame "
                   "shape or region, fewer poses or shots) or run on a machine with more memory")
    return 3, (f"internal error: {type(err).__name__}: {text}. Fix: this is probably a bug in "
               "sunlab; run again with --debug and report the traceback")


def run() -> None:
    """The ``sunlab`` console script and ``python -m sunlab.cli``: :func:`main`, then exit with
    its status. Library code calls :func:`main`, which returns the status instead."""
    status = main()
    if _PIPE_CLOSED:  # stdout to the null device: the interpreter's last flush of the closed
        with contextlib.suppress(OSError, ValueError, AttributeError):  # pipe cannot print
            devnull = os.open(os.devnull, os.O_WRONLY)  # a second error (Python's remedy)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
    sys.exit(status)
