"""Tests of sunlab.calibration.registry and the lab's path through the library.

Every registered method fits a single-hole table with default options and comes back from its
document with identical predictions (or says which extra it needs); :func:`calibration.fit`
is the one door to the registry; a lab's CSV tables go from :func:`sunlab.io.open_centroids`
through ``fit`` to :func:`sunlab.stats.evaluate` and a saved file.
"""

import json

import numpy as np
import pytest

from sunlab import calibration, io, sim, stats
from sunlab.calibration import table4_methods
from sunlab.calibration.registry import POLYNOMIAL_REFIT, TRIGONOMETRIC_PERIOD
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


@pytest.mark.parametrize("kind", sorted(calibration.registry.KINDS))
def test_every_method_fits_with_defaults_and_round_trips(train, kind):
    try:
        cal = calibration.fit(train, kind)
    except ImportError as err:  # a method of an extra: the message names it
        assert any(f'"sunlab[{extra}]"' in str(err) for extra in EXTRAS.values())
        return
    assert cal.kind == kind
    back = calibration.artifact.from_dict(json.loads(json.dumps(cal.to_dict())))
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
    assert calibration.registry.method_class("linear") is calibration.Interpolation


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
    assert frame.equals(stats.evaluate({cal.label: est}))
    assert frame.equals(stats.evaluate({cal.label: cal}, test))


def test_open_centroids_refuses_a_frame_cube(tmp_path):
    from sunlab import schema

    cube = schema.frames_dataset(np.zeros((1, 1, 4, 4), np.uint16), alpha=[0.0], beta=[0.0])
    io.save_frames(cube, tmp_path / "cube.zarr")
    with pytest.raises(SchemaError, match="centroid the frames first"):
        io.open_centroids(tmp_path / "cube.zarr")


# -- one path: the library does what the command line does (issue 36) ---------------------------
def _lab_csv(folder, table, bad_line: int):
    """``table`` as a lab's CSV, one row moved 40 px off (screening removes it), and a
    ``sensor.json`` beside it."""
    rows = ["alpha,beta,x,y,shot"]
    for p in range(table.sizes["pose"]):
        for s in range(table.sizes["shot"]):
            x = float(table.x.values[p, s]) + (40.0 if len(rows) + 1 == bad_line else 0.0)
            rows.append(f"{float(table.alpha.values[p])!r},{float(table.beta.values[p])!r},"
                        f"{x!r},{float(table.y.values[p, s])!r},{s}")
    path = folder / "train.csv"
    path.write_text("\n".join(rows) + "\n")
    (folder / "sensor.json").write_text(json.dumps({
        "pixel_pitch_mm": 0.007, "mask_distance_mm": 5.0, "x_cf_px": 640.0, "y_cf_px": 512.0}))
    return path


def test_calibrate_and_the_library_give_identical_coefficients(tmp_path, capsys):
    from sunlab import screening
    from sunlab.calibration import registry
    from sunlab.cli import main

    path = _lab_csv(tmp_path, _table(1), bad_line=17)
    assert main(["calibrate", str(path), "--method", "polynomial", "--order", "3", "--out",
                 str(tmp_path / "cal.json")]) == 0
    assert f"{path} line 17 (train): excluded as an outlier" in capsys.readouterr().out
    cli_cal = calibration.load(tmp_path / "cal.json")
    table = io.open_centroids(path)
    assert table.attrs["mask_distance_mm"] == 5.0  # the sensor.json beside the CSV
    lib_cal = calibration.fit(table, "polynomial", order=3)
    for angle in ("alpha", "beta"):
        np.testing.assert_array_equal(cli_cal.coefficients[angle],
                                      lib_cal.coefficients[angle])  # bit for bit
    assert [o["pose"] for o in lib_cal.training["excluded"]] == [7]
    assert cli_cal.training["excluded"] == lib_cal.training["excluded"]
    assert registry.OUTLIER_MADS == screening.N_MAD  # one default, library and CLI
    # and screening is what made them equal to each other, not to an unscreened fit
    raw = calibration.fit(table, "polynomial", order=3, outlier_mads=0)
    assert not np.array_equal(raw.coefficients["alpha"], lib_cal.coefficients["alpha"])


