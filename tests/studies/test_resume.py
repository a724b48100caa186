"""``python -m studies.identify`` stopped part way and started again resumes: the runs it
finished are kept in ``DIR/runs/`` and skipped, and its tables are an uninterrupted run's."""

import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from studies import evidence
from studies import identification as idn

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_a_stopped_identification_resumes_and_equals_an_uninterrupted_one(tmp_path):
    # the smallest run the command allows: one hypothesis without a gear, two seeds, no presets
    out, seeds = tmp_path / "ev", ["3000", "3001"]
    cmd = [sys.executable, "-m", "studies.identify", "--out", str(out), "--hypotheses", "F5",
           "--seeds", *seeds, "--jobs", "1", "--no-presets"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}

    def uninterrupted():  # the same two runs in this process (no parts), for the reference
        cells = evidence.run_protocol(idn.load_protocol(), ["F5"], [int(s) for s in seeds])
        evidence.write_evidence(tmp_path / "ref", cells, presets=False)

    # the reference runs on a thread from the start, beside both commands: on two cores the
    # command's two runs and the reference's two overlap instead of following each other
    with ThreadPoolExecutor(1) as pool:  # an error or a failed assert waits for it
        reference = pool.submit(uninterrupted)
        first = subprocess.Popen(cmd, cwd=ROOT, env=env, start_new_session=True,
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        part = out / "runs" / "F5-3000.csv"
        while not part.exists() and first.poll() is None:
            time.sleep(0.2)
        os.killpg(first.pid, signal.SIGKILL)  # stopped hard, after its first run's file
        _, err = first.communicate()
        assert part.exists(), err
        assert "2 of 2 runs to go" in err  # the estimate, printed though stderr is no terminal
        assert not (out / "evidence_cells.csv").exists()  # no table of a half-run

        second = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        stdout, stderr = second.communicate()
        reference.result()  # the uninterrupted run's error, if any, raised here
    assert second.returncode == 0, stderr
    assert "1 of 2 runs to go" in stderr  # the finished run skipped, not redone
    assert "runs: F5 seed" not in stderr  # no progress lines where no one watches
    assert "chosen by the protocol's rule: F5" in stdout
    assert sorted(p.name for p in out.iterdir()) == [
        "evidence.csv", "evidence_cells.csv", "evidence_provenance.json", "intervals.csv"]
    # (the runs folder goes once the tables are written); the uninterrupted run's tables:
    for name in ("evidence_cells.csv", "evidence.csv", "intervals.csv"):
        assert (out / name).read_bytes() == (tmp_path / "ref" / name).read_bytes(), name


def test_parts_of_another_protocol_or_code_are_refused(tmp_path):
    protocol = idn.load_protocol()
    evidence._check_parts(tmp_path, protocol)  # a new folder: its stamp written
    evidence._check_parts(tmp_path, protocol)  # the same code and protocol: accepted
    with pytest.raises(evidence.ConfigurationError, match="another protocol version or code"):
        evidence._check_parts(tmp_path, {**protocol, "version": protocol["version"] + 1})
    stamp = tmp_path / "stamp.json"
    stamp.write_text(stamp.read_text().replace('"source_sha256": "', '"source_sha256": "0'))
    with pytest.raises(evidence.ConfigurationError, match=r"Fix: remove the folder"):
        evidence._check_parts(tmp_path, protocol)
    # a folder of the user's own under that name is never taken for (and removed with) runs
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes.txt").write_text("kept")
    with pytest.raises(evidence.ConfigurationError, match="holds no runs"):
        evidence._check_parts(tmp_path / "mine", protocol)
    assert (tmp_path / "mine" / "notes.txt").read_text() == "kept"
