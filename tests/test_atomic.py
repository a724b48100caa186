"""Outputs are never written through a link nor over a special file (sunlab.atomic, issue 37):
a FIFO a reader holds open survives ``--overwrite``, a planted symlink is replaced, not
followed, and a folder given as an output file is named as such. Issue 47, with the faults
real: a file-size limit (``RLIMIT_FSIZE``, SIGXFSZ ignored: a write past it fails with EFBIG),
a name of the file system's own ``NAME_MAX`` bytes, a folder whose name is not UTF-8, and a
request of terabytes refused before any work."""

from __future__ import annotations

import errno
import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from sunlab import atomic, cli, sim
from sunlab.errors import SunlabError
from sunlab.reproduce.pipeline import write_json


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    from sunlab import io

    root = tmp_path_factory.mktemp("t")
    a = [float(v) for v in range(-4, 5, 2)]
    cen = sim.synthetic_centroids([x for x in a for _ in a], [y for _ in a for y in a])
    return io.save_centroids(cen, root / "train.nc") or root / "train.nc"


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_calibrate_never_replaces_a_fifo_a_reader_holds_open(table, tmp_path, capsys):
    fifo = tmp_path / "cal.json"
    os.mkfifo(fifo)
    reader = os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)  # a reader holds it open
    try:
        status = cli.main(["calibrate", str(table), "--out", str(fifo), "--overwrite"])
        err = capsys.readouterr().err.strip()
        assert status == 1 and len(err.splitlines()) == 1
        assert "is a named pipe (FIFO), not a regular file" in err
        assert fifo.is_fifo() and os.read(reader, 10) == b""  # still the pipe; nothing sent
        assert sorted(p.name for p in tmp_path.iterdir()) == ["cal.json"]
    finally:
        os.close(reader)


def test_a_folder_given_as_an_output_file_is_named_as_a_folder(table, tmp_path, capsys):
    (tmp_path / "out").mkdir()
    for extra in ([], ["--overwrite"]):
        status = cli.main(["calibrate", str(table), "--out", str(tmp_path / "out"), *extra])
        err = capsys.readouterr().err
        assert status == 1 and "is a directory, not a file" in err
        assert "a directory, a directory" not in err and "pass --overwrite" not in err


def test_an_overwrite_replaces_a_planted_symlink_and_leaves_its_target(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    link = tmp_path / "out.json"
    link.symlink_to(victim)
    atomic.write_text(link, "{}", overwrite=True)
    assert victim.read_text() == "precious"
    assert not link.is_symlink() and link.read_text() == "{}"


def test_the_reproduction_json_is_written_atomically_not_through_a_link(tmp_path):
    victim = tmp_path / "victim.txt"
    victim.write_text("precious")
    (tmp_path / "table5.json").symlink_to(victim)
    write_json({"mu": 0.5}, tmp_path / "table5.json")
    assert victim.read_text() == "precious"
    assert not (tmp_path / "table5.json").is_symlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["table5.json", "victim.txt"]


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_the_reproduction_json_refuses_a_fifo(tmp_path):
    os.mkfifo(tmp_path / "platform.json")
    with pytest.raises(SunlabError, match="named pipe"):
        write_json({"mu": 0.5}, tmp_path / "platform.json")
    assert (tmp_path / "platform.json").is_fifo()


def _limited(code: str, limit: int, cwd) -> subprocess.CompletedProcess:
    """Run ``python -c code`` (this tree's sunlab) under a real file-size limit of ``limit``
    bytes, SIGXFSZ ignored, so that a write past it fails with EFBIG as on a full disk."""
    resource = pytest.importorskip("resource")

    def limit_size():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    env = {**os.environ, "PYTHONPATH": str(Path(atomic.__file__).parents[1])}
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, env=env, text=True,
                          capture_output=True, preexec_fn=limit_size, timeout=300, check=False)


_LEARNED = """
import sys
from pathlib import Path
from sunlab.errors import SunlabError
from sunlab.reproduce import learned_files
recs = [{"bench": b, "method": m, "angle": a, "stat": "mu", "value": v}
        for b in ("paper", "good-platform") for a in ("alpha", "beta")
        for m, v in (("learned", 0.01), ("polynomial", 0.012))]
result = {"models": [], "command": "test", "settings": {"seed": 0}, "records": recs,
          "floors": {}, "histories": {}}
try:
    learned_files.write(result, Path(sys.argv[1] if len(sys.argv) > 1 else "out"))
except SunlabError as err:
    print(f"SunlabError: {err}")
    sys.exit(1)
"""


def test_the_learned_table_under_a_file_size_limit_changes_nothing(tmp_path):
    """The learned table's records and figure go through sunlab.atomic: past a real file-size
    limit the earlier files stay, no figure is cut off, and the error names the output."""
    limit = 20_000
    (tmp_path / "out").mkdir()  # made by the run, for models/ and benches/
    free = _limited(_LEARNED, 1 << 30, tmp_path)  # the same write, unlimited: the figure
    assert free.returncode == 0, free.stderr     # alone is past the limit
    assert (tmp_path / "out" / "learned.png").stat().st_size > limit
    assert (tmp_path / "out" / "learned.json").stat().st_size < limit
    earlier = {n: f"earlier {n}".encode() for n in
               ("learned.json", "learned_settings.json", "learned.png")}
    for name, data in earlier.items():
        (tmp_path / "out" / name).write_bytes(data)
    done = _limited(_LEARNED, limit, tmp_path)
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stdout.startswith(f"SunlabError: out: {os.strerror(errno.EFBIG)}"), done.stdout
    assert {p.name: p.read_bytes() for p in (tmp_path / "out").iterdir()} == earlier