def test_order_auto_is_the_librarys(tmp_path):
    cal = calibration.fit(_table(1), "polynomial", _table(2), order="auto")
    best, scores = calibration.Polynomial.select_order(_table(1), _table(2))
    assert cal.orders == best.orders and cal.order_scores.equals(scores)
    with pytest.raises(ConfigurationError, match="without a validation table"):
        calibration.fit(_table(1), "polynomial", order="auto")
    with pytest.raises(ConfigurationError, match="methods that choose their order"):
        calibration.fit(_table(1), "linear", _table(2), order="auto")


def test_order_auto_of_another_method_keeps_the_best_validation_error():
    # the trigonometric expansion chooses its order by the same select_order as the
    # polynomial: each order fitted on I, scored by its mean absolute error on II's shots
    # (alpha + beta), as the paper picks its orders
    train, val = _table(1, n=7), _table(2, n=7)
    cal = calibration.fit(train, "trigonometric", val, order="auto", orders=(1, 2, 3),
                          period=2.0, outlier_mads=None)
    errors = {}
    for order in (1, 2, 3):
        est = calibration.Trigonometric(order, period=2.0).fit(train).predict(val)
        errors[order] = float(abs(est.alpha - est.alpha_cmd).mean()
                              + abs(est.beta - est.beta_cmd).mean())
    assert cal.order == min(errors, key=errors.get) and cal.period == 2.0
    scores = cal.order_scores
    np.testing.assert_allclose(scores["alpha_mean_abs"] + scores["beta_mean_abs"],
                               list(errors.values()), rtol=1e-12)


def test_table4_recipes_are_registry_entries_fitted_by_fit():
    from sunlab.calibration import registry

    train, val = _table(1, n=7), _table(2, n=7)
    recipes = table4_methods(neural=False)
    assert list(recipes) == [k for k, (kind, _) in registry.RECIPES.items() if kind != "neural"]
    poly = recipes["polynomial"](train, val)
    best, _ = calibration.Polynomial.select_order(train, val, refit=registry.POLYNOMIAL_REFIT)
    assert poly.orders == best.orders
    assert np.array_equal(poly.coefficients["alpha"], best.coefficients["alpha"])
    cubic = recipes["cubic interp."](train, val)
    assert cubic.kind == "interpolation-cubic" and "outlier_mads" not in cubic.training


def test_evaluate_and_the_library_give_identical_statistics(tmp_path):
    from sunlab.cli import main

    cal = calibration.fit(_table(1), "polynomial", order=3)
    cal.save(tmp_path / "cal.json")
    io.save_centroids(_table(3), tmp_path / "test.nc")
    assert main(["evaluate", str(tmp_path / "cal.json"), str(tmp_path / "test.nc"), "--out",
                 str(tmp_path / "ev")]) == 0
    written = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    table = stats.evaluate(calibration.load(tmp_path / "cal.json"),
                           io.open_centroids(tmp_path / "test.nc"))[cal.label]
    for a in ("alpha", "beta"):
        for s in ("mu", "sigma", "M", "sigma_M"):
            assert written[f"{a}.{s}"] == float(table[(a, s)])  # bit for bit


def test_evaluate_writes_the_files_of_write_report(tmp_path, capsys):
    # the command only calls the library: its folder and write_report's hold the same files,
    # byte for byte (the JSON, the CSV and both figures, drawn once from the errors)
    from sunlab import report
    from sunlab.cli import main

    cal_path = calibration.fit(_table(1, n=6), "polynomial", order=3).save(tmp_path / "c.json")
    test_path = tmp_path / "test.nc"
    io.save_centroids(_table(3, n=6), test_path)
    assert main(["evaluate", str(cal_path), str(test_path), "--out", str(tmp_path / "cli"),
                 "--paper"]) == 0
    got = report.write_report(tmp_path / "lib", calibration.load(cal_path),
                              io.open_centroids(test_path), paper=True,
                              sources={"calibration": str(cal_path), "test": str(test_path)})
    assert [p.name for p in got["files"]] == list(report.REPORT_FILES) and got["notes"] == []
    assert sorted(p.name for p in (tmp_path / "cli").iterdir()) == sorted(report.REPORT_FILES)
    for name in report.REPORT_FILES:
        assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "lib" / name).read_bytes()
    assert got["evaluation"]["paper"]["column"] == "polynomial"
    assert "wrote" in capsys.readouterr().out


