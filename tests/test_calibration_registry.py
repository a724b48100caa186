"""Tests of sunlab.calibration.registry and the lab's path through the library.

Every registered method fits a single-hole table with default options and comes back from its
document with identical predictions (or says which extra it needs); :func:`calibration.fit`
is the one door to the registry; a lab's CSV tables go from :func:`sunlab.io.open_centroids`
through ``fit`` to :func:`sunlab.stats.evaluate` and a saved file.
"""

import json

import numpy as np
import pytest

from sunlab import calibration, io, stats
from sunlab.errors import ConfigurationError, SchemaError
from sunlab.extras import EXTRAS
from sunlab.sim import synthetic_centroids


def _table(seed, n=11, noise_px=0.02):
    a, b = np.meshgrid(np.linspace(-10.0, 10.0, n), np.linspace(-10.0, 10.0, n), indexing="ij")
    return synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=noise_px, seed=seed,
                               delta_f_mm=0.05)


@pytest.fixture(scope="module")
def train():
    return _table(1)


@pytest.mark.parametrize("kind", sorted(calibration.KINDS))
def test_every_method_fits_with_defaults_and_round_trips(train, kind):
    try:
        cal = calibration.fit(train, kind)
    except ImportError as err:  # a method of an extra: the message names it
        assert any(f'"sunlab[{extra}]"' in str(err) for extra in EXTRAS.values())
        return
    assert cal.kind == kind
    back = calibration.from_dict(json.loads(json.dumps(cal.to_dict())))
    assert type(back) is type(cal) and back.kind == kind
    x, y = train.x.values, train.y.values
    for got, want in zip(back.predict_xy(x, y), cal.predict_xy(x, y), strict=True):
        assert np.array_equal(got, want, equal_nan=True)
    # and the fit means something: the estimate is near the commanded angles (the ideal
    # model ignores the bench's 0.05 mm dF: about 0.1 deg at 10 deg)
    a, _ = cal.predict_xy(x, y)
    assert np.nanmax(np.abs(a - train.alpha.values[:, None])) < 0.5


@pytest.mark.parametrize("kind", ["ideal", "optimised"])
def test_a_geometric_model_names_the_missing_sensor_attribute(train, kind):
    bare = train.copy()
    bare.attrs = {k: v for k, v in train.attrs.items() if k != "mask_distance_mm"}
    with pytest.raises(SchemaError, match="mask_distance_mm"):
        calibration.fit(bare, kind)


def test_fit_refuses_an_unknown_method_or_option(train):
    with pytest.raises(ConfigurationError, match="expected one of"):
        calibration.fit(train, "spline")
    with pytest.raises(ConfigurationError, match="Polynomial"):
        calibration.fit(train, "polynomial", strategy=2)


def test_aliases_and_options_reach_the_class(train):
    cal = calibration.fit(train, "cubic", extrapolate="nearest")
    assert cal.kind == "interpolation-cubic" and cal.extrapolate == "nearest"
    assert calibration.fit(train, "polynomial", order=2).label == "polynomial(2)"
    assert calibration.method_class("linear") is calibration.Interpolation


def _write_csv(table, path):
    rows = ["alpha,beta,x,y,shot"]
    for p in range(table.sizes["pose"]):
        for s in range(table.sizes["shot"]):
            rows.append(f"{float(table.alpha[p])!r},{float(table.beta[p])!r},"
                        f"{float(table.x[p, s])!r},{float(table.y[p, s])!r},{s}")
    path.write_text("\n".join(rows) + "\n")
    return path


def test_the_lab_path_on_csv_tables(tmp_path):
    # open_centroids -> fit(train, "polynomial", order=3) -> evaluate(cal, test); save/load
    train = io.open_centroids(_write_csv(_table(1), tmp_path / "train.csv"))
    test = io.open_centroids(_write_csv(_table(2), tmp_path / "test.csv"))
    assert dict(train.sizes) == {"pose": 121, "shot": 2}
    cal = calibration.fit(train, "polynomial", order=3)
    table = stats.evaluate(cal, test)
    assert table.index.equals(stats.paper_table4().index)
    assert list(table.columns) == [cal.label]
    # 0.02 px of centroid noise at 7 um / 5 mm per px: a few thousandths of a degree
    assert 0 < table.loc[("alpha", "mu"), cal.label] < 0.01
    back = calibration.load(cal.save(tmp_path / "cal.json"))
    assert stats.evaluate(back, test).equals(table)
    for got, want in zip(back.predict_xy(test.x, test.y), cal.predict_xy(test.x, test.y),
                         strict=True):
        assert np.array_equal(got, want)


def test_evaluate_returns_what_the_cli_writes():
    test = _table(2)
    cal = calibration.fit(_table(1), "polynomial", order=3)
    frame, est, local = stats.evaluate(cal, test, return_errors=True)
    assert est.alpha.shape == test.x.shape and set(local.angle.values) == {"alpha", "beta"}
    assert frame.equals(stats.global_stats({cal.label: local}))


def test_open_centroids_refuses_a_frame_cube(tmp_path):
    from sunlab import schema

    cube = schema.frames_dataset(np.zeros((1, 1, 4, 4), np.uint16), alpha=[0.0], beta=[0.0])
    io.save_frames(cube, tmp_path / "cube.zarr")
    with pytest.raises(SchemaError, match="centroid the frames first"):
        io.open_centroids(tmp_path / "cube.zarr")
