"""Tests of sunlab.jit: the first compile of a process is announced once on stderr."""

import subprocess
import sys
from pathlib import Path

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
