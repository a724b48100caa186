"""How a command ends on a signal: SIGINT, SIGTERM and SIGHUP raise in the main thread so that
every ``finally`` runs (temporary outputs removed, workers stopped), then
:func:`sunlab.cli.main` prints one line and exits with 128 + the signal's number."""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading

__all__: list[str] = []


class _Terminated(KeyboardInterrupt):
    """SIGTERM, raised in the main thread like Ctrl-C so that every ``finally`` (temporary
    outputs removed, workers stopped, an acquisition's record closed) runs."""


class _HungUp(_Terminated):
    """SIGHUP (the terminal or the SSH session closed): cleaned up as SIGTERM is."""


#: The signals that end a command cleanly: name, the exception raised, the exit status.
_ENDING = {signal.SIGTERM: ("SIGTERM", _Terminated, 143),
           signal.SIGINT: ("Ctrl-C (SIGINT)", KeyboardInterrupt, 130)}
if hasattr(signal, "SIGHUP"):
    _ENDING[signal.SIGHUP] = ("SIGHUP", _HungUp, 129)


def _ended_by(err: KeyboardInterrupt) -> tuple[str, int]:
    """The name of the signal behind ``err`` and the exit status (128 + its number)."""
    for name, kind, status in sorted(_ENDING.values(), key=lambda v: -v[2]):
        if type(err) is kind:
            return name, status
    return _ENDING[signal.SIGINT][0], 130


@contextlib.contextmanager
def _signals_interrupt(quiet: bool = True):
    """While a command runs (main thread only): SIGTERM raises :class:`_Terminated` and SIGINT
    :class:`KeyboardInterrupt` (whatever handler the caller had), both restored after; with
    ``quiet``, errors that extensions print from destructors are logged instead.

    Yields the list of signals received. A signal that arrives while the main thread is
    importing a module is raised once the import is over (the signal is sent again 50 ms
    later): an exception inside an import can leave the import locks of other threads held
    (a deadlock), and a library's bare ``except:`` around an import would swallow it. The
    caller also treats a command that returns after a signal as interrupted."""
    received: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def on_signal(signum, frame):
        received.append(signum)
        if _importing(frame):
            timer = threading.Timer(0.05, os.kill, (os.getpid(), signum))
            timer.daemon = True
            timer.start()
            return
        raise _ENDING.get(signum, _ENDING[signal.SIGINT])[1]

    previous = {sig: signal.signal(sig, on_signal) for sig in _ENDING}
    import logging

    hooks = sys.unraisablehook, sys.excepthook
    # an interrupted dask.distributed client leaves tasks whose errors asyncio logs
    loop_log = logging.getLogger("asyncio")
    was_disabled = loop_log.disabled
    if quiet:
        sys.unraisablehook, sys.excepthook = _unraisable, _printed
        loop_log.disabled = True
    try:
        yield received
    finally:
        sys.unraisablehook, sys.excepthook = hooks
        loop_log.disabled = was_disabled
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _importing(frame) -> bool:
    """Whether ``frame`` or one of its callers runs Python's import machinery."""
    while frame is not None:
        if frame.f_code.co_filename.startswith("<frozen importlib"):
            return True
        frame = frame.f_back
    return False


def _unraisable(info) -> None:
    """Errors Python cannot raise (a destructor's, e.g. h5py closing a file on a full disk)
    follow the error that the command reports: logged, not printed as tracebacks."""
    import logging

    logging.getLogger("sunlab").debug("ignored in %r: %s", info.object, info.exc_value)


def _printed(kind, value, tb) -> None:
    """What an extension prints while a command runs (Cython's destructors print their
    errors through ``sys.excepthook``): logged, as :func:`_unraisable`."""
    import logging

    logging.getLogger("sunlab").debug("ignored: %s: %s", kind.__name__, value)
