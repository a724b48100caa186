"""How a command ends on a signal: SIGINT, SIGTERM and SIGHUP raise in the main thread so that
every ``finally`` runs (temporary outputs removed, workers stopped), then
:func:`sunlab.cli.main` prints one line and exits with 128 + the signal's number."""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import sys
import threading

__all__: list[str] = []

_LOG = logging.getLogger("sunlab")


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C so that every ``finally`` runs."""

    name, status = "SIGTERM", 143


class _HungUp(_Terminated):
    """SIGHUP (the terminal or the SSH session closed): cleaned up as SIGTERM is."""

    name, status = "SIGHUP", 129


#: The signals that end a command cleanly, and the exception each raises.
_RAISES = {signal.SIGINT: KeyboardInterrupt, signal.SIGTERM: _Terminated}
if hasattr(signal, "SIGHUP"):
    _RAISES[signal.SIGHUP] = _HungUp


def ended_by(err: KeyboardInterrupt) -> tuple[str, int]:
    """The name of the signal behind ``err`` and the exit status (128 + its number)."""
    return getattr(err, "name", "Ctrl-C (SIGINT)"), getattr(err, "status", 130)


@contextlib.contextmanager
def interrupting(quiet: bool = True):
    """While a command runs (main thread only): SIGINT, SIGTERM and SIGHUP raise (whatever
    handler the caller had; restored after); with ``quiet``, errors that extensions print from
    destructors, and asyncio's log of an interrupted dask.distributed client, are logged.

    A signal that arrives while the main thread imports a module is sent again 50 ms later, so
    it is raised once the import is over: an exception inside an import can leave other
    threads' import locks held (a deadlock), and a library's bare ``except:`` around an import
    would swallow it. A command that returns although a signal came (a library swallowed it)
    raises the signal's exception on the way out."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    received: list[int] = []

    def on_signal(signum, frame):
        received.append(signum)
        if _importing(frame):
            timer = threading.Timer(0.05, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
            return
        raise _RAISES[signum]

    previous = {sig: signal.signal(sig, on_signal) for sig in _RAISES}
    hooks, loop_log = (sys.unraisablehook, sys.excepthook), logging.getLogger("asyncio")
    was_disabled = loop_log.disabled
    if quiet:
        sys.unraisablehook = lambda info: _LOG.debug("ignored in %r: %s", info.object,
                                                     info.exc_value)
        sys.excepthook = lambda kind, value, tb: _LOG.debug("ignored: %s: %s", kind.__name__,
                                                            value)
        loop_log.disabled = True
    try:
        yield
    finally:
        sys.unraisablehook, sys.excepthook = hooks
        loop_log.disabled = was_disabled
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    if received:
        raise _RAISES[received[0]]


def _importing(frame) -> bool:
    """Whether ``frame`` or one of its callers runs Python's import machinery."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False
