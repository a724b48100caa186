"""The benchmarks' shared scaffolding: one-core runs, best-of timings, and the floors each
benchmark prints its times against, measured in the same run (``import _timing`` from a script in
this folder)."""

from __future__ import annotations

import os
import time

FRAME = (1024, 1280)  # the paper's detector, rows x columns


def single_thread() -> None:
    """BLAS and Numba on one thread; call it before numpy is imported."""
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS"):
        os.environ.setdefault(var, "1")


def times(fn, repeat: int = 5, warm: bool = True) -> dict:
    """Wall and process CPU time of ``repeat`` calls ``fn(i)`` (i = 1..repeat) after a warm-up
    call ``fn(0)``, ms: ``{"wall": (median, best), "cpu": (median, best)}``."""
    import numpy as np

    if warm:
        fn(0)
    wall, cpu = [], []
    for i in range(repeat):
        w, c = time.perf_counter(), time.process_time()
        fn(i + 1)
        wall.append(1e3 * (time.perf_counter() - w))
        cpu.append(1e3 * (time.process_time() - c))
    return {k: (float(np.median(v)), min(v)) for k, v in (("wall", wall), ("cpu", cpu))}


def best_ms(fn, repeat: int = 5, clock: str = "wall", warm: bool = True) -> float:
    """Best time of ``repeat`` calls ``fn()``, ms (``clock``: ``"wall"`` or ``"cpu"``)."""
    return times(lambda i: fn(), repeat, warm)[clock][1]


def noise_ms(repeat: int = 5) -> float:
    """The frame-noise unit u: best wall time of one frame of float32 standard normals, ms."""
    import numpy as np

    rng = np.random.default_rng()
    return best_ms(lambda: rng.standard_normal(FRAME, dtype=np.float32), repeat, warm=False)


def copy_ms(repeat: int = 10) -> float:
    """Best wall time of ``np.copy`` of one uint16 frame, ms: the floor of any frame pass."""
    import numpy as np

    frame = np.zeros(FRAME, np.uint16)
    return best_ms(lambda: np.copy(frame), repeat, warm=False)
