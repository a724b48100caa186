"""Table 4's pieces (sunlab.reproduce.table4) that need no simulated run: the bench's own values
of what the optimised model estimates, and the methods that Fig. 12 draws."""

import pandas as pd
import pytest

from sunlab import sim
from sunlab.reproduce.table4 import bench_optimised_truth, comparable_methods


def test_a_perfect_bench_has_nothing_for_the_optimised_model_to_find():
    bench = sim.Bench.paper_single_hole().ideal_platform().ideal_mask().without_lid()
    t = bench_optimised_truth(bench)
    assert t["alpha0"] == 0.0 and t["beta0"] == 0.0
    assert t["delta_f_mm"] == pytest.approx(0.0, abs=1e-9)


def test_the_paper_bench_truth_is_its_platform_mounting_and_its_masks_height():
    bench = sim.Bench.paper_single_hole()
    t = bench_optimised_truth(bench)
    assert (t["alpha0"], t["beta0"]) == (bench.platform.alpha0_deg, bench.platform.beta0_deg)
    # the glass lid shortens the apparent height: removing it raises dF by what it took
    no_lid = bench_optimised_truth(bench.without_lid())
    assert no_lid["delta_f_mm"] - t["delta_f_mm"] == pytest.approx(
        bench.detector.lid_height_loss_mm, abs=1e-12)
    assert 0 < t["delta_f_mm"] < 0.5  # a fraction of a mm on a 5 mm mask distance


def _table(m):
    rows = pd.MultiIndex.from_tuples([("alpha", "mu"), ("alpha", "M"), ("beta", "mu"),
                                      ("beta", "M")])
    return pd.DataFrame({k: [0.0, a, 0.0, b] for k, (a, b) in m.items()}, index=rows)


def test_fig12_keeps_the_methods_within_a_factor_of_the_best_on_both_angles():
    t = _table({"polynomial": (0.01, 0.012), "cubic": (0.02, 0.011), "ideal": (0.5, 0.01),
                "trig": (0.05, 0.3)})
    assert comparable_methods(t) == ["polynomial", "cubic"]
    assert comparable_methods(t, factor=100.0) == ["polynomial", "cubic", "ideal", "trig"]
    # the best method on each angle is always drawn
    assert comparable_methods(t, factor=1.0) == []  # no method is best on both
    assert comparable_methods(_table({"a": (0.01, 0.01), "b": (0.02, 0.02)}), 1.0) == ["a"]
