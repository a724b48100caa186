"""The registry of stages (sunlab.hardware.stage): built-ins by URL scheme, a lab's own stage
by the entry point group ``sunlab.stages`` (issue 36), and a stage plug-in that fails named
in one line (issue 37)."""

from __future__ import annotations

import sys
import textwrap

import pytest

from sunlab import cli
from sunlab.errors import ConfigurationError
from sunlab.hardware import ESP300, open_stage
from sunlab.hardware.stage import available_stages


@pytest.fixture
def plugin(tmp_path, monkeypatch):
    """A real distribution on sys.path registering two stages (importlib.metadata finds it)."""
    (tmp_path / "labstages.py").write_text(textwrap.dedent("""
        class Rig:
            def __init__(self, url):
                self.url, self.at = url, (0.0, 0.0)
            def move_to(self, alpha, beta):
                self.at = (float(alpha), float(beta))
                return self.at
            def position(self):
                return self.at
            def describe(self):
                return {"model": "rig", "url": self.url}
            def close(self):
                pass

        def open_rig(url, **options):
            return Rig(url)

        def open_dead(url, **options):
            raise RuntimeError("controller not found on the bus")
        """))
    info = tmp_path / "labstages-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labstages\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.stages]\nrig = labstages:open_rig\ndead = labstages:open_dead\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield
    sys.modules.pop("labstages", None)


def test_the_builtins_are_registered():
    assert "fake" in available_stages()
    stage = open_stage("fake://?velocity=1e4", retry_delay_s=0.0, poll_s=0.001)
    try:
        assert isinstance(stage, ESP300) and stage.move_to(1.0, 2.0) == (1.0, 2.0)
    finally:
        stage.close()


def test_a_registered_stage_opens_by_its_scheme(plugin):
    assert available_stages()["rig"] == "labstages:open_rig"
    stage = open_stage("rig:bay-3")
    assert type(stage).__name__ == "Rig" and stage.move_to(1.5, -2.0) == (1.5, -2.0)
    assert stage.describe() == {"model": "rig", "url": "rig:bay-3"}


def test_a_stage_plugin_that_raises_is_named(plugin):
    with pytest.raises(ConfigurationError, match=r"open_dead did not open \(RuntimeError: "
                                                 r"controller not found on the bus\)"):
        open_stage("dead:bay-1")


def test_acquire_through_a_registered_stage(plugin, tmp_path, capsys):
    status = cli.main(["acquire", "--stage", "rig:bay-3", "--camera", "sim", "--plan", "I",
                       "--step", "60", "--shots", "1", "--out", str(tmp_path / "run.zarr"),
                       "--no-progress"])
    assert status == 0, capsys.readouterr().err
    status = cli.main(["acquire", "--stage", "dead:bay-1", "--camera", "sim", "--plan", "I",
                       "--step", "60", "--shots", "1", "--out", str(tmp_path / "r2.zarr"),
                       "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1 and "controller not found" in err
