"""The resumable acquisition runner: store contract, resume, Ctrl-C, faults, SIGKILL at random.

The bench is the fake ESP301 on a real pseudo-terminal and the virtual-bench camera on a small
detector (128 x 128 px, binned 2 x 2), so that a run of 12 poses x 2 shots takes a second.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest
import zarr
from numpy.testing import assert_array_equal

from sunlab import ConfigurationError, plans, schema, sim
from sunlab.hardware import ESP300, MotionTimeout, SimCamera, acquire, open_run
from sunlab.hardware.errors import CameraError, ErrorReplyLost
from sunlab.hardware.fake import FakeESP

SEED = 5
NX = 128
BINNING = 2
DRIVER = {"timeout": 0.1, "retries": 3, "retry_delay_s": 0.0, "poll_s": 0.001}
#: 3 x 4 poses within +-1.5 deg, so that the spot stays on the 128 px detector
PLAN = plans.grid(-1.5, 0.5, 1.0, -1.0, 1.25, 0.75, shots=2, name="bench-test")
#: 5 x 4 poses for the SIGKILL test: room for ten kills spread over the run
KILL_PLAN = plans.grid(-2.5, 0.5, 0.75, -1.0, 1.25, 0.75, shots=2, name="kill-test")


@pytest.fixture(scope="module")
def bench():
    return sim.Bench.paper_single_hole().replace(detector__nx=NX, detector__ny=NX)


class Rig:
    """Fake controller on a pty, driver, simulated camera; closed by the fixture."""

    def __init__(self, bench, **driver):
        self.fake = FakeESP(bench=bench, seed=SEED, velocity_deg_s=1000.0)
        self.stage = ESP300(self.fake.serve_pty(), **{**DRIVER, **driver})
        self.camera = SimCamera(bench, seed=SEED, truth=self.fake.true_pose, binning=BINNING)

    def close(self):
        self.stage.close()
        self.fake.close()


@pytest.fixture
def rig(bench):
    made = []

    def make(**driver):
        made.append(Rig(bench, **driver))
        return made[-1]

    yield make
    for r in made:
        r.close()


def expected_frames(bench, plan):
    """Frames the runner must record, computed independently from the virtual bench."""
    out = np.empty((len(plan), plan.shots, NX // BINNING, NX // BINNING), np.uint16)
    for p in range(len(plan)):
        for s in range(plan.shots):
            a, b = sim.platform.platform_pose(bench, plan.alpha[p], plan.beta[p], seed=SEED, pose=p,
                                     shot=s)
            f = sim.render_frame(bench, a, b, seed=SEED, pose=p, shot=s).astype(np.uint32)
            out[p, s] = f.reshape(NX // 2, 2, NX // 2, 2).sum(axis=(1, 3))
    return out


@pytest.fixture(scope="module")
def truth_frames(bench):
    return expected_frames(bench, PLAN)


class Hooked:
    """Wrap a camera; call ``hook(pose, shot)`` before each grab."""

    def __init__(self, camera, hook):
        self.camera, self.hook = camera, hook
        self.shape, self.dtype, self.bit_depth = camera.shape, camera.dtype, camera.bit_depth
        self.attrs = camera.attrs
        self.index = (0, 0)

    def set_index(self, pose, shot, **kw):
        self.index = (pose, shot)
        self.camera.set_index(pose, shot, **kw)

    def grab(self):
        self.hook(*self.index)
        return self.camera.grab()


# -- a complete run ---------------------------------------------------------------------------
def test_a_complete_run_follows_the_contract(rig, tmp_path, truth_frames):
    r = rig()
    t0 = time.time()
    result = acquire(PLAN, r.stage, r.camera, tmp_path / "run.zarr", progress=False)
    t1 = time.time()
    assert (result.exit_status, result.poses_done, result.poses_this_session) == ("complete", 12,
                                                                                  12)
    run = open_run(result.path)
    schema.validate_frames(run)
    assert dict(run.frames.sizes) == {"pose": 12, "shot": 2, "y": 64, "x": 64}
    assert run.frames.data.chunksize == (1, 1, 64, 64)
    assert_array_equal(run.frames.values, truth_frames)
    assert_array_equal(run.alpha.values, PLAN.alpha)
    # the encoder read-back of the fake is the commanded angle to its 1e-4 deg resolution
    np.testing.assert_allclose(run.alpha_read.values, PLAN.alpha[:, None] + 0 * run.shot.values,
                               atol=1e-4)
    np.testing.assert_allclose(run.beta_read.values, np.repeat(PLAN.beta[:, None], 2, 1),
                               atol=1e-4)
    seconds = run.time.values.astype("datetime64[ns]").astype(np.int64).ravel() / 1e9
    assert np.all(np.diff(seconds) > 0) and t0 <= seconds[0] and seconds[-1] <= t1
    assert run.done.values.tolist() == [1] * 12
    attrs = run.attrs
    assert attrs["exit_status"] == "complete" and attrs["error"] is None
    assert attrs["uid"] == result.uid and len(attrs["uid"]) == 32
    assert attrs["plan"] == {"name": "bench-test", "n_poses": 12, "shots": 2}
    assert set(attrs["versions"]) >= {"sunlab", "numpy", "xarray", "zarr", "pyserial"}
    assert attrs["stage"]["identity"].startswith("ESP301")
    assert attrs["camera"]["binning"] == BINNING
    assert attrs["start"] <= attrs["stop"]
    assert [s["exit_status"] for s in attrs["sessions"]] == ["complete"]
    assert attrs["bit_depth"] == 12 and attrs["pixel_pitch_mm"] == 0.014
    # sunlab.io reads it as any cube (every chunk present)
    from sunlab import io

    assert_array_equal(io.open_frames(result.path).frames.values, truth_frames)


def test_an_existing_store_needs_resume_and_the_same_plan(rig, tmp_path):
    r = rig()
    path = tmp_path / "run.zarr"
    small = PLAN[:2]
    acquire(small, r.stage, r.camera, path, progress=False)
    with pytest.raises(ConfigurationError, match="resume"):
        acquire(small, r.stage, r.camera, path, progress=False)
    with pytest.raises(ConfigurationError, match="plan and camera"):
        acquire(PLAN[:3], r.stage, r.camera, path, resume=True, progress=False)
    shifted = plans.custom(small.alpha + 0.5, small.beta, shots=2)
    with pytest.raises(ConfigurationError, match="commanded angles"):
        acquire(shifted, r.stage, r.camera, path, resume=True, progress=False)
    other = SimCamera(r.camera.bench, seed=SEED, binning=4)
    with pytest.raises(ConfigurationError, match="plan and camera"):
        acquire(small, r.stage, other, path, resume=True, progress=False)
    # resuming a finished run does nothing and says complete
    again = acquire(small, r.stage, r.camera, path, resume=True, progress=False)
    assert (again.exit_status, again.poses_this_session) == ("complete", 0)
    foreign = tmp_path / "foreign.zarr"
    zarr.open_group(foreign, mode="w").attrs["sunlab_schema"] = "frames/1"
    with pytest.raises(ConfigurationError, match="not a sunlab acquisition store"):
        acquire(small, r.stage, r.camera, foreign, resume=True, progress=False)


# -- stopping and resuming --------------------------------------------------------------------
def test_stop_between_poses_then_resume_equals_an_uninterrupted_run(rig, tmp_path,
                                                                    truth_frames):
    r = rig()
    stop = threading.Event()
    cam = Hooked(r.camera, lambda pose, shot: stop.set() if pose == 4 else None)
    path = tmp_path / "run.zarr"
    first = acquire(PLAN, r.stage, cam, path, progress=False, stop=stop)
    assert (first.exit_status, first.poses_done) == ("interrupted", 5)  # pose 4 was finished
    g = zarr.open_group(path, mode="r")
    assert g["done"][:].tolist() == [1] * 5 + [0] * 7
    assert np.isnan(g["alpha_read"][5:]).all()
    second = acquire(PLAN, r.stage, r.camera, path, resume=True, progress=False)
    assert (second.exit_status, second.poses_this_session, second.uid) == ("complete", 7,
                                                                          first.uid)
    run = open_run(path)
    assert_array_equal(run.frames.values, truth_frames)
    assert [s["exit_status"] for s in run.attrs["sessions"]] == ["interrupted", "complete"]
    assert [s["poses"] for s in run.attrs["sessions"]] == [5, 7]


def test_ctrl_c_stops_cleanly_between_poses(rig, tmp_path):
    r = rig()

    def hook(pose, shot):
        if (pose, shot) == (2, 0):
            os.kill(os.getpid(), signal.SIGINT)

    before = signal.getsignal(signal.SIGINT)
    result = acquire(PLAN, r.stage, Hooked(r.camera, hook), tmp_path / "run.zarr",
                     progress=False)
    assert (result.exit_status, result.poses_done) == ("interrupted", 3)
    assert signal.getsignal(signal.SIGINT) is before
    assert open_run(result.path).attrs["exit_status"] == "interrupted"


# -- faults -----------------------------------------------------------------------------------
def _assert_pose_untouched(path, pose):
    g = zarr.open_group(path, mode="r")
    assert g["done"][pose] == 0
    assert np.isnan(g["alpha_read"][pose]).all() and np.isnan(g["time"][pose]).all()
    assert not (path / "frames" / "c" / str(pose)).exists()  # no frame chunk at all


def test_a_camera_fault_writes_nothing_for_its_pose(rig, tmp_path, truth_frames):
    r = rig()

    def hook(pose, shot):
        if (pose, shot) == (3, 1):
            raise CameraError("camera: test fault at pose 3 shot 1")

    path = tmp_path / "run.zarr"
    with pytest.raises(CameraError, match="test fault"):
        acquire(PLAN, r.stage, Hooked(r.camera, hook), path, progress=False)
    _assert_pose_untouched(path, 3)
    g = zarr.open_group(path, mode="r")
    assert g["done"][:].tolist() == [1, 1, 1] + [0] * 9
    assert g.attrs["exit_status"] == "failed" and "test fault" in g.attrs["error"]
    done = acquire(PLAN, r.stage, r.camera, path, resume=True, progress=False)
    assert done.exit_status == "complete"
    assert_array_equal(open_run(path).frames.values, truth_frames)


def test_a_stuck_stage_writes_nothing_for_its_pose(rig, tmp_path):
    r = rig(motion_timeout_s=0.1)
    path = tmp_path / "run.zarr"
    calls = []

    def hook(pose, shot):
        calls.append(pose)
        if pose == 1 and shot == 1:
            r.fake.inject("stuck", "2PA")  # the move to pose 2 never finishes

    with pytest.raises(MotionTimeout):
        acquire(PLAN, r.stage, Hooked(r.camera, hook), path, progress=False)
    _assert_pose_untouched(path, 2)
    assert 2 not in calls  # no frame was taken at a pose the stage never reached
    assert "MotionTimeout" not in zarr.open_group(path).attrs["error"]  # the message, not a type
    assert "did not reach" in zarr.open_group(path).attrs["error"]


def test_link_faults_during_a_run_are_survived(rig, tmp_path, truth_frames):
    r = rig()
    r.fake.inject("garble", "1TP?", count=3)
    r.fake.inject("timeout", "2MD?", count=2)
    r.fake.inject("silent", "1MD?", silent_s=0.15)
    result = acquire(PLAN, r.stage, r.camera, tmp_path / "run.zarr", progress=False)
    assert result.exit_status == "complete"
    assert_array_equal(open_run(result.path).frames.values, truth_frames)


def test_a_lost_error_reply_fails_the_run_and_resume_completes_it(rig, tmp_path, truth_frames):
    r = rig()
    path = tmp_path / "run.zarr"
    r.fake.inject("timeout", "TB?", count=1, after=4)
    with pytest.raises(ErrorReplyLost):
        acquire(PLAN, r.stage, r.camera, path, progress=False)
    assert zarr.open_group(path).attrs["exit_status"] == "failed"
    done = acquire(PLAN, r.stage, r.camera, path, resume=True, progress=False)
    assert done.exit_status == "complete"
    assert_array_equal(open_run(path).frames.values, truth_frames)


def test_leftovers_of_a_killed_writer_are_cleaned_on_resume(rig, tmp_path):
    r = rig()
    path = tmp_path / "run.zarr"
    stop = threading.Event()
    stop.set()
    acquire(PLAN, r.stage, r.camera, path, progress=False, stop=stop)  # create, take nothing
    partial = path / "frames" / "c" / "0" / "0" / "0" / "0.1234abcd.partial"
    partial.parent.mkdir(parents=True)
    partial.write_bytes(b"half a chunk")
    (tmp_path / ".run.zarr.deadbeef.tmp").mkdir()  # a store whose creation was killed
    result = acquire(PLAN[:12], r.stage, r.camera, path, resume=True, progress=False)
    assert result.exit_status == "complete" and not partial.exists()


# -- SIGKILL at random points -----------------------------------------------------------------
ZYGOTE = r"""
import json, os, sys
cfg = json.loads(sys.argv[1])
import numpy as np
import zarr  # noqa: F401  (imported once here, inherited by every forked run)
from sunlab import plans, sim
from sunlab.hardware import ESP300, SimCamera, acquire
from sunlab.hardware.fake import FakeESP

