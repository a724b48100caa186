"""The command line's own guarantees (sunlab.cli.commands): every signal that ends a command
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
                assert [p for p in tmp_path.iterdir() if ".cube.zarr.tmp-" in p.name]
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
