"""Outputs are never written through a link nor over a special file (sunlab.atomic, issue 37):
a FIFO a reader holds open survives ``--overwrite``, a planted symlink is replaced, not
followed, and a folder given as an output file is named as such."""

from __future__ import annotations

import os

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
        assert status == 1 and "is a directory, expected a file" in err
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
