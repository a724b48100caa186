"""Table 5's pieces (sunlab.reproduce.table5) that need no simulated run: the per-spot
estimator, the mounting offset that numbers the 100 spots, and the text of the table."""

import numpy as np
import pandas as pd
import pytest

from sunlab import sim, stats
from sunlab.centroid.estimators import PER_SPOT
from sunlab.errors import ConfigurationError
from sunlab.reproduce.pipeline import mounting_offset_px, spot_method
from sunlab.reproduce.table5 import COLUMNS, REJECTION_COLUMN, format_table5


def test_single_spot_algorithms_become_the_tight_window_on_100_spots():
    assert {m: spot_method(m) for m in PER_SPOT} == {
        "projection": "tight", "threshold": "tight", "tight": "tight", "fit": "fit"}
    with pytest.raises(ConfigurationError, match="method: found 'nearest'"):
        spot_method("nearest")


def test_mounting_offset_is_the_median_shift_from_the_design_track():
    a, b = np.meshgrid(np.arange(-8.0, 8.1, 4.0), np.arange(-8.0, 8.1, 4.0))
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, mask_distance_mm=17.0,
                                  hole_offset_px=(80.0, 18.0))
    assert mounting_offset_px(cen) == pytest.approx((80.0, 18.0), abs=1e-6)
    # one wild centroid (a hot pixel taken for the spot) does not move a median
    cen["x"][3, 1] = 5000.0
    assert mounting_offset_px(cen)[0] == pytest.approx(80.0, abs=1e-6)


def test_the_text_puts_each_paper_cell_above_ours():
    keys = [(a, s) for a in stats.ANGLES for s in stats.STATS]
    cols = {(c, "paper"): np.full(len(keys), 0.0123) for c in COLUMNS}
    cols |= {(c, "sunlab"): np.full(len(keys), 0.0456) for c in COLUMNS}
    cols[(REJECTION_COLUMN, "sunlab")] = np.full(len(keys), 0.0789)
    table = pd.DataFrame(cols, index=pd.MultiIndex.from_tuples(keys))
    lines = format_table5({"table": table}).splitlines()
    assert lines[0].startswith("Table 5")
    i = next(k for k, line in enumerate(lines) if line.startswith(COLUMNS[0]))
    assert lines[i].endswith("paper") and lines[i].count("0.0123") == len(keys)
    assert lines[i + 1].endswith("ours") and lines[i + 1].count("0.0456") == len(keys)
    rej = next(line for line in lines if line.startswith(REJECTION_COLUMN))
    assert rej.count("0.0789") == len(keys) and rej.endswith("ours")


def test_the_text_gives_held_out_coverage_beside_the_whole_tables():
    # the identified bench's intervals with their roles: the paper's own cells are counted
    # inside their intervals on the held-out columns apart from the whole table
    from sunlab.reproduce.intervals import identified, interval_coverage

    iv = identified("table5")
    keys = [(a, s) for a in stats.ANGLES for s in stats.STATS]
    paper = stats.paper_table5()
    cols = {(c, src): paper[c].reindex(keys).to_numpy() for c in COLUMNS
            for src in ("paper", "sunlab")}
    cols[(REJECTION_COLUMN, "sunlab")] = np.full(len(keys), 0.01)
    table = pd.DataFrame(cols, index=pd.MultiIndex.from_tuples(keys))
    text = format_table5({"table": table, **iv})
    values = {f"{c} [sunlab]": {f"{a}.{s}": float(paper.loc[(a, s), c]) for a, s in keys}
              for c in COLUMNS}
    cov = interval_coverage(iv["interval90"], iv["interval_role"], values)
    assert cov["held-out"]["cells"] == 16 and cov["all"]["cells"] == 24
    line = next(ln for ln in text.splitlines() if ln.startswith("  paper "))
    assert f"held-out {cov['held-out']['inside']} of 16" in line
    assert f"all {cov['all']['inside']} of 24" in line


def test_table5_json_keeps_interval90_and_adds_each_cells_role(tmp_path):
    import json
    from pathlib import Path

    from sunlab.reproduce.intervals import identified
    from sunlab.reproduce.table5 import _write_json

    keys = [(a, s) for a in stats.ANGLES for s in stats.STATS]
    table = pd.DataFrame({(c, "sunlab"): np.full(len(keys), 0.01) for c in COLUMNS},
                         index=pd.MultiIndex.from_tuples(keys))
    result = {"table": table, "bad_holes": [], "injected": [], "budget": {}, "sizes": {},
              "runtime_s": 0.0, "timings_s": {}, "centroid_status": {}, "findings": [],
              "order": 3, **identified("table5")}
    path = _write_json(result, tmp_path, quick=True, seed=0, method="projection")
    doc = json.loads(Path(path).read_text(encoding="utf-8"))
    assert doc["interval90"] == identified("table5")["interval90"]
    assert {c: set(v) for c, v in doc["interval_role"].items()} == {
        c: set(v) for c, v in doc["interval90"].items()}
    assert set(doc["interval_role"]["100 holes: averaging [sunlab]"].values()) == {"held-out"}
