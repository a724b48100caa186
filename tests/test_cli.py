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


def test_reproduce_passes_the_scheduler_to_every_table(monkeypatch, tmp_path, capsys):
    # --address, --scheduler, --workers and --method reach every table alike (issues 16, 15)
    import pandas as pd

    from sunlab import reproduce

    seen = {}

    def table4(**kw):
        seen[4] = kw
        return type("R", (), {"files": []})()

    def table5(**kw):
        seen[5] = kw
        return {"table": pd.DataFrame({"x": [1.0]}),
                "centroid_status": {"I": {"removed": {"saturated": 2}}, "II": {"removed": {}}},
                "runtime_s": 0.0, "files": []}

    monkeypatch.setattr(reproduce, "reproduce_table4", table4)
    monkeypatch.setattr(reproduce.table4, "format_table", lambda res: "table 4")
    monkeypatch.setattr(reproduce, "reproduce_table5", table5)
    monkeypatch.setattr(reproduce.table5, "format_table5", lambda res: "table 5")

    def platform(**kw):
        seen["platform"] = kw
        return {"files": []}

    monkeypatch.setattr(reproduce, "reproduce_platform", platform)
    monkeypatch.setattr(reproduce.platform, "format_platform", lambda res: "platform")
    for table in ("all", "platform"):
        rc = main(["reproduce", "--table", table, "--quick", "--address", "tcp://10.0.0.1:8786",
                   "--scheduler", "cluster", "--workers", "2", "--method", "fit",
                   "--out", str(tmp_path)])
        assert rc == 0
    # Table 5's removed frames, in the words of Table 4's text (one function for both)
    assert "\nFrames removed (status: count): I: 2 saturated; II: none\n" in capsys.readouterr().out
    for k in (4, 5, "platform"):
        assert (seen[k]["address"], seen[k]["scheduler"], seen[k]["workers"],
                seen[k]["method"]) == ("tcp://10.0.0.1:8786", "cluster", 2, "fit"), k
        assert seen[k]["quick"] is True
    # without --scheduler: processes where there are several cores (rendering holds the GIL
    # part of each frame), threads on one
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert main(["reproduce", "--table", "4", "--quick", "--out", str(tmp_path)]) == 0
    assert seen[4]["scheduler"] == "processes" and seen[4]["address"] is None
    monkeypatch.setattr("os.cpu_count", lambda: 1)
    assert main(["reproduce", "--table", "4", "--quick", "--out", str(tmp_path)]) == 0
    assert seen[4]["scheduler"] == "threads"
    capsys.readouterr()


def test_console_script_exits_with_the_status_after_the_exit_handlers(tmp_path):
    # run() ends the process without the interpreter's teardown, but only after the exit
    # handlers ran and the output was flushed to a pipe
    import subprocess
    import sys

    code = ("import atexit, sys\n"
            "atexit.register(lambda: print('handler ran', flush=False))\n"
            f"sys.argv = ['sunlab', 'info', {str(tmp_path / 'missing.zarr')!r}]\n"
            "print('x' * 100000, end='')\n"
            "from sunlab.cli import run\n"
            "run()\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stdout.startswith("x" * 100000) and proc.stdout.endswith("handler ran\n")
    assert "missing.zarr" in proc.stderr and "Traceback" not in proc.stderr
