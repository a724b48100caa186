"""The registry of stages (sunlab.hardware.stage): built-ins by URL scheme, a lab's own stage
by the entry point group ``sunlab.stages`` (issue 36), a stage plug-in that fails named
in one line (issue 37), when it opens or mid-run (issue 47)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
import zarr

from sunlab import cli
from sunlab.errors import ConfigurationError
from sunlab.hardware import ESP300, open_stage
from sunlab.hardware.stage import available_stages
from sunlab.sim import _jit


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

        class Flaky(Rig):  # "flaky:N": the N-th move raises, as a driver's own bug would
            def move_to(self, alpha, beta):
                self.moves = getattr(self, "moves", 0) + 1
                if self.url == f"flaky:{self.moves}":
                    raise KeyError("encoder frame 0x7f")
                return super().move_to(alpha, beta)

        def open_flaky(url, **options):
            return Flaky(url)
        """))
    info = tmp_path / "labstages-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labstages\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.stages]\nrig = labstages:open_rig\ndead = labstages:open_dead\n"
        "flaky = labstages:open_flaky\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
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


def test_a_stage_plugin_that_raises_mid_run_ends_the_cli_in_one_line_and_resumes(plugin):
    """The real ``sunlab`` in a process of its own, the plug-in's distribution on its path: the
    third move raises; the command names the plug-in and the method in one line, exit 1, and
    the two poses done are kept for ``--resume``."""
    out = plugin / "run.zarr"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(plugin),
                                                       str(Path(__file__).parents[2])]))

    def sunlab(stage, *extra):
        return subprocess.run(
            [sys.executable, "-m", "sunlab.cli", "acquire", "--stage", stage, "--camera", "sim",
             "--plan", "I", "--step", "30", "--shots", "1", "--binning", "8", "--out", str(out),
             "--no-progress", *extra], env=env, capture_output=True, text=True, timeout=300)

    failed = sunlab("flaky:3")
    lines = [n for n in failed.stderr.splitlines() if n and n != _jit.MESSAGE]  # once a machine
    assert failed.returncode == 1 and len(lines) == 1, failed.stderr
    line = lines[0]
    for words in ("'flaky'", "labstages:open_flaky", "labstages 0.1", "move_to", "KeyError",
                  "encoder frame 0x7f", "--resume"):
        assert words in line, (words, line)
    assert zarr.open_group(out, mode="r")["done"][:].tolist() == [1, 1] + [0] * 12
    resumed = sunlab("flaky:never", "--resume")
    assert resumed.returncode == 0, resumed.stderr
    assert "14/14 poses" in resumed.stdout and "12 this session" in resumed.stdout
    group = zarr.open_group(out, mode="r")
    sessions = group.attrs["sessions"]
    assert [s["exit_status"] for s in sessions] == ["failed", "complete"]
    assert sessions[0]["poses"] == 2 and group["done"][:].all()
