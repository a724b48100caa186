"""Tests of the common calibration interface: fit/predict contract, save/load, bad files."""

import json
import subprocess
import sys

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from sunlab import ConfigurationError, SchemaError, calibration, sim
from sunlab.calibration import (
    IdealModel,
    Interpolation,
    NeuralNet,
    OptimisedModel,
    Polynomial,
    Trigonometric,
)
from sunlab.schema import STATUS

BENCH = dict(delta_f_mm=0.094, mounting_deg=(1.864, 0.415, 0.2), hole_offset_px=(3.0, -2.0),
             pose_error_deg=(0.015, 0.03), jitter_deg=7e-4, noise_px=0.005)


def _table(step, start=(-17.0, -2.0), stop=(2.0, 17.0), shots=2, seed=0, **kw):
    a, b = np.meshgrid(np.arange(start[0], stop[0] + 1e-9, step),
                       np.arange(start[1], stop[1] + 1e-9, step), indexing="ij")
    return sim.synthetic_centroids(a.ravel(), b.ravel(), shots, seed=seed,
                                        **{**BENCH, **kw})


@pytest.fixture(scope="module")
def tables():
    return _table(2.0, seed=1), _table(3.0, start=(-16.0, -1.0), stop=(1.0, 16.0), seed=2)


FACTORIES = {
    "ideal": lambda: IdealModel(),
    "optimised": lambda: OptimisedModel(),
    "polynomial": lambda: Polynomial(order=(3, 4)),
    "trigonometric": lambda: Trigonometric(order=2),
    "interpolation-linear": lambda: Interpolation("linear"),
    "interpolation-cubic": lambda: Interpolation("cubic", extrapolate="nearest"),
    "neural-1": lambda: NeuralNet(strategy=1, hidden=4, max_iter=60),
    "neural-3": lambda: NeuralNet(strategy=3, hidden=4, max_iter=60),
    "neural-4": lambda: NeuralNet(strategy=4, hidden=4, max_iter=60),
}


@pytest.mark.parametrize("name", list(FACTORIES))
def test_save_load_round_trip_gives_identical_predictions(name, tables, tmp_path):
    train, val = tables
    cal = FACTORIES[name]().fit(train, val)
    path = cal.save(tmp_path / "cal.json")
    doc = json.loads(path.read_text())
    assert doc["sunlab_schema"] == "calibration/1" and doc["kind"] == cal.kind
    assert set(doc["domain"]) >= {"alpha", "beta", "x", "y"}
    n_val = doc["residuals"]["validation"]["alpha"]["n"]
    assert n_val == val.x.size
    back = calibration.load(path)
    assert type(back) is type(cal) and back.label == cal.label
    e1, e2 = cal.predict(val), back.predict(val)
    assert_array_equal(e1.alpha.values, e2.alpha.values)
    assert_array_equal(e1.beta.values, e2.beta.values)
    # artifacts are plain JSON: no pickle, finite numbers
    assert "pickle" not in path.read_text() and "NaN" not in path.read_text()


def test_predict_contract(tables):
    train, val = tables
    x = val.x.values.copy()
    status = val.status.values.copy()
    x[0, 0] = np.nan
    status[1, 1] = STATUS["saturated"]
    bad = val.assign(x=(val.x.dims, x), status=(val.status.dims, status))
    est = Polynomial(order=3).fit(train).predict(bad)
    assert est.alpha.dims == ("pose", "shot") and est.beta.shape == val.x.shape
    assert np.isnan(est.alpha[0, 0]) and np.isnan(est.beta[0, 0])
    assert np.isfinite(est.alpha[1, 1])  # estimates are computed; the status says whether to use
    assert int(est.status[1, 1]) == STATUS["saturated"]
    assert_allclose(est.alpha_cmd, val.alpha)
    assert est.attrs["calibration"] == "polynomial"


def test_fit_uses_only_ok_shots(tables):
    train, _ = tables
    x = train.x.values.copy()
    status = train.status.values.copy()
    x[:, 1] += 50.0  # garbage shots ...
    status[:, 1] = STATUS["clipped"]  # ... flagged
    flagged = train.assign(x=(train.x.dims, x), status=(train.status.dims, status))
    clean = train.isel(shot=[0])
    a = Polynomial(order=3).fit(flagged).coefficients["alpha"]
    b = Polynomial(order=3).fit(clean).coefficients["alpha"]
    assert_allclose(a, b, rtol=1e-12, atol=1e-12)
    assert Polynomial(order=3).fit(flagged).training["n_ok_shots"] == train.sizes["pose"]


