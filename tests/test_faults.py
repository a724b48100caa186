"""Faults injected for real, one class at a time (issue 29): corruption that stays well-formed,
partial outputs (a file-size limit, SIGKILL), interrupts (real signals to a subprocess), two
sessions on one run (a second process), late serial replies (a fake controller that answers
after the timeout), hostile input, and outliers in a centroid table.

Each test asserts the contract of its class: a status that is not 0, one line naming the file or
field, no traceback, nothing that existed altered, nothing partial left behind.
"""

from __future__ import annotations

import json
import math
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from sunlab import atomic, calibration, integrity, io, plans, schema, sim
from sunlab.calibration import Polynomial
from sunlab.cli import main
from sunlab.hardware import ESP300, acquire, open_stage
from sunlab.hardware.fake import FakeESP
from sunlab.hardware.runner import RunLockedError, run_lock
from sunlab.screening import screen_outliers

ROOT = Path(__file__).parents[1]


def _sunlab(*args, cwd, limit_bytes: int | None = None, timeout: float = 300,
            **popen) -> subprocess.Popen:
    """Start ``python -m sunlab.cli ARGS`` (this tree's sunlab), optionally under a file-size
    limit (a write past it fails with EFBIG, as on a full disk)."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))

    def limit():
        if limit_bytes is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit_bytes, limit_bytes))

    return subprocess.Popen([sys.executable, "-m", "sunlab.cli", *map(str, args)], cwd=cwd,
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            preexec_fn=limit, **popen)


def _run(*args, cwd, **kw) -> tuple[int, str, str]:
    proc = _sunlab(*args, cwd=cwd, **kw)
    out, err = proc.communicate(timeout=300)
    return proc.returncode, out, err


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def _snapshot(folder: Path) -> dict:
    """Every file under ``folder`` (hidden ones too) and its bytes."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def grid():
    a, b = np.meshgrid(np.linspace(-30, 30, 9), np.linspace(-30, 30, 9))
    return sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2)


# -- 1. corruption that stays well-formed ------------------------------------------------------
def test_a_flipped_bit_in_a_netcdf_centroid_table_is_refused_naming_the_file(tmp_path, grid):
    path = tmp_path / "train.nc"
    io.save_centroids(grid, path)
    raw = bytearray(path.read_bytes())
    where = bytes(raw).find(np.ascontiguousarray(grid.x.values, "<f8").tobytes()[:16])
    assert where > 0
    raw[where + 5] ^= 0x04  # one bit of one centroid: still a valid float, another number
    path.write_bytes(bytes(raw))
    with pytest.raises(integrity.IntegrityError, match=re.escape(str(path))):
        io.open_centroids(path)
    code, _, err = _run("calibrate", path, "--out", tmp_path / "c.json", cwd=tmp_path)
    assert code == 1 and "train.nc: checksum mismatch" in _one_line(err)
    assert not (tmp_path / "c.json").exists()


@pytest.mark.parametrize("edit", [("[2,2,3,4]", "[2,2,3,3]"), ('"little"', '"big"')],
                         ids=["shape", "endianness"])
def test_a_one_character_edit_of_zarr_metadata_is_refused(tmp_path, edit):
    cube = schema.frames_dataset(np.arange(48, dtype=np.uint16).reshape(2, 2, 3, 4),
                                 alpha=[0.0, 1.0], beta=[0.0, 0.0])
    store = tmp_path / "cube.zarr"
    io.save_frames(cube, store)
    meta = store / "frames" / "zarr.json"
    text = meta.read_text()
    compact = re.sub(r"\s+", "", text)
    assert edit[0] in compact
    meta.write_text(json.dumps(json.loads(compact.replace(edit[0], edit[1])), indent=2))
    with pytest.raises(integrity.IntegrityError, match=r"cube.zarr: checksum mismatch"):
        io.open_frames(store)


def test_an_edited_calibration_value_is_refused_but_an_unsealed_file_reads(tmp_path, grid):
    path = Polynomial(order=2).fit(grid).save(tmp_path / "cal.json")
    doc = json.loads(path.read_text())
    doc["parameters"]["coefficients"]["alpha"][1] *= 1.001
    path.write_text(json.dumps(doc))
    with pytest.raises(integrity.IntegrityError, match=re.escape(f"{path}: checksum mismatch")):
        calibration.load(path)
    doc.pop(integrity.ATTR)  # written by another tool: no checksum, read as before
    path.write_text(json.dumps(doc))
    assert calibration.load(path).kind == "polynomial"


