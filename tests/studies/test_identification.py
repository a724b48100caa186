"""The identification study: its protocol, score, rule and intervals (docs/identification.md)."""

import json
import math
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from studies import evidence
from studies import identification as idn
from sunlab import stats

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def protocol():
    return idn.load_protocol()


def test_protocol_counts_every_parameter_and_switch(protocol):
    # F (a discrete choice) + the fitted parameters + the nuisances; a gear adds its switch,
    # its fitted amplitude and its period (fitted on a grid from version 4 on)
    fitted = [k for k in protocol["cells"]["pinning"] if k != "beta_gear_deg"]
    assert "gear_period_deg" not in protocol["priors"]
    for name, hyp in protocol["hypotheses"].items():
        expected = 1 + len(fitted) + len(protocol["priors"]) + (3 if hyp["gear"] else 0)
        assert hyp["parameters"] == expected, name
        # tau's degrees of freedom: 12 minus the fitted ones (amplitude and period with a gear)
        assert evidence._fitted_count(protocol, name) == len(fitted) + (2 if hyp["gear"] else 0)


def test_a_gear_fit_keeps_the_period_of_least_fit_side_misfit(protocol, monkeypatch):
    # the grid is searched whole and the least sum of squares wins, the others' fits recorded
    ssr = {1.0: 0.5, 1.26: 0.07, 1.587: 0.09, 2.0: 0.3, 2.52: 0.6, 3.175: 1.2, 4.0: 1.5}
    seen = []

    def fake_fit(protocol, name, nuisances, *, seed, noise_px=None, fixed=None, **kw):
        seen.append(fixed["gear_period_deg"])
        return {"beta_gear_deg": 0.01 * fixed["gear_period_deg"], **fixed, "pinning": {},
                "fit_ssr": ssr[fixed["gear_period_deg"]], "noise_px": 0.004}

    monkeypatch.setattr(idn, "fit_hypothesis", fake_fit)
    assert protocol["fit"]["gear_period"]["grid_deg"] == sorted(ssr)
    fit = idn.fit_draw(protocol, "F5-gear", idn.draw_nuisances(protocol, None), seed=0)
    assert seen == sorted(ssr) and fit["gear_period_deg"] == 1.26
    assert fit["beta_gear_deg"] == pytest.approx(0.0126) and fit["period_ssr"] == ssr
    # a hypothesis without the gear is one fit, no period
    seen.clear()
    monkeypatch.setattr(idn, "fit_hypothesis",
                        lambda *a, **k: {"fit_ssr": 0.1, "pinning": {}, "noise_px": 0.0})
    assert "gear_period_deg" not in idn.fit_draw(protocol, "F5", {}, seed=0)


def test_scored_quantities_drop_the_duplicated_cells(protocol):
    q = idn.scored_quantities(protocol)
    every = q["fit"] + q["held_out"]
    assert len(set(every)) == len(every) == 36
    assert not any(stat == "sigma_M" or stat == "M" for *_, stat in every)
    assert not any(col == "1 hole" for _, col, *_ in every)
    # the fit never sees a held-out column
    assert not {c for _, c, *_ in q["fit"]} & {c for _, c, *_ in q["held_out"]}


def test_nuisance_draws_lie_in_their_priors_and_are_shared_by_hypotheses(protocol):
    draws = [idn.draw_nuisances(protocol, s) for s in range(200)]
    for k, prior in protocol["priors"].items():
        v = np.array([d[k] for d in draws])
        assert (v >= prior["low"]).all() and (v <= prior["high"]).all(), k
        # 200 uniform quantiles: both halves of the prior are visited
        mid = idn._median(prior)
        assert 60 < (v < mid).sum() < 140, k
    assert idn.draw_nuisances(protocol, 7) == idn.draw_nuisances(protocol, 7)


