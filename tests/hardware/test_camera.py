"""Cameras: the protocol, the virtual-bench camera and the folder-watching camera."""

from __future__ import annotations

import io
import math
import threading
import time

import numpy as np
import pytest
import tifffile
from numpy.testing import assert_allclose, assert_array_equal
from PIL import Image

from sunlab import ConfigurationError, sim
from sunlab.hardware import FolderCamera, SimCamera
from sunlab.hardware.cameras import Camera
from sunlab.hardware.errors import CameraError, CameraTimeout
from sunlab.hardware.fake import FakeESP


@pytest.fixture(scope="module")
def small_bench():
    """The paper's single-hole bench on a 128 x 128 detector, the hole above its centre at
    F = 5 mm (a 35 px spot that stays on the small detector over +-1 deg), the mask held
    still (no play: the spot is where spot_truth puts it)."""
    return sim.Bench.paper_single_hole().replace(
        detector__nx=128, detector__ny=128, mask__distance_mm=5.0,
        mask__holes=(sim.holes.Hole(0.0, 0.0, 0.2),), mask__play_x_mm=0.0, mask__play_y_mm=0.0)


def _centroid(frame: np.ndarray, background: float) -> tuple[float, float]:
    """Intensity-weighted centroid (x, y) of the whole frame above a constant background."""
    w = frame.astype(float) - background
    y, x = np.indices(frame.shape)
    return float((w * x).sum() / w.sum()), float((w * y).sum() / w.sum())


# -- the protocol -----------------------------------------------------------------------------
def test_cameras_satisfy_the_protocol(small_bench, tmp_path):
    assert isinstance(SimCamera(small_bench), Camera)
    assert isinstance(FolderCamera(tmp_path), Camera)
    assert not isinstance(object(), Camera)


# -- SimCamera --------------------------------------------------------------------------------
def test_sim_frames_are_deterministic_per_seed_pose_shot(small_bench):
    cam = SimCamera(small_bench, seed=3)
    frames = {}
    for pose, shot in [(0, 0), (0, 1), (1, 0), (0, 0)]:
        cam.set_index(pose, shot, alpha=-0.5, beta=0.25)
        frames.setdefault((pose, shot), []).append(cam.grab())
    assert_array_equal(*frames[(0, 0)])
    assert not np.array_equal(frames[(0, 0)][0], frames[(0, 1)][0])  # new noise per shot
    assert not np.array_equal(frames[(0, 0)][0], frames[(1, 0)][0])  # new pose error per pose
    other = SimCamera(small_bench, seed=4)
    other.set_index(0, 0, alpha=-0.5, beta=0.25)
    assert not np.array_equal(other.grab(), frames[(0, 0)][0])


def test_sim_frame_is_the_virtual_bench_frame_at_the_true_pose(small_bench):
    cam = SimCamera(small_bench, seed=1)
    cam.set_index(4, 1, alpha=-0.75, beta=0.5)
    frame = cam.grab()
    a, b = sim.platform.platform_pose(small_bench, -0.75, 0.5, seed=1, pose=4, shot=1)
    assert cam.last_truth == (a, b)
    assert abs(a + 0.75) > 0 and abs(a + 0.75) < 0.05  # a platform error, and a small one
    assert_array_equal(frame, sim.render_frame(small_bench, a, b, seed=1, pose=4, shot=1))


def test_sim_camera_takes_the_true_pose_from_the_controller(small_bench):
    fake = FakeESP(bench=small_bench, seed=2, velocity_deg_s=math.inf)
    fake.handle(b"1PA-1;2PA0.5")
    cam = SimCamera(small_bench, seed=2, truth=fake.true_pose)
    cam.set_index(7, 0, alpha=99.0, beta=99.0)  # read-back ignored: the controller knows best
    frame = cam.grab()
    truth = sim.platform.platform_pose(small_bench, -1.0, 0.5, seed=2, pose=7, shot=0)
    assert cam.last_truth == truth
    assert_array_equal(frame, sim.render_frame(small_bench, *truth, seed=2, pose=7, shot=0))


