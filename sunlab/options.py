"""Package-wide options (like :func:`xarray.set_options`): progress bars and the kernels.

``progress``: long computations show a progress bar unless the caller passes
``progress=False`` *or* the switch is off. Notebooks turn it off once
(``sunlab.set_options(progress=False)``) so that their saved outputs hold figures and numbers,
not bars; the environment variable ``SUNLAB_PROGRESS=0`` does the same for a whole process.
A bar is tqdm's in a terminal or Jupyter, a few plain lines in a log (:func:`dask_progress`).

``kernels``: ``"numba"`` runs the compiled kernels, ``"numpy"`` their plain numpy references
(slower, readable, and Numba compiles nothing; ``sunlab.sim._jit``). The environment variable
``SUNLAB_KERNELS=numpy`` sets it for a whole process and the worker processes it starts, e.g.
``SUNLAB_KERNELS=numpy sunlab reproduce --quick``.

Examples
--------
>>> import sunlab
>>> with sunlab.set_options(progress=False):
...     show_progress(True)
False
>>> show_progress(True) == OPTIONS["progress"]
True
>>> with sunlab.set_options(kernels="numpy"):
...     OPTIONS["kernels"]
'numpy'
"""

from __future__ import annotations

import contextlib
import os
import sys
import time

from .errors import ConfigurationError

__all__ = ["set_options"]

#: Values of the option ``kernels``: the compiled kernels, or their numpy references.
KERNELS = ("numba", "numpy")
_KERNELS_ENV = os.environ.get("SUNLAB_KERNELS", "numba").strip().lower() or "numba"
if _KERNELS_ENV not in KERNELS:
    raise ConfigurationError(
        f"environment variable SUNLAB_KERNELS: found {_KERNELS_ENV!r}; expected one of "
        f"{KERNELS}. Fix: SUNLAB_KERNELS=numpy for the references, or unset it.")

#: Current values of the options (read them; change them with :func:`set_options`).
OPTIONS: dict[str, object] = {"progress": os.environ.get("SUNLAB_PROGRESS", "1") != "0",
                              "kernels": _KERNELS_ENV}


class set_options:  # noqa: N801 - used as a function, as xarray.set_options is
    """Set options for the process, or for a ``with`` block only.

    Parameters
    ----------
    progress : bool
        Allow progress bars (default True, or False when ``SUNLAB_PROGRESS=0``).
    kernels : {"numba", "numpy"}
        Run the compiled kernels (default, or as ``SUNLAB_KERNELS`` says) or their numpy
        references (``sunlab.sim._jit``). It is also written to ``SUNLAB_KERNELS`` in the
        environment, so worker processes started afterwards (Dask's ``"cluster"`` scheduler,
        a new process pool) follow it; a pool already running keeps the value it started with.

    Returns
    -------
    set_options
        A context manager: the previous values come back at the end of a ``with`` block.

    Examples
    --------
    >>> _ = set_options(progress=False)   # from now on
    >>> OPTIONS["progress"]
    False
    >>> _ = set_options(progress=True)
    >>> set_options(kernels="fortran")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    sunlab.errors.ConfigurationError: set_options(kernels=...): found 'fortran'; expected one ...
    """

    def __init__(self, **options):
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise ConfigurationError(f"set_options: unknown option(s) {unknown}; expected one "
                                     f"of {sorted(OPTIONS)}.")
        for name, value in options.items():
            ok = value is True or value is False if name == "progress" else value in KERNELS
            if not ok:
                expected = "True or False" if name == "progress" else f"one of {KERNELS}"
                raise ConfigurationError(
                    f"set_options({name}=...): found {value!r}; expected {expected}.")
        self._old = {name: OPTIONS[name] for name in options}
        self._old_env = os.environ.get("SUNLAB_KERNELS")
        _apply(options)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        _apply(self._old)
        if "kernels" in self._old and self._old_env is None:
            os.environ.pop("SUNLAB_KERNELS", None)


def _apply(options: dict) -> None:
    """Set the options, and mirror ``kernels`` in the environment for new worker processes."""
    OPTIONS.update(options)
    if "kernels" in options:
        os.environ["SUNLAB_KERNELS"] = str(options["kernels"])


def show_progress(requested: bool) -> bool:
    """Whether to draw a progress bar: the caller asked for one and the switch allows it.

    Parameters
    ----------
    requested : bool
        The caller's ``progress=`` argument.

    Returns
    -------
    bool
        True when ``requested`` and the option ``progress`` are both true.
    """
    return bool(requested) and bool(OPTIONS["progress"])


def _interactive() -> bool:
    """True in a terminal (stderr is a TTY) or a Jupyter kernel: a bar redrawn in place fits;
    elsewhere (a log file, a pipe, CI) it would leave a carriage return per redraw."""
    with contextlib.suppress(AttributeError, ValueError):  # a closed or replaced stream
        if sys.stderr.isatty():
            return True
    ip = getattr(sys.modules.get("IPython"), "get_ipython", lambda: None)()
    return ip is not None and "IPKernelApp" in getattr(ip, "config", {})


def dask_progress(progress: bool, desc: str = "sunlab", minimum: float = 1.0):
    """A context manager that shows the progress of the Dask computations inside it, as fits
    the place: a tqdm bar (:class:`tqdm.dask.TqdmCallback`) in a terminal or in Jupyter, a few
    plain lines on stderr otherwise (the task count once the work has run for ``minimum`` s,
    then at 25, 50 and 75 % and at the end: a log file gets no carriage returns); nothing when
    :func:`show_progress` says no.

    Parameters
    ----------
    progress : bool
        The caller's ``progress=`` argument (see :func:`show_progress`).
    desc : str
        The label of the bar or lines.
    minimum : float
        Seconds of work before anything is shown.

    Returns
    -------
    context manager
        A Dask callback, or :func:`contextlib.nullcontext` when no progress is shown.

    Examples
    --------
    >>> import dask.array as da
    >>> with dask_progress(False):
    ...     int(da.ones(4, chunks=2).sum().compute())
    4
    """
    if not show_progress(progress):
        return contextlib.nullcontext()
    if _interactive():
        from tqdm.dask import TqdmCallback

        return TqdmCallback(desc=desc, mininterval=0.5, delay=minimum)
    from dask.callbacks import Callback

    run = {}

    def say(text):
        print(f"{desc}: {text} {time.perf_counter() - run['t0']:.1f} s", file=sys.stderr,
              flush=True)

    def start(dsk, state):
        run.update(t0=time.perf_counter(), n=0, said=0, total=sum(
            len(state.get(k, ())) for k in ("ready", "waiting", "running", "finished")))

    def posttask(key, result, dsk, state, worker_id):
        run["n"] += 1
        quarter = 4 * run["n"] // max(run["total"], 1)
        if time.perf_counter() - run["t0"] >= minimum and run["said"] < quarter < 4:
            run["said"] = quarter
            say(f"{25 * quarter} % of {run['total']} tasks,")

    def finish(dsk, state, errored):
        if time.perf_counter() - run["t0"] >= minimum and not errored:
            say(f"done, {run['total']} tasks in")

    return Callback(start_state=start, posttask=posttask, finish=finish)
