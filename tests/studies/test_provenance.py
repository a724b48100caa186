"""The evidence's record of the code that produced it (sunlab/data/evidence_provenance.json)."""

import hashlib
import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
RECORD = json.loads((ROOT / "sunlab" / "data" / "evidence_provenance.json").read_text("utf-8"))


def _git(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", "-C", str(ROOT), *args], capture_output=True, text=True)


def _need_commits(*commits: str) -> None:
    if shutil.which("git") is None:
        pytest.skip("git is not installed: the commits cannot be checked")
    if _git("rev-parse", "--git-dir").returncode != 0:
        pytest.skip(f"{ROOT} is not a git checkout (an sdist or an installed copy): "
                    "the commits cannot be checked")
    for c in commits:
        if _git("cat-file", "-e", f"{c}^{{commit}}").returncode != 0:
            pytest.skip(f"commit {c[:7]} is not in this checkout (a shallow clone?): "
                        "fetch the history to check it")


def test_the_record_names_full_commits_and_the_files_it_covers():
    for key in ("code_commit", "protocol_commit", "evidence_commit"):
        assert re.fullmatch(r"[0-9a-f]{40}", RECORD[key]), key
    assert RECORD["protocol_version"] == json.loads(
        (ROOT / "studies" / "protocol.json").read_text("utf-8"))["version"]
    # the shipped evidence is the one recorded, byte for byte
    for path, digest in RECORD["sha256"].items():
        assert hashlib.sha256((ROOT / path).read_bytes()).hexdigest() == digest, path


def test_the_code_commit_precedes_the_commit_that_added_the_evidence():
    code, protocol, added = (RECORD[k] for k in ("code_commit", "protocol_commit",
                                                 "evidence_commit"))
    _need_commits(code, protocol, added)
    assert _git("merge-base", "--is-ancestor", code, added).returncode == 0
    assert _git("merge-base", "--is-ancestor", protocol, code).returncode == 0
    assert code != added
    # the evidence commit is the one that wrote the evidence cells; the code commit holds the
    # code (the protocol commit none: protocol.json and docs only)
    assert "sunlab/data/evidence_cells.csv" in _git(
        "show", "--name-only", "--format=", added).stdout.split()
    assert "sunlab/studies/evidence.py" in _git(
        "show", "--name-only", "--format=", code).stdout.split()
    assert not [f for f in _git("show", "--name-only", "--format=", protocol).stdout.split()
                if f.endswith(".py")]
    # and the evidence it added is the evidence shipped now (moved to studies/results/)
    for name in ("evidence_cells.csv", "evidence.csv", "profiles.csv", "ablation.csv"):
        old = subprocess.run(["git", "-C", str(ROOT), "show", f"{added}:sunlab/data/{name}"],
                             capture_output=True, check=True).stdout
        assert old == (ROOT / "studies" / "results" / name).read_bytes(), name
    # the library's two files: the same but for the columns and keys added since, declared
    assert set(RECORD["later_additions"]) == {"sunlab/data/intervals.csv",
                                              "sunlab/data/presets.json"}
    then = json.loads(_git("show", f"{added}:sunlab/data/presets.json").stdout)
    now = json.loads((ROOT / "sunlab" / "data" / "presets.json").read_text("utf-8"))
    assert {k: v for k, v in now.items() if k not in ("choices", "command")} == then
    old = _git("show", f"{added}:sunlab/data/intervals.csv").stdout.splitlines()
    new = (ROOT / "sunlab" / "data" / "intervals.csv").read_text("utf-8").splitlines()
    assert [line.rsplit(",", 1)[0] for line in new] == old


def test_a_new_run_records_its_code_commit(tmp_path):
    from studies import evidence

    c = evidence.code_commit(tmp_path)  # not a checkout
    assert c == {"code_commit": None, "dirty": None}
    _need_commits()
    c = evidence.code_commit()
    assert re.fullmatch(r"[0-9a-f]{40}", c["code_commit"]) and isinstance(c["dirty"], bool)


def test_write_evidence_records_the_code_commit_and_each_intervals_role(tmp_path):
    # a tiny case from the shipped cells (three seeds, no presets): no run, only the writing
    import pandas as pd

    from studies import evidence

    cells = pd.read_csv(ROOT / "studies" / "results" / "evidence_cells.csv")
    evidence.write_evidence(tmp_path, cells[cells["seed"].isin([3000, 3001, 3002])],
                            presets=False, provenance={"code_commit": "a" * 40, "dirty": True})
    record = json.loads((tmp_path / "evidence_provenance.json").read_text("utf-8"))
    assert record["code_commit"] == "a" * 40 and record["dirty"] is True
    roles = pd.read_csv(tmp_path / "intervals.csv").groupby("role").size().to_dict()
    assert roles == {"fit": 64, "held-out": 128, "duplicate": 32}  # 4 hypotheses x 16/32/8
