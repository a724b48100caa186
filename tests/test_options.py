"""Progress that fits the place: plain lines in a log, a tqdm bar in a terminal or Jupyter, and
the first compile of the kernels said once."""

import types

import dask.array as da
import pytest

from sunlab import options


def test_a_log_gets_a_few_plain_lines_without_carriage_returns(capsys):
    # pytest's captured stderr is not a terminal: the log form
    with options.dask_progress(True, "centroid", minimum=0.0):
        assert int(da.ones(40, chunks=1).sum().compute(scheduler="synchronous")) == 40
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert "\r" not in err
    assert lines[-1].startswith("centroid: done,") and 2 <= len(lines) <= 5


def test_nothing_is_said_when_progress_is_off(capsys):
    with options.set_options(progress=False), options.dask_progress(True, "x", minimum=0.0):
        da.ones(4, chunks=1).sum().compute(scheduler="synchronous")
    assert capsys.readouterr().err == ""


def test_a_terminal_gets_a_tqdm_bar(monkeypatch):
    from tqdm.dask import TqdmCallback

    monkeypatch.setattr(options, "_interactive", lambda: True)
    assert isinstance(options.dask_progress(True, "x"), TqdmCallback)


def _fake_kernel(tmp_path, cached: bool):
    index = tmp_path / ("k.nbi" if cached else "missing.nbi")
    if cached:
        index.write_bytes(b"")
    cache_file = types.SimpleNamespace(_index_path=str(index))
    return types.SimpleNamespace(signatures=[], _cache=types.SimpleNamespace(
        _cache_file=cache_file))


@pytest.mark.parametrize("cached", [False, True])
def test_the_first_compile_is_announced_once(tmp_path, capsys, monkeypatch, cached):
    monkeypatch.setattr(options, "_ANNOUNCED", set())
    module = types.SimpleNamespace(kernel=_fake_kernel(tmp_path, cached))
    assert options.announce_compile([module], "test") is (not cached)
    assert options.announce_compile([module], "test") is False  # once per process
    err = capsys.readouterr().err
    assert err.count("compiling the test kernels once") == (0 if cached else 1)
