"""The gain of N holes over one, eq. (5), and its error budget (sunlab.multihole.budget).

With independent hole-specific errors of RMS s and an error common to all holes of RMS c, one
hole errs by sqrt(c^2 + s^2) and the mean of N by sqrt(c^2 + s^2 / N): averaging reaches
sqrt(N) only without the common part.
"""

import math

import numpy as np
import pytest
import xarray as xr

from sunlab.multihole.budget import error_budget, gain_study
from sunlab.sim import synthetic_centroids


def _estimates(s, c, n_frames=2000, n_holes=100, seed=0):
    rng = np.random.default_rng(seed)
    e = rng.normal(0, s, (n_frames, 1, n_holes)) + rng.normal(0, c, (n_frames, 1, 1))
    dims = ("pose", "shot", "hole")
    return xr.Dataset({"alpha": (dims, e), "beta": (dims, 2 * e)},
                      coords={"alpha_cmd": ("pose", np.zeros(n_frames)),
                              "beta_cmd": ("pose", np.zeros(n_frames))})


def test_budget_splits_common_and_specific_errors():
    s, c = 1.0, 0.3
    b = error_budget(_estimates(s, c))
    a = b["alpha"]
    # 200 000 specific samples: s to 1 %; 2 000 frames: c to ~3 % (3 sampling errors: 10 %)
    assert a["specific"] == pytest.approx(s, rel=0.01)
    assert a["common"] == pytest.approx(c, rel=0.10)
    assert a["single"] == pytest.approx(math.hypot(s, c), rel=0.01)
    assert a["n_holes"] == 100 and a["sqrt_n"] == 10.0
    assert a["gain_limit"] == pytest.approx(
        math.sqrt((a["common"]**2 + a["specific"]**2)
                  / (a["common"]**2 + a["specific"]**2 / 100)), rel=1e-12)
    # the budget scales with the errors: beta's are twice alpha's
    assert b["beta"]["specific"] == pytest.approx(2 * a["specific"], rel=1e-12)


def test_without_a_common_error_the_limit_is_root_n():
    b = error_budget(_estimates(1.0, 0.0))["alpha"]
    assert b["common"] < 0.03 and b["gain_limit"] == pytest.approx(10.0, rel=0.05)


def test_budget_over_chosen_holes_counts_only_them():
    holes = np.zeros(100, bool)
    holes[:25] = True
    b = error_budget(_estimates(1.0, 0.0), holes=holes)["alpha"]
    assert b["n_holes"] == 25 and b["sqrt_n"] == 5.0


def _tables(**errors):
    a = np.repeat(np.linspace(-8, 2, 6), 6)
    b = np.tile(np.linspace(-2, 8, 6), 6)
    kw = dict(shots=2, noise_px=0.01, layout="grid", **errors)
    return (synthetic_centroids(a, b, seed=1, **kw),
            synthetic_centroids(a + 0.5, b + 0.5, seed=2, **kw))


def test_gain_study_gains_nothing_on_an_error_common_to_all_holes():
    # a common platform error of 0.05 deg next to ~0.008 deg of hole errors: the limit is
    # sqrt((c^2 + s^2) / (c^2 + s^2 / 100)) ~ 1.01
    # (without it the same tables gain more than 5: gain_study's own example)
    g = gain_study(*_tables(hole_sigma_px=0.1, common_sigma_deg=0.05), order=4)
    assert g["gain"]["averaging"]["alpha"]["rms"] < 1.2
    assert g["budget"]["alpha"]["gain_limit"] < 1.2
    assert g["bad"] == []  # no defect was injected
    assert set(g["stats"]) == {"one_hole_median", "geometric_centre",
                               "geometric_centre_rejected", "averaging", "averaging_rejected"}
