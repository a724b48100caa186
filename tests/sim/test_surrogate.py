"""The centroid-level surrogate (sunlab.sim.surrogate) and the paper's tables computed on it
against known truth."""

import math

import numpy as np
import pandas as pd
import pytest
from numpy.testing import assert_allclose

from sunlab import plans, sim, stats
from sunlab.errors import ConfigurationError
from sunlab.reproduce.pipeline import experiment_plans
from sunlab.sim import surrogate

#: "the 130 x 130 ROI is about 2.5 times the spot" (docs/paper.md sec. 1, sec. 3 step 4)
ROI_OVER_SPOT = 2.5


def surrogate_table4(bench, seed=0, *, step=1, shots=8, noise_px=0.004,
                     methods=("polynomial", "linear interp.", "cubic interp.")):
    """Table 4 of the surrogate bench: the library's calibrations (table4_methods) fitted on
    I (order on II), applied to III, as `sunlab reproduce` does on rendered frames."""
    from sunlab.calibration import table4_methods
    from sunlab.calibration.registry import RECIPES, fit

    cens = {n: surrogate.surrogate_centroids(bench, p, seed, noise_px=noise_px)
            for n, p in experiment_plans(step=step, shots=shots).items()}
    fits = table4_methods(neural=any(m.startswith("NN") for m in methods), seed=seed)
    # the interpolations without their leave-one-out diagnostic (it enters no cell; most of a
    # fine-grid fit's time), as the identification fits them
    cals = {m: fit(cens["I"], RECIPES[m][0], cens["II"], outlier_mads=None, leave_one_out=False)
            if m.endswith("interp.") else fits[m](cens["I"], cens["II"]) for m in methods}
    return stats.evaluate(cals, cens["III"])


def score(table, paper=None, cells=(("alpha", "mu"), ("alpha", "M"), ("beta", "mu"),
                                    ("beta", "M"))):
    """RMS of log(ours / paper) over ``cells`` of the shared columns (default: Table 4's)."""
    paper = stats.paper_table4() if paper is None else paper
    cols = [c for c in table.columns if c in paper.columns]
    if not cols:
        raise ConfigurationError(
            f"table: found columns {list(table.columns)}; expected at least one of the paper's "
            f"{list(paper.columns)}. Fix: name the columns as stats.paper_table4 does.")
    r = [math.log(float(table.loc[c, k]) / float(paper.loc[c, k])) for k in cols for c in cells]
    return float(math.sqrt(np.mean(np.square(r))))


@pytest.fixture(scope="module")
def bench():
    return sim.Bench.paper_single_hole()


def test_surrogate_geometry_matches_the_rendered_truth(bench):
    # Without the pattern and noise terms the surrogate's centroid is the renderer's true
    # centroid (ray + sun-disk kernel), to a few thousandths of a pixel, and shares its
    # platform table (the same true angles for the same seed and plan).
    plan = plans.experiment("III").thin(6).with_shots(2)
    cen = surrogate.surrogate_centroids(bench, plan, seed=3, noise_px=0.0, spot_error=False)
    cube = sim.simulate(plan, bench, seed=3)
    assert_allclose(cen["true_alpha"].values, cube["true_alpha"].values, atol=1e-12)
    assert_allclose(cen.x.values, cube["true_x"].values, atol=0.02)
    assert_allclose(cen.y.values, cube["true_y"].values, atol=0.02)


