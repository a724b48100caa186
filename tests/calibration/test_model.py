"""Tests of the geometric models as calibrations: IdealModel (1), OptimisedModel (3)-(4)."""

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import ConfigurationError, geometry, sim
from sunlab.calibration import IdealModel, OptimisedModel
from sunlab.schema import centroids_dataset

F, P, XZP, YZP = 5.0, 0.007, 610.0, 505.0
ATTRS = {"mask_distance_mm": F, "pixel_pitch_mm": P, "x_cf_px": 639.5, "y_cf_px": 511.5}


def _optimised_table(a, b, shots=2):
    x, y = geometry.optimised_centroid(a, b, F, P, 0.094, 1.864, 0.415, XZP, YZP)
    x, y = np.repeat(x[:, None], shots, 1), np.repeat(y[:, None], shots, 1)
    return centroids_dataset(x, y, alpha=a, beta=b, attrs=ATTRS)


def _grid(lo=(-17.0, -2.0), hi=(2.0, 17.0), step=1.0):
    a, b = np.meshgrid(np.arange(lo[0], hi[0] + 1e-9, step), np.arange(lo[1], hi[1] + 1e-9, step),
                       indexing="ij")
    return a.ravel(), b.ravel()


def test_ideal_model_is_exact_on_ideal_centroids():
    a, b = _grid(step=3.0)
    cen = sim.synthetic_centroids(a, b, shots=1)
    est = IdealModel().fit(cen).predict(cen)
    assert_allclose(est.alpha[:, 0], a, atol=1e-10)
    assert_allclose(est.beta[:, 0], b, atol=1e-10)


def test_ideal_model_overrides_and_bias_from_mounting():
    a, b = _grid(step=3.0)
    cen = _optimised_table(a, b)
    cal = IdealModel(x_cf_px=600.0).fit(cen)
    assert cal.sensor["x_cf_px"] == 600.0 and cal.sensor["y_cf_px"] == 511.5
    # the ideal model ignores the mounting errors: about alpha0 = 1.864 deg of bias
    err = IdealModel().fit(cen).predict(cen).alpha - cen.alpha
    assert 1.0 < float(abs(err).mean()) < 3.0


def test_optimised_model_recovers_injected_parameters():
    a, b = _grid()
    # by default the zero-pose centroid is fitted jointly (noise-free data: exact)
    cal = OptimisedModel().fit(_optimised_table(a, b))
    r = cal.result
    assert r.zero_pose_fitted
    assert_allclose([r.delta_f_mm, r.alpha0, r.beta0, r.x_zp, r.y_zp],
                    [0.094, 1.864, 0.415, XZP, YZP], atol=1e-6)
    assert cal.residuals["alpha"]["max_abs"] < 1e-8
    # anchored on the plan's (0, 0) pose, the paper's procedure
    cal = OptimisedModel(fit_zero_pose=False).fit(_optimised_table(a, b))
    r = cal.result
    assert not r.zero_pose_fitted and (r.x_zp, r.y_zp) == (XZP, YZP)
    assert_allclose([r.delta_f_mm, r.alpha0, r.beta0], [0.094, 1.864, 0.415], atol=1e-7)


def test_optimised_model_fits_the_zero_pose_when_the_plan_lacks_it():
    a, b = _grid(lo=(-16.5, -1.5), hi=(1.5, 16.5))  # experiment III has no (0, 0) pose
    cal = OptimisedModel().fit(_optimised_table(a, b))
    r = cal.result
    assert r.zero_pose_fitted
    assert_allclose([r.delta_f_mm, r.alpha0, r.beta0, r.x_zp, r.y_zp],
                    [0.094, 1.864, 0.415, XZP, YZP], atol=1e-5)


def test_optimised_model_beats_ideal_on_a_distorted_bench():
    a, b = _grid(step=2.0)
    kw = dict(delta_f_mm=0.094, mounting_deg=(1.864, 0.415, 0.0), pose_error_deg=(0.01, 0.02))
    tr = sim.synthetic_centroids(a, b, 2, seed=1, **kw)
    te = sim.synthetic_centroids(a + 1, b + 1, 2, seed=2, **kw)
    errs = {}
    for cal in (IdealModel(), OptimisedModel()):
        est = cal.fit(tr).predict(te)
        errs[cal.kind] = float(abs(est.alpha - est.alpha_cmd).mean())
    assert errs["optimised"] < 0.05 < errs["ideal"]


@pytest.mark.parametrize("force", [True, False])
def test_fit_zero_pose_switch(force):
    a, b = _grid(lo=(-8.0, -2.0), hi=(2.0, 8.0))
    cal = OptimisedModel(fit_zero_pose=force).fit(_optimised_table(a, b))
    assert cal.result.zero_pose_fitted is force


def test_measured_zero_pose_needs_the_pose():
    a, b = _grid(step=2.0)  # alpha = -17, -15, ..., 1: no zero pose
    with pytest.raises(ConfigurationError, match="fit_zero_pose"):
        OptimisedModel(fit_zero_pose=False).fit(_optimised_table(a, b))
