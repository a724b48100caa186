"""What every worker process of :func:`sunlab.parallel.worker_pool` needs, made once.

The pool's workers are forked from a fork server (:mod:`multiprocessing`'s ``forkserver``
start method) that imports this module first. Importing it imports the modules a rendering and
centroiding task runs, and renders and centroids one small pose of each built-in bench, which
loads every compiled kernel (Numba's cache) and builds the detector's fixed pattern. The
workers forked afterwards inherit all of it, so each starts at once instead of spending about
2 s of CPU importing sunlab and loading the kernels; the fork server does it once, in parallel
with the main process's own start.

Nothing here changes a result: a worker that did not inherit the warm-up (another start
method, a custom bench) imports and builds the same things on its first task.

Examples
--------
>>> from sunlab import _worker_preload
>>> _worker_preload.warmed_up()
True
"""

from __future__ import annotations

import sys

__all__ = ["warm_up", "warmed_up"]

_DONE = False


def warm_up() -> None:
    """Import the task modules and run each compiled kernel of the built-in benches once.

    Examples
    --------
    >>> warm_up()  # a second call does nothing
    """
    global _DONE
    if _DONE:
        return
    from . import centroid, plans, sim

    plan = plans.custom([-4.0], [4.0], shots=2)
    for bench, methods in ((sim.Bench.paper_single_hole(), ("projection", "tight")),
                           (sim.Bench.paper_multi_hole(), ("tight",))):
        cube = sim.simulate(plan, bench, seed=0, chunks="pose")
        for method in methods:
            centroid.locate(cube, method, scheduler="synchronous", progress=False)
    _DONE = True


def warmed_up() -> bool:
    """Whether :func:`warm_up` has run in this process.

    Examples
    --------
    >>> warmed_up() in (True, False)
    True
    """
    return _DONE


def _warm_up_quietly() -> None:
    """:func:`warm_up`, with Ctrl-C ignored meanwhile: the fork server imports this module
    before it ignores SIGINT itself, and Ctrl-C reaches the whole process group, so it would
    print a traceback here; the main process stops the workers."""
    import signal
    import threading

    previous = None
    if threading.current_thread() is threading.main_thread():
        previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:  # a failed warm-up must never stop the fork server: the workers warm up themselves
        warm_up()
    except Exception:  # noqa: BLE001
        pass
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def _quiet_when_orphaned(kind, value, tb) -> None:
    """The fork server's excepthook, which its workers inherit: only an error that stops a
    worker from starting reaches it (a task's error goes back to the pool), and a worker that
    cannot read its start-up data because the main process is stopping (Ctrl-C: the pool's
    pipes and semaphores are gone) ends without a traceback; the main process reports."""
    import os

    if issubclass(kind, OSError | EOFError) and os.getpid() != _SERVER_PID:
        return
    sys.__excepthook__(kind, value, tb)


if "multiprocessing.forkserver" in sys.modules and sys.argv[:1] == ["-c"]:  # the fork server
    import os

    _SERVER_PID = os.getpid()
    sys.excepthook = _quiet_when_orphaned

_warm_up_quietly()