def test_spot_error_maps_predict_the_rendered_pattern_shift(bench):
    # The gain-pattern shift of the maps is what a noise-free rendered frame's centroid shows
    # beyond the truth: correlated with it, and of the same size.
    # (a strong, long pattern, so that it stands out of the fill factor's own pixel-phase
    # error; the mask held still, so that the truth is where spot_truth puts it)
    quiet = bench.replace(detector__temporal_noise=False, detector__prnu_correlated=0.12,
                          detector__prnu_correlation_px=6.0, mask__play_x_mm=0.0,
                          mask__play_y_mm=0.0)
    from sunlab import centroid

    dx, _ = surrogate.spot_error_maps(quiet)
    pred, seen = [], []
    for k, (a, b) in enumerate([(-15.0, 1.0), (-11.0, 4.0), (-7.0, 9.0), (-3.0, 13.0),
                                (0.0, 15.0), (-13.0, 12.0), (-5.0, 2.0), (-9.0, 16.0)]):
        frame = sim.render_frame(quiet, a, b, seed=0, pose=k)
        tx, ty = sim.spots.spot_truth(quiet, a, b)
        c = centroid.projection_window(frame)
        seen.append(c.x - tx[0])
        pred.append(dx[int(round(ty[0])), int(round(tx[0]))])
    assert np.corrcoef(pred, seen)[0, 1] > 0.8
    assert 0.5 < np.std(seen) / np.std(pred) < 2.0


def test_scan_recovers_a_planted_pose_error(bench):
    # Plant a known per-pose alpha error on an otherwise ideal bench, make "paper" numbers
    # from it, and scan the parameter: the best-scoring value is the planted one.
    ideal = bench.replace(detector__prnu_correlated=0.0,
                          platform=sim.Platform.ideal().replace(alpha0_deg=1.864))

    def make(w):
        return ideal.replace(platform__alpha_pose_error_deg=w)

    methods = ("polynomial", "linear interp.")
    target = surrogate_table4(make(0.012), seed=5, step=2, shots=2,
                                               methods=methods)
    scores = []
    for w in (0.004, 0.008, 0.012, 0.018, 0.024):
        t = surrogate_table4(make(w), seed=5, step=2, shots=2, methods=methods)
        scores.append(score(t, target, cells=(("alpha", "mu"), ("alpha", "M"))))
    assert int(np.argmin(scores)) == 2
    assert scores[2] < 0.05


def test_identified_bench_gives_the_papers_alpha_ordering(bench):
    # On the identified bench the one hole's alpha error is node noise that does not repeat
    # between experiments I and III (the platform's per-pose error, the mask's play, a pattern
    # correlated over 2 px): a 1-degree table copies it and loses to the smoothing polynomial,
    # polynomial < linear interp. as in Table 4. A pattern correlated over 6 px without the
    # play is partly learned by the table at F = 5 mm (12.5 px per degree), and the order flips.
    methods = ("polynomial", "linear interp.")
    t = surrogate_table4(bench, seed=0, step=1, shots=2, methods=methods)
    assert t.loc[("alpha", "mu"), "polynomial"] < 0.95 * t.loc[("alpha", "mu"),
                                                               "linear interp."]
    learnable = bench.replace(mask__play_x_mm=0.0, mask__play_y_mm=0.0,
                              detector__prnu_correlated=0.12, detector__prnu_correlation_px=6.0,
                              platform__alpha_pose_error_deg=0.002)
    t6 = surrogate_table4(learnable, seed=0, step=1, shots=2, methods=methods)
    assert t6.loc[("alpha", "mu"), "polynomial"] > t6.loc[("alpha", "mu"), "linear interp."]


def test_spot_size_and_what_the_roi_clue_would_need(bench):
    # the spot is the hole plus the sun's penumbra, (d + F' theta) / p: 35 px at F = 5 mm
    theta = np.radians(bench.source.diameter_deg)
    expected = (0.2 + bench.mask.true_distance_mm * theta) / 0.007
    assert surrogate.spot_diameter_px(bench) == pytest.approx(expected, rel=1e-12)
    # "the 130 x 130 ROI is about 2.5 times the spot" would need a 52 px spot, F of 17-19 mm:
    # the clue the presets' F = 5 mm sets aside (sunlab.sim.mask.PAPER_DISTANCE_MM)
    f_clue = (130 / ROI_OVER_SPOT * 0.007 - 0.2) / theta
    assert 17.0 < f_clue < 19.0 and bench.mask_distance_mm == 5.0


