"""Package-wide options (like :func:`xarray.set_options`): today only the progress switch.

Long computations show a progress bar unless the caller passes ``progress=False`` *or* the
switch is off. Notebooks turn it off once (``sunlab.set_options(progress=False)``) so that their
saved outputs hold figures and numbers, not bars; the environment variable
``SUNLAB_PROGRESS=0`` does the same for a whole process.

Examples
--------
>>> import sunlab
>>> with sunlab.set_options(progress=False):
...     sunlab.show_progress(True)
False
>>> sunlab.show_progress(True) == sunlab.OPTIONS["progress"]
True
"""

from __future__ import annotations

import os

from .errors import ConfigurationError

__all__ = ["OPTIONS", "set_options", "show_progress"]

#: Current values of the options (read them; change them with :func:`set_options`).
OPTIONS: dict[str, object] = {"progress": os.environ.get("SUNLAB_PROGRESS", "1") != "0"}


class set_options:  # noqa: N801 - used as a function, as xarray.set_options is
    """Set options for the process, or for a ``with`` block only.

    Parameters
    ----------
    progress : bool
        Allow progress bars (default True, or False when ``SUNLAB_PROGRESS=0``).

    Examples
    --------
    >>> _ = set_options(progress=False)   # from now on
    >>> OPTIONS["progress"]
    False
    >>> _ = set_options(progress=True)
    """

    def __init__(self, **options):
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise ConfigurationError(
                f"set_options: unknown option(s) {unknown}; expected one of {sorted(OPTIONS)}."
            )
        for name, value in options.items():
            if not isinstance(value, bool):
                raise ConfigurationError(
                    f"set_options({name}=...): found {value!r}; expected True or False."
                )
        self._old = {name: OPTIONS[name] for name in options}
        OPTIONS.update(options)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        OPTIONS.update(self._old)


def show_progress(requested: bool) -> bool:
    """Whether to draw a progress bar: the caller asked for one and the switch allows it."""
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


_ANNOUNCED: set = set()


def announce_compile(modules, what: str) -> bool:
    """Say once per process, on stderr, that the numba kernels of ``modules`` compile now: the
    first run after an install (or an edit of a kernel) pauses for tens of seconds while they
    compile, and numba caches them on disk for every later run.

    Said only when a kernel has neither been compiled in this process nor has a cache on disk;
    returns whether it was said.
    """
    import sys

    if what in _ANNOUNCED:
        return False
    uncached = []
    for module in modules:
        for obj in vars(module).values():
            cache = getattr(getattr(obj, "_cache", None), "_cache_file", None)
            if cache is None or getattr(obj, "signatures", None):
                continue
            try:
                from pathlib import Path

                if not Path(cache._index_path).exists():
                    uncached.append(obj)
            except (AttributeError, OSError, TypeError):  # another numba: say nothing
                continue
    _ANNOUNCED.add(what)
    if uncached:
        print(f"sunlab: compiling the {what} kernels once ({len(uncached)} functions, up to a "
              "minute); numba caches them for every later run", file=sys.stderr, flush=True)
    return bool(uncached)
