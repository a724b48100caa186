"""Progress that fits the place: plain lines in a log, a tqdm bar in a terminal or Jupyter (the
first compile of the kernels is said by sunlab.sim._jit: tests/sim/test_kernels.py)."""

import dask.array as da

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