bench = sim.Bench.paper_single_hole().replace(detector__nx=cfg["nx"], detector__ny=cfg["nx"])
plan = plans.custom(cfg["alpha"], cfg["beta"], shots=cfg["shots"], name=cfg["name"])
warm = SimCamera(bench, seed=cfg["seed"], binning=cfg["binning"])
warm.grab()  # load the compiled kernels once, before forking
print("ready", flush=True)
for line in sys.stdin:
    cmd = line.split()
    if cmd[0] == "run":
        store = cmd[1]
        pid = os.fork()
        if pid == 0:
            null = os.open(os.devnull, os.O_WRONLY)
            os.dup2(null, 1)
            os.dup2(null, 2)
            code = 1
            try:
                fake = FakeESP(bench=bench, seed=cfg["seed"], velocity_deg_s=1000.0)
                stage = ESP300(fake.serve_pty(), **cfg["driver"])
                cam = SimCamera(bench, seed=cfg["seed"], truth=fake.true_pose,
                                binning=cfg["binning"])
                result = acquire(plan, stage, cam, store, resume=True, progress=False,
                                 handle_sigint=False)
                code = 0 if result.exit_status == "complete" else 2
            finally:
                os._exit(code)
        print("pid", pid, flush=True)
    elif cmd[0] == "reap":
        _, status = os.waitpid(int(cmd[1]), 0)
        print("status", status, flush=True)
    else:
        break
