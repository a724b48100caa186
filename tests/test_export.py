"""On-board export (sunlab.export): the generated C reproduces Python's predict; domain flags.

The C is compiled with the system compiler (cc/gcc/clang) and evaluated at 1,000 points drawn
in the training box widened by 10 % (so that some lie outside the domain). Tolerances: double
precision within 1e-9 deg (the same arithmetic up to the order of operations: ~1e-14 deg is
seen); single precision within 1e-5 deg (float32 keeps 24 bits: the rounding of a 20-degree
result alone is 1e-6 deg, and a few roundings of intermediate values add up to a few 1e-6 deg).
"""

import json

import numpy as np
import pytest

from sunlab import ConfigurationError, export, sim
from sunlab.calibration import (
    IdealModel,
    Interpolation,
    NeuralNet,
    OptimisedModel,
    Polynomial,
    Trigonometric,
    load,
)

CC = export.find_c_compiler()
needs_cc = pytest.mark.skipif(CC is None, reason="no C compiler (cc, gcc, clang) on the PATH")
BENCH = dict(delta_f_mm=0.094, mounting_deg=(1.864, 0.415, 0.0))
TOL_DOUBLE, TOL_FLOAT = 1e-9, 1e-5


def _table(step=3.0, seed=1, lo=(-17.0, -2.0), hi=(2.0, 17.0)):
    a, b = np.meshgrid(np.arange(lo[0], hi[0] + 1e-9, step), np.arange(lo[1], hi[1] + 1e-9, step),
                       indexing="ij")
    return sim.synthetic_centroids(a.ravel(), b.ravel(), 2, seed=seed, **BENCH)


@pytest.fixture(scope="module")
def train():
    return _table()


def _fits(train):
    return {
        "polynomial": lambda: Polynomial(order=5).fit(train),
        "polynomial-mixed": lambda: Polynomial(order=(3, 4)).fit(train),
        "linear": lambda: Interpolation("linear").fit(train),
        "linear-nearest": lambda: Interpolation("linear", extrapolate="nearest").fit(train),
        "neural-4": lambda: NeuralNet(strategy=4, hidden=5, max_iter=60).fit(train),
        "neural-1": lambda: NeuralNet(strategy=1, hidden=4, max_iter=60).fit(train),
        "neural-3": lambda: NeuralNet(strategy=3, hidden=4, max_iter=60).fit(train),
        "ideal": lambda: IdealModel().fit(train),
        "optimised": lambda: OptimisedModel().fit(train),
    }


@needs_cc
@pytest.mark.parametrize("name", ["polynomial", "polynomial-mixed", "linear", "linear-nearest",
                                  "neural-4", "neural-1", "neural-3", "ideal", "optimised"])
def test_c_reproduces_predict(train, name, tmp_path):
    cal = _fits(train)[name]()
    export.export(cal, tmp_path)
    report = export.check_c(cal, tmp_path, n=1000)
    assert report["n_outside"] > 50  # the widened box reaches outside the domain
    assert report["max_error_double"] < TOL_DOUBLE, report
    assert report["max_error_float"] < TOL_FLOAT, report
    assert report["flags_agree"] and report["nan_agree"], report


@needs_cc
def test_c_flags_and_extrapolation(train, tmp_path):
    far_x, far_y = 1e4, 1e4  # far outside every domain
    poly = Polynomial(order=3).fit(train)
    export.export(poly, tmp_path / "p")
    got = export.run_c(tmp_path / "p", [np.mean(poly.domain["x"]), far_x, np.nan],
                       [np.mean(poly.domain["y"]), far_y, 0.0])
    assert got["flag"].tolist() == [export.FLAGS["ok"], export.FLAGS["outside"],
                                    export.FLAGS["bad_input"]]
    assert got["flag_f"].tolist() == got["flag"].tolist()
    assert np.isfinite(got["alpha"][1])  # a polynomial extrapolates: angles still set
    assert np.isnan(got["alpha"][2]) and np.isnan(got["beta_f"][2])
    lin = Interpolation("linear").fit(train)
    export.export(lin, tmp_path / "l")
    got = export.run_c(tmp_path / "l", [far_x], [far_y])
    assert got["flag"].tolist() == [export.FLAGS["undefined"]]  # no extrapolation: NaN
    assert np.isnan(got["alpha"][0]) and np.isnan(got["beta"][0])


def test_header_declares_the_interface(train, tmp_path):
    h, c = export.export(Polynomial(order=2).fit(train), tmp_path)
    header, source = h.read_text(), c.read_text()
    assert ("int sunlab_calibration_eval(double x_px, double y_px, double *alpha_deg, "
            "double *beta_deg);") in header
    assert ("int sunlab_calibration_evalf(float x_px, float y_px, float *alpha_deg, "
            "float *beta_deg);") in header
    includes = [line for line in source.splitlines() if line.startswith("#include")]
    assert includes == ["#include <math.h>", '#include "sunlab_calibration.h"']
    for word in ("malloc", "calloc", "static double *", "pow("):
        assert word not in source
    # the float variant has its own single-precision tables
    assert "static const float coef_alpha_f[9]" in source


