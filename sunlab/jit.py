"""The compiled (Numba) kernels' one piece of shared behaviour: say so when they compile.

Every kernel is compiled with ``cache=True``: the first run on a machine compiles it (tens of
seconds for all of them) and writes the machine code beside the module (``__pycache__``);
later processes load it in milliseconds. A user who sees the first run stall deserves to know
why, so :func:`announce_first_compile` prints one line on stderr when a process starts to
compile its first kernel, and nothing when the kernels come from the cache. It is once per
process: the workers of a pool that compile at the same time each print it.

The off switch is Numba's own: ``NUMBA_DISABLE_JIT=1`` in the environment before sunlab is
imported runs every kernel as plain Python and numpy, the readable reference of the compiled
code (slow: for checking and debugging). The centroid kernels agree with their compiled selves
to rounding (``tests/test_jit.py``); the virtual bench's noise stream does not yet run
uncompiled (its 64-bit wrap-around arithmetic overflows numpy scalars).

Examples
--------
>>> announce_first_compile()   # registers the notice once; a second call does nothing
>>> announce_first_compile()
"""

from __future__ import annotations

import sys
import threading

from numba.core import event

__all__ = ["announce_first_compile", "MESSAGE"]

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

    Parameters
    ----------
    stream : file-like, optional
        Where the line goes (default ``sys.stderr`` at the time of the compile).
    """
    with _LOCK:
        if _STATE["registered"]:
            return
        _STATE["registered"] = True
    event.register("numba:compile", _Notice(stream))
