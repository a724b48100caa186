"""The presets and the profile likelihoods of the identification (protocol version 4)."""

import math

import pandas as pd
import pytest

from studies import identification as idn
from studies import profiles


@pytest.fixture(scope="module")
def protocol():
    return idn.load_protocol()


def test_the_interval_is_where_the_deviance_crosses_chi2_one_at_90_percent():
    # a deviance linear in log parameter on each side: the crossing is exact under the
    # log-linear interpolation, at log(v) = -+ 2.706 / slope
    values = [0.25, 0.5, 1.0, 2.0, 4.0]
    slope = 4.0 / math.log(2.0)  # deviance 4 per factor two
    prof = pd.DataFrame({"parameter": "p", "value": values,
                         "deviance": [abs(math.log(v)) * slope for v in values]})
    r = profiles.profile_intervals(prof, {"fitted": {"p": 1.0}}).iloc[0]
    x = profiles.CHI2_1_90 / slope
    assert r.lo == pytest.approx(math.exp(-x)) and r.hi == pytest.approx(math.exp(x))
    assert not r.lo_open and not r.hi_open
    # a flat profile is open on both sides and bounded by the grid
    flat = prof.assign(deviance=0.0)
    r = profiles.profile_intervals(flat, {"fitted": {"p": 1.0}}).iloc[0]
    assert (r.lo, r.hi, r.lo_open, r.hi_open) == (0.25, 4.0, True, True)


def test_profile_holds_each_parameter_refits_the_rest_and_reads_the_period_grid(
        protocol, monkeypatch):
    presets = {"hypothesis": "F5-gear", "seed": 4000, "nuisances": {}, "noise_px": 0.004,
               "fitted": {"alpha_total_deg": 0.02, "beta_gear_deg": 0.01,
                          "gear_period_deg": 1.26},
               "fit_ssr": 0.05, "period_ssr": {"1.0": 0.3, "1.26": 0.05, "2.0": 0.4}}
    held = []

    def fake_fit(protocol, name, nuisances, *, seed, noise_px=None, fixed=None, **kw):
        held.append(dict(fixed))
        (k, v), = ((k, v) for k, v in fixed.items() if k != "gear_period_deg")
        return {"fit_ssr": 0.05 + math.log(v / presets["fitted"][k]) ** 2}

    monkeypatch.setattr(idn, "fit_hypothesis", fake_fit)
    prof = profiles.profile_likelihood(protocol, presets, tau=0.1)
    factors = protocol["profiles"]["factors"]
    assert len(held) == 2 * len(factors)
    # the period stays at the presets' in the other parameters' profiles
    assert all(h["gear_period_deg"] == 1.26 for h in held)
    row = prof[(prof.parameter == "alpha_total_deg") & (prof.factor == 2.0)].iloc[0]
    assert row.deviance == pytest.approx(math.log(2.0) ** 2 / 0.01)
    period = prof[prof.parameter == "gear_period_deg"].set_index("value")
    assert period.loc[1.26, "deviance"] == 0.0
    assert period.loc[2.0, "deviance"] == pytest.approx((0.4 - 0.05) / 0.01)


def test_presets_are_one_fit_at_the_prior_medians_on_the_preset_seed(protocol, monkeypatch):
    calls = []

    def fake_draw(protocol, name, nuisances, *, seed, fixed=None):
        calls.append((name, nuisances, seed))
        return {"alpha_total_deg": 0.02, "fit_ssr": 0.1, "pinning": {}, "noise_px": 0.004}

    monkeypatch.setattr(idn, "fit_draw", fake_draw)
    p = profiles.fit_presets(protocol, "F5")
    assert calls == [("F5", idn.draw_nuisances(protocol, None), protocol["presets"]["seed"])]
    assert p["fitted"] == {"alpha_total_deg": 0.02} and p["seed"] == 4000


def test_every_fitted_parameter_has_a_profile_interval_around_its_preset():
    presets = profiles.load_presets()
    iv = profiles.profile_intervals(profiles.load_profiles(), presets).set_index("parameter")
    assert set(iv.index) == set(presets["fitted"])
    assert ((iv.lo <= iv.preset * (1 + 1e-9)) & (iv.preset <= iv.hi * (1 + 1e-9))).all()
