"""The command line's own guarantees (sunlab.cli): every signal that ends a command
cleans up (issue 37: SIGHUP as SIGINT and SIGTERM)."""

from __future__ import annotations

import os
import signal
import threading

import numpy as np
import pytest
from PIL import Image

from sunlab.cli import main


def _folder(root, n=12):
    imgs = root / "imgs"
    imgs.mkdir()
    rows = ["file,alpha,beta,shot"]
    for k in range(n):
        Image.fromarray(np.full((16, 16), 100 + k, np.uint16)).save(imgs / f"f{k}.png")
        rows.append(f"f{k}.png,{k},0,0")
    (imgs / "manifest.csv").write_text("\n".join(rows) + "\n")
    return imgs


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="no SIGHUP on this system")
@pytest.mark.parametrize("sig, status", [(signal.SIGINT, 130), (signal.SIGTERM, 143),
                                         (getattr(signal, "SIGHUP", 1), 129)],
                         ids=["SIGINT", "SIGTERM", "SIGHUP"])
def test_a_signal_during_import_ends_in_one_line_and_leaves_nothing(tmp_path, monkeypatch,
                                                                   capsys, sig, status):
    from sunlab.io import folder

    imgs = _folder(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    handler = signal.getsignal(sig)
    real, calls, lock = folder._read_checked, [], threading.Lock()

    def read(*args):
        with lock:
            calls.append(args[0])
            if len(calls) == 6:  # mid-write: the temporary store exists
                assert [p for p in tmp_path.iterdir() if p.name.startswith(".sl-")]
                os.kill(os.getpid(), sig)  # the real signal, to this process
        return real(*args)

    monkeypatch.setattr(folder, "_read_checked", read)
    code = main(["import", str(imgs), "--out", str(tmp_path / "cube.zarr"), "--bit-depth",
                 "10", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert code == status
    name = {130: "Ctrl-C (SIGINT)", 143: "SIGTERM", 129: "SIGHUP"}[status]
    assert err.splitlines() == [f"sunlab import: interrupted by {name}"]
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    assert signal.getsignal(sig) == handler  # the caller's handler is put back


def _sunlab(*args, **popen):
    """``python -m sunlab.cli ARGS`` of this tree, as a real process."""
    import subprocess
    import sys
    from pathlib import Path

    root = Path(__file__).parents[2]
    env = dict(os.environ, PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.Popen([sys.executable, "-m", "sunlab.cli", *map(str, args)], env=env,
                            stderr=subprocess.PIPE, text=True, **popen)


def test_a_closed_stdout_pipe_is_named_as_such_not_as_a_full_disk(tmp_path):
    from sunlab import calibration, sim

    cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    path = calibration.Polynomial(order=1).fit(cen).save(tmp_path / "cal.json")
    read, write = os.pipe()
    os.close(read)  # the reader is gone before the command writes
    try:
        proc = _sunlab("info", path, stdout=write)
    finally:
        os.close(write)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 1
    assert err.strip().splitlines() == [
        "sunlab info: error: the output pipe was closed before the command finished (its "
        "reader stopped). Fix: read the whole output, or redirect it to a file"]


def test_info_escapes_a_terminal_sequence_from_a_file(tmp_path, capsys):
    from sunlab import io, schema

    cube = schema.frames_dataset(np.zeros((1, 1, 4, 4), np.uint16), alpha=[0.0], beta=[0.0])
    # a cube written by another tool: a coordinate named with a terminal's escape sequences
    cube = cube.assign_coords({"\x1b]0;pwned\x07\x1b[2Jnote": (("pose", "shot"), [[1.0]])})
    io.save_frames(cube, tmp_path / "c.zarr")
    assert main(["info", str(tmp_path / "c.zarr")]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\\x1b[2J" in out


def test_a_sensor_json_string_with_an_escape_is_refused_and_echoed_escaped(tmp_path, capsys):
    imgs = _folder(tmp_path, n=2)
    (imgs / "sensor.json").write_text('{"bit_depth": 10, "experiment": "\\u001b[2Jrun",'
                                      ' "mask_distance_mm": "\\u001b[31m17"}')
    code = main(["import", str(imgs), "--out", str(tmp_path / "c.zarr"), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 1 and "\x1b" not in err and "\\x1b" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "c.zarr").exists()
