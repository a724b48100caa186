"""The compiled kernels beside their numpy references: the time of each, and their ratio, measured
in the same run.

For each kernel on the paper's bench (a full 1280 x 1024 frame, one spot's spectra) and for the
whole of one rendered frame, the best process CPU time of a few
calls of the compiled kernel (``kernels="numba"``) and of its numpy reference
(``kernels="numpy"``), after one call of each (compiling or loading from Numba's cache, and the
fixed-pattern maps). CPU time, not wall time: on a shared machine it is the fairer figure. BLAS
and Numba run single-threaded.

Usage::

    python benchmarks/bench_kernels.py            # 5 calls of each
    python benchmarks/bench_kernels.py --repeat 20
"""

from __future__ import annotations

import argparse

import _timing

_timing.single_thread()

import numpy as np  # noqa: E402

import sunlab  # noqa: E402
from sunlab import sim  # noqa: E402
from sunlab.sim import render, spots  # noqa: E402
from sunlab.sim._adc import adc_frame, normal_table  # noqa: E402
from sunlab.sim.detector import fixed_pattern  # noqa: E402


def _cases():
    """(name, zero-argument callable) for each measured kernel and for one whole frame."""
    bench = sim.Bench.paper_single_hole()
    det = bench.detector
    fp, table = fixed_pattern(det), normal_table()
    out = np.empty(det.shape, dtype=np.uint16)
    group = spots._groups(bench, render.spot_geometry(bench, -7.0, 6.0))[0]
    m = group.stamp_size()
    al = np.arange(-1, 2)
    fx = (al[:, None] + (np.arange(m // 2 + 1) / m)[None, :]).ravel()
    fy = (al[:, None] + np.fft.fftfreq(m)[None, :]).ravel()
    seed = np.array([7], np.uint64)
    return [
        ("adc_frame (1280 x 1024)", lambda: adc_frame(fp.bg_mean_dn, fp.bg_sigma_dn, table, seed,
                                                      float(det.max_dn), out)),
        (f"spectrum ({fy.size} x {fx.size})", lambda: group.common(fx, fy, tabulated=True)),
        ("render_frame", lambda: sim.render_frame(bench, -7.0, 6.0, seed=0, pose=0, shot=1)),
    ]


def main(repeat: int = 5) -> None:
    """Print, per case, the compiled and reference CPU times and their ratio.

    Parameters
    ----------
    repeat : int
        Timed calls of each (the best is kept).

    Returns
    -------
    None
        The table is printed.
    """
    print(f"{'case':34s} {'numba ms':>10s} {'numpy ms':>10s} {'numpy/numba':>12s}")
    for name, fn in _cases():
        ms = {}
        for kernels in ("numba", "numpy"):
            with sunlab.set_options(kernels=kernels):
                ms[kernels] = _timing.best_ms(fn, repeat, "cpu")
        print(f"{name:34s} {ms['numba']:10.2f} {ms['numpy']:10.2f} "
              f"{ms['numpy'] / ms['numba']:12.1f}")


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timed calls of each (default 5)")
    main(parser.parse_args().repeat)