def test_hypothesis_bench_is_the_datasheet_detector_and_the_protocols_switches(protocol):
    nuis = idn.draw_nuisances(protocol, None)
    fitted = {"alpha_total_deg": 0.01, "beta_zero_shift_deg": 0.02,
              "beta_pose_error_deg": 0.003, "beta_gear_deg": 0.01, "gear_period_deg": 1.26}
    b5 = idn.hypothesis_bench(protocol, "F5", nuis, fitted)
    b17g = idn.hypothesis_bench(protocol, "F17-gear", nuis, fitted)
    for b in (b5, b17g):
        assert b.detector.read_noise_e == 20.0 and b.detector.fill_factor == 0.6
        assert b.detector.fill_factor * b.detector.qe == pytest.approx(0.35)
        assert b.platform.beta_wobble_deg == 0 and b.platform.nonorthogonality_deg == 0
        # the one hole's alpha error: platform and play in quadrature make alpha_total
        play_deg = math.degrees(math.atan(b.mask.play_x_mm / b.mask.true_distance_mm))
        assert math.hypot(b.platform.alpha_pose_error_deg, play_deg) == pytest.approx(0.01)
    assert b5.mask_distance_mm == 5.0 and b17g.mask_distance_mm == 17.0
    assert b5.platform.beta_gear_deg == 0 and b17g.platform.beta_gear_deg == 0.01
    assert b17g.platform.beta_gear_period_deg == 1.26
    many = idn.hypothesis_bench(protocol, "F5", nuis, fitted, multi=True)
    assert many.mask.play_y_mm == nuis["multi_play_mm"] and many.n_holes == 100


def _cells(values: dict) -> pd.DataFrame:
    """A long table of predictions, every published cell, from {(h, seed): scale}."""
    paper = idn._paper_cells()
    rows = []
    for (h, seed), scale in values.items():
        rows += [{"hypothesis": h, "seed": seed, "table": t, "column": c, "angle": a,
                  "stat": s, "value": v * scale} for (t, c, a, s), v in paper.items()]
    return pd.DataFrame(rows)


def test_score_is_the_held_out_log_density_and_falls_with_the_miss(protocol):
    # predictions off by a seed-dependent factor: the better-centred hypothesis scores higher;
    # with every prediction exact but one seed off, tau and the spread follow from the formula
    cells = _cells({("F5", 0): 1.0, ("F5", 1): 1.1, ("F17", 0): 1.5, ("F17", 1): 1.7})
    ev = evidence.score_table(cells, protocol)
    mean = ev.groupby("hypothesis")["score"].mean()
    assert mean["F5"] > mean["F17"]
    f5 = ev[ev.hypothesis == "F5"].set_index("seed")
    # tau^2: the fit side's 12 log residuals, 0 on seed 0 and log 1.1 on seed 1 (M - mu and
    # every other quantity scale alike), over 12 - 5 degrees of freedom (F5 fits 5 parameters)
    tau2 = 0.5 * 12 * math.log(1.1) ** 2 / 7
    assert f5["tau"].iloc[0] == pytest.approx(math.sqrt(tau2))
    sd2 = np.var([0.0, math.log(1.1)], ddof=1)
    var = sd2 + tau2
    n = len(idn.scored_quantities(protocol)["held_out"])
    assert f5.loc[0, "score"] == pytest.approx(-0.5 * n * math.log(2 * math.pi * var))
    assert f5.loc[1, "score"] == pytest.approx(
        n * (-0.5 * math.log(1.1) ** 2 / var - 0.5 * math.log(2 * math.pi * var)))


def test_rule_takes_the_simplest_within_one_standard_error_of_the_best():
    ev = pd.DataFrame({"hypothesis": ["big"] * 3 + ["small"] * 3 + ["bad"] * 3,
                       "seed": [0, 1, 2] * 3, "parameters": [11] * 3 + [8] * 3 + [5] * 3,
                       "score": [10.0, 12.0, 14.0, 9.5, 11.0, 12.5, 0.0, 1.0, 2.0]})
    # best: big, 12 +- 2 / sqrt(3) = 1.15; small's 11.0 is within it, bad's 1.0 is not
    assert evidence.chosen_hypothesis(ev) == "small"
    ev.loc[ev.hypothesis == "small", "score"] -= 1.0
    assert evidence.chosen_hypothesis(ev) == "big"


