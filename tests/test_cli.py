"""The command line: help, version, and clean errors."""

import pytest

from sunlab import __version__
from sunlab.cli import build_parser, main


def test_help_lists_subcommands(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for name in ("info",):
        assert name in out


def test_version(capsys):
    with pytest.raises(SystemExit):
        main(["--version"])
    assert __version__ in capsys.readouterr().out


def test_no_command_prints_help_and_fails(capsys):
    assert main([]) == 2
    assert "usage: sunlab" in capsys.readouterr().out


def test_every_subcommand_has_a_handler():
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    for name, p in sub.choices.items():
        assert p.get_default("func") is not None, name


def test_reproduce_passes_the_scheduler_to_both_tables(monkeypatch, tmp_path, capsys):
    # --address, --scheduler and --workers reach Table 4 and Table 5 alike (issue 16)
    import pandas as pd

    from sunlab import reproduce, reproduce_table5

    seen = {}

    def table4(**kw):
        seen[4] = kw
        return type("R", (), {"files": []})()

    def table5(**kw):
        seen[5] = kw
        return {"table": pd.DataFrame({"x": [1.0]}), "centroid_status": {},
                "runtime_s": 0.0, "files": []}

    monkeypatch.setattr(reproduce, "reproduce_table4", table4)
    monkeypatch.setattr(reproduce, "format_table", lambda res: "table 4")
    monkeypatch.setattr(reproduce_table5, "reproduce_table5", table5)
    rc = main(["reproduce", "--table", "all", "--quick", "--address", "tcp://10.0.0.1:8786",
               "--scheduler", "cluster", "--workers", "2", "--out", str(tmp_path)])
    assert rc == 0
    for k in (4, 5):
        assert (seen[k]["address"], seen[k]["scheduler"], seen[k]["workers"]) == (
            "tcp://10.0.0.1:8786", "cluster", 2), k
        assert seen[k]["quick"] is True
    capsys.readouterr()