"""


def _check_consistent(path, truth_frames):
    """Every pose flagged done holds exactly the uninterrupted run's data."""
    g = zarr.open_group(path, mode="r")
    done = g["done"][:].astype(bool)
    frames = g["frames"][:]
    assert_array_equal(frames[done], truth_frames[done])
    assert np.isfinite(g["alpha_read"][:][done]).all() and np.isfinite(g["time"][:][done]).all()
    return int(done.sum())


def _check_complete(path, reference):
    """A finished store equals the uninterrupted run: every (pose, shot) exactly once."""
    run = open_run(path)
    assert run.done.values.all()
    assert_array_equal(run.frames.values, reference.frames.values)
    assert not np.isnat(run.time.values).any()
    np.testing.assert_allclose(run.alpha_read.values, reference.alpha_read.values)
    np.testing.assert_allclose(run.beta_read.values, reference.beta_read.values)
    sessions = run.attrs["sessions"]
    assert sessions[-1]["exit_status"] == "complete"
    assert sum(s["poses"] for s in sessions if s["exit_status"] != "killed") <= run.sizes["pose"]
    assert not list(path.rglob("*.partial"))
    return sum(s["exit_status"] == "killed" for s in sessions)


@pytest.mark.slow
def test_sigkill_at_random_points_then_resume_equals_an_uninterrupted_run(rig, tmp_path):
    cfg = {"nx": NX, "seed": SEED, "binning": BINNING, "alpha": KILL_PLAN.alpha.tolist(),
           "beta": KILL_PLAN.beta.tolist(), "shots": KILL_PLAN.shots, "name": KILL_PLAN.name,
           "driver": DRIVER}
    # the forking server starts (imports, compiled kernels) while this process works below
    zygote = subprocess.Popen([sys.executable, "-c", ZYGOTE, json.dumps(cfg)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                              bufsize=1)
    # an uninterrupted run of the same rig: the reference, and the time a pose takes
    r = rig()
    t0 = time.perf_counter()
    ref = acquire(KILL_PLAN, r.stage, r.camera, tmp_path / "ref.zarr", progress=False,
                  fsync=False)
    per_pose = (time.perf_counter() - t0) / len(KILL_PLAN)
    reference = open_run(ref.path)
    truth_frames = reference.frames.values
    stopped = threading.Event()
    stopped.set()

    def allocate(k):
        path = tmp_path / f"killed-{k}.zarr"
        acquire(KILL_PLAN, r.stage, r.camera, path, progress=False, stop=stopped)
        return path

    stores = [allocate(0)]
    rng = np.random.default_rng(20240607)
    kills, attempts, progress, windows, killed_sessions = 0, 0, [[]], [], 0
    try:
        assert zygote.stdout.readline().strip() == "ready"

        def run_child(path, delay):
            zygote.stdin.write(f"run {path}\n")
            zygote.stdin.flush()
            pid = int(zygote.stdout.readline().split()[1])
            if delay is not None:
                time.sleep(delay)
                os.kill(pid, signal.SIGKILL)  # not reaped yet: the pid cannot be reused
            zygote.stdin.write(f"reap {pid}\n")
            zygote.stdin.flush()
            return int(zygote.stdout.readline().split()[1])

        # kill at a uniform random time in [0, window]; the window adapts to the machine's
        # speed: it grows while kills land before the first pose and shrinks while whole
        # poses go through, so the kills fall before, inside and between pose writes
        window = 0.1 + 2.5 * per_pose
        while kills < 10:
            attempts += 1
            assert attempts <= 60, f"only {kills} kills in 60 attempts"
            windows.append(round(window, 3))
            status = run_child(stores[-1], rng.uniform(0.0, window))
            if os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGKILL:
                kills += 1
            else:
                assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0, status
            done = _check_consistent(stores[-1], truth_frames)
            gained = done - (progress[-1][-1] if progress[-1] else 0)
            progress[-1].append(done)
            window *= 1.3 if gained == 0 else (1 / 1.3 if gained > 1 else 1.0)
            if done == len(KILL_PLAN) and kills < 10:  # the runs outpaced the kills
                killed_sessions += _check_complete(stores[-1], reference)
                stores.append(allocate(len(stores)))
                progress.append([])
        status = run_child(stores[-1], None)  # the last resume runs to the end
        assert os.WIFEXITED(status) and os.WEXITSTATUS(status) == 0
        killed_sessions += _check_complete(stores[-1], reference)
    finally:
        zygote.communicate("quit\n", timeout=30)
    print(f"\nSIGKILL test: {kills} kills in {attempts} runs on {len(stores)} store(s); poses "
          f"done after each run: {progress}; kill windows (s): {windows}")
    assert kills >= 10
    assert all(p == sorted(p) for p in progress)  # a finished pose was never lost
    assert 1 <= killed_sessions <= kills  # kills before a session was recorded leave none


# -- the command line -------------------------------------------------------------------------
def test_cli_acquire_with_the_fake_stage(tmp_path, capsys):
    from sunlab.cli import main

    plan_csv = tmp_path / "poses.csv"
    plan_csv.write_text("alpha,beta\n-1.0,0.5\n0.0,-0.5\n")
    out = tmp_path / "run.zarr"
    args = ["acquire", "--stage", "fake://?velocity=1e4", "--camera", "sim", "--plan",
            str(plan_csv), "--out", str(out), "--shots", "1", "--settle", "0", "--binning", "8",
            "--roi", "256,768,320,960", "--no-progress"]
    assert main(args) == 0
    assert "2/2 poses" in capsys.readouterr().out
    run = open_run(out)
    assert dict(run.frames.sizes) == {"pose": 2, "shot": 1, "y": 64, "x": 80}
    assert run.attrs["experiment"] == "poses"
    assert main(args) == 1  # exists, no --resume
    assert "--resume" in capsys.readouterr().err
    assert main([*args, "--resume"]) == 0
    assert main(["acquire", "--stage", "fake://", "--camera", "webcam", "--plan", "I",
                 "--out", str(tmp_path / "x.zarr")]) == 1
    assert "folder:PATH" in capsys.readouterr().err


def test_a_run_the_disk_cannot_hold_is_refused_before_the_stage_moves(tmp_path, capsys):
    """Issue 47 (size before work): 10,000 shots of experiment III's 361 poses in full 10-bit
    frames (uint16, ~9.5 TB) are refused at once with the estimate, before any move; nothing is
    made."""
    import shutil

    from sunlab.cli import main

    nbytes = 2 * 1024 * 1280 * 361 * 10_000
    if shutil.disk_usage(tmp_path).free > nbytes / 5:  # 5: sunlab.atomic.COMPRESSION
        pytest.skip("this disk could hold the run")
    out = tmp_path / "big.zarr"
    args = ["acquire", "--stage", "fake://?velocity=1e4", "--camera", "sim", "--plan", "III",
            "--out", str(out), "--shots", "10000", "--settle", "0", "--no-progress"]
    assert main(args) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and f"{nbytes / 1e9:,.1f} GB uncompressed" in err, err
    assert not out.exists() and not [p for p in tmp_path.iterdir() if p.name.startswith(".sl-")]


def test_camera_options_given_to_a_built_in_camera_are_refused_not_dropped(tmp_path, capsys):
    """Issue 47: ``--camera sim --camera-option exposure_s=0.002`` took the option silently;
    a lab's setting is refused in one line naming it, before the stage opens."""
    from sunlab.cli import main

    out = tmp_path / "run.zarr"
    for camera in ("sim", f"folder:{tmp_path}"):
        assert main(["acquire", "--stage", "fake://", "--camera", camera, "--camera-option",
                     "exposure_s=0.002", "--plan", "I", "--out", str(out)]) == 1
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and "'exposure_s=0.002'" in err and "Fix:" in err
    assert not out.exists()


def test_a_lock_that_is_a_directory_is_named_as_one(tmp_path):
    from sunlab.hardware.runner import RunLockedError, run_lock

    (tmp_path / "run.zarr.lock").mkdir()
    with pytest.raises(RunLockedError, match=r"run.zarr.lock is not a lock file that sunlab "
                                             r"writes \(Is a directory\)"), \
            run_lock(tmp_path / "run.zarr"):
        pass
    assert (tmp_path / "run.zarr.lock").is_dir()


def test_a_held_lock_without_a_session_is_named_not_reported_as_pid_none(tmp_path):
    """A holder that has not yet written its id (or a lock file another tool flocks) is
    refused as held, its holder unknown, not as ``pid None``; an unheld file with garbage is
    taken (flock, not the file's content, says who holds the run)."""
    import fcntl

    from sunlab.hardware.runner import RunLockedError, run_lock

    lock = tmp_path / "run.zarr.lock"
    lock.write_text("garbage")
    with open(lock) as other:
        fcntl.flock(other, fcntl.LOCK_EX)
        with pytest.raises(RunLockedError, match=r"holder unknown") as info, \
                run_lock(tmp_path / "run.zarr"):
            pass
    assert "pid None" not in str(info.value)
    with run_lock(tmp_path / "run.zarr"):
        assert f'"pid": {os.getpid()}' in lock.read_text()
    assert not lock.exists()