@pytest.fixture
def lab_plugin(tmp_path, monkeypatch):
    """A lab's calibration, registered in the entry point group sunlab.calibrations by a real
    distribution on sys.path (as the multi-hole strategies are by sunlab's own)."""
    import sys
    import textwrap

    (tmp_path / "labcal.py").write_text(textwrap.dedent("""
        from sunlab.calibration import Polynomial

        class LabPoly(Polynomial):
            kind = "lab-poly"
        """))
    (tmp_path / "labcal_broken.py").write_text("raise RuntimeError('licence server down')\n")
    info = tmp_path / "labcal-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labcal\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.calibrations]\nlab-poly = labcal:LabPoly\nlab-broken = labcal_broken:X\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    yield tmp_path
    for name in ("labcal", "labcal_broken"):
        sys.modules.pop(name, None)


def test_a_plugin_calibration_is_fitted_saved_and_loaded_by_the_registry(lab_plugin, train):
    assert calibration.registry.available_kinds()["lab-poly"] == "labcal:LabPoly"
    cal = calibration.fit(train, "lab-poly", order=2)
    assert type(cal).__name__ == "LabPoly" and cal.kind == "lab-poly"
    back = calibration.load(cal.save(lab_plugin / "lab.json"))
    assert type(back) is type(cal)
    x, y = train.x.values, train.y.values
    for got, want in zip(back.predict_xy(x, y), cal.predict_xy(x, y), strict=True):
        assert np.array_equal(got, want, equal_nan=True)
    with pytest.raises(ConfigurationError, match=r"lab-broken.*RuntimeError: licence server"):
        calibration.registry.method_class("lab-broken")


LAB_PLUGINS = """
import os
from sunlab.calibration import Calibration, Polynomial

class Half(Calibration):  # no _fit, no map: what the registry needs is missing
    kind = "lab-half"

    def _parameters(self):
        return {}

class Flaky(Polynomial):  # fails where LABCAL_FAIL says, as a lab's code can
    kind = "lab-flaky"

    def _fit(self, data, val):
        if os.environ.get("LABCAL_FAIL") == "fit":
            raise ZeroDivisionError("no light in the lab's model")
        return super()._fit(data, val)

    def _predict_xy(self, x, y):
        if os.environ.get("LABCAL_FAIL") == "predict":
            raise KeyError("lookup table")
        return super()._predict_xy(x, y)
"""


FIT = ("import sys\nfrom sunlab import calibration, io\nfrom sunlab.errors import SunlabError\n"
       "kw = {'order': 2} if sys.argv[2] == 'lab-flaky' else {}\ntry:\n    calibration.fit("
       "io.open_centroids(sys.argv[1]), sys.argv[2], **kw).save(sys.argv[3])\n"
       "except SunlabError as err:\n    sys.exit(f'{err}')\n")


@pytest.mark.parametrize("method, fail, message", [
    ("lab-half", "", r"calibration plug-in 'lab-half' \(labcal2:Half\): Half lacks "
     r"\['_fit or _fit_tables', '_predict_xy or predict_xy', '_from_parameters'\]"),
    ("lab-flaky", "fit", r"calibration plug-in labcal2:Flaky: _fit raised "
     r"\(ZeroDivisionError: no light in the lab's model\)"),
    ("lab-flaky", "predict", r"calibration plug-in labcal2:Flaky: _predict_xy raised "
     r"\(KeyError: 'lookup table'\)"),
])
def test_a_plugin_that_lacks_the_interface_or_raises_is_named_in_one_line(train, tmp_path,
                                                                           method, fail,
                                                                           message):
    # a real distribution on the path of real processes: the library fits (sunlab calibrate
    # offers the built-in kinds only), `python -m sunlab evaluate` predicts
    import os
    import re
    import subprocess
    import sys

    (tmp_path / "labcal2.py").write_text(LAB_PLUGINS)
    info = tmp_path / "labcal2-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: labcal2\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[sunlab.calibrations]\nlab-half = labcal2:Half\nlab-flaky = labcal2:Flaky\n")
    from sunlab import io

    io.save_centroids(train, tmp_path / "I.nc")
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), *sys.path])}

    def python(*args, fail=""):
        return subprocess.run([sys.executable, *map(str, args)], text=True, timeout=300,
                              capture_output=True, env={**env, "LABCAL_FAIL": fail})

    cal = tmp_path / "cal.json"
    run = python("-c", FIT, tmp_path / "I.nc", method, cal, fail=fail if fail == "fit" else "")
    if fail == "predict":  # fitted and saved while the lab's code works, then it fails
        assert run.returncode == 0, run.stderr
        run = python("-m", "sunlab", "evaluate", cal, tmp_path / "I.nc", fail=fail)
    else:
        assert not cal.exists()
    err = run.stderr.strip()
    assert run.returncode == 1 and len(err.splitlines()) == 1, err
    assert re.search(message, err) and "Fix:" in err, err


