"""Running lazy work: one pass of Dask over several results, on threads, processes, a local
cluster made for the call, or a ``dask.distributed`` scheduler given by address.

Every long computation of sunlab (centroiding a cube, rendering an experiment, the tables of
:mod:`sunlab.reproduce`) is a Dask graph; this module is the one place that decides where the
graph runs. Results never depend on the scheduler.

Examples
--------
>>> import dask.array as da
>>> from sunlab import parallel
>>> (total,) = parallel.compute(da.ones(6, chunks=2).sum(), progress=False)
>>> int(total)
6
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import forkserver

import dask
import numpy as np
from dask.multiprocessing import get_context, initialize_worker_process
from threadpoolctl import threadpool_limits

from .errors import ConfigurationError
from .extras import require
from .options import dask_progress, show_progress

__all__: list[str] = []


#: Local schedulers of :func:`compute`.
SCHEDULERS = ("threads", "processes", "synchronous", "cluster")


def compute(*objs, scheduler: str = "threads", address: str | None = None,
            num_workers: int | None = None, progress: bool = True, pool=None) -> tuple:
    """Compute lazy results (e.g. of ``locate(..., compute=False)``) in one pass of Dask.

    Several cubes computed together keep every worker busy to the end, where one after the
    other leave workers idle at each tail.

    Parameters
    ----------
    *objs : dask collections (xarray objects with Dask data, Dask arrays)
    scheduler : {"threads", "processes", "synchronous", "cluster"}
        Local Dask scheduler when no address is given. ``"processes"``: on the warm workers
        of :func:`worker_pool` (``pool``, or one started for the call); only tables cross
        processes (``sunlab reproduce`` uses it on several cores). ``"cluster"``: a
        ``dask.distributed.LocalCluster`` of ``num_workers`` single-threaded worker processes,
        started for this call and closed after it (the GIL does not limit it, as it limits
        threads on rendering; it costs a few seconds to start). Its workers run without
        ``MALLOC_TRIM_THRESHOLD_``, which distributed sets by default and which makes every
        frame-sized allocation a fresh ``mmap`` (about 1.6x the CPU per rendered frame).
    address : str, optional
        Address of a ``dask.distributed`` scheduler (its workers started separately); the
        results are identical to a local run.
    num_workers : int, optional
        Threads or processes of a local scheduler. Default: the CPU count, except for threads:
        twice the CPU count, because a frame alternates between Python that holds the GIL
        (geometry, glue) and compiled kernels that release it (noise, spectra, centroid), and
        a second thread per core fills the gaps (simulate + centroid of 2,000 frames: 20-25 %
        faster than one thread per core on 2 cores; results do not depend on it).
    progress : bool
        Show a progress bar.
    pool : concurrent.futures.Executor, optional
        The worker processes of the ``"processes"`` scheduler, kept for several calls
        (:func:`worker_pool`); ignored by the other schedulers. Default: a pool started for
        the call.

    Returns
    -------
    tuple
        The computed objects, in order.

    Examples
    --------
    >>> import dask.array as da
    >>> a, b = compute(da.ones(4, chunks=2).sum(), da.arange(3, chunks=1).max(), progress=False)
    >>> int(a), int(b)
    (4, 2)
    """
    if scheduler not in SCHEDULERS:
        raise ConfigurationError(
            f"scheduler: found {scheduler!r}; expected one of {SCHEDULERS}. Fix: 'threads' "
            "(default), or 'cluster' for CPU-bound rendering on several cores.")
    if num_workers is not None and (not isinstance(num_workers, int | np.integer)
                                    or num_workers < 1):
        raise ConfigurationError(
            f"num_workers: found {num_workers!r}; expected a positive integer or None.")
    if address is not None or scheduler == "cluster":
        return _distributed(objs, address, num_workers, progress)
    with contextlib.ExitStack() as stack:
        if scheduler == "processes" and pool is None:
            pool = stack.enter_context(worker_pool(scheduler, num_workers))
        kw = {"pool": pool} if scheduler == "processes" else {}
        n = num_workers or (2 * (os.cpu_count() or 1) if scheduler == "threads" else None)
        if n:
            kw["num_workers"] = int(n)
        with dask_progress(progress, "sunlab"):  # a bar in a terminal, plain lines in a log
            return dask.compute(*objs, scheduler=scheduler, **kw)


@contextlib.contextmanager
def worker_pool(scheduler: str = "threads", num_workers: int | None = None,
                address: str | None = None):
    """The worker processes of Dask's ``"processes"`` scheduler, started once for several
    :func:`compute` calls (``pool=``), each of which would start its own; shut down on exit.
    None for the other schedulers, which need no pool, and when an ``address`` is given (the
    work then runs on that cluster's workers): the arguments of :func:`compute`.

    The workers are forked from a fork server that has imported the task modules (rendering and
    centroiding: :data:`PRELOAD`), so a worker does not import them again; each loads the
    compiled kernels it runs from Numba's disk cache on its first task. Two calls may share the
    pool at once (e.g. from two threads).

    Parameters
    ----------
    scheduler : {"threads", "processes", "synchronous", "cluster"}
        The scheduler of the :func:`compute` calls; only ``"processes"`` gets a pool.
    num_workers : int, optional
        Worker processes (default: the CPU count).
    address : str, optional
        A ``dask.distributed`` scheduler's address (then no pool).

    Examples
    --------
    >>> import dask.array as da
    >>> with worker_pool("processes", 1) as pool:
    ...     a = compute(da.ones(4, chunks=2).sum(), scheduler="processes", pool=pool,
    ...                 progress=False)
    ...     b = compute(da.arange(3, chunks=1).max(), scheduler="processes", pool=pool,
    ...                 progress=False)
    >>> int(a[0]), int(b[0])
    (4, 2)
    >>> with worker_pool("threads") as pool:
    ...     pool is None
    True
    """
    if scheduler != "processes" or address is not None:
        yield None
        return
    n = int(num_workers) if num_workers else (os.cpu_count() or 1)
    pool = ProcessPoolExecutor(n, mp_context=_warm_context(), initializer=_init_worker)
    try:
        yield pool
    finally:  # on Ctrl-C too: queued tasks are dropped, running ones end, workers stop
        pool.shutdown(wait=True, cancel_futures=True)


def _init_worker() -> None:
    """Start a pool worker: Dask's set-up, and Ctrl-C left to the parent."""
    initialize_worker_process()
    dask_setup()


def dask_setup(worker=None) -> None:
    """Ignore Ctrl-C in a worker process, which the terminal sends to every process of the
    command: the main process stops the workers (a worker interrupted itself would print a
    traceback). Dask calls it in each worker of :func:`local_cluster` (whose ``preload`` is
    this module); :func:`worker_pool`'s workers call it when they start.

    Parameters
    ----------
    worker : distributed.Worker, optional
        The worker Dask passes (unused).
    """
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGINT, signal.SIG_IGN)


