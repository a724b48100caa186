"""The verdicts' sensitivity table (studies.sensitivity) from the shipped per-cell evidence."""

import numpy as np
import pandas as pd
import pytest

from studies import evidence, sensitivity
from studies.identification import HERE


@pytest.fixture(scope="module")
def table():
    return sensitivity.sensitivity_table()


def test_the_protocol_row_is_the_shipped_score_and_the_rules_pick(table):
    # the rescoring reproduces evidence.csv's scores to rounding, and the rule its pick
    ev = evidence.load_evidence()
    row = table.set_index("row").loc["protocol"]
    for h, m in ev.groupby("hypothesis")["score"].mean().items():
        assert row[f"score_{h}"] == pytest.approx(m, abs=1e-9)
    assert row["pick"] == evidence.identified_hypothesis()
    paired = (ev.pivot(index="seed", columns="hypothesis", values="score")
              .eval("`F5` - `F17`"))
    assert row["d_F5_F17"] == pytest.approx(paired.mean(), abs=1e-9)


def test_every_declared_row_is_there_and_the_shipped_table_is_this_one(table):
    declared = sensitivity.load_protocol()["sensitivity"]["rows"]
    rows = list(table["row"])
    assert set(rows) == set(declared)
    assert table.set_index("row").loc["mu and sigma only", "quantities"] == 16
    assert table.set_index("row").loc["without the 100-hole beta M - mu", "quantities"] == 22
    shipped = pd.read_csv(HERE / "results" / "sensitivity.csv")
    assert list(shipped["row"]) == rows
    for c in shipped.columns:
        if shipped[c].dtype.kind == "f":
            np.testing.assert_allclose(shipped[c], table[c], rtol=1e-3, err_msg=c)
        else:
            assert list(shipped[c]) == list(table[c]), c


def test_a_verdict_stands_only_where_every_row_agrees(table):
    v = sensitivity.verdicts(table)
    assert v == {"F": "not identified", "gear": "not identified"}
    one = pd.DataFrame({"F": ["5 mm"] * 3, "gear": ["no gear error", "not identified",
                                                       "no gear error"]})
    assert sensitivity.verdicts(one) == {"F": "identified: 5 mm", "gear": "not identified"}


def test_the_pooled_row_pairs_seeds_and_is_reproducible():
    a = sensitivity.sensitivity_table().iloc[-1]
    b = sensitivity.sensitivity_table().iloc[-1]
    assert a["row"].startswith("pooled") and a.equals(b)
    assert a["se_d_F5_F17"] > 0


def test_held_out_coverage_is_reported_apart_and_by_scored_quantity():
    cov = sensitivity.interval_coverage().set_index(["hypothesis", "cells"])
    assert (cov.loc[("F5", "held-out"), "inside"], cov.loc[("F5", "held-out"), "of"]) == (26, 32)
    assert (cov.loc[("F5", "all"), "inside"], cov.loc[("F5", "all"), "of"]) == (50, 56)
    z = sensitivity.quantity_z()
    assert len(z) == 24 and int(z["inside"].sum()) == 17 and int((z["z"].abs() > 3).sum()) == 3
