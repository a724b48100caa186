"""Loaded by every worker process of :func:`sunlab.parallel.local_cluster` (Dask's worker
``preload``): Ctrl-C, which a terminal sends to every process of the command, is left to the
main process, which closes the cluster; a worker interrupted itself would print a traceback.

Examples
--------
>>> from sunlab import _cluster_preload
>>> callable(_cluster_preload.dask_setup)
True
"""

from __future__ import annotations

__all__ = []


def dask_setup(worker=None) -> None:
    """Ignore SIGINT in this worker process (Dask calls this when the worker starts)."""
    import signal
    import threading

    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)
