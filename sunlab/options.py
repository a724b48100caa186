"""Package-wide options (like :func:`xarray.set_options`): progress bars and the kernels.

``progress``: long computations show a progress bar unless the caller passes
``progress=False`` *or* the switch is off. Notebooks turn it off once
(``sunlab.set_options(progress=False)``) so that their saved outputs hold figures and numbers,
not bars; the environment variable ``SUNLAB_PROGRESS=0`` does the same for a whole process.

``kernels``: ``"numba"`` runs the compiled kernels, ``"numpy"`` their plain numpy references
(slower, readable, and Numba compiles nothing; ``sunlab.sim._jit``). The environment variable
``SUNLAB_KERNELS=numpy`` sets it for a whole process and the worker processes it starts, e.g.
``SUNLAB_KERNELS=numpy sunlab reproduce --quick``.

Examples
--------
>>> import sunlab
>>> with sunlab.set_options(progress=False):
...     sunlab.show_progress(True)
False
>>> sunlab.show_progress(True) == sunlab.OPTIONS["progress"]
True
>>> with sunlab.set_options(kernels="numpy"):
...     sunlab.OPTIONS["kernels"]
'numpy'
"""

from __future__ import annotations

import os

from .errors import ConfigurationError

__all__ = ["OPTIONS", "KERNELS", "set_options", "show_progress"]

#: Values of the option ``kernels``: the compiled kernels, or their numpy references.
KERNELS = ("numba", "numpy")


def _kernels_from_environment() -> str:
    """The option ``kernels`` as ``SUNLAB_KERNELS`` sets it (default ``"numba"``)."""
    value = os.environ.get("SUNLAB_KERNELS", "numba").strip().lower() or "numba"
    if value not in KERNELS:
        raise ConfigurationError(
            f"environment variable SUNLAB_KERNELS: found {value!r}; expected one of {KERNELS}. "
            "Fix: SUNLAB_KERNELS=numpy for the references, or unset it."
        )
    return value


#: Current values of the options (read them; change them with :func:`set_options`).
OPTIONS: dict[str, object] = {"progress": os.environ.get("SUNLAB_PROGRESS", "1") != "0",
                              "kernels": _kernels_from_environment()}

#: The values each option accepts.
_ALLOWED = {"progress": (True, False), "kernels": KERNELS}


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
            raise ConfigurationError(
                f"set_options: unknown option(s) {unknown}; expected one of {sorted(OPTIONS)}."
            )
        for name, value in options.items():
            allowed = _ALLOWED[name]
            if not any(value is a if isinstance(a, bool) else value == a for a in allowed):
                expected = "True or False" if name == "progress" else f"one of {allowed}"
                raise ConfigurationError(
                    f"set_options({name}=...): found {value!r}; expected {expected}."
                )
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
    import sys

    try:
        if sys.stderr is not None and sys.stderr.isatty():
            return True
    except (AttributeError, ValueError):  # a closed or replaced stream
        return False
    shell = sys.modules.get("IPython")
    ip = getattr(shell, "get_ipython", lambda: None)() if shell else None
    return ip is not None and "IPKernelApp" in getattr(ip, "config", {})


class _LogLines:
    """A Dask callback that writes a few plain lines to stderr: the task count once the work
    has run for ``minimum`` s, then at 25, 50 and 75 % and at the end (no carriage returns)."""

    def __new__(cls, desc: str, minimum: float = 1.0):
        import sys
        import time

        from dask.callbacks import Callback

        class LogLines(Callback):
            def _start_state(self, dsk, state):
                self._t0, self._n, self._said = time.perf_counter(), 0, 0
                self._total = sum(len(state[k]) for k in ("ready", "waiting", "running"))
                self._total += len(state.get("finished", ()))

            def _posttask(self, key, result, dsk, state, worker_id):
                self._n += 1
                elapsed = time.perf_counter() - self._t0
                if elapsed < minimum or not self._total:
                    return
                quarter = 4 * self._n // self._total
                if quarter > self._said and quarter < 4:
                    self._said = quarter
                    print(f"{desc}: {25 * quarter} % of {self._total} tasks, {elapsed:.1f} s",
                          file=sys.stderr, flush=True)

            def _finish(self, dsk, state, errored):
                elapsed = time.perf_counter() - self._t0
                if elapsed >= minimum and not errored:
                    print(f"{desc}: done, {self._total} tasks in {elapsed:.1f} s",
                          file=sys.stderr, flush=True)

        return LogLines()


def dask_progress(progress: bool, desc: str = "sunlab", minimum: float = 1.0):
    """A context manager that shows the progress of the Dask computations inside it, as fits
    the place: a tqdm bar (:class:`tqdm.dask.TqdmCallback`) in a terminal or in Jupyter, a few
    plain lines on stderr otherwise (a log file gets no carriage returns); nothing when
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
    import contextlib

    if not show_progress(progress):
        return contextlib.nullcontext()
    if _interactive():
        from tqdm.dask import TqdmCallback

        return TqdmCallback(desc=desc, mininterval=0.5, delay=minimum)
    return _LogLines(desc, minimum)