def test_any_legal_name_is_written_whatever_its_temporary(tmp_path):
    """A name of NAME_MAX bytes (the file system's own limit) is written by each kind of
    atomic output: a file, a Zarr store replaced (the old one set aside), a folder of files."""
    from sunlab import export, io
    from sunlab.calibration import Polynomial

    longest = os.pathconf(tmp_path, "PC_NAME_MAX")
    name = lambda suffix: "n" * (longest - len(suffix)) + suffix  # noqa: E731
    atomic.write_text(tmp_path / name(".json"), "{}")
    cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    for _ in range(2):
        io.save_centroids(cen, tmp_path / name(".zarr"), overwrite=True)
    export.export(Polynomial(order=1).fit(cen), tmp_path / name(""))
    assert sorted(len(p.name) for p in tmp_path.iterdir()) == [longest] * 3
    assert sorted(p.name for p in (tmp_path / name("")).iterdir()) == [
        "sunlab_calibration.c", "sunlab_calibration.h"]
    with pytest.raises(SunlabError, match=f"{name('.json')}x: the name is longer than the "
                       f"file system allows \\({longest + 1} bytes\\)"):
        atomic.write_text(tmp_path / (name(".json") + "x"), "{}")


def test_a_folder_whose_name_is_not_utf8_takes_every_output_format(tmp_path, capsys):
    """Frames imported into a folder named by bytes that are not UTF-8: NetCDF and Zarr cubes
    (their attributes name the folder), centroids, a calibration, the evaluation's CSV, JSON and
    PNG files, the C export compiled. The folder's name comes back exact from each cube."""
    from sunlab import io

    folder = Path(os.fsdecode(os.fsencode(tmp_path) + b"/caf\xe9"))
    try:
        folder.mkdir()
    except (OSError, UnicodeError):
        pytest.skip("this file system refuses names that are not UTF-8")
    shutil.copytree(Path(sim.__file__).parents[1] / "data" / "example" / "train",
                    folder / "frames")
    runs = [["import", folder / "frames", "--out", folder / "c.nc"],
            ["import", folder / "frames", "--out", folder / "c.zarr"],
            ["centroid", folder / "c.nc", "--out", folder / "cen.nc"],
            ["calibrate", folder / "cen.nc", "--order", "2", "--out", folder / "cal.json"],
            ["evaluate", folder / "cal.json", folder / "cen.nc", "--out", folder / "ev"]]
    if shutil.which("cc") or shutil.which("gcc"):
        runs.append(["export", folder / "cal.json", "--out", folder / "onboard", "--check"])
    for args in runs:
        status = cli.main([str(a) for a in args] + ["--no-progress"] * (args[0] in (
            "import", "centroid")))
        assert status == 0, (args[0], capsys.readouterr().err)
    for cube in ("c.nc", "c.zarr"):
        with io.open_frames(folder / cube) as back:
            assert back.attrs["source"] == str((folder / "frames").resolve())


def test_a_request_of_terabytes_is_refused_before_any_work(tmp_path):
    """A typo in a shot count (10,000 shots of the 100-hole experiment III: ~9.5 TB of frames)
    is refused at once with the estimate and the free space; nothing is made. Under a real
    file-size limit, so that a run that starts the work fails (EFBIG) instead of filling the
    disk."""
    nbytes = 2 * 1024 * 1280 * 361 * 10_000  # uint16 frames x poses of experiment III x shots
    if shutil.disk_usage(tmp_path).free > nbytes / 5:  # 5: sunlab.atomic.COMPRESSION
        pytest.skip("this disk could hold the request")
    done = _limited("from sunlab.cli import main; raise SystemExit(main(['simulate', "
                    "'--experiment', 'III', '--mask', 'multi', '--shots', '10000', '--out', "
                    "'big.zarr', '--no-progress']))", 50_000_000, tmp_path)
    line = done.stderr.strip()
    assert done.returncode == 1 and len(line.splitlines()) == 1, done.stderr
    assert f"big.zarr: would be about {nbytes / 1e9:,.1f} GB uncompressed" in line
    assert "GB free; nothing was done" in line
    assert list(tmp_path.iterdir()) == []


def test_a_signal_sent_during_a_held_block_is_delivered_at_its_end():
    """The kernel may hand a process-directed SIGINT to any thread that does not block it (here
    one started before the block, as zarr's I/O loop and dask's workers are): Python still runs
    the handler in the main thread, so a thread's signal mask held nothing back, and zarr's
    metadata writes recreated a removed temporary store (a leftover ``.sl-*.tmp`` under load)."""
    import threading

    go, sent = threading.Event(), threading.Event()

    def sender():
        go.wait()
        # SIGINT handed to this thread, as the kernel may hand a process-directed one: directed
        # at the calling thread, it is taken before pthread_kill returns (os.kill gives no such
        # promise when another thread leaves it unblocked: under load it could land after the
        # block, and the test failed once so)
        signal.pthread_kill(threading.get_ident(), signal.SIGINT)
        sent.set()

    thread = threading.Thread(target=sender)
    thread.start()
    steps = []
    with pytest.raises(KeyboardInterrupt):
        with atomic.signals_held():
            go.set()
            assert sent.wait(30)
            for _ in range(10_000):  # bytecodes run: a pending handler would fire here
                steps.append(None)
            steps.append("end")
    thread.join()
    assert steps[-1] == "end"
