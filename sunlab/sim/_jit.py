"""The simulator's compiled kernels: one switch to their numpy references, one compile notice.

A kernel (:func:`kernel`) is a Numba function compiled with ``cache=True, nogil=True`` beside a
plain numpy reference of the same signature. The option ``kernels`` of
:func:`sunlab.set_options` picks which one runs, on every call: ``"numba"`` (the default; the
first run on a machine compiles, later processes load the machine code from ``__pycache__``)
or ``"numpy"`` (the references: nothing compiles). ``SUNLAB_KERNELS=numpy`` sets it for a
process and the workers it starts. The references give the same frames bit for bit (the noise
stream) or agree to the 1e-8 of the compiled Bessel approximation (the spectra).

A user who sees the first run stall deserves to know why: the first compile of a process prints
:data:`MESSAGE` on stderr (Numba's public event API, ``numba.core.event``), and nothing when the
kernels come from the cache. A kernel registers the notice on its first compiled call, never at
import.
"""

from __future__ import annotations

import functools
import sys
import threading

import numba
from numba.core import event

from ..options import OPTIONS

#: The line printed on stderr when the first kernel of a process compiles.
MESSAGE = ("sunlab: compiling the numba kernels for this machine (once: they are cached on "
           "disk for later runs)")

_LOCK = threading.Lock()
_STATE = {"registered": False, "announced": False}


class _Notice(event.Listener):
    def on_start(self, ev) -> None:
        with _LOCK:
            if _STATE["announced"]:
                return
            _STATE["announced"] = True
        print(MESSAGE, file=sys.stderr, flush=True)

    def on_end(self, ev) -> None:
        pass


def announce_first_compile() -> None:
    """Print :data:`MESSAGE` on stderr when this process first compiles a Numba function (a
    cache miss); calling it again does nothing.

    Returns
    -------
    None
        The listener stays registered with ``numba.core.event`` for the rest of the process.
    """
    with _LOCK:
        if _STATE["registered"]:
            return
        _STATE["registered"] = True
    event.register("numba:compile", _Notice())


def kernel(reference, **options):
    """Decorator: the function compiled by ``numba.njit(cache=True, nogil=True, **options)``,
    or ``reference`` (same parameters) when the option ``kernels`` is ``"numpy"``.

    Parameters
    ----------
    reference : function
        The numpy reference.
    **options
        More options of ``numba.njit``.

    Returns
    -------
    callable
        A decorator; the function it returns has ``compiled`` and ``numpy`` attributes.
    """

    def wrap(fn):
        compiled = numba.njit(**{"cache": True, "nogil": True, **options})(fn)

        @functools.wraps(fn)
        def run(*args):
            if OPTIONS["kernels"] == "numpy":
                return reference(*args)
            announce_first_compile()
            return compiled(*args)

        run.compiled, run.numpy = compiled, reference
        return run

    return wrap
