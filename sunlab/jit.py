"""Compiled kernels beside their numpy references, one switch between them, one compile notice.

Every compiled (Numba) kernel of sunlab is a :class:`Kernel`: the compiled function and a plain
numpy reference with the same signature, behind one name. The option ``kernels`` of
:func:`sunlab.set_options` picks which one runs, on every call:

* ``"numba"`` (the default): the compiled kernel. Every kernel is compiled with ``cache=True``:
  the first run on a machine compiles it (tens of seconds for all of them) and writes the
  machine code beside the module (``__pycache__``); later processes load it in milliseconds.
* ``"numpy"``: the references, slower but readable, and Numba compiles nothing. The
  environment variable ``SUNLAB_KERNELS=numpy`` sets it for a whole process and for the worker
  processes it starts (``SUNLAB_KERNELS=numpy sunlab reproduce --quick``).

A reference is either a vectorised numpy function written beside the kernel
(:meth:`Kernel.reference` registers it) or, for a kernel that has none, the kernel's own source
run by the interpreter (:func:`interpreted`: Python loops over numpy arrays, with every
compiled helper it calls interpreted too). Each kernel and its reference agree: the noise
stream bit for bit, the centroid kernels to rounding, the spectra to the 1e-8 of the compiled
Bessel approximation (``tests/test_jit.py`` and ``tests/sim/test_kernels.py`` check them).

The compile notice: a user who sees the first run stall deserves to know why, so
:func:`announce_first_compile` prints :data:`MESSAGE` on stderr when a process starts to compile
its first kernel, and nothing when the kernels come from the cache. A :class:`Kernel` registers
it on its first compiled call (nothing happens at import); it is once per process: the workers
of a pool that compile at the same time each print it. It listens to Numba's public event API
(``numba.core.event``), no cache internals.

``NUMBA_DISABLE_JIT=1`` still works (Numba's own switch: every compiled kernel then runs as its
interpreted source), but it must be set before Numba is imported; the option need not.

Examples
--------
>>> import numpy as np
>>> from sunlab import set_options
>>> @kernel(cache=False)
... def total(a):
...     s = 0.0
...     for v in a:
...         s += v
...     return s
>>> @total.reference
... def _total_numpy(a):
...     return float(np.sum(a))
>>> with set_options(kernels="numpy"):
...     total(np.arange(4.0))
6.0
>>> total.compiled.signatures   # the reference ran: nothing compiled
[]
"""

from __future__ import annotations

import functools
import inspect
import sys
import threading
import types

import numba
import numpy as np
from numba.core import event
from numba.extending import is_jitted, typeof_impl

from .errors import ConfigurationError
from .options import OPTIONS

__all__ = ["Kernel", "kernel", "interpreted", "announce_first_compile", "MESSAGE"]

#: The line printed on stderr when the first kernel of a process compiles.
MESSAGE = ("sunlab: compiling the numba kernels for this machine (once: they are cached on "
           "disk for later runs)")

_LOCK = threading.Lock()
_STATE = {"registered": False, "announced": False}


