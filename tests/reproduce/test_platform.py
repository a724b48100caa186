"""The platform table's pieces (sunlab.reproduce.platform) that need no simulated run: the
bench's own fault values, which the fitted ones are compared with, and the table's text."""

import dataclasses

import pytest

from sunlab import plans, sim
from sunlab.reproduce.platform import GEAR_ROW, ROWS, bench_fault_values, format_platform
from sunlab.sim import bench as bench_module
from sunlab.sim.platform import homing_offset

RUNS = {"I": plans.experiment("I"), "III": plans.experiment("III")}


def test_fault_values_are_the_benchs_own():
    bench = sim.Bench.paper_single_hole()
    platform = dataclasses.replace(bench.platform, beta_backlash_deg=0.012, beta_gear_deg=0.003)
    faulty = dataclasses.replace(bench, platform=platform)
    v = bench_fault_values(faulty, 4, RUNS)
    assert v["beta_backlash_deg"] == 0.012 and v["beta_gear_amplitude_deg"] == 0.003
    # the test run's homing offset less the calibration run's, as drawn for this seed
    assert v["beta_homing_difference_deg"] == pytest.approx(
        homing_offset(faulty, 4, "III") - homing_offset(faulty, 4, "I"), abs=0.0)
    # the identified bench re-homes its inner axis by PAPER_BETA_REHOMING_DEG between I and III
    assert bench_fault_values(bench, 0, RUNS)["beta_homing_difference_deg"] == pytest.approx(
        bench_module.PAPER_BETA_REHOMING_DEG, abs=5e-5)


def test_rows_are_the_protocol_then_the_remedies():
    assert ROWS[0].startswith("polynomial (paper's protocol)")
    assert [r[:3] for r in ROWS[1:]] == ["(a)", "(a)", "(b)", "(b)"] and GEAR_ROW[:3] == "(b)"


def _result():
    rows = {r: {"alpha mu": 0.01 + k / 1000, "beta mu": 0.02 - k / 1000}
            for k, r in enumerate(ROWS)}
    return {
        "settings": {"engine": "surrogate", "scan": "serpentine"},
        "rows": rows,
        "parameters": {"beta_backlash_deg": {"fitted": 0.00012, "stderr": 0.0001, "bench": 0.0,
                                             "z": 1.2}},
        "diagnosis": {"candidate": "homing", "z": {"backlash": 0.4, "homing": 6.0}},
        "paper_shape": {"beta": {"ratio": 0.41}},
        "must_show": {"best_remedy": ROWS[4], "best_beta_mu": 0.016, "limit_alpha": 0.013,
                      "limit_beta": 0.012, "beta_mu_within_1.3x_polynomial_alpha_mu": False,
                      "beta_mu_within_0.6x_polynomial_beta_mu": False,
                      "parameters_within_2.5_stderr": True},
    }


def test_text_says_every_row_parameter_and_verdict():
    text = format_platform(_result())
    lines = text.splitlines()
    assert lines[0] == "Platform fault - polynomial calibration on experiment III, one hole (deg)"
    assert "ours = sunlab virtual bench (surrogate); scan serpentine" == lines[1]
    row = next(line for line in lines if line.startswith(ROWS[1]))
    assert row.split()[-2:] == ["0.0110", "0.0190"]
    assert "beta_backlash_deg" in text and "0.00012 +- 0.00010 |  0.00000 | +1.20" in text
    assert "Diagnosis: homing (z: backlash 0.4, homing 6.0)" in text
    assert f"Best remedy: {ROWS[4]}: beta mu 0.0160" in text
    assert "within 2.5 s.e. of the bench's value: yes" in text
