"""Tests of sunlab.multihole.strategies as calibrations: save/load round trips, the protocol."""

import json

import numpy as np
import pytest

from sunlab import calibration
from sunlab import multihole as mh
from sunlab.errors import ConfigurationError, SchemaError
from sunlab.sim import synthetic_centroids

A = np.repeat(np.linspace(-8.0, 2.0, 5), 5)
B = np.tile(np.linspace(-2.0, 8.0, 5), 5)


@pytest.fixture(scope="module")
def tables():
    kw = dict(shots=2, layout="grid", noise_px=0.01, hole_sigma_px=0.03,
              defects={4: {"missing": 0.5}, 9: {"sigma_px": 1.0}})
    return (synthetic_centroids(A, B, seed=1, **kw),
            synthetic_centroids(A + 0.5, B + 0.5, seed=2, **kw))


def _same(a, b):
    for name in ("alpha", "beta"):
        assert np.array_equal(a[name].values, b[name].values, equal_nan=True)


@pytest.mark.parametrize("make", [
    lambda: mh.GeometricCentre(order=2),
    lambda: mh.GeometricCentre(order=2, fill=False),
    lambda: mh.GeometricCentre(order=2, holes=np.arange(100) != 9),
    lambda: mh.PerHoleAverage(order=2),
    lambda: mh.PerHoleAverage(order=2, weighting="inverse_variance", clip=4.0),
])
def test_save_load_round_trip_is_exact(tables, tmp_path, make):
    train, test = tables
    fitted = make().fit(train)
    assert isinstance(fitted, calibration.Calibration) and fitted.is_fitted
    path = fitted.save(tmp_path / "strategy.json")
    doc = json.loads(path.read_text())
    assert doc["kind"] == fitted.kind and doc["training"]["n_holes"] == 100
    back = mh.load_strategy(path)
    assert type(back) is type(fitted)
    _same(back.predict(test), fitted.predict(test))
    if isinstance(fitted, mh.PerHoleAverage):
        _same(back.predict_holes(test), fitted.predict_holes(test))
        assert np.array_equal(back.variance_, fitted.variance_)
    assert back.to_dict()["parameters"] == doc["parameters"]


def test_a_hole_without_calibration_survives_the_round_trip(tmp_path):
    a, b = np.repeat(np.linspace(-8, 2, 4), 4), np.tile(np.linspace(-2, 8, 4), 4)
    cen = synthetic_centroids(a, b, shots=1, layout="grid", defects={3: {"missing": 0.5}}, seed=2)
    s2 = mh.PerHoleAverage(order=3).fit(cen)
    assert s2.calibrations_[3] is None and not np.isfinite(s2.variance_[3])
    back = mh.load_strategy(s2.save(tmp_path / "s2.json"))
    assert back.calibrations_[3] is None and np.isinf(back.variance_[3])
    _same(back.predict(cen), s2.predict(cen))


def test_unfitted_strategies_refuse_to_save_or_predict(tables, tmp_path):
    with pytest.raises(ConfigurationError, match="not fitted"):
        mh.GeometricCentre().save(tmp_path / "x.json")
    with pytest.raises(ConfigurationError, match="fit"):
        mh.PerHoleAverage().predict(tables[0])


def test_residuals_and_domain_describe_the_training(tables):
    s2 = mh.PerHoleAverage(order=2).fit(tables[0])
    assert s2.domain["alpha"] == [-8.0, 2.0]
    assert 0 < s2.residuals["alpha"]["rms"] < 0.01
    s1 = mh.GeometricCentre(order=2).fit(tables[0])
    assert s1.residuals["alpha"]["n"] == 50


def test_review_holes_serves_the_explorer(tables):
    train, test = tables
    r = mh.review.review_holes(test, train=train, order=2)
    assert np.flatnonzero(r.flagged).tolist() == [4, 9]
    st = r.stats(~r.flagged, 9)
    assert st["included"]["alpha"]["mu"] < st["all"]["alpha"]["mu"]
    res = r.residual_map(9, np.ones(100, bool))
    assert res["alpha"].shape == (25,)
    assert mh.review.injected_defects(test) == {}


@pytest.mark.parametrize("make", [
    lambda: mh.GeometricCentre(order=2),
    lambda: mh.GeometricCentre(order=2, fill=False),
    lambda: mh.PerHoleAverage(order=2, weighting="inverse_variance", clip=4.0),
])
def test_predict_xy_on_hole_arrays_equals_predict(tables, make):
    # the protocol's predict_xy: centroid arrays whose last axis is the hole give, frame by
    # frame, the estimate predict gives from the table (missing holes as NaN)
    train, test = tables
    s = make().fit(train)
    ok = mh.usable(test).values
    x = np.where(ok, test.x.values, np.nan)
    y = np.where(ok, test.y.values, np.nan)
    a, b = s.predict_xy(x, y)
    est = s.predict(test)
    assert a.shape == est.alpha.shape
    np.testing.assert_allclose(a, est.alpha.values, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b, est.beta.values, rtol=0, atol=1e-12)


def test_predict_xy_needs_the_hole_axis(tables):
    s1 = mh.GeometricCentre(order=2).fit(tables[0])
    with pytest.raises(ConfigurationError, match="last axis is the hole"):
        s1.predict_xy(1.0, 2.0)


def test_fit_with_validation_records_its_residuals(tables):
    train, val = tables
    s2 = mh.PerHoleAverage(order=2).fit(train, val)
    assert s2.residuals["validation"]["alpha"]["n"] > 0
    assert s2.residuals["validation"]["alpha"]["rms"] < 0.01  # 0.01 px noise: ~1e-3 deg


def test_strategies_have_their_own_registry(tables, tmp_path):
    # calibration.load knows only single-hole methods and says where a strategy loads
    path = mh.GeometricCentre(order=2).fit(tables[0]).save(tmp_path / "gc.json")
    with pytest.raises(SchemaError, match="sunlab.multihole.load_strategy"):
        calibration.load(path)
    assert set(mh.strategies.STRATEGY_KINDS).isdisjoint(calibration.KINDS)
    assert type(mh.load_strategy(path)) is mh.GeometricCentre