class _Notice(event.Listener):
    """Prints :data:`MESSAGE` at the start of the process's first compile."""

    def __init__(self, stream=None):
        self.stream = stream

    def on_start(self, ev) -> None:
        with _LOCK:
            if _STATE["announced"]:
                return
            _STATE["announced"] = True
        print(MESSAGE, file=self.stream or sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        """Nothing at the end of a compile."""


def announce_first_compile(stream=None) -> None:
    """Print :data:`MESSAGE` on ``stream`` (default stderr) when this process first compiles
    a Numba kernel (a cache miss); a kernel loaded from Numba's disk cache prints nothing.

    Every :class:`Kernel` calls it before its first compiled run; calling it again does nothing.

    Parameters
    ----------
    stream : file-like, optional
        Where the line goes (default ``sys.stderr`` at the time of the compile).

    Returns
    -------
    None
        The listener is registered with ``numba.core.event`` for the rest of the process.

    Examples
    --------
    >>> announce_first_compile()   # registers the notice once; a second call does nothing
    >>> announce_first_compile()
    """
    if _STATE["registered"]:  # the common case, without the lock
        return
    with _LOCK:
        if _STATE["registered"]:
            return
        _STATE["registered"] = True
    event.register("numba:compile", _Notice(stream))


class Kernel:
    """A compiled kernel and its numpy reference behind one name (make one with :func:`kernel`).

    Calling it runs the compiled function, or the reference when the option ``kernels`` is
    ``"numpy"``. Compiled code calls a kernel as it calls any Numba function (its type is the
    compiled dispatcher's), so kernels call kernels.

    Parameters
    ----------
    fn : function
        The kernel's source: Python that Numba compiles (loops over numpy arrays).
    options : dict
        Options of ``numba.njit`` (``cache``, ``nogil``, ``fastmath``, ...).

    Attributes
    ----------
    compiled : numba dispatcher
        The compiled kernel (compiled on its first call with new argument types).
    py_func : function
        The kernel's source, as written.
    """

    def __init__(self, fn, options: dict):
        self.py_func = fn
        self.compiled = numba.njit(**options)(fn)
        self._reference = None
        self._interpreted = None
        functools.update_wrapper(self, fn)

    def reference(self, fn):
        """Register ``fn``, a plain numpy function with the kernel's signature, as the reference.

        Parameters
        ----------
        fn : function
            The reference: the same parameters (names and order) as the kernel, the same
            results to rounding.

        Returns
        -------
        function
            ``fn`` itself (so that it keeps its own name in its module).

        Raises
        ------
        ConfigurationError
            When the parameters differ from the kernel's.
        """
        mine, theirs = inspect.signature(self.py_func), inspect.signature(fn)
        if list(mine.parameters) != list(theirs.parameters):
            raise ConfigurationError(
                f"{fn.__qualname__}: parameters {list(theirs.parameters)}; expected those of "
                f"the kernel {self.__qualname__}, {list(mine.parameters)}."
            )
        self._reference = fn
        return fn

    @property
    def numpy(self):
        """The function that runs when ``kernels="numpy"``: the registered reference, or the
        kernel's own source interpreted (:func:`interpreted`) when it has none, with numpy's
        floating-point warnings off, as compiled code has none."""
        if self._reference is not None:
            return self._reference
        if self._interpreted is None:
            self._interpreted = _quiet(interpreted(self.py_func))
        return self._interpreted

    @property
    def has_reference(self) -> bool:
        """Whether a numpy reference was written for this kernel (else its source serves)."""
        return self._reference is not None

    def __call__(self, *args, **kwargs):
        if OPTIONS["kernels"] == "numpy":
            return self.numpy(*args, **kwargs)
        announce_first_compile()
        return self.compiled(*args, **kwargs)

    def __repr__(self) -> str:
        kind = "numpy reference" if self.has_reference else "interpreted source"
        return f"<sunlab kernel {self.__module__}.{self.__qualname__} ({kind})>"


@typeof_impl.register(Kernel)
def _typeof_kernel(val, c):
    """In compiled code a kernel is its compiled dispatcher (kernels call kernels)."""
    return numba.typeof(val.compiled)


def kernel(**options):
    """Decorator: a :class:`Kernel` compiled with ``numba.njit(**options)``.

    Parameters
    ----------
    **options
        Options of ``numba.njit`` (e.g. ``cache=True, nogil=True``).

    Returns
    -------
    callable
        A decorator that turns a function into a :class:`Kernel`; register its numpy reference
        with ``@name.reference``.
    """
    return lambda fn: Kernel(fn, options)


_PLAIN: dict[int, dict] = {}
_INTERPRETED: dict = {}


def interpreted(fn):
    """``fn``, the source of a compiled function, as a plain Python function whose compiled
    callees (Numba dispatchers and kernels) are interpreted too: what ``NUMBA_DISABLE_JIT=1``
    runs, chosen per call instead of per process.

    Parameters
    ----------
    fn : function
        A Python function (e.g. a kernel's ``py_func``).

    Returns
    -------
    function
        The same code, run by the interpreter, with module globals in which every Numba
        dispatcher is its own interpreted source and every :class:`Kernel` its numpy reference.

    Examples
    --------
    >>> import numba
    >>> inc = numba.njit(lambda x: x + 1)
    >>> def twice(x):
    ...     return inc(inc(x))
    >>> interpreted(twice)(1), inc.signatures
    (3, [])
    """
    if isinstance(fn, Kernel):
        return fn.numpy
    if is_jitted(fn):
        fn = fn.py_func
    key = (fn.__code__, id(fn.__globals__))
    if key not in _INTERPRETED:
        _INTERPRETED[key] = types.FunctionType(fn.__code__, _plain_globals(fn.__globals__),
                                               fn.__name__, fn.__defaults__, fn.__closure__)
    return _INTERPRETED[key]


def _plain_globals(module_globals: dict) -> dict:
    key = id(module_globals)
    if key not in _PLAIN:
        plain = dict(module_globals)
        _PLAIN[key] = plain
        for name, value in module_globals.items():
            if isinstance(value, Kernel) or is_jitted(value):
                plain[name] = _Deferred(value)
    return _PLAIN[key]


def _quiet(fn):
    """``fn`` with numpy's floating-point warnings off (compiled code raises none: a division by
    zero under ``error_model="numpy"`` gives inf or NaN silently)."""

    @functools.wraps(fn)
    def run(*args, **kwargs):
        with np.errstate(all="ignore"):
            return fn(*args, **kwargs)

    return run


class _Deferred:
    """A compiled callee, resolved to its plain counterpart on its first call."""

    def __init__(self, target):
        self.target = target
        self.fn = None

    def __call__(self, *args, **kwargs):
        if self.fn is None:
            self.fn = interpreted(self.target)
        return self.fn(*args, **kwargs)
