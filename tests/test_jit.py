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
KERNEL_MODULES = ["sunlab.sim._kernels"] + [
    f"sunlab.centroid._k_{m}" for m in ("aperture", "detect", "diskfit", "lattice", "windows")]
#: Kernels whose reference is their own source, interpreted (jit.interpreted), not a numpy
#: function written beside them: the tight window's aperture, the disk fits, the detection and
#: the lattice (sequential algorithms: flood fills, Gauss-Newton iterations, row tables).
INTERPRETED = {"clip_convex", "aperture_rows", "shift_rows", "rows_com", "rows_moments",
               "aperture_moments", "annulus_mean", "measure_spots", "sample_stats",
               "coarse_blobs", "fit_disk", "disk_noise", "zone_noise", "fit_profile",
               "profile_noise", "profile_flux", "neighbour_vectors", "fit_lattice",
               "spot_table", "quality_metrics", "nearest_spot_per_hole", "tight_spots",
               "fill_holes", "grid_offset", "new_holes", "assign_grid", "locate_tight"}


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
    assert len(kernels) == 40
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


def _spot_frame(seed=1, centres=((70.3, 55.7),), shape=(120, 160)):
    rng = np.random.default_rng(seed)
    yy, xx = np.mgrid[0:shape[0], 0:shape[1]]
    spot = sum(600 * np.exp(-((xx - x) ** 2 + (yy - y) ** 2) / (2 * 3.0**2)) for x, y in centres)
    return (40 + spot + rng.normal(0, 2, yy.shape)).clip(0, 1023).astype(np.uint16)


@pytest.mark.parametrize("method", ["threshold", "projection", "tight", "fit"])
def test_every_estimator_gives_the_same_centroid_on_the_references(method):
    from sunlab.centroid import METHODS

    frame = _spot_frame()
    compiled = METHODS[method](frame)
    with sunlab.set_options(kernels="numpy"):
        ref = METHODS[method](frame)
    assert ref.status == compiled.status and ref.window == compiled.window
    # sums in another order (numpy's pairwise sums, the kernels' fastmath reassociation):
    # the centroid to rounding, far below the 1e-3 px the estimators resolve
    np.testing.assert_allclose([ref.x, ref.y], [compiled.x, compiled.y], rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.flux, compiled.flux, rtol=1e-10)


@pytest.mark.parametrize("method", ["tight", "fit"])
def test_the_lattice_gives_the_same_spots_on_the_references(method):
    from sunlab.centroid import locate_spots

    centres = [(50.3 + 30 * j + 0.3 * i, 45.6 + 30 * i - 0.2 * j) for i in range(3)
               for j in range(3)]
    frame = _spot_frame(2, centres, shape=(150, 160))
    compiled = locate_spots(frame, shape=(3, 3), pitch=30.0, method=method)
    with sunlab.set_options(kernels="numpy"):
        ref = locate_spots(frame, shape=(3, 3), pitch=30.0, method=method)
    assert ref.status.tolist() == compiled.status.tolist()
    assert (compiled.status == 0).sum() >= 8  # spots found and indexed, not an empty agreement
    np.testing.assert_allclose(ref.x, compiled.x, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ref.y, compiled.y, rtol=0, atol=1e-9)


_WINDOWS_CASES = [
    ("ring_mean", (0, 120, 0, 160, 2)), ("ring_mean", (10, 14, 20, 23, 3)),
    ("ring_mean", (5, 5, 0, 9, 1)),  # empty box: NaN
    ("scan_first", (300.0, 2, 13, 1, 119, 1, 159, 0, 0, 0, 0)),
    ("scan_first", (300.0, 2, 13, 1, 119, 1, 159, 40, 70, 50, 90)),  # the spot excluded
    ("scan_first", (5000.0, 2, 13, 1, 119, 1, 159, 0, 0, 0, 0)),  # nothing above
    ("com_above", (40, 70, 55, 90, 300.0)), ("com_above", (0, 10, 0, 10, 5000.0)),
    ("com_box", (40, 70, 55, 90, 40.0)), ("com_box", (0, 0, 0, 10, 40.0)),
]


@pytest.mark.parametrize(("name", "args"), _WINDOWS_CASES)
def test_the_window_kernels_agree_with_their_references(name, args):
    from sunlab.centroid import _k_windows

    k = getattr(_k_windows, name)
    frame = _spot_frame()
    np.testing.assert_allclose(np.array(k.numpy(frame, *args), dtype=float),
                               np.array(k.compiled(frame, *args), dtype=float),
                               rtol=1e-12, atol=1e-12, equal_nan=True)


def test_the_profile_kernels_agree_with_their_references():
    from sunlab.centroid import _k_windows as K

    frame = _spot_frame()
    for a, b in zip(K.profiles.numpy(frame), K.profiles.compiled(frame), strict=True):
        np.testing.assert_array_equal(a, b)  # integer sums: exact in float64
    p = K.profiles.compiled(frame)[0]
    np.testing.assert_array_equal(K.robust_level.numpy(p), K.robust_level.compiled(p))


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
    assert res == {"compiles": 0, "compiled": {}, "kernels": 40, "registered_at_import": False,
                   "error": res["error"]}
    assert jit.MESSAGE not in out.stderr
    assert res["error"] < 0.1  # the paper's algorithm B on a rendered frame: a real centroid
