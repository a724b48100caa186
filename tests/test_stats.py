"""Tests of sunlab.stats on hand-computed examples."""

import numpy as np
import pandas as pd
import pytest
import xarray as xr
from numpy.testing import assert_allclose

from sunlab import ConfigurationError, SchemaError, stats
from sunlab.schema import STATUS


def _estimate():
    # 2 poses x 3 shots; commanded (alpha, beta) = (1, 0) and (2, 5)
    return xr.Dataset(
        {
            "alpha": (("pose", "shot"), [[1.1, 0.8, 1.0], [2.0, 2.4, 1.9]]),
            "beta": (("pose", "shot"), [[0.0, -0.1, 0.2], [5.5, 5.0, np.nan]]),
            "status": (("pose", "shot"), np.array([[0, 0, 0], [0, 0, STATUS["clipped"]]],
                                                  dtype=np.int8)),
        },
        coords={"pose": [0, 1], "alpha_cmd": ("pose", [1.0, 2.0]),
                "beta_cmd": ("pose", [0.0, 5.0])},
        attrs={"label": "demo"},
    )


def test_shot_errors_absolute_signed_and_status():
    err = stats.shot_errors(_estimate())
    assert_allclose(err.alpha.values, [[0.1, 0.2, 0.0], [0.0, 0.4, np.nan]], atol=1e-12)
    signed = stats.shot_errors(_estimate(), absolute=False)
    assert_allclose(signed.alpha.values[0], [0.1, -0.2, 0.0], atol=1e-12)


def _local(est, reference=None):
    return stats.evaluate(est, reference=reference, return_errors=True)[2]


def test_local_and_maximum_errors_by_hand():
    loc = _local(_estimate())
    # alpha: pose 0 -> mean(0.1, 0.2, 0) = 0.1, max 0.2; pose 1 -> mean(0, 0.4) = 0.2 (clipped
    # shot excluded), max 0.4
    assert_allclose(loc.local_error.sel(angle="alpha"), [0.1, 0.2], atol=1e-12)
    assert_allclose(loc.max_error.sel(angle="alpha"), [0.2, 0.4], atol=1e-12)
    # beta: pose 0 -> (0, 0.1, 0.2) mean 0.1 max 0.2; pose 1 -> (0.5, 0) mean 0.25 max 0.5
    assert_allclose(loc.local_error.sel(angle="beta"), [0.1, 0.25], atol=1e-12)
    assert_allclose(loc.max_error.sel(angle="beta"), [0.2, 0.5], atol=1e-12)
    assert loc.n_shots.values.tolist() == [[3, 2], [3, 2]]


def test_pose_without_usable_shot_is_nan_and_skipped():
    est = _estimate()
    est["status"][1, :] = STATUS["no_spot"]
    loc = _local(est)
    assert np.isnan(loc.local_error.sel(angle="alpha")[1])
    tab = stats.evaluate({"m": est})
    assert_allclose(tab.loc[("alpha", "mu"), "m"], 0.1, atol=1e-12)
    assert np.isnan(tab.loc[("alpha", "sigma"), "m"])  # one pose: no sample std


def test_global_stats_by_hand_and_layout():
    tab = stats.evaluate(_estimate())
    assert list(tab.columns) == ["demo"]
    assert tab.index.names == ["angle", "stat"]
    assert [s for _, s in tab.index][:4] == ["mu", "sigma", "M", "sigma_M"]
    # alpha local (0.1, 0.2): mu 0.15, sigma (ddof=1) = 0.0707107; max (0.2, 0.4): M 0.3, sM 0.1414
    assert_allclose(tab["demo"].loc["alpha"].values, [0.15, 0.05 * 2**0.5, 0.3, 0.1 * 2**0.5],
                    atol=1e-12)
    pop = stats.evaluate(_estimate(), ddof=0)
    assert_allclose(pop.loc[("alpha", "sigma"), "demo"], 0.05, atol=1e-12)