@pytest.mark.parametrize("binning", [1, 2, 4])
def test_roi_and_binning_keep_the_pixel_convention(small_bench, binning):
    """Binned centroid = (centroid - roi origin - (b - 1) / 2) / b, and x_cf_px likewise.

    Binning moves each pixel's weight to the centre of its bin: for a spot some 35 px wide the
    centroid moves by far less than 1e-3 px, the tolerance used."""
    bench = small_bench.noise_free().ideal_platform()
    roi = (16, 112, 24, 120)
    full = SimCamera(bench)
    cut = SimCamera(bench, roi=roi, binning=binning)
    assert cut.shape == (96 // binning, 96 // binning)
    assert cut.bit_depth == 10 + int(2 * np.log2(binning))
    for cam in (full, cut):
        cam.set_index(0, 0, alpha=1.0, beta=-0.5)
    f_full, f_cut = full.grab(), cut.grab()
    bias = float(np.median(f_full))
    x, y = _centroid(f_full[roi[0]:roi[1], roi[2]:roi[3]], bias)
    xb, yb = _centroid(f_cut, bias * binning**2)
    assert_allclose([xb, yb], [(x - (binning - 1) / 2) / binning,
                               (y - (binning - 1) / 2) / binning], atol=1e-3)
    # the whole-frame centroid is the true spot (noise-free frame; 0.05 px allows the blur tail
    # cut by the frame edge and the rounding to DN)
    tx, ty = sim.spots.spot_truth(bench, 1.0, -0.5)
    assert_allclose(_centroid(f_full, bias), [tx[0], ty[0]], atol=0.05)
    xd, yd = bench.hole_design_px()
    attrs = cut.attrs
    assert_allclose(attrs["x_cf_px"], (xd[0] - roi[2] - (binning - 1) / 2) / binning)
    assert_allclose(attrs["y_cf_px"], (yd[0] - roi[0] - (binning - 1) / 2) / binning)
    assert_allclose(attrs["pixel_pitch_mm"], 0.007 * binning)


def test_the_spot_moves_plus_x_with_plus_alpha(small_bench):
    cam = SimCamera(small_bench.noise_free().ideal_platform())
    xs = []
    for alpha in (-1.0, 0.0, 1.0):
        cam.set_index(0, 0, alpha=alpha, beta=0.0)
        frame = cam.grab()
        xs.append(_centroid(frame, float(np.median(frame)))[0])
    # eq. (1): dx = F tan(alpha) / pitch = 5.0 * tan(1 deg) / 0.007 ~ 12.5 px (F' = F + dF)
    assert 11.0 < xs[1] - xs[0] < 14.0 and 11.0 < xs[2] - xs[1] < 14.0


@pytest.mark.parametrize("kwargs", [{"roi": (0, 200, 0, 10)}, {"roi": (10, 5, 0, 10)},
                                    {"binning": 3}, {"binning": 0}, {"binning": 16}])
def test_bad_roi_or_binning_is_a_configuration_error(small_bench, kwargs):
    with pytest.raises(ConfigurationError):
        SimCamera(small_bench, **kwargs)


# -- FolderCamera -----------------------------------------------------------------------------
def _tiff_bytes(frame: np.ndarray) -> bytes:
    buf = io.BytesIO()
    tifffile.imwrite(buf, frame)
    return buf.getvalue()


def _slow_write(path, data: bytes, pieces: int = 4, pause: float = 0.04) -> threading.Thread:
    def run():
        step = -(-len(data) // pieces)
        with open(path, "wb") as f:
            for i in range(0, len(data), step):
                f.write(data[i:i + step])
                f.flush()
                time.sleep(pause)

    thread = threading.Thread(target=run)
    thread.start()
    return thread


def test_folder_camera_waits_for_a_complete_new_file(tmp_path):
    tifffile.imwrite(tmp_path / "old.tif", np.zeros((8, 10), np.uint16))  # there before: ignored
    frame = np.arange(80, dtype=np.uint16).reshape(8, 10) * 12
    writers = []  # the camera starts writing, slowly, when triggered
    cam = FolderCamera(tmp_path, shape=(8, 10), stable_s=0.02, poll_s=0.005, timeout_s=5.0,
                       trigger=lambda: writers.append(_slow_write(tmp_path / "new.tif",
                                                                  _tiff_bytes(frame))))
    got = cam.grab()
    writers[0].join()
    assert_array_equal(got, frame)
    assert cam.last_file.name == "new.tif"


def test_folder_camera_reads_png_written_after_the_trigger_only(tmp_path):
    frames = [np.full((4, 6), 100 * (i + 1), np.uint16) for i in range(3)]
    cam = FolderCamera(tmp_path, shape=(4, 6), stable_s=0.0, poll_s=0.005, timeout_s=2.0,
                       trigger=lambda: Image.fromarray(frames[2]).save(tmp_path / "f2.png"))
    for i in (0, 1):  # written before the grab (during the move): never taken
        Image.fromarray(frames[i]).save(tmp_path / f"f{i}.png")
    got = cam.grab()
    assert_array_equal(got, frames[2])
    assert got.dtype == np.uint16 and cam.last_file.name == "f2.png"


def test_folder_camera_takes_the_first_file_of_a_free_running_writer(tmp_path):
    # A camera that runs free writes a frame every 20 ms whatever the stage does; the grab
    # (called once the pose is settled) takes the first file written after it starts, never
    # one written before, and skip=1 drops that first file (its exposure may have begun before
    # the grab) for the next.
    stop = threading.Event()
    written = []

    def writer():
        k = 0
        while not stop.is_set():
            # written under a hidden name, then renamed: the file appears whole
            tifffile.imwrite(tmp_path / f".tmp{k}.tif", np.full((2, 2), k, np.uint16))
            (tmp_path / f".tmp{k}.tif").rename(tmp_path / f"f{k:04d}.tif")
            written.append(k)
            k += 1
            time.sleep(0.02)

    thread = threading.Thread(target=writer, daemon=True)
    thread.start()
    try:
        for skip in (0, 1):
            cam = FolderCamera(tmp_path, shape=(2, 2), stable_s=0.0, poll_s=0.002,
                               timeout_s=2.0, skip=skip)
            time.sleep(0.1)  # the writer goes on while the stage moves and settles
            before = written[-1]  # the last file written before the grab starts
            value = int(cam.grab()[0, 0])
            first_after = before + 1
            # never a file written before the grab; the grab's own snapshot may see a file or
            # two more that the writer wrote meanwhile (a loaded machine)
            assert first_after + skip <= value <= first_after + skip + 3
    finally:
        stop.set()
        thread.join()


def test_folder_camera_trigger_is_fired_per_grab(tmp_path):
    count = []

    def trigger():
        count.append(1)
        tifffile.imwrite(tmp_path / f"t{len(count)}.tif", np.full((2, 2), len(count), np.uint16))

    cam = FolderCamera(tmp_path, shape=(2, 2), stable_s=0.0, poll_s=0.005, trigger=trigger)
    assert [int(cam.grab()[0, 0]) for _ in range(3)] == [1, 2, 3]


def test_folder_camera_times_out_with_a_clear_error(tmp_path):
    (tmp_path / "broken.tif").write_bytes(b"II*\x00")  # there before: ignored
    cam = FolderCamera(tmp_path, shape=(2, 2), timeout_s=0.2, poll_s=0.01, stable_s=0.0,
                       trigger=lambda: (tmp_path / "late.tif").write_bytes(b"II*\x00\x08"))
    # late.tif appears after the trigger and never completes
    t0 = time.monotonic()
    with pytest.raises(CameraTimeout, match="within 0.2 s.*last read error") as info:
        cam.grab()
    assert time.monotonic() - t0 >= 0.2  # it waited its timeout (no upper bound: a busy
    # machine may take longer, and a test must not depend on wall-clock speed)
    assert str(tmp_path) in str(info.value)


@pytest.mark.parametrize("frame, match", [(np.zeros((3, 3), np.uint16), "expected \\(2, 2\\)"),
                                          (np.zeros((2, 2), np.float32), "do not fit"),
                                          (np.zeros((2, 2, 3), np.uint8), "one grey frame")])
def test_folder_camera_rejects_wrong_frames(tmp_path, frame, match):
    cam = FolderCamera(tmp_path, shape=(2, 2), stable_s=0.0, timeout_s=1.0,
                       trigger=lambda: tifffile.imwrite(tmp_path / "x.tif", frame))
    with pytest.raises(CameraError, match=match):
        cam.grab()


def test_folder_camera_needs_a_folder(tmp_path):
    with pytest.raises(ConfigurationError, match="not a directory"):
        FolderCamera(tmp_path / "missing")
