"""Tests of sunlab.jit: every compiled kernel beside its numpy reference, one switch between them
(the option ``kernels``), and one compile notice, said once, registered by no import."""

import importlib
import inspect
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numba
import numpy as np
import pytest

import sunlab
from sunlab import jit
from sunlab.errors import ConfigurationError

ROOT = Path(__file__).resolve().parents[1]
KERNEL_MODULES = ["sunlab.sim._kernels"]
#: Kernels whose reference is their own source, interpreted (jit.interpreted), not a numpy
#: function written beside them.
INTERPRETED = {"clip_convex"}


def _run(code: str, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT), **env})


def _kernels() -> dict:
    out = {}
    for name in KERNEL_MODULES:
        for attr, value in vars(importlib.import_module(name)).items():
            if isinstance(value, jit.Kernel) and value.__module__ == name:  # not re-imported
                out[f"{name}.{attr}"] = value
    return out


def test_the_first_compile_is_announced_once():
    # two fresh kernels compiled (no cache: defined in -c): one line, however many compiles
    err = _run("import numba\nfrom sunlab import jit\njit.announce_first_compile()\n"
               "jit.announce_first_compile()\n"
               "f = numba.njit(lambda x: x + 1)\ng = numba.njit(lambda x: x * 2)\n"
               "assert f(1) == 2 and g(2.0) == 4.0 and f(1.5) == 2.5\n").stderr
    assert err.count(jit.MESSAGE) == 1


def test_nothing_is_printed_without_a_compile():
    err = _run("from sunlab import jit\njit.announce_first_compile()\n").stderr
    assert jit.MESSAGE not in err


def test_a_kernel_registers_the_notice_on_its_first_compiled_call(monkeypatch):
    # (that no import registers it: the references-only run below)
    registered = []
    monkeypatch.setattr(jit, "_STATE", {"registered": False, "announced": False})
    monkeypatch.setattr(jit, "event", types.SimpleNamespace(
        register=lambda kind, listener: registered.append(kind)))
    k = jit.kernel(cache=False)(lambda x: x + 1)
    with sunlab.set_options(kernels="numpy"):
        assert k(1) == 2
    assert registered == []  # the reference compiles nothing: nothing to announce
    assert k(1) == 2 and k(2) == 3
    assert registered == ["numba:compile"]


def test_every_kernel_has_a_reference_with_its_signature():
    kernels = _kernels()
    assert len(kernels) == 8
    for name, k in kernels.items():
        short = name.rsplit(".", 1)[1]
        assert k.has_reference is (short not in INTERPRETED), name
        params = list(inspect.signature(k.py_func).parameters)
        if k.has_reference:
            assert list(inspect.signature(k.numpy).parameters) == params, name


def test_a_reference_with_other_parameters_is_refused():
    k = jit.kernel(cache=False)(lambda a, b: a + b)
    with pytest.raises(ConfigurationError, match=r"parameters \['a'\]; expected"):
        k.reference(lambda a: a)


def test_the_option_picks_the_reference_and_compiles_nothing():
    k = jit.kernel(cache=False)(lambda a: a.sum() + 1.0)
    k.reference(lambda a: float(np.sum(a)) + 2.0)  # a different value: which one ran
    with sunlab.set_options(kernels="numpy"):
        assert k(np.ones(3)) == 5.0
        assert os.environ["SUNLAB_KERNELS"] == "numpy"  # for workers started inside
    assert k.compiled.signatures == []
    assert k(np.ones(3)) == 4.0 and len(k.compiled.signatures) == 1
    assert sunlab.options.OPTIONS["kernels"] == "numba"


def test_bad_values_of_the_switch_are_refused_with_the_fix():
    with pytest.raises(ConfigurationError, match=r"kernels=.*'cuda'.*'numba', 'numpy'"):
        sunlab.set_options(kernels="cuda")
    with pytest.raises(ConfigurationError, match="True or False"):
        sunlab.set_options(progress="no")
    out = _run("import sunlab; sunlab.options.OPTIONS", SUNLAB_KERNELS="cuda")
    assert out.returncode != 0
    assert "SUNLAB_KERNELS: found 'cuda'" in out.stderr and "Fix:" in out.stderr


_triple = numba.njit(lambda x: x * 3)


def _outer_source(x):
    return _triple(x) + 1


def test_interpreted_runs_compiled_callees_uncompiled():
    outer = jit.kernel(cache=False)(_outer_source)
    assert jit.interpreted(outer.py_func)(2) == 7
    with sunlab.set_options(kernels="numpy"):
        assert outer(2) == 7
    assert _triple.signatures == [] and outer.compiled.signatures == []
    assert outer(2) == 7 and outer.compiled.signatures  # and compiled, kernels call kernels


_REFERENCES_RUN = """
import json
from numba.core import event
from sunlab import centroid, jit, plans, sim

compiles = []

class Count(event.Listener):
    def on_start(self, ev):
        compiles.append(1)

    def on_end(self, ev):
        pass

event.register("numba:compile", Count())
registered_at_import = jit._STATE["registered"]
cube = sim.simulate(plans.custom([-8.0], [4.0], shots=1), sim.Bench.paper_single_hole())
cen = centroid.locate(cube, method="projection", progress=False, scheduler="synchronous")
kernels = {}
for name in %r:
    mod = __import__(name, fromlist=["_"])
    kernels.update({f"{name}.{a}": len(v.compiled.signatures) for a, v in vars(mod).items()
                    if isinstance(v, jit.Kernel) and v.__module__ == name})
print(json.dumps({"compiles": len(compiles), "compiled": {k: n for k, n in kernels.items() if n},
                  "kernels": len(kernels), "registered_at_import": registered_at_import,
                  "error": float(abs(cen.x - cube.true_x).max())}))
"""


def test_a_references_only_run_renders_and_centroids_without_compiling_anything():
    out = _run(_REFERENCES_RUN % (KERNEL_MODULES,), SUNLAB_KERNELS="numpy")
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout)
    assert res == {"compiles": 0, "compiled": {}, "kernels": 8, "registered_at_import": False,
                   "error": res["error"]}
    assert jit.MESSAGE not in out.stderr
    assert res["error"] < 0.1  # the paper's algorithm B on a rendered frame: a real centroid
