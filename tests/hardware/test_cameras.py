"""Which camera ``--camera`` opens (sunlab.hardware.cameras): a lab's plug-in that raises on
import or in its constructor ends in one line naming it, on the entry-point and the module:Class
paths alike (issue 37); every name listed loads (issue 36)."""

from __future__ import annotations

import sys
import textwrap

import pytest

from sunlab import cli
from sunlab.errors import ConfigurationError
from sunlab.hardware import open_camera
from sunlab.hardware.cameras import available_cameras, camera_class


@pytest.fixture
def plugins(tmp_path, monkeypatch):
    """A real plug-in distribution on sys.path: importlib.metadata finds its entry points."""
    (tmp_path / "labcams_broken.py").write_text("raise RuntimeError('driver DLL not found')\n")
    (tmp_path / "labcams_absent.py").write_text(textwrap.dedent("""
        class Cam:
            def __init__(self, **options):
                raise RuntimeError("no camera found")
        """))
    info = tmp_path / "labcams-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labcams\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.cameras]\nbroken = labcams_broken:Cam\nabsent = labcams_absent:Cam\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("labcams_broken", "labcams_absent"):
        sys.modules.pop(name, None)


def test_registered_plugins_are_listed(plugins):
    cams = available_cameras()
    assert cams["broken"] == "labcams_broken:Cam" and cams["absent"] == "labcams_absent:Cam"


@pytest.mark.parametrize("spec", ["broken", "labcams_broken:Cam"])
def test_a_module_that_raises_on_import_is_named(plugins, spec):
    with pytest.raises(ConfigurationError, match=r"--camera .*labcams_broken.*RuntimeError: "
                                                 r"driver DLL not found.*Fix: check that the "
                                                 r"camera is connected"):
        camera_class(spec)


@pytest.mark.parametrize("spec", ["absent", "labcams_absent:Cam"])
def test_a_constructor_that_raises_is_named(plugins, spec):
    with pytest.raises(ConfigurationError, match=r"Cam did not open \(RuntimeError: no camera "
                                                 r"found\)"):
        open_camera(spec)


@pytest.mark.parametrize("spec", ["broken", "absent", "labcams_absent:Cam",
                                  "labcams_broken:Cam"])
def test_acquire_with_a_failing_plugin_ends_in_one_line_with_status_1(plugins, tmp_path,
                                                                      capsys, spec):
    status = cli.main(["acquire", "--stage", "fake://", "--camera", spec, "--plan", "I",
                       "--step", "50", "--shots", "1", "--out", str(tmp_path / "run.zarr"),
                       "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert status == 1, err
    assert len(err.splitlines()) == 1 and "RuntimeError" in err and "Fix:" in err
    assert not (tmp_path / "run.zarr").exists()


def test_every_listed_camera_loads():
    for name in available_cameras():
        assert isinstance(camera_class(name), type), name