def test_the_shipped_choice_is_the_rule_applied_by_hand_to_the_shipped_evidence(protocol):
    ev = evidence.load_evidence()
    assert {"hypothesis", "seed", "score"} <= set(ev.columns)
    assert sorted(set(ev.seed)) == protocol["confirmation_seeds"]
    g = ev.groupby("hypothesis")["score"]
    mean, se = g.mean(), g.std(ddof=1) / np.sqrt(g.count())
    best = mean.idxmax()
    eligible = [h for h in mean.index if mean[h] >= mean[best] - se[best]]
    fewest = min(protocol["hypotheses"][h]["parameters"] for h in eligible)
    picks = [h for h in eligible if protocol["hypotheses"][h]["parameters"] == fewest]
    assert evidence.identified_hypothesis() == max(picks, key=lambda h: mean[h])


def test_every_published_cell_has_a_90_percent_interval():
    # what the library reads (sunlab/data: presets.json's hypothesis, intervals.csv) is the
    # rule's pick from the studies' evidence, and every published cell has its interval
    from sunlab.reproduce.intervals import identified

    iv = {t: identified(t) for t in ("table4", "table5")}
    assert {v["hypothesis"] for v in iv.values()} == {evidence.identified_hypothesis()}
    n4 = sum(len(v) for v in iv["table4"]["interval90"].values())
    n5 = sum(len(v) for v in iv["table5"]["interval90"].values())
    assert (n4, n5) == (stats.paper_table4().size, stats.paper_table5().size)
    for table in ("table4", "table5"):
        for col, cells in iv[table]["interval90"].items():
            for key, (lo, hi) in cells.items():
                assert 0 < lo < hi, (col, key)
    assert set(iv["table5"]["interval90"]) == {f"{c} [sunlab]"
                                               for c in stats.paper_table5().columns}


def test_intervals_follow_the_log_normal_formula():
    cells = _cells({("F5", 0): 1.0, ("F5", 1): 1.2})
    ev = pd.DataFrame({"hypothesis": ["F5"], "tau": [0.1]})
    iv = evidence.intervals(cells, ev).set_index(["table", "column", "angle", "stat"])
    row = iv.loc[("table4", "polynomial", "alpha", "mu")]
    m = 0.5 * math.log(1.2)
    sd = math.hypot(np.std([0, math.log(1.2)], ddof=1), 0.1)
    assert row["mean"] == pytest.approx(0.0089 * math.exp(m))
    assert row["hi"] == pytest.approx(0.0089 * math.exp(m + evidence.Z90 * sd))
    assert row["lo"] == pytest.approx(0.0089 * math.exp(m - evidence.Z90 * sd))
    assert bool(row["inside"])


#: Protocol keys written after the version 4 evidence, which score nothing it holds: the
#: history (entries only appended) and the sensitivity analysis (declared before its table).
AFTER_EVIDENCE = ("history", "sensitivity")


def _git_or_skip(*args: str) -> str:
    if shutil.which("git") is None or not (ROOT / ".git").exists():
        pytest.skip("needs git and the history of a checkout (not an sdist or installed copy)")
    out = subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True)
    if out.returncode != 0:
        pytest.skip(f"git {' '.join(args[:2])}: not in this checkout (a shallow clone?)")
    return out.stdout


def test_the_protocol_was_committed_before_the_evidence_it_rules():
    # the protocol's commit precedes the commit that added the evidence, and what the protocol
    # says the evidence is scored by has not changed since (renames: the files moved out of
    # sunlab/data); the history and the sensitivity analysis came after, and score nothing
    record = json.loads((ROOT / "sunlab" / "data" / "evidence_provenance.json").read_text())
    protocol_commit, evidence_commit = record["protocol_commit"], record["evidence_commit"]
    _git_or_skip("merge-base", "--is-ancestor", protocol_commit, evidence_commit)
    assert protocol_commit != evidence_commit
    then = json.loads(_git_or_skip("show", f"{evidence_commit}:sunlab/data/protocol.json"))
    now = idn.load_protocol()
    assert ({k: v for k, v in then.items() if k not in AFTER_EVIDENCE}
            == {k: v for k, v in now.items() if k not in AFTER_EVIDENCE})
    assert now["history"][:len(then["history"])] == then["history"]  # appended, never edited
