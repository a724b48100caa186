"""Tests of sunlab.jit: the first compile of a process is announced once on stderr."""

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

from sunlab import jit

ROOT = Path(__file__).resolve().parents[1]


def _run(code: str) -> str:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          check=True, cwd=ROOT).stderr


def test_the_first_compile_is_announced_once():
    # two fresh kernels compiled (no cache: defined in -c): one line, however many compiles
    err = _run("import numba\nfrom sunlab import jit\njit.announce_first_compile()\n"
               "jit.announce_first_compile()\n"
               "f = numba.njit(lambda x: x + 1)\ng = numba.njit(lambda x: x * 2)\n"
               "assert f(1) == 2 and g(2.0) == 4.0 and f(1.5) == 2.5\n")
    assert err.count(jit.MESSAGE) == 1


def test_nothing_is_printed_without_a_compile():
    err = _run("from sunlab import jit\njit.announce_first_compile()\n")
    assert jit.MESSAGE not in err


_ESTIMATES = """
import json
import numba
import numpy as np
from sunlab.centroid import estimators
rng = np.random.default_rng(1)
yy, xx = np.mgrid[0:120, 0:160]
spot = 600 * np.exp(-((xx - 70.3) ** 2 + (yy - 55.7) ** 2) / (2 * 3.0 ** 2))
frame = (40 + spot + rng.normal(0, 2, yy.shape)).clip(0, 1023).astype(np.uint16)
out = {m: [float(c.x), float(c.y)] for m in ("threshold", "projection", "tight")
       for c in [estimators.METHODS[m](frame)]}
print(json.dumps({"disabled": bool(numba.config.DISABLE_JIT), "xy": out}))
"""


def test_the_centroid_kernels_uncompiled_agree_with_the_compiled_ones():
    # NUMBA_DISABLE_JIT=1, the off switch: the same kernels as plain Python and numpy
    def run(**env):
        out = subprocess.run([sys.executable, "-c", _ESTIMATES], capture_output=True, text=True,
                             check=True, cwd=ROOT, env={**os.environ, **env})
        return json.loads(out.stdout)

    compiled, plain = run(NUMBA_DISABLE_JIT="0"), run(NUMBA_DISABLE_JIT="1")
    assert (compiled["disabled"], plain["disabled"]) == (False, True)
    assert compiled["xy"].keys() == plain["xy"].keys()
    for method, xy in compiled["xy"].items():
        # fastmath reassociation in the compiled kernels: rounding only
        np.testing.assert_allclose(plain["xy"][method], xy, rtol=0, atol=1e-9)
