"""The shared pipeline of the reproduced tables (sunlab.reproduce.pipeline): the plans of Table 3
as run, which frames the calibrations use, the status counts, and the results file."""

import json

import numpy as np
import pytest

from sunlab import plans, schema
from sunlab.reproduce.pipeline import (
    EXPERIMENTS,
    QUICK,
    centroid_status,
    experiment_plans,
    usable_table,
    write_json,
)


def test_full_plans_are_table3s_and_quick_thins_every_grid_axis():
    full = experiment_plans()
    assert set(full) == set(EXPERIMENTS) == {"I", "II", "III"}
    for name, plan in full.items():
        assert len(plan) == len(plans.experiment(name)) and plan.shots == 8
    quick = experiment_plans(quick=True)
    assert {k: p.shots for k, p in quick.items()} == dict.fromkeys(EXPERIMENTS, QUICK["shots"])
    # every 2nd angle along each axis: a 20 x 20 grid keeps 10 x 10
    assert len(quick["I"]) == 100 and len(quick["III"]) == 100
    a = np.unique(quick["I"].alpha)
    assert np.allclose(np.diff(a), 2 * np.diff(np.unique(full["I"].alpha))[0])
    # explicit step and shots override quick
    assert {k: (len(p), p.shots) for k, p in experiment_plans(("I",), quick=True, step=4,
                                                              shots=3).items()} == {"I": (25, 3)}


def _table(statuses):
    n = len(statuses)
    return schema.centroids_dataset(np.ones((1, n)), np.ones((1, n)), alpha=[0.0], beta=[0.0],
                                    status=[[schema.STATUS[s] for s in statuses]])


def test_usable_statuses_become_ok_and_the_others_stay():
    cen = _table(["ok", "repaired", "saturated", "no_spot"])
    out = usable_table(cen)
    names = [schema.STATUS_NAMES[int(s)] for s in out.status.values[0]]
    usable = set(schema.USABLE_STATUS)
    assert names == [("ok" if s in usable else s)
                     for s in ("ok", "repaired", "saturated", "no_spot")]
    assert out.status.dtype == cen.status.dtype


def test_status_counts_list_what_the_calibrations_leave_out():
    counts = centroid_status({"I": _table(["ok", "ok", "repaired", "saturated", "clipped"])})
    assert counts["I"]["ok"] == 2 and counts["I"]["saturated"] == 1
    removed = counts["I"]["removed"]
    assert removed == {k: 1 for k in ("repaired", "saturated", "clipped")
                       if k not in schema.USABLE_STATUS}


def test_results_file_is_plain_json_and_replaces_a_planted_link(tmp_path):
    target = tmp_path / "elsewhere.txt"
    target.write_text("keep")
    path = tmp_path / "table4.json"
    path.symlink_to(target)
    assert write_json({"mu": np.float64(0.5), "n": np.arange(3), "ok": np.bool_(True)},
                      path) == str(path)
    assert json.loads(path.read_text()) == {"mu": 0.5, "n": [0, 1, 2], "ok": True}
    assert not path.is_symlink() and target.read_text() == "keep"
    with pytest.raises(TypeError):
        write_json({"x": object()}, tmp_path / "bad.json")


def test_each_interval_carries_its_role_and_the_held_out_coverage_is_reported_apart():
    # interval_role has interval90's keys; the fit side and the duplicate are not held out;
    # the shipped intervals hold the paper's held-out cells as the record says
    # (docs/identification.md): 26 of 32, median half-width 0.565 of the paper's value
    from sunlab import stats
    from sunlab.reproduce.intervals import identified, interval_coverage

    counts = {"held-out": [0, 0], "all": [0, 0]}
    widths = {"held-out": [], "all": []}
    for table, paper in (("table4", stats.paper_table4()), ("table5", stats.paper_table5())):
        iv = identified(table)
        assert {c: set(v) for c, v in iv["interval_role"].items()} == {
            c: set(v) for c, v in iv["interval90"].items()}
        roles = {c: set(v.values()) for c, v in iv["interval_role"].items()}
        if table == "table4":
            assert roles == {"polynomial": {"fit"}, "linear interp.": {"fit"},
                             "cubic interp.": {"held-out"}, "NN strategy 4": {"held-out"}}
        else:
            assert roles["1 hole [sunlab]"] == {"duplicate"}
            assert set().union(*(r for c, r in roles.items() if c != "1 hole [sunlab]")) == {
                "held-out"}
        values = {(c if table == "table4" else f"{c} [sunlab]"):
                  {f"{a}.{s}": float(v) for (a, s), v in paper[c].items()}
                  for c in paper.columns}
        cov = interval_coverage(iv["interval90"], iv["interval_role"], values)
        for role in counts:
            counts[role][0] += cov[role]["inside"]
            counts[role][1] += cov[role]["cells"]
        for c, cells in iv["interval90"].items():
            for k, (lo, hi) in cells.items():
                w = (hi - lo) / 2 / values[c][k]
                widths["all"].append(w)
                if iv["interval_role"][c][k] == "held-out":
                    widths["held-out"].append(w)
    assert counts == {"held-out": [26, 32], "all": [50, 56]}
    assert np.median(widths["held-out"]) == pytest.approx(0.565, abs=5e-4)
    assert np.median(widths["all"]) == pytest.approx(0.240, abs=5e-4)


def test_intervals_without_their_role_column_are_refused(tmp_path, monkeypatch):
    # an intervals file written before the roles were added is refused, naming it and the fix,
    # never read as if every cell were held out
    import importlib.resources
    import types

    import pandas as pd

    from sunlab import ConfigurationError
    from sunlab.reproduce import intervals

    data = importlib.resources.files("sunlab") / "data"
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "presets.json").write_text((data / "presets.json").read_text("utf-8"))
    old = pd.read_csv(data / "intervals.csv").drop(columns="role")
    old.to_csv(tmp_path / "data" / "intervals.csv", index=False)
    monkeypatch.setattr(intervals, "resources", types.SimpleNamespace(
        files=lambda package: tmp_path, as_file=importlib.resources.as_file))
    with pytest.raises(ConfigurationError, match=r"intervals\.csv: no 'role' column\. Fix: "
                                                 r"rewrite it with `python -m studies\.identify`"):
        intervals.identified("table4")
