"""Tests of sunlab.extras and the package's dependencies: a light core, heavy parts as extras.

The core (``pip install sunlab``) must not need torch, pyserial or ipywidgets; each of them is
an extra, and a missing one is an ImportError naming it. The extras are hidden here through a
monkeypatched ``importlib.import_module`` (what :func:`sunlab.extras.require` calls), so the
tests run the same in a full and in a core install.
"""

import importlib
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from sunlab import extras

ROOT = Path(__file__).resolve().parents[1]


def _name(requirement: str) -> str:
    return re.split(r"[\s<>=!~;\[]", requirement, maxsplit=1)[0].lower()


@pytest.fixture(scope="module")
def project() -> dict:
    return tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))["project"]


def test_the_core_holds_no_extra_and_no_unused_package(project):
    core = {_name(r) for r in project["dependencies"]}
    assert {"numpy", "scipy", "pandas", "xarray", "dask", "zarr", "h5netcdf", "matplotlib",
            "numba", "tqdm", "jsonschema", "tifffile", "pillow"} <= core
    # the networks, the stage, the explorer and scikit-image (imported by no module of the
    # core) are not core dependencies
    assert core.isdisjoint({"torch", "pyserial", "ipywidgets", "scikit-image", "distributed"})


def test_each_extra_brings_its_package(project):
    opt = {k: [_name(r) for r in v] for k, v in project["optional-dependencies"].items()}
    assert project["optional-dependencies"]["neural"] == ["torch==2.13.0"]  # the CPU wheel
    assert opt["hardware"] == ["pyserial"] and opt["widgets"] == ["ipywidgets"]
    assert opt["distributed"] == ["distributed"]
    assert opt["course"] == ["nbgrader"]
    assert project["optional-dependencies"]["all"] == [
        "sunlab[neural,hardware,widgets,distributed,course]"]
    # every extra that sunlab.extras names exists in pyproject.toml
    assert set(extras.EXTRAS.values()) <= set(opt)


def test_make_installs_every_extra():
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    assert "-e '.[all,dev,benchmarks,browser,docs]'" in makefile


@pytest.fixture
def hide(monkeypatch):
    """``hide("torch", ...)``: importing those packages through sunlab.extras fails as if they
    were not installed."""
    real = importlib.import_module

    def hide_(*names):
        def fake(name, package=None):
            if name.partition(".")[0] in names:
                raise ModuleNotFoundError(f"No module named {name!r}", name=name)
            return real(name, package)

        monkeypatch.setattr(importlib, "import_module", fake)

    return hide_


def test_require_names_the_extra(hide):
    hide("torch")
    with pytest.raises(ImportError, match=re.escape('pip install "sunlab[neural]"')) as err:
        extras.require("torch", purpose="the networks")
    assert isinstance(err.value.__cause__, ModuleNotFoundError)
    assert "for the networks" in str(err.value)


def _grid_table(n=9):
    from sunlab import sim

    a, b = np.meshgrid(np.linspace(-8.0, 8.0, n), np.linspace(-8.0, 8.0, n), indexing="ij")
    return sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, noise_px=0.01, seed=3)


def test_neural_net_without_torch_names_the_neural_extra(hide):
    from sunlab.calibration import NeuralNet

    hide("torch")
    with pytest.raises(ImportError, match=re.escape('pip install "sunlab[neural]"')):
        NeuralNet(hidden=2).fit(_grid_table())


def test_a_saved_network_predicts_without_torch(hide):
    # only fitting needs torch: a saved network is numpy arithmetic
    pytest.importorskip("torch")
    from sunlab import calibration

    table = _grid_table()
    doc = calibration.NeuralNet(hidden=2, max_iter=50).fit(table).to_dict()
    hide("torch")
    back = calibration.artifact.from_dict(doc)
    a, _ = back.predict_xy(table.x.values, table.y.values)
    assert np.isfinite(a).all()


def test_a_cluster_without_distributed_names_its_extra(hide):
    from sunlab import parallel

    hide("distributed")
    with pytest.raises(ImportError, match=re.escape('"sunlab[distributed]"')):
        with parallel.local_cluster(1):
            pass


def test_a_serial_port_without_pyserial_names_the_hardware_extra(hide):
    from sunlab.hardware import ESP300

    hide("serial")
    with pytest.raises(ImportError, match=re.escape('"sunlab[hardware]"')):
        ESP300("loop://")


def test_table4_without_torch_marks_the_networks_not_run(hide):
    from sunlab.reproduce.table4 import format_table, reproduce_table4

    hide("torch")
    res = reproduce_table4(step=4, shots=1, out=None, progress=False)
    not_run = res.settings["not_run"]
    assert sorted(not_run) == [f"NN strategy {s}" for s in (1, 2, 3, 4)]
    assert not any(c.startswith("NN") for c in res.table.columns)
    assert "polynomial" in res.table.columns  # every method without an extra still runs
    text = format_table(res)
    assert all(f"NN strategy {s}" in text for s in (1, 2, 3, 4))
    assert text.count("not run") == 4 and 'pip install "sunlab[neural]"' in text


def test_import_of_the_core_loads_no_heavy_module():
    # what `import sunlab` plus io, calibration and stats loads, counted in a fresh interpreter
    # (a count of modules, not a timing): none of the extras, no compiler, no plotting, no
    # virtual bench
    heavy = ["torch", "serial", "ipywidgets", "distributed", "numba", "matplotlib", "skimage",
             "sunlab.sim", "sunlab.centroid", "sunlab.plots", "sunlab.reproduce"]
    code = ("import sys\nimport sunlab, sunlab.io, sunlab.calibration, sunlab.stats\n"
            f"print([m for m in {heavy!r} if m in sys.modules])")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True, cwd=ROOT).stdout.strip()
    assert out == "[]"


def test_installed_version_of_an_absent_distribution_is_none():
    assert extras.installed_version("no-such-distribution-xyz") is None