#: The modules the fork server imports before it forks a worker (:func:`worker_pool`): imports
#: only, no work (the kernels compile or load from Numba's cache on a worker's first task).
PRELOAD = ("sunlab.sim", "sunlab.centroid")


def start_workers(scheduler: str = "threads", address: str | None = None) -> None:
    """Start :func:`worker_pool`'s fork server now, when it will give a pool (the
    ``"processes"`` scheduler and no ``address``): it imports the task modules on another core
    while the caller goes on with its own imports. Nothing for the other schedulers; calling it
    twice, or before :func:`worker_pool`, changes nothing else.

    Parameters
    ----------
    scheduler : {"threads", "processes", "synchronous", "cluster"}
        The scheduler :func:`compute` will use.
    address : str, optional
        A ``dask.distributed`` scheduler's address (then no local pool is started).

    Examples
    --------
    >>> start_workers("threads")  # no pool, nothing to start
    """
    if scheduler == "processes" and address is None:
        _warm_context()


def _warm_context():
    """The start method of :func:`worker_pool`'s processes: forked from a fork server that has
    imported the task modules (:data:`PRELOAD`), started here so that it imports them while the
    caller goes on. Where there is no fork server (Windows), Dask's own context (spawn: each
    worker imports everything itself)."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return get_context()
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(PRELOAD))
    forkserver.ensure_running()
    return ctx


def single_threaded_blas():
    """A context in which BLAS runs on one thread (``threadpoolctl``), for small linear algebra
    on a busy machine: the calibration fits (L-BFGS-B on a few dozen weights, small
    least-squares solves, a Delaunay point location) are slowed several-fold by idle BLAS
    threads. The limit holds for the whole process while the context is open.

    Returns
    -------
    threadpoolctl.threadpool_limits
        The context manager; the previous limits come back when it exits.

    Examples
    --------
    >>> from threadpoolctl import threadpool_info
    >>> with single_threaded_blas():
    ...     {p["num_threads"] for p in threadpool_info() if p["user_api"] == "blas"}
    {1}
    """
    return threadpool_limits(limits=1)


def _distributed(objs, address, num_workers, progress) -> tuple:
    """:func:`compute` on the scheduler at ``address``, else on a :func:`local_cluster` of
    ``num_workers`` processes made for the call."""
    distributed = require("distributed", purpose="a Dask cluster (address=...)")
    with contextlib.ExitStack() as stack:
        if address is None:
            address = stack.enter_context(local_cluster(num_workers))
        client = stack.enter_context(distributed.Client(address))
        futures = client.compute(list(objs))
        if show_progress(progress):
            distributed.progress(futures)
        return tuple(client.gather(futures))


@contextlib.contextmanager
def local_cluster(workers: int | None = None):
    """A ``dask.distributed.LocalCluster`` of ``workers`` single-threaded processes (default:
    the CPU count), closed on exit; its workers run without ``MALLOC_TRIM_THRESHOLD_`` (see
    :func:`compute`). Pass ``cluster.scheduler_address`` as ``address`` to share it between
    several computations. Needs the ``distributed`` extra.

    Parameters
    ----------
    workers : int, optional
        Worker processes (default: the CPU count).

    Examples
    --------
    >>> import dask.array as da
    >>> with local_cluster(1) as cluster:
    ...     (total,) = compute(da.ones(4, chunks=2).sum(), address=cluster.scheduler_address,
    ...                        progress=False)
    >>> int(total)
    4
    """
    LocalCluster = require("distributed", purpose="a LocalCluster").LocalCluster

    n = int(workers) if workers else (os.cpu_count() or 1)
    env = dict(dask.config.get("distributed.nanny.pre-spawn-environ", {}))
    env.pop("MALLOC_TRIM_THRESHOLD_", None)
    with dask.config.set({"distributed.nanny.pre-spawn-environ": env}), LocalCluster(
        n_workers=n, threads_per_worker=1, processes=True, dashboard_address=None,
        # CRITICAL: a task's error reaches the caller as an exception; a worker that outlives
        # the scheduler at Ctrl-C is not an error to print. Ctrl-C is the main process's.
        silence_logs=50, preload=["sunlab.parallel"],
    ) as cluster:
        yield cluster