# -- 2. partial outputs ----------------------------------------------------------------------
def test_a_full_disk_during_export_overwrite_keeps_the_old_pair_and_names_the_file(tmp_path,
                                                                                    grid):
    Polynomial(order=1).fit(grid).save(tmp_path / "old.json")
    Polynomial(order=3).fit(grid).save(tmp_path / "new.json")
    assert main(["export", str(tmp_path / "old.json"), "--out", str(tmp_path / "onboard")]) == 0
    before = _snapshot(tmp_path / "onboard")
    # the new header (1.4 kB) fits under 2 kB, its source (3.8 kB) does not: EFBIG for real
    code, _, err = _run("export", tmp_path / "new.json", "--out", tmp_path / "onboard",
                        "--overwrite", cwd=tmp_path, limit_bytes=2000)
    line = _one_line(err)
    assert code == 1 and "onboard" in line and "File too large" in line
    assert _snapshot(tmp_path / "onboard") == before  # the old header and source, nothing else
    assert sorted(p.name for p in tmp_path.iterdir()) == ["new.json", "old.json", "onboard"]


@pytest.mark.parametrize("out", ["s.zarr", "s.nc"])
def test_a_full_disk_during_simulate_names_the_output_and_leaves_nothing(tmp_path, out):
    code, _, err = _run("simulate", "--experiment", "I", "--subset", "10", "--shots", "1",
                        "--out", out, "--no-progress", cwd=tmp_path, limit_bytes=20_000)
    line = _one_line(err)
    assert code == 1 and line.startswith(f"sunlab simulate: error: {out}: File too large")
    assert list(tmp_path.iterdir()) == []


def test_a_failed_evaluate_leaves_no_folder_and_no_file(tmp_path, grid):
    cal = Polynomial(order=2).fit(grid).save(tmp_path / "cal.json")
    io.save_centroids(grid, tmp_path / "test.nc")
    before = sorted(p.name for p in tmp_path.iterdir())
    # inputs refused before anything is made
    code, _, err = _run("evaluate", tmp_path / "test.nc", tmp_path / "test.nc", "--out",
                        tmp_path / "ev", cwd=tmp_path)
    assert code == 1 and "test.nc" in _one_line(err)
    # a figure (tens of kB) past a 20 kB file-size limit: the JSON and CSV were written first
    code, _, err = _run("evaluate", cal, tmp_path / "test.nc", "--out", tmp_path / "ev",
                        cwd=tmp_path, limit_bytes=20_000)
    assert code == 1 and "ev" in _one_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_killed_write_leaves_a_temporary_store_that_the_next_run_removes(tmp_path):
    proc = _sunlab("simulate", "--experiment", "III", "--shots", "2", "--out", "s.zarr",
                   "--no-progress", cwd=tmp_path)
    try:
        tmp = _wait_for(lambda: [p for p in tmp_path.iterdir() if p.name.startswith(".sl-")])
    finally:
        proc.kill()  # SIGKILL: no clean-up can run
        proc.communicate()
    assert tmp[0].exists() and not (tmp_path / "s.zarr").exists()
    code, _, _ = _run("simulate", "--experiment", "I", "--subset", "20", "--shots", "1",
                      "--out", "s.zarr", "--no-progress", cwd=tmp_path)
    assert code == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.zarr"]


def test_an_old_output_set_aside_by_a_killed_writer_is_put_back(tmp_path):
    (tmp_path / "store").mkdir()
    (tmp_path / "store" / "zarr.json").write_text("{}")
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True).stdout.strip()
    (aside := tmp_path / f".sl-{dead}-0123abcd.old").mkdir()
    os.replace(tmp_path / "store", aside / "store")  # killed between the two renames of a swap
    atomic.check_target(tmp_path / "store", overwrite=True, kind="zarr")
    assert (tmp_path / "store" / "zarr.json").read_text() == "{}" and not aside.exists()


def test_export_check_builds_its_driver_outside_the_delivery_folder(tmp_path, grid):
    from sunlab import export

    if export.find_c_compiler() is None:
        pytest.skip("no C compiler")
    cal = Polynomial(order=2).fit(grid)
    export.export(cal, tmp_path / "onboard")
    report = export.check_c(cal, tmp_path / "onboard")
    assert report["flags_agree"]
    assert sorted(p.name for p in (tmp_path / "onboard").iterdir()) == [
        "sunlab_calibration.c", "sunlab_calibration.h"]


