"""``python -m studies.identify`` (studies.identify): the command parses, checks its arguments
before any work, calls the study with them and prints the evidence per hypothesis and the rule's
choice. The study itself is replaced here (it runs for hours; test_identification.py)."""

import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from studies import evidence
from studies import identification as idn
from studies.identify import build_parser, main

ROOT = Path(__file__).resolve().parents[2]


def test_defaults_are_the_protocols():
    args = build_parser().parse_args(["--out", "ev"])
    assert (args.out, args.hypotheses, args.seeds, args.jobs, args.overwrite) == (
        "ev", None, None, 2, False)


def test_help_says_what_is_written(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "evidence_cells.csv" in out and "--hypotheses" in out


def test_bad_arguments_end_in_one_line_before_any_work(monkeypatch, tmp_path, capsys):
    called = []
    monkeypatch.setattr(evidence, "regenerate", lambda *a, **k: called.append(1))
    assert main(["--out", str(tmp_path), "--hypotheses", "no-such-bench"]) != 0
    err = capsys.readouterr().err
    assert "--hypotheses: ['no-such-bench'] not in the protocol" in err
    assert "Traceback" not in err
    assert main(["--out", str(tmp_path), "--jobs", "0"]) != 0
    assert "--jobs: found 0; expected 1 or more" in capsys.readouterr().err
    assert called == []


def test_the_study_gets_the_arguments_and_its_evidence_is_printed(monkeypatch, tmp_path,
                                                                    capsys):
    name = sorted(idn.load_protocol()["hypotheses"])[0]
    seen = {}

    def regenerate(out, **kw):
        seen.update(out=out, **kw)
        ev = pd.DataFrame({"hypothesis": [name, name], "parameters": [3, 3],
                           "score": [1.0, 3.0], "tau": [0.5, 0.5],
                           "held_out_within_1.25": [1.0, 0.0]})
        return {"evidence": ev, "chosen": name}

    monkeypatch.setattr(evidence, "regenerate", regenerate)
    rc = main(["--out", str(tmp_path), "--hypotheses", name, "--seeds", "7", "8", "--jobs", "1"])
    assert rc == 0
    assert seen["out"] == str(tmp_path) and seen["names"] == [name]
    assert seen["seeds"] == [7, 8] and seen["jobs"] == 1 and seen["overwrite"] is False
    assert seen["presets"] is True  # presets, profiles and ablations follow the evidence
    out = capsys.readouterr().out
    # mean score 2, its standard error std / sqrt(n) = 1.414 / 1.414 = 1
    row = next(line for line in out.splitlines() if line.startswith(name))
    assert row.split()[1:] == ["3", "2.0", "1.0", "0.5", "0.5"]
    assert out.rstrip().endswith(f"chosen by the protocol's rule: {name}")


def test_no_presets_asks_for_the_evidence_alone(monkeypatch, tmp_path):
    name = sorted(idn.load_protocol()["hypotheses"])[0]
    seen = {}

    def regenerate(out, **kw):
        seen.update(kw)
        ev = pd.DataFrame({"hypothesis": [name], "parameters": [3], "score": [1.0],
                           "tau": [0.5], "held_out_within_1.25": [1.0]})
        return {"evidence": ev, "chosen": name}

    monkeypatch.setattr(evidence, "regenerate", regenerate)
    assert main(["--out", str(tmp_path), "--no-presets"]) == 0
    assert seen["presets"] is False


def test_the_module_runs_from_the_root_and_refuses_an_unknown_hypothesis(tmp_path):
    out = subprocess.run([sys.executable, "-m", "studies.identify", "--out", str(tmp_path),
                          "--hypotheses", "F9"], capture_output=True, text=True, cwd=ROOT)
    assert out.returncode == 1
    assert "F9" in out.stderr and "Traceback" not in out.stderr
    assert list(tmp_path.iterdir()) == []


def test_the_library_never_imports_the_studies():
    # research lives beside the library, not in it: no module of sunlab/ names `studies`
    import ast

    for path in sorted((ROOT / "sunlab").rglob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import) else
                     [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] == "studies" or ".studies" in f".{n}"
                           for n in names), path