def test_average_pose_and_shot_agree_for_a_linear_fit(tables):
    train, _ = tables
    p = Polynomial(order=2, average="pose").fit(train)
    s = Polynomial(order=2, average="shot").fit(train)
    assert s.training["n_samples"] == 2 * p.training["n_samples"]
    e = p.predict(train).alpha - s.predict(train).alpha
    assert float(abs(e).max()) < 1e-3


def test_hole_dimension_is_refused_for_fitting_but_predicted(tables):
    train, _ = tables
    from sunlab.schema import centroids_dataset

    x3 = np.stack([train.x.values, train.x.values + 1], axis=-1)
    multi = centroids_dataset(x3, np.stack([train.y.values] * 2, axis=-1),
                              alpha=train.alpha.values, beta=train.beta.values,
                              attrs=train.attrs)
    with pytest.raises(SchemaError, match="hole"):
        Polynomial(order=2).fit(multi)
    est = Polynomial(order=2).fit(train).predict(multi)
    assert est.alpha.dims == ("pose", "shot", "hole")


def test_not_fitted_and_bad_arguments(tables):
    with pytest.raises(ConfigurationError, match="not fitted"):
        Polynomial(order=2).predict(tables[0])
    with pytest.raises(ConfigurationError, match="order"):
        Polynomial(order=-1)
    with pytest.raises(ConfigurationError, match="average"):
        Polynomial(order=2, average="frame").fit(tables[0])
    with pytest.raises(ConfigurationError, match="strategy"):
        NeuralNet(strategy=5)
    with pytest.raises(ConfigurationError, match="method"):
        Interpolation("quintic")
    with pytest.raises(SchemaError, match="mask_distance_mm"):
        IdealModel().fit(tables[0].assign_attrs(mask_distance_mm=None))
    with pytest.raises(SchemaError, match="sunlab_schema"):
        Polynomial(order=2).fit(tables[0].assign_attrs(sunlab_schema="frames/1"))


@pytest.fixture
def saved(tables, tmp_path):
    return Polynomial(order=2).fit(tables[0]).save(tmp_path / "cal.json")


def test_corrupt_json_gives_a_clear_error(saved):
    saved.write_text(saved.read_text()[:100])
    with pytest.raises(SchemaError, match="invalid JSON.*re-fit"):
        calibration.load(saved)


def test_wrong_version_gives_a_clear_error(saved):
    doc = json.loads(saved.read_text())
    doc["sunlab_schema"] = "calibration/2"
    saved.write_text(json.dumps(doc))
    with pytest.raises(SchemaError) as err:
        calibration.load(saved)
    assert err.value.field == "sunlab_schema" and "calibration/1" in str(err.value)


@pytest.mark.parametrize("mutate, field", [
    (lambda d: d.pop("parameters"), "parameters"),
    (lambda d: d.update(kind="spline"), "kind"),
    (lambda d: d["parameters"]["coefficients"].update(alpha=[1.0, 2.0]), "parameters"),
    (lambda d: d["parameters"].pop("scaling"), "parameters"),
    (lambda d: d["domain"].pop("x"), "domain"),
])
def test_corrupt_documents_name_the_field(saved, mutate, field):
    doc = json.loads(saved.read_text())
    mutate(doc)
    saved.write_text(json.dumps(doc))
    with pytest.raises(SchemaError, match=field):
        calibration.load(saved)


def test_missing_file(tmp_path):
    with pytest.raises(SchemaError, match="existing calibration"):
        calibration.load(tmp_path / "none.json")


def test_combine_renumbers_poses(tables):
    train, val = tables
    both = calibration.base.combine(train, val)
    assert both.sizes["pose"] == train.sizes["pose"] + val.sizes["pose"]
    assert_array_equal(both.pose, np.arange(both.sizes["pose"]))
    cal = Interpolation("linear").fit(both)
    assert cal.training["n_poses"] == both.sizes["pose"]