def _wait_for(found, timeout: float = 120.0):
    """Poll until ``found()`` is truthy (an event, not a duration, is what is waited for)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        got = found()
        if got:
            return got
        time.sleep(0.02)
    raise AssertionError("the awaited state never came")


# -- 3. interrupts ---------------------------------------------------------------------------
@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143)],
                         ids=["SIGINT", "SIGTERM"])
def test_a_signal_during_simulate_ends_in_one_line_and_leaves_nothing(tmp_path, sig, status):
    (tmp_path / "keep.txt").write_text("mine")
    proc = _sunlab("simulate", "--experiment", "III", "--shots", "2", "--out", "s.zarr",
                   "--no-progress", cwd=tmp_path)
    _wait_for(lambda: [p for p in tmp_path.iterdir() if p.name.startswith(".sl-")])
    proc.send_signal(sig)  # mid-write: the temporary store exists
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == status
    assert "interrupted" in _one_line(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.txt"]


def test_an_interrupt_a_library_swallows_still_ends_the_command(monkeypatch, capsys):
    from sunlab.cli import _files

    def swallowing(args):
        try:
            os.kill(os.getpid(), signal.SIGINT)  # Ctrl-C, for real
            time.sleep(5)
        except BaseException:  # noqa: BLE001 - a library's bare except
            pass
        return 0

    monkeypatch.setattr(_files, "run_info", swallowing)
    assert main(["info", "x"]) == 130
    assert capsys.readouterr().err.strip() == "sunlab info: interrupted by Ctrl-C (SIGINT)"


def test_an_interrupt_during_an_import_waits_for_the_import(tmp_path, monkeypatch, capsys):
    from sunlab.cli import _files

    (tmp_path / "slow_import_29.py").write_text(
        "import os, signal, time\nos.kill(os.getpid(), signal.SIGINT)\ntime.sleep(0.3)\n"
        "DONE = True\n")
    monkeypatch.syspath_prepend(str(tmp_path))

    def importing(args):
        import slow_import_29  # noqa: F401

        time.sleep(5)  # the interrupt, delivered again after the import, lands here
        return 0

    monkeypatch.setattr(_files, "run_info", importing)
    assert main(["info", "x"]) == 130
    assert sys.modules["slow_import_29"].DONE  # the import ran to its end
    assert "interrupted" in capsys.readouterr().err


# -- 4. one writer per acquisition run -------------------------------------------------------
def test_a_second_session_is_refused_naming_the_holder(tmp_path):
    out = tmp_path / "run.zarr"
    holder = subprocess.Popen(
        [sys.executable, "-c", textwrap.dedent(f"""
            import sys, time
            from sunlab.hardware.runner import run_lock
            with run_lock({str(out)!r}):
                print("held", flush=True)
                sys.stdin.read()  # until the test closes it
        """)], env=dict(os.environ, PYTHONPATH=str(ROOT)), stdin=subprocess.PIPE,
        stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        code, _, err = _run("acquire", "--stage", "fake://?velocity=inf", "--camera", "sim",
                            "--plan", "I", "--step", "80", "--shots", "1", "--settle", "0",
                            "--out", out, "--resume", "--no-progress", cwd=tmp_path)
        line = _one_line(err)
        assert code == 1 and f"pid {holder.pid}" in line and "run.zarr.lock" in line
        assert not out.exists()  # the stage never moved, nothing was written
        with pytest.raises(RunLockedError, match=f"pid {holder.pid}"):
            with run_lock(out):
                pass
    finally:
        holder.communicate("")
    assert not (tmp_path / "run.zarr.lock").exists()


def test_a_stale_lock_is_taken_over_and_the_run_holds_exactly_its_plan(tmp_path):
    """A session killed while it holds the lock leaves its lock file; the kernel released the
    flock with the process, so the next session takes the run (its lock file then names it)."""
    out = tmp_path / "run.zarr"
    dead = subprocess.run([sys.executable, "-c", textwrap.dedent(f"""
        import os
        from sunlab.hardware.runner import run_lock
        held = run_lock({str(out)!r})
        held.__enter__()
        print(os.getpid(), flush=True)
        os._exit(9)  # killed: no cleanup runs
    """)], env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True, text=True)
    assert dead.returncode == 9
    assert f'"pid": {dead.stdout.strip()}' in (tmp_path / "run.zarr.lock").read_text()
    plan = plans.custom([0.0, 1.0, 2.0, 3.0, 4.0], [0.0] * 5, shots=2)
    stage = open_stage("fake://?velocity=inf", retry_delay_s=0.0, poll_s=0.001)

    class Ramp:
        shape, dtype, bit_depth = (4, 5), np.dtype(np.uint16), 10

        def grab(self):
            return np.arange(20, dtype=np.uint16).reshape(4, 5)

    try:
        stop_after_two = _StopAfter(2)
        first = acquire(plan, stage, stop_after_two.camera(Ramp()), out, progress=False,
                        stop=stop_after_two.event, handle_sigint=False)
        second = acquire(plan, stage, Ramp(), out, resume=True, progress=False)
    finally:
        stage.close()
    assert (first.poses_done, second.exit_status, second.poses_done) == (2, "complete", 5)
    run = io.open_frames(out)  # sealed at the end of the session: the checksum holds
    assert run.sizes["pose"] == 5 and int(run.done.sum()) == 5
    assert sum(s["poses"] for s in run.attrs["sessions"]) == 5
    assert not (tmp_path / "run.zarr.lock").exists()


class _StopAfter:
    """A camera wrapper that sets a stop event once ``n`` poses are complete."""

    def __init__(self, n: int):
        import threading

        self.n, self.grabs, self.event = n, 0, threading.Event()

    def camera(self, inner):
        outer = self

        class Cam:
            shape, dtype, bit_depth = inner.shape, inner.dtype, inner.bit_depth

            def grab(self):
                outer.grabs += 1
                if outer.grabs == 2 * outer.n:  # two shots per pose
                    outer.event.set()
                return inner.grab()

        return Cam()


# -- 5. serial replies matched to their queries ----------------------------------------------
def test_a_late_reply_is_never_taken_as_the_next_answer():
    fake = FakeESP(velocity_deg_s=math.inf)
    stage = ESP300(fake.serve_pty(), timeout=0.2, retry_delay_s=0.0, poll_s=0.001)
    try:
        assert stage.move_to(1.0, 2.0) == (1.0, 2.0)
        for axis in ("1TP?", "2TP?"):
            fake.inject("late", axis, silent_s=0.6)  # three timeouts late
            assert stage.position() == (1.0, 2.0)
            assert stage.position() == (1.0, 2.0)
    finally:
        stage.close()
        fake.close()


@pytest.mark.parametrize("velocity", [1e-3, 1.0, 200.0, 1e6, 1e9, 1e15, math.inf])
def test_the_fake_position_stays_on_the_path_at_any_velocity(velocity):
    now = [1e6]  # a clock advanced by hand, at a large value: move times round
    fake = FakeESP(velocity_deg_s=velocity, clock=lambda: now[0])
    fake.handle(b"1PA10")
    seen = []
    for _ in range(50):
        seen.append(fake.position()[0])  # the replies round it to the encoder's resolution
        assert abs(float(fake.handle(b"1TP?")) - seen[-1]) <= fake.resolution_deg / 2 + 5e-7
        done = fake.handle(b"1MD?") == b"1\r\n"
        assert done == (seen[-1] == 10.0)
        now[0] += 10.0 / velocity / 20 if math.isfinite(velocity) else 1.0
    assert all(0.0 <= s <= 10.0 for s in seen) and seen == sorted(seen)


# -- 6. hostile or malformed input -----------------------------------------------------------
def test_an_experiment_name_never_becomes_code_in_the_export(tmp_path, grid):
    from sunlab import export

    evil = "I */ int sunlab_evil(void) { return 1; } /* \n#include <stdlib.h>\n"
    cal = Polynomial(order=2).fit(grid.assign_attrs(experiment=evil))
    header, source = export.c_sources(cal)
    for text in (header, source):
        code = re.sub(r"/\*.*?\*/", "", text, flags=re.S)  # what a compiler sees
        assert "sunlab_evil" not in code and "stdlib" not in code
    if export.find_c_compiler() is not None:
        export.export(cal, tmp_path / "onboard")
        assert export.check_c(cal, tmp_path / "onboard")["flags_agree"]


@pytest.mark.parametrize("argv, field", [
    (["info", "{deep}"], "nested more than 64"),
    (["info", "{fifo}"], "not a regular file"),
    (["calibrate", "{cal}", "--method", "neural", "--seed", "99999999999999999999", "--out",
      "{tmp}/n.json"], "--seed"),
    (["acquire", "--stage", "fake://?velocity=fast", "--camera", "sim", "--plan", "I", "--out",
      "{tmp}/run.zarr"], "velocity='fast'"),
    (["acquire", "--stage", "fake://", "--camera", "folder:{tmp}", "--shape", "99999x99999",
      "--plan", "I", "--out", "{tmp}/run.zarr"], "--shape"),
    (["simulate", "--shots", "1000000000000", "--out", "{tmp}/s.zarr"], "--shots"),
    (["export", "{cal}", "--out", "/proc/sunlab-out"], "/proc/sunlab-out"),
], ids=["deep JSON", "FIFO", "seed", "stage velocity", "shape", "shots", "export to /proc"])
def test_hostile_arguments_end_in_one_line_naming_the_field(tmp_path, grid, argv, field):
    (tmp_path / "deep.json").write_text('{"sunlab_schema": "calibration/1", "kind": '
                                        + "[" * 5000 + "]" * 5000 + "}")
    os.mkfifo(tmp_path / "fifo")
    Polynomial(order=1).fit(grid).save(tmp_path / "cal.json")
    names = {"deep": tmp_path / "deep.json", "fifo": tmp_path / "fifo",
             "cal": tmp_path / "cal.json", "tmp": tmp_path}
    code, _, err = _run(*[a.format(**names) for a in argv], cwd=tmp_path, timeout=120)
    assert code in (1, 2) and field in err.strip().splitlines()[-1] and "Traceback" not in err


# -- 7. outliers -----------------------------------------------------------------------------
def test_one_absurd_row_among_81_is_excluded_and_its_line_named(tmp_path):
    a, b = np.meshgrid(np.linspace(-40, 40, 9), np.linspace(-40, 40, 9))
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1)
    rows = ["# one shot per pose", "alpha,beta,x,y"] + [
        f"{al!r},{be!r},{(1e20 if i == 40 else x)!r},{y!r}" for i, (al, be, x, y) in enumerate(
            zip(a.ravel().tolist(), b.ravel().tolist(), cen.x.values[:, 0].tolist(),
                cen.y.values[:, 0].tolist(), strict=True))]
    (tmp_path / "train.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "sensor.json").write_text(json.dumps({"mask_distance_mm": 5.0}))
    code, out, _ = _run("calibrate", "train.csv", "--order", "3", "--out", "cal.json",
                        cwd=tmp_path)
    assert code == 0 and "train.csv line 43 (train): excluded as an outlier" in out
    cal = calibration.load(tmp_path / "cal.json")
    est_a, est_b = cal.predict_xy(cen.x.values[:, 0], cen.y.values[:, 0])
    # without the screening the fit is tens of degrees off; with it, the synthetic table's own
    # scatter (platform errors of about 0.1 deg) is what is left
    assert np.nanmax(np.abs(est_a - a.ravel())) < 1.0
    assert np.nanmax(np.abs(est_b - b.ravel())) < 2.0


def test_screening_flags_nothing_on_centroids_of_simulated_frames():
    from sunlab import centroid

    plan = plans.experiment("I", shots=2).thin(3)
    cube = sim.simulate(plan, sim.Bench.paper_single_hole(), seed=3)
    cen = centroid.locate(cube, "projection", progress=False)
    screened, found = screen_outliers(cen)
    assert found == [] and screened.attrs["screening"]["flagged"] == 0
    cen["y"][4, 1] = cen["y"][4, 1] + 200.0  # a spot taken 200 px away
    assert [(o["pose"], o["shot"]) for o in screen_outliers(cen)[1]] == [(4, 1)]


def test_the_check_cannot_pass_on_a_corrupted_copy(tmp_path, grid):
    """The integrity check reads the file: a copy with the same digest and other values fails."""
    io.save_centroids(grid, tmp_path / "a.nc")
    shutil.copy(tmp_path / "a.nc", tmp_path / "b.nc")
    changed = grid.copy(deep=True)
    changed["x"][0, 0] = changed["x"][0, 0] + 1.0
    io.save_centroids(changed, tmp_path / "c.nc")
    import h5netcdf

    with h5netcdf.File(tmp_path / "a.nc", "r") as f:
        digest = f.attrs[integrity.ATTR]
    with h5netcdf.File(tmp_path / "c.nc", "r+") as f:
        f.attrs[integrity.ATTR] = digest  # the right digest on the wrong values
    io.open_centroids(tmp_path / "b.nc")
    with pytest.raises(integrity.IntegrityError, match="c.nc"):
        io.open_centroids(tmp_path / "c.nc")