# -- the paper's Table 4 recipes (table4_methods) on tables with known truth -------------------
# The tables come from the exact pinhole model of a sensor whose mask sits 0.05 mm off its
# nominal F = 5 mm and is mounted at (0.5, -0.3) deg: the ideal model (1) cannot know either,
# the optimised model (3)-(4) is exactly this sensor.
SENSOR = {"delta_f_mm": 0.05, "mounting_deg": (0.5, -0.3, 0.0)}


def _grid(step, lo=-6.0, hi=6.01):
    a, b = np.meshgrid(np.arange(lo, hi, step), np.arange(lo, hi, step), indexing="ij")
    return sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, **SENSOR)


@pytest.fixture(scope="module")
def tables():
    # experiment I on a 1-deg grid, II on the 1.5-deg grid between, a test grid off both
    return _grid(1.0), _grid(1.5, -5.25, 5.3), _grid(1.0, -5.5, 5.6)


def _mean_error(cal, test):
    return float(stats.evaluate(cal, test).xs("mu", level="stat").mean().iloc[0])


def test_labels_are_table4s_in_its_order():
    assert list(table4_methods(neural=False)) == [
        "ideal model (1)", "optimised model (3)-(4)", "linear interp.", "cubic interp.",
        "polynomial", "trigonometric"]
    # the networks are added as recipes only: nothing is fitted (nor torch imported) here
    assert list(table4_methods())[6:] == [f"NN strategy {s}" for s in (1, 2, 3, 4)]


def test_optimised_model_recovers_the_sensor_the_ideal_model_misses(tables):
    train, val, test = tables
    recipes = table4_methods(neural=False)
    ideal = recipes["ideal model (1)"](train, val)
    optimised = recipes["optimised model (3)-(4)"](train, val)
    # 0.5 deg of mounting is left whole in the ideal model's error; the optimised model is the
    # generating model, so only least-squares rounding remains (far below 1e-9 deg)
    assert _mean_error(ideal, test) > 0.3
    assert _mean_error(optimised, test) < 1e-9
    p = optimised.to_dict()["parameters"]
    assert p["delta_f_mm"] == pytest.approx(0.05, abs=1e-9)
    assert (p["alpha0"], p["beta0"]) == pytest.approx((0.5, -0.3), abs=1e-9)


def test_polynomial_order_is_chosen_on_validation_and_refitted(tables):
    train, val, test = tables
    cal = table4_methods(neural=False)["polynomial"](train, val)
    assert POLYNOMIAL_REFIT
    # the arctan map is smooth: the chosen order is high and its error far below 0.01 deg
    assert cal.kind == "polynomial" and min(cal.orders) >= 5
    assert _mean_error(cal, test) < 1e-6
    # refitted on I and II together (169 + 64 poses)
    assert cal.to_dict()["training"]["n_poses"] == train.sizes["pose"] + val.sizes["pose"]


def test_trigonometric_series_of_period_two_is_much_worse(tables):
    # one period across [-1, 1] forces the series to wrap from the domain's one edge to the other:
    # the near-linear map then costs tenths of a degree, the paper's "much worse"
    train, val, test = tables
    assert TRIGONOMETRIC_PERIOD == 2.0
    cal = table4_methods(neural=False)["trigonometric"](train, val)
    assert cal.period == TRIGONOMETRIC_PERIOD and 1 <= cal.order <= 4
    assert _mean_error(cal, test) > 0.05


def test_trigonometric_needs_poses_for_its_lowest_order():
    few = sim.synthetic_centroids([0.0, 1.0, 0.0, 1.0], [0.0, 0.0, 1.0, 1.0], shots=1)
    with pytest.raises(ConfigurationError, match="4 poses support no order"):
        table4_methods(neural=False)["trigonometric"](few, few)