def test_score_names_the_problem():
    with pytest.raises(ConfigurationError, match="columns"):
        score(pd.DataFrame({"x": [1.0]}))


def _table4_pair(cen):
    """Table 4's polynomial and linear interpolation fitted on I (II for the order), as
    ``sunlab reproduce`` fits them; the interpolation without its leave-one-out diagnostic,
    which enters no prediction."""
    from sunlab.calibration import table4_methods
    from sunlab.calibration.registry import RECIPES, fit

    return {"polynomial": table4_methods(neural=False)["polynomial"](cen["I"], cen["II"]),
            "linear interp.": fit(cen["I"], RECIPES["linear interp."][0], cen["II"],
                                  outlier_mads=None, leave_one_out=False)}


def test_linear_interpolation_is_left_with_138_percent_of_an_aliased_gear_error(bench):
    # A gear error of period 1.6 deg on the inner axis, sampled at whole degrees (I) and half
    # degrees (III): a polynomial cannot follow it and is left with about all of it; linear
    # interpolation predicts cos(pi / 1.6) = -0.38 times it at III's poses and is left with
    # 1.38 times it (docs/paper.md sec. 10).
    geared = bench.ideal_platform().replace(mask__play_x_mm=0.0, mask__play_y_mm=0.0,
                                            platform__beta_gear_deg=0.01,
                                            platform__beta_gear_period_deg=1.6)
    exps = {k: plans.experiment(k, shots=1) for k in ("I", "II", "III")}
    cen = {k: surrogate.surrogate_centroids(geared, p, 0, spot_error=False, noise_px=0.0)
           for k, p in exps.items()}
    err = {m: c.predict(cen["III"]) for m, c in _table4_pair(cen).items()}
    rms = {m: float(np.sqrt(((e.beta - cen["III"].beta) ** 2).mean())) for m, e in err.items()}
    true = 0.01 * np.sqrt(0.5)  # the gear error's own RMS at III's poses
    assert rms["linear interp."] / true == pytest.approx(1.38, abs=0.06)
    # the polynomial, refitted on I + II, follows a little of the aliased pattern the wrong way
    assert 0.95 < rms["polynomial"] / true < 1.2
    assert rms["linear interp."] > 1.2 * rms["polynomial"]


def test_a_zero_shift_between_sessions_gives_betas_offset_shape_and_the_tables_beta_gap(bench):
    # The inner axis's zero shift between the session of I and that of II-III is an offset of
    # the test run: where it dominates beta's error (a small per-pose error, no gear error),
    # sigma / mu of beta's local errors falls below the 0.577 of any symmetric unimodal error
    # (the paper: 0.47 polynomial, 0.48 linear). The polynomial, refitted on I + II, takes part
    # of the shift from II and the table on I's grid does not: linear interpolation loses more
    # to it on beta than on alpha (the paper: 1.38 and 1.12). The presets themselves put
    # more of beta's error in its per-pose error (no gear error: a choice, docs/identification.md).
    bench = bench.replace(platform__beta_pose_error_deg=0.0005, platform__beta_gear_deg=0.0)
    from studies.identification import surrogate_runs
    from sunlab import stats

    cen = surrogate_runs(bench, seed=0, step=1, shots=2)
    t = stats.evaluate(_table4_pair(cen), cen["III"])
    shape = t.xs("sigma", level="stat") / t.xs("mu", level="stat")
    assert (shape.loc["beta"] < 1 / np.sqrt(3)).all(), shape
    assert (shape.loc["alpha"] > 1 / np.sqrt(3)).all(), shape
    gap = t.loc[(slice(None), "mu"), "linear interp."] / t.loc[(slice(None), "mu"), "polynomial"]
    assert gap[("beta", "mu")] > gap[("alpha", "mu")] + 0.1, gap
