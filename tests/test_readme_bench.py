"""The README's "Your own bench" block runs as written, on the recording shipped with sunlab.

The block is read from README.md and run by bash in an empty folder, with ``sunlab`` and
``python`` meaning this interpreter and this checkout; it must make every file it uses (the
test table it evaluates on included) and end with the evaluation and the C sources.
"""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _own_bench_block() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text[text.index("## Your own bench"):]
    return re.search(r"```bash\n(.*?)```", section, re.S).group(1)


@pytest.mark.slow
def test_readme_own_bench_block_runs_verbatim(tmp_path):
    block = _own_bench_block()
    assert "sunlab evaluate cal.json test.nc" in block
    script = (
        "set -euo pipefail\n"
        f'sunlab() {{ "{sys.executable}" -m sunlab.cli "$@"; }}\n'
        f'python() {{ "{sys.executable}" "$@"; }}\n'
        + block
    )
    env = {"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin", "HOME": str(tmp_path),
           "MPLBACKEND": "Agg"}
    run = subprocess.run(["bash", "-c", script], cwd=tmp_path, env=env, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    doc = json.loads((tmp_path / "evaluation" / "evaluation.json").read_text())
    assert doc["n_ok_shots"] == doc["n_poses"] * doc["n_shots"] > 0
    assert doc["alpha.mu"] < 0.05 and doc["beta.mu"] < 0.05  # the example's 17 mm bench
    assert (tmp_path / "onboard" / "sunlab_calibration.c").is_file()