def test_reference_can_be_the_truth():
    est = _estimate()
    truth = {"alpha": xr.full_like(est.alpha, 1.0), "beta": xr.full_like(est.beta, 0.0)}
    err = stats.shot_errors(est, truth)
    assert_allclose(err.alpha.values[1, :2], [1.0, 1.4], atol=1e-12)
    # evaluate scores against the same reference: pose 1's alpha errors (1.0, 1.4)
    assert_allclose(_local(est, truth).local_error.sel(angle="alpha")[1], 1.2, atol=1e-12)
    with pytest.raises(SchemaError, match="reference"):
        stats.shot_errors(est, {"alpha": est.alpha})
    with pytest.raises(SchemaError, match="alpha_cmd"):
        stats.shot_errors(est.drop_vars(["alpha_cmd", "beta_cmd"]))


def test_rectangles_and_areas():
    tab = stats.paper_table4()
    rect = stats.rectangles(tab)
    m, s = 0.0099, 0.0054
    assert_allclose(rect.loc["polynomial", ["alpha_low", "alpha_high"]], [m - 3 * s, m + 3 * s])
    assert_allclose(rect["area"], 36 * tab.loc[("alpha", "sigma_M")] * tab.loc[("beta",
                    "sigma_M")], rtol=1e-12)
    # the paper: polynomial and NN strategy 4 are best, cubic interpolation worst
    assert set(rect["area"].nsmallest(2).index) == {"polynomial", "NN strategy 4"}
    assert rect["area"].idxmax() == "cubic interp."


def test_paper_tables_are_transcribed():
    t4, t5 = stats.paper_table4(), stats.paper_table5()
    assert t4.shape == (8, 4) and t5.shape == (8, 3)
    assert t4.loc[("beta", "sigma_M"), "cubic interp."] == 0.0152
    assert t5.loc[("beta", "M"), "100 holes: averaging"] == 0.0423
    # the one-hole column of Table 5 is the polynomial column of Table 4
    assert_allclose(t5["1 hole"], t4["polynomial"])
    # beta worse than alpha for every method of Table 4 (the paper's finding) -- but NN 4
    mu = t4.xs("mu", level="stat")
    assert (mu.loc["beta"] > mu.loc["alpha"]).drop("NN strategy 4").all()
    assert "Table 4" in t4.attrs["source"]


def test_side_by_side():
    ours = pd.DataFrame({"polynomial": np.arange(8.0)}, index=stats.paper_table4().index)
    both = stats.side_by_side(ours, stats.paper_table4())
    assert both[("polynomial", "paper")].loc[("alpha", "mu")] == 0.0089
    with pytest.raises(ConfigurationError, match="share no"):
        stats.side_by_side(ours.rename(columns={"polynomial": "x"}), stats.paper_table4())


def test_unstack_poses_to_grid():
    a, b = np.meshgrid([-1.0, 0.0, 1.0], [2.0, 3.0], indexing="ij")
    da = xr.DataArray(np.arange(6.0), dims="pose",
                      coords={"pose": np.arange(6), "alpha_cmd": ("pose", a.ravel()),
                              "beta_cmd": ("pose", b.ravel())})
    g = stats.unstack_poses(da)
    assert g.dims == ("alpha", "beta") and g.shape == (3, 2)
    assert float(g.sel(alpha=1.0, beta=2.0)) == 4.0


def test_evaluate_bad_input():
    with pytest.raises(ConfigurationError, match="empty mapping"):
        stats.evaluate({})
    with pytest.raises(SchemaError, match=r"m\.alpha"):
        stats.evaluate({"m": xr.Dataset()})


def test_error_summary_is_one_column_of_evaluate():
    rng = np.random.default_rng(1)
    e = xr.Dataset({a: (("pose", "shot"), rng.normal(0, 0.01, (6, 3))) for a in ("alpha", "beta")})
    s = stats.error_summary(e)
    ref = {"alpha": xr.DataArray(0.0), "beta": xr.DataArray(0.0)}
    table = stats.evaluate({"m": e}, reference=ref)["m"]
    for a in ("alpha", "beta"):
        for k in stats.STATS:
            assert s[a][k] == float(table.loc[(a, k)])
        assert s[a]["n_poses"] == 6
        assert s[a]["rms"] == pytest.approx(float(np.sqrt((e[a] ** 2).mean())))