def test_polynomial_coefficients_are_exported_exactly(train, tmp_path):
    cal = Polynomial(order=2).fit(train)
    _, c = export.export(cal, tmp_path)
    text = c.read_text()
    for value in cal.coefficients["alpha"]:
        assert repr(float(value)) in text


def test_refuses_what_it_cannot_reproduce(train, tmp_path):
    with pytest.raises(ConfigurationError, match="cubic interpolation is not exported"):
        export.export(Interpolation("cubic").fit(train), tmp_path)
    with pytest.raises(ConfigurationError, match="trigonometric"):
        export.export(Trigonometric(order=1).fit(train), tmp_path)
    assert not list(tmp_path.iterdir())  # nothing half-written


def test_json_export_round_trips(train, tmp_path):
    cal = Polynomial(order=3).fit(train)
    (path,) = export.export(cal, tmp_path, format="json")
    back = load(path)
    x, y = train.x.values, train.y.values
    np.testing.assert_array_equal(back.predict_xy(x, y)[0], cal.predict_xy(x, y)[0])
    assert json.loads(path.read_text())["sunlab_schema"] == "calibration/1"
    with pytest.raises(FileExistsError):
        export.export(cal, tmp_path, format="json")


def test_prediction_far_outside_the_domain_is_flagged():
    # a +-10 deg calibration asked about a spot of ~38 deg (the example)
    cal = Polynomial(order=3).fit(_table(step=2.0, lo=(-10.0, -10.0), hi=(10.0, 10.0)))
    far = sim.synthetic_centroids([38.0, 0.0], [0.0, 0.0], 1, **BENCH)
    est = cal.predict(far)
    assert est["in_domain"].values[:, 0].tolist() == [False, True]
    assert est.attrs["n_out_of_domain"] == 1
    assert np.isfinite(est.alpha.values).all()  # a polynomial extrapolates, flagged
    lin = Interpolation("linear").fit(_table(step=2.0, lo=(-10.0, -10.0), hi=(10.0, 10.0)))
    est = lin.predict(far)
    assert est["in_domain"].values[:, 0].tolist() == [False, True]
    assert np.isnan(est.alpha.values[0, 0])  # interpolation cannot extrapolate: NaN


def test_fit_refuses_too_few_distinct_poses():
    # 6 poses, 2 distinct positions: an order-2 polynomial (6 coefficients) would "fit"
    cen = sim.synthetic_centroids([0.0, 0, 0, 1, 1, 1], [0.0] * 6)
    with pytest.raises(ConfigurationError, match=r"2 distinct poses.*needs at least 6"):
        Polynomial(order=2).fit(cen)
    with pytest.raises(ConfigurationError, match="distinct poses"):
        NeuralNet(hidden=8).fit(_table(step=6.0))  # 16 poses < 33 weights


@needs_cc
def test_check_hands_no_folder_of_the_users_to_the_compiler(train, tmp_path, monkeypatch,
                                                            capsys):
    """``export --check`` into a folder named like an option (``-otrap``: ``-o`` with the
    output ``trap/...``): the compiler never sees it, and the lab's ``trap/`` file stays."""
    from sunlab import cli

    monkeypatch.chdir(tmp_path)
    Polynomial(order=2).fit(train).save(tmp_path / "cal.json")
    (tmp_path / "trap").mkdir()
    (tmp_path / "trap" / "sunlab_calibration.c").write_text("the lab's file")
    status = cli.main(["export", "cal.json", "--out=-otrap", "--check"])
    out, err = capsys.readouterr()
    assert status == 0 and "domain flags agree: True" in out, err
    assert (tmp_path / "trap" / "sunlab_calibration.c").read_text() == "the lab's file"
    assert sorted(p.name for p in (tmp_path / "-otrap").iterdir()) == [
        "sunlab_calibration.c", "sunlab_calibration.h"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["-otrap", "cal.json", "trap"]


def test_a_coefficient_beyond_single_precision_is_refused_naming_it(train, tmp_path, capsys):
    # 1e39 is a double (up to 1.8e308) but no float (up to 3.4e38): the float tables of the C
    # source would hold an infinity that does not compile
    cal = Polynomial(order=2).fit(train)
    cal.coefficients["alpha"][-1] = 1e39
    path = cal.save(tmp_path / "cal.json")
    from sunlab import cli

    status = cli.main(["export", str(path), "--out", str(tmp_path / "onboard")])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1 and "1e+39" in err and "float" in err
    assert not (tmp_path / "onboard").exists()