def test_import_does_not_load_torch():
    code = ("import sys, sunlab.calibration as c; c.NeuralNet; c.Polynomial; "
            "print('torch' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True)
    assert out.stdout.strip() == "False"


@pytest.mark.parametrize("argv", [
    ["--method", "polynomial", "--order", "3"],
    ["--method", "polynomial", "--order", "auto"],
    ["--method", "cubic", "--extrapolate"],
    ["--method", "neural", "--strategy", "2", "--hidden", "4", "--max-iter", "40"],
])
def test_cli_calibrate(tables, tmp_path, argv, capsys):
    from sunlab import io
    from sunlab.cli import main

    train, val = tables
    io.save_centroids(train, tmp_path / "I.nc")
    io.save_centroids(val, tmp_path / "II.nc")
    out = tmp_path / "cal.json"
    rc = main(["calibrate", str(tmp_path / "I.nc"), *argv, "--validation",
               str(tmp_path / "II.nc"), "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "training residuals" in text and "validation residuals" in text
    cal = calibration.load(out)
    assert_allclose(cal.predict(val).alpha, val.alpha.broadcast_like(val.x), atol=0.1)


def test_cli_calibrate_bad_order(tables, tmp_path, capsys):
    from sunlab import io
    from sunlab.cli import main

    io.save_centroids(tables[0], tmp_path / "I.nc")
    rc = main(["calibrate", str(tmp_path / "I.nc"), "--order", "auto", "--out",
               str(tmp_path / "c.json")])
    assert rc == 1 and "--validation" in capsys.readouterr().err


def test_a_hot_pixel_repaired_in_the_window_keeps_the_shot_in_the_calibration(tmp_path, capsys):
    # Issue 37: one hot pixel at full scale inside the centroid window of 20 of 25 poses. The
    # estimator repairs it (status 'repaired', centroid as on the clean frame); the calibration
    # keeps those shots, counts them and says so, instead of dropping most of its poses.
    import _spots

    from sunlab import centroid, cli, io, schema
    from sunlab.calibration import Polynomial

    grid = [(a, b) for a in (-8.0, -4.0, 0.0, 4.0, 8.0) for b in (-8.0, -4.0, 0.0, 4.0, 8.0)]
    clean, hot = [], []
    for k, (a, b) in enumerate(grid):
        x, y = 200.3 + 9.0 * a, 150.6 + 8.0 * b
        f = np.round(_spots.frame([(x, y)], noise=False, shape=(300, 400))).astype(np.uint16)
        clean.append(f)
        f = f.copy()
        if k < 20:
            f[int(y) + 4, int(x) - 3] = 1023  # inside the spot, 10-bit full scale
        hot.append(f)
    alpha, beta = [a for a, _ in grid], [b for _, b in grid]
    cen = {}
    for name, frames in (("clean", clean), ("hot", hot)):
        cube = schema.frames_dataset(np.stack(frames)[:, None], alpha=alpha, beta=beta,
                                     bit_depth=10)
        cen[name] = centroid.locate(cube, progress=False)
    status = cen["hot"]["status"].values[:, 0]
    assert (status[:20] == schema.STATUS["repaired"]).all() and (status[20:] == 0).all()
    assert np.abs(cen["hot"]["x"] - cen["clean"]["x"]).max() < 0.1  # px: the spot is intact
    cal = Polynomial(order=1).fit(cen["hot"])
    assert cal.training["n_poses"] == 25 and cal.training["n_repaired_shots"] == 20
    ref = Polynomial(order=1).fit(cen["clean"])
    est, want = cal.predict_xy(200.0, 150.0), ref.predict_xy(200.0, 150.0)
    np.testing.assert_allclose(est, want, atol=0.1 / 8.0)  # 0.1 px at >= 8 px/deg
    io.save_centroids(cen["hot"], tmp_path / "train.nc")
    assert cli.main(["calibrate", str(tmp_path / "train.nc"), "--method", "polynomial",
                     "--order", "1", "--out", str(tmp_path / "cal.json")]) == 0
    assert "20 of the 25 shots used are 'repaired'" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [
    ["--method", "ideal"], ["--method", "optimised"], ["--method", "polynomial", "--order", "2"],
    ["--method", "trigonometric", "--order", "1"], ["--method", "linear"],
    ["--method", "cubic", "--extrapolate"], ["--method", "neural", "--hidden", "2"],
])
def test_a_table_whose_spot_never_moves_is_refused_by_every_kind(tables, tmp_path, argv, capsys):
    # every pose gives the same spot (a camera that kept one frame): no map from the spot to
    # the angles can be learned, whatever the kind
    from sunlab import io
    from sunlab.cli import main

    train = tables[0].copy(deep=True)
    train["x"][:] = 512.25
    train["y"][:] = 498.75
    io.save_centroids(train, tmp_path / "I.nc")
    out = tmp_path / "cal.json"
    rc = main(["calibrate", str(tmp_path / "I.nc"), *argv, "--out", str(out)])
    err = capsys.readouterr().err.strip()
    assert rc == 1 and len(err.splitlines()) == 1 and "train" in err and "spot" in err
    assert not out.exists()
