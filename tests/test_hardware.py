"""A lab's own hardware: a camera class found without editing sunlab (module:Class, the
``sunlab.cameras`` entry point group) and dark frames."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
import zarr

from sunlab import ConfigurationError, io, schema
from sunlab.cli import main
from sunlab.hardware import SimCamera, open_camera
from sunlab.hardware.cameras import available_cameras, capture_darks
from sunlab.hardware.errors import CameraError

LAB_CAMERA = '''
import numpy as np


class LabCamera:
    """A lab's camera: a bright square whose place follows the frame count."""

    def __init__(self, level=500, bit_depth=12, fail_at=None):
        self.shape, self.dtype, self.bit_depth = (24, 32), np.dtype(np.uint16), bit_depth
        self.level, self.n, self.fail_at = level, 0, fail_at

    def grab(self):
        if self.n == self.fail_at:
            raise OSError("USB transfer stalled")
        frame = np.full(self.shape, 20, self.dtype)
        frame[4:8, 2 + self.n:6 + self.n] = self.level
        self.n += 1
        return frame


class NotACamera:
    pass
'''


@pytest.fixture
def lab_package(tmp_path, monkeypatch):
    """A package ``labcams`` on sys.path with a dist-info that registers ``labcam`` in the
    ``sunlab.cameras`` entry point group, as ``pip install`` of the lab's package would."""
    (tmp_path / "labcams.py").write_text(textwrap.dedent(LAB_CAMERA))
    info = tmp_path / "labcams-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labcams\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.cameras]\nlabcam = labcams:LabCamera\nbroken = labcams:Missing\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path


def test_a_registered_camera_is_found_by_its_entry_point(lab_package):
    assert available_cameras()["labcam"] == "labcams:LabCamera"
    cam = open_camera("labcam", level=700)
    assert cam.grab().max() == 700 and cam.bit_depth == 12


def test_a_camera_class_is_found_by_its_import_path(lab_package):
    assert type(open_camera("labcams:LabCamera")).__name__ == "LabCamera"


@pytest.mark.parametrize("spec, words", [
    ("nosuchcam", "register it in the entry point group 'sunlab.cameras'"),
    ("broken", "does not load"),
    ("labcams:Nope", "has no 'Nope'"),
    ("nomodule_xyz:Cam", "cannot import 'nomodule_xyz'"),
    ("labcams:NotACamera", "lacks \\['grab', 'shape', 'dtype', 'bit_depth'\\]"),
])
def test_a_wrong_camera_spec_says_what_and_how(lab_package, spec, words):
    with pytest.raises(ConfigurationError, match=words):
        open_camera(spec)


def _acquire_labcam(tmp_path, option: str) -> tuple[int, Path]:
    """``sunlab acquire`` of two poses x 2 shots with the lab's camera given ``option``."""
    plan = tmp_path / "plan.csv"
    plan.write_text("alpha,beta\n0,0\n1,0\n")
    out = tmp_path / "run.zarr"
    return main(["acquire", "--stage", "fake://?velocity=1e4", "--camera", "labcam",
                 "--camera-option", option, "--plan", str(plan), "--shots", "2",
                 "--settle", "0", "--out", str(out), "--no-progress"]), out


def test_acquire_runs_a_lab_camera_without_editing_sunlab(lab_package, tmp_path, capsys):
    status, out = _acquire_labcam(tmp_path, "level=900")
    assert status == 0
    cube = io.open_frames(out)
    assert cube.attrs["bit_depth"] == 12 and dict(cube.sizes)["pose"] == 2
    # the lab camera's frames, in the order it gave them: the square moves one column a frame
    cols = [int(np.argmax(cube.frames[p, s, 5].values == 900)) for p in range(2)
            for s in range(2)]
    assert cols == [2, 3, 4, 5]


def test_a_lab_camera_that_raises_mid_run_is_named_in_one_line(lab_package, tmp_path, capsys):
    """Issue 47: the third frame's grab raises; one line names the plug-in and the method,
    exit 1, and the pose done is kept."""
    status, out = _acquire_labcam(tmp_path, "fail_at=2")
    assert status == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    for words in ("camera LabCamera of the plug-in 'labcam'", "labcams:LabCamera", "grab()",
                  "OSError: USB transfer stalled"):
        assert words in err, (words, err)
    assert zarr.open_group(out, mode="r")["done"][:].tolist() == [1, 0]


def test_dark_frames_of_a_camera_become_the_cube_master_dark():
    cam = SimCamera(roi=(100, 132, 900, 964))
    darks = capture_darks(cam, 4)
    assert darks.shape == (4, 32, 64) and not np.array_equal(darks[0], darks[1])  # new noise
    cube = schema.frames_dataset(np.stack([[cam.grab()]]), alpha=[0.0], beta=[0.0])
    cube = io.with_calibration_frames(cube, dark=darks)
    np.testing.assert_allclose(cube.master_dark.values, np.median(darks, axis=0))
    with pytest.raises(CameraError, match="cannot take dark frames"):
        capture_darks(object(), 1)


def test_sim_camera_roi_can_be_changed():
    cam = SimCamera()
    cam.set_roi((0, 64, 0, 128))
    assert cam.shape == (64, 128) and cam.grab().shape == (64, 128)
    with pytest.raises(ConfigurationError, match="roi"):
        cam.set_roi((0, 2000, 0, 10))
