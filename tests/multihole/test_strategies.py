"""Tests of sunlab.multihole.strategies as calibrations: save/load round trips, the protocol."""

import json

import numpy as np
import pytest

from sunlab import calibration
from sunlab import multihole as mh
from sunlab.errors import ConfigurationError, SchemaError
from sunlab.multihole.review import injected_defects, review_holes
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
def test_calibration_load_reads_a_100_hole_strategy_file_and_predicts_identically(
        tables, tmp_path, make):
    # one registry: the file a strategy's save writes is read by calibration.load itself
    train, test = tables
    fitted = make().fit(train)
    assert isinstance(fitted, calibration.Calibration) and fitted.is_fitted
    path = fitted.save(tmp_path / "strategy.json")
    doc = json.loads(path.read_text())
    assert doc["kind"] == fitted.kind and doc["training"]["n_holes"] == 100
    back = calibration.load(path)
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
    back = calibration.load(s2.save(tmp_path / "s2.json"))
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
    r = review_holes(test, train=train, order=2)
    assert np.flatnonzero(r.flagged).tolist() == [4, 9]
    st = r.stats(~r.flagged, 9)
    assert st["included"]["alpha"]["mu"] < st["all"]["alpha"]["mu"]
    res = r.residual_map(9, np.ones(100, bool))
    assert res["alpha"].shape == (25,)
    assert injected_defects(test) == {}


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
    ok = mh.holes.usable(test).values
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


def test_strategies_are_entries_of_the_calibration_registry(tables):
    # registered by entry point (multihole sits above calibration), so the registry's own
    # doors list them and fit them
    train, test = tables
    kinds = calibration.registry.available_kinds()
    assert {"multihole-geometric-centre", "multihole-per-hole-average"} <= set(kinds)
    assert calibration.registry.method_class("multihole-geometric-centre") is mh.GeometricCentre
    s2 = calibration.fit(train, "multihole-per-hole-average", order=2, outlier_mads=None)
    assert type(s2) is mh.PerHoleAverage
    _same(s2.predict(test), mh.PerHoleAverage(order=2).fit(train).predict(test))


def test_an_unregistered_strategy_kind_names_the_entry_point_group(tables):
    doc = mh.GeometricCentre(order=2).fit(tables[0]).to_dict()
    doc["kind"] = "multihole-unknown"
    with pytest.raises(SchemaError, match="sunlab.calibrations"):
        calibration.artifact.from_dict(doc)
