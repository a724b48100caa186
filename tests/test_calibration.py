"""The package sunlab.calibration: every public name resolves to its module's object, fit builds
a method by its kind, and what save writes load reads back."""

import importlib

import numpy as np
import pytest

import sunlab.calibration as cal
from sunlab import sim


def test_every_public_name_is_its_submodules_object():
    assert cal.__all__ and set(cal.__all__) <= set(dir(cal))
    for name in cal.__all__:
        obj = getattr(cal, name)
        home = getattr(obj, "__module__", None)
        if home and home.startswith("sunlab.calibration."):
            assert getattr(importlib.import_module(home), name) is obj, name
    with pytest.raises(AttributeError, match="no_such_method"):
        cal.no_such_method  # noqa: B018


def test_fit_by_kind_equals_the_class_and_round_trips_through_a_file(tmp_path):
    a, b = np.meshgrid(np.arange(-5.0, 5.1), np.arange(-5.0, 5.1))
    table = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, delta_f_mm=0.05)
    by_kind = cal.fit(table, "polynomial", order=3)
    direct = cal.Polynomial(order=3).fit(table)
    assert isinstance(by_kind, cal.Polynomial)
    x, y = np.array([600.0, 700.0]), np.array([480.0, 560.0])
    np.testing.assert_array_equal(by_kind.predict_xy(x, y), direct.predict_xy(x, y))
    path = tmp_path / "cal.json"
    by_kind.save(path)
    back = cal.load(path)
    assert type(back) is cal.Polynomial
    np.testing.assert_array_equal(back.predict_xy(x, y), direct.predict_xy(x, y))


def test_every_registered_kind_names_a_calibration_class():
    for kind in cal.registry.KINDS:
        assert issubclass(cal.registry.method_class(kind), cal.Calibration), kind


def test_fit_and_the_class_give_identical_coefficients_on_a_table_with_an_outlier():
    # one fit: calibration.fit and the class's own fit screen outliers with the same default
    # (outlier_mads, 10 MADs), so one absurd row is excluded by both, and the same shot
    a, b = np.meshgrid(np.linspace(-10, 10, 11), np.linspace(-10, 10, 11), indexing="ij")
    table = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=0.02, seed=1,
                                    delta_f_mm=0.05)
    table["x"][7, 0] += 40.0
    by_kind = cal.fit(table, "polynomial", order=3)
    direct = cal.Polynomial(order=3).fit(table)
    for angle in ("alpha", "beta"):
        np.testing.assert_array_equal(by_kind.coefficients[angle], direct.coefficients[angle])
    assert [(o["pose"], o["shot"]) for o in direct.training["excluded"]] == [(7, 0)]
    assert by_kind.training == direct.training
    # the one default, and the explicit argument that turns it off on both paths
    unscreened = cal.Polynomial(order=3).fit(table, outlier_mads=None)
    np.testing.assert_array_equal(
        cal.fit(table, "polynomial", order=3, outlier_mads=None).coefficients["alpha"],
        unscreened.coefficients["alpha"])
    assert not np.array_equal(unscreened.coefficients["alpha"], direct.coefficients["alpha"])
    assert "excluded" not in unscreened.training
