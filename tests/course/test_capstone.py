"""The capstone's recordings (sunlab.course.capstone): folders a lab's camera would write,
deterministic in the seed, each frame's spot where the returned truth says."""

import csv
import io

import numpy as np
import pytest

from sunlab.course.capstone import STUDENT_SEED, Recording, write_recording
from sunlab.io.images import read_image
from sunlab.io.sensor import read_sensor_json


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    return write_recording(tmp_path_factory.mktemp("rec"), seed=1, step=6.0)


def test_folders_manifests_and_sensor_json(rec):
    assert isinstance(rec, Recording)
    assert sorted(p.name for p in rec.folder.iterdir()) == ["dark", "flat", "test", "train"]
    # a 3 x 3 training grid over +-6 deg, the 2 x 2 test grid half a step inside it
    assert rec.poses["train"].shape == (9, 2) and rec.poses["test"].shape == (4, 2)
    np.testing.assert_array_equal(np.unique(rec.poses["test"][:, 0]), [-3.0, 3.0])
    for name in ("train", "test"):
        rows = list(csv.DictReader(io.StringIO((rec.folder / name / "manifest.csv").read_text())))
        assert len(rows) == rec.truth[name].shape[0] * rec.truth[name].shape[1]
        assert all((rec.folder / name / r["file"]).is_file() for r in rows)
        sensor = read_sensor_json(rec.folder / name / "sensor.json")
        assert sensor["bit_depth"] == 10 and sensor["experiment"] == f"capstone-{name}"
    assert 2.5 <= rec.camera["mask_distance_mm"] <= 3.0


def test_the_spot_is_where_the_truth_says(rec):
    dark = np.mean([read_image(p, bit_depth=10).astype(float)
                    for p in sorted((rec.folder / "dark").glob("*.png"))], axis=0)
    for p in (0, 4, 8):
        frame = read_image(rec.folder / "train" / f"p{p:03d}_s0.png", bit_depth=10) - dark
        # the lit disk (half of full scale, ~16 px radius) against read noise of 2 DN: the
        # pixels above a quarter of full scale are the disk; the centroid of that binary disk
        # is within a few 0.1 px of its centre (edge pixels are all or nothing)
        yy, xx = np.nonzero(frame > 0.25 * 1023)
        assert len(xx) > 400
        x, y = rec.truth["train"][p, 0]
        assert abs(xx.mean() - x) < 0.5 and abs(yy.mean() - y) < 0.5


def test_a_recording_is_the_same_for_a_seed_and_another_for_another(rec, tmp_path):
    again = write_recording(tmp_path / "a", seed=1, step=6.0)
    np.testing.assert_array_equal(again.truth["train"], rec.truth["train"])
    png = "train/p004_s1.png"
    assert (again.folder / png).read_bytes() == (rec.folder / png).read_bytes()
    other = write_recording(tmp_path / "b", seed=2, step=6.0)
    assert other.camera != rec.camera
    assert STUDENT_SEED not in (1, 2)  # the student's own recording is none of these
