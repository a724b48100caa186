"""A lab's own bench on the command line: import, centroid, calibrate, evaluate, export, info.

The end-to-end test builds a folder that sunlab did not make: frames rendered here with plain
NumPy (a uniform disk spot at the ideal pinhole position, eq. (1), 4x supersampled, bias and
Gaussian read noise) and written as 16-bit PNG with Pillow, with a hand-written manifest.csv.
"""

import json
import subprocess
import sys

import numpy as np
import pandas as pd
import pytest
from PIL import Image

from sunlab import SchemaError, export, geometry, io, sim
from sunlab.calibration import Interpolation, load
from sunlab.calibration.summary import calibration_summary
from sunlab.cli import main

F_MM, PITCH_MM = 5.0, 0.007  # 1 deg ~ 12.5 px
N_PX, RADIUS_PX, SUB = 144, 8.0, 4
BIAS_DN, PEAK_DN, NOISE_DN = 32.0, 700.0, 2.0


def _render(alpha, beta, rng):
    """One 16-bit frame: a disk of RADIUS_PX at the ideal-model centroid of (alpha, beta)."""
    c = (N_PX - 1) / 2
    xc, yc = geometry.ideal_centroid(alpha, beta, F_MM, PITCH_MM, c, c)
    sub = (np.arange(N_PX * SUB) + 0.5) / SUB - 0.5  # sub-pixel centres, px
    inside = ((sub[None, :] - xc) ** 2 + (sub[:, None] - yc) ** 2) <= RADIUS_PX**2
    frac = inside.reshape(N_PX, SUB, N_PX, SUB).mean(axis=(1, 3))
    dn = BIAS_DN + PEAK_DN * frac + rng.normal(0.0, NOISE_DN, frac.shape)
    return np.clip(np.rint(dn), 0, 1023).astype(np.uint16)


def _write_folder(folder, alphas, betas, shots, seed):
    folder.mkdir()
    rng = np.random.default_rng(seed)
    rows = ["file,alpha,beta,shot"]
    for a in alphas:
        for b in betas:
            for s in range(shots):
                name = f"img_a{a:+.1f}_b{b:+.1f}_{s}.png"
                Image.fromarray(_render(a, b, rng)).save(folder / name)
                rows.append(f"{name},{a},{b},{s}")
    (folder / "manifest.csv").write_text("\n".join(rows) + "\n")
    return folder


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """The pipeline run once on a foreign folder: paths of everything it wrote."""
    root = tmp_path_factory.mktemp("lab")
    grid = np.arange(-4.0, 4.1, 2.0)
    train = _write_folder(root / "train_frames", grid, grid, 2, seed=1)
    test = _write_folder(root / "test_frames", grid[:-1] + 1, grid[:-1] + 1, 2, seed=2)
    p = {k: root / v for k, v in [("cube", "train.zarr"), ("train", "train.nc"),
                                  ("test", "test.nc"), ("cal", "poly.json"), ("ev", "ev"),
                                  ("c", "onboard")]}
    steps = [
        ["import", str(train), "--out", str(p["cube"]), "--mask-distance-mm", str(F_MM),
         "--no-progress"],
        ["centroid", str(p["cube"]), "--out", str(p["train"]), "--no-progress"],
        ["centroid", str(test), "--out", str(p["test"]), "--mask-distance-mm", str(F_MM),
         "--no-progress"],  # a folder straight to a centroid table
        ["calibrate", str(p["train"]), "--method", "polynomial", "--order", "3", "--out",
         str(p["cal"])],
        ["evaluate", str(p["cal"]), str(p["test"]), "--out", str(p["ev"]), "--paper"],
        ["export", str(p["cal"]), "--format", "c", "--out", str(p["c"])],
    ]
    p["status"] = [main(argv) for argv in steps]
    return p


def test_every_step_succeeds(lab):
    assert lab["status"] == [0] * 6


def test_import_reads_the_foreign_folder(lab):
    cube = io.open_frames(lab["cube"])
    assert dict(cube.sizes) == {"pose": 25, "shot": 2, "y": N_PX, "x": N_PX}
    assert cube.frames.dtype == np.uint16
    assert cube.attrs["bit_depth"] == 10  # from the images: max DN < 1024
    assert cube.attrs["mask_distance_mm"] == F_MM
    assert "pixel_pitch_mm" not in cube.attrs  # not said, so not guessed


def test_evaluation_holds_the_papers_statistics(lab):
    doc = json.loads((lab["ev"] / "evaluation.json").read_text())
    keys = [f"{a}.{s}" for a in ("alpha", "beta") for s in ("mu", "sigma", "M", "sigma_M")]
    assert all(isinstance(doc[k], float) for k in keys)
    # Known truth: an order-3 polynomial of the ideal model over +-4 deg leaves < 1e-3 deg of
    # model error, and the centroid noise (~0.02 px, 0.0016 deg) dominates: mu well under 0.01
    assert doc["alpha.mu"] < 0.01 and doc["beta.mu"] < 0.01
    assert doc["alpha.M"] >= doc["alpha.mu"] and doc["beta.M"] >= doc["beta.mu"]
    assert doc["n_poses"] == 16 and doc["n_out_of_domain"] == 0
    assert doc["paper"]["column"] == "polynomial"
    errors = pd.read_csv(lab["ev"] / "errors.csv")
    assert len(errors) == 16 and errors["in_domain"].all()
    np.testing.assert_allclose(errors["alpha_local_error"].mean(), doc["alpha.mu"], rtol=1e-6)
    for png in ("fig10_error_maps.png", "fig11_histograms.png"):
        assert (lab["ev"] / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.skipif(export.find_c_compiler() is None, reason="no C compiler on the PATH")
def test_exported_c_reproduces_predict(lab):
    cal = load(lab["cal"])
    report = export.check_c(cal, lab["c"], n=1000)
    assert report["max_error_double"] < 1e-9  # same arithmetic up to the order of operations
    assert report["max_error_float"] < 1e-5  # float32 rounding of ~5-degree results
    assert report["flags_agree"]


def _to_csv(table_path, csv_path):
    cen = io.open_centroids(table_path)
    df = pd.DataFrame({
        "alpha": np.repeat(cen.alpha.values, cen.sizes["shot"]),
        "beta": np.repeat(cen.beta.values, cen.sizes["shot"]),
        "x": cen.x.values.ravel(), "y": cen.y.values.ravel(),
        "shot": np.tile(np.arange(cen.sizes["shot"]), cen.sizes["pose"]),
    })
    df.to_csv(csv_path, index=False, float_format="%.17g")
    return csv_path


def test_evaluate_and_calibrate_read_csv_tables(lab, tmp_path):
    test_csv = _to_csv(lab["test"], tmp_path / "test.csv")
    assert main(["evaluate", str(lab["cal"]), str(test_csv), "--out", str(tmp_path / "ev")]) == 0
    nc = json.loads((lab["ev"] / "evaluation.json").read_text())
    csv = json.loads((tmp_path / "ev" / "evaluation.json").read_text())
    for key in ("alpha.mu", "alpha.sigma", "alpha.M", "alpha.sigma_M", "beta.mu", "beta.M"):
        assert csv[key] == pytest.approx(nc[key], rel=1e-12)
    train_csv = _to_csv(lab["train"], tmp_path / "train.csv")
    out = tmp_path / "poly_csv.json"
    assert main(["calibrate", str(train_csv), "--order", "3", "--out", str(out)]) == 0
    np.testing.assert_allclose(load(out).coefficients["alpha"], load(lab["cal"]).coefficients[
        "alpha"], rtol=1e-9, atol=1e-12)


def test_csv_reader_pads_and_explains(tmp_path):
    path = tmp_path / "c.csv"
    path.write_text("alpha,beta,x,y\n0,0,1,2\n0,0,1.5,2\n1,0,,\n# comment\n2,1,3,4\n")
    cen = io.open_centroids(path)
    assert dict(cen.sizes) == {"pose": 3, "shot": 2}
    assert cen.status.values.tolist() == [[0, 0], [1, 1], [0, 1]]  # no spot, padding
    path.write_text("alpha,beta,col,row\n0,0,1,2\n")
    with pytest.raises(SchemaError, match=r"columns \['x', 'y'\].*missing"):
        io.open_centroids(path)


def test_info_describes_a_calibration_without_heavy_imports(lab):
    code = ("import sys; from sunlab.cli import main; rc = main(['info', sys.argv[1]]); "
            "heavy = [m for m in ('numpy', 'xarray', 'jsonschema', 'torch', 'pandas') "
            "if m in sys.modules]; print('HEAVY', heavy); sys.exit(rc)")
    run = subprocess.run([sys.executable, "-c", code, str(lab["cal"])], capture_output=True,
                         text=True, timeout=60, check=True)
    assert "polynomial(3) (kind 'polynomial'), order 3" in run.stdout
    assert "domain: alpha [-4, 4] deg" in run.stdout
    assert "training residuals (deg)" in run.stdout
    assert "HEAVY []" in run.stdout


def test_cli_import_is_light():
    code = ("import sys, sunlab.cli; sunlab.cli.build_parser(); print(sorted(m for m in "
            "('numpy', 'xarray', 'jsonschema', 'torch', 'pandas', 'dask') if m in sys.modules))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=60, check=True)
    assert run.stdout.strip() == "[]"


def test_info_reports_leave_one_out_for_interpolation(tmp_path):
    a, b = np.meshgrid(np.arange(-6.0, -1.0), np.arange(0.0, 5.0), indexing="ij")
    cal = Interpolation("linear").fit(sim.synthetic_centroids(a.ravel(), b.ravel(), 1,
                                                                   seed=3))
    text = calibration_summary(cal.to_dict())
    assert "leave-one-out errors (deg): alpha mean|e|" in text
    assert "training residuals (deg)" not in text
    assert cal.residuals["leave_one_out"]["alpha"]["mean_abs"] > 0  # not the zero residuals


def test_info_on_other_json_says_what_it_is(tmp_path, capsys):
    path = tmp_path / "other.json"
    path.write_text('{"hello": 1}')
    assert main(["info", str(path)]) == 1
    assert "not written by sunlab" in capsys.readouterr().err


def test_calibrate_refuses_options_of_other_methods(lab, tmp_path, capsys):
    out = str(tmp_path / "x.json")
    assert main(["calibrate", str(lab["train"]), "--method", "linear", "--order", "3",
                 "--out", out]) == 1
    err = capsys.readouterr().err
    assert "--order: does not apply to --method linear" in err
    assert main(["calibrate", str(lab["train"]), "--hidden", "4", "--out", out]) == 1
    assert "--hidden: does not apply to --method polynomial" in capsys.readouterr().err


def test_import_asks_for_no_geometry_and_the_geometric_models_name_sensor_json(
    lab, tmp_path, capsys
):
    folder = tmp_path / "frames"
    folder.mkdir()
    src = lab["cube"].parent / "train_frames"
    # header + one shot of two poses apart on both axes: the spot moves (a table whose spot
    # never moves is refused before the model is asked for its geometry)
    rows = (src / "manifest.csv").read_text().splitlines()
    first = rows[1].split(",")
    lines = [rows[0], rows[1], next(r for r in rows[2:] if all(
        u != v for u, v in zip(r.split(",")[1:3], first[1:3], strict=True)))]
    for line in lines[1:]:
        name = line.split(",")[0]
        (folder / name).write_bytes((src / name).read_bytes())
    (folder / "manifest.csv").write_text("\n".join(lines) + "\n")
    out = str(tmp_path / "c.zarr")
    assert main(["import", str(folder), "--out", out, "--no-progress"]) == 0
    assert "F = not given mm, pitch not given mm" in capsys.readouterr().out
    table = str(tmp_path / "c.nc")
    assert main(["centroid", out, "--out", table, "--no-progress"]) == 0
    cal = str(tmp_path / "ideal.json")
    assert main(["calibrate", table, "--method", "ideal", "--out", cal]) == 1
    assert "sensor.json" in capsys.readouterr().err
    (folder / "sensor.json").write_text(json.dumps({"mask_distance_mm": 5.0, "bit_depth": 12}))
    assert main(["import", str(folder), "--out", out, "--no-progress", "--overwrite"]) == 0
    cube = io.open_frames(out)
    assert cube.attrs["mask_distance_mm"] == 5.0 and cube.attrs["bit_depth"] == 12


def test_simulate_lists_experiments_and_subset_thins_the_grid(tmp_path, capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--experiment", "IV", "--out", str(tmp_path / "x.zarr")])
    assert "choose from 'I', 'II', 'III'" in capsys.readouterr().err
    out = tmp_path / "q.zarr"
    assert main(["simulate", "--experiment", "I", "--subset", "10", "--shots", "1",
                 "--noise-free", "--no-progress", "--out", str(out)]) == 0
    cube = io.open_frames(out)
    assert (np.unique(cube.alpha).size, np.unique(cube.beta).size, cube.sizes["pose"]) == (2, 2, 4)


def test_example_recording_is_a_lab_folder():
    folder = io.example_folder("train")
    manifest = pd.read_csv(folder / "manifest.csv")
    assert list(manifest.columns) == ["file", "alpha", "beta", "shot"]
    assert len(manifest) == 50  # 5 x 5 poses x 2 shots
    size = sum(p.stat().st_size for p in folder.parent.rglob("*") if p.is_file())
    assert size <= 5 * 2**20
    with Image.open(folder / manifest.file[0]) as im:
        assert im.mode in ("I;16", "I;16L", "I;16B")


def test_csv_table_takes_sensor_json_beside_it(tmp_path, capsys):
    a, b = np.meshgrid([-2.0, 0.0, 2.0], [-2.0, 0.0, 2.0], indexing="ij")
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), 1)  # F 5 mm, centre 639.5, 511.5
    csv = tmp_path / "train.csv"
    pd.DataFrame({"alpha": cen.alpha.values, "beta": cen.beta.values,
                  "x": cen.x.values[:, 0], "y": cen.y.values[:, 0]}).to_csv(csv, index=False)
    out = tmp_path / "ideal.json"
    assert main(["calibrate", str(csv), "--method", "ideal", "--out", str(out)]) == 1
    assert "mask_distance_mm" in capsys.readouterr().err
    (tmp_path / "sensor.json").write_text(json.dumps(
        {"mask_distance_mm": 5.0, "pixel_pitch_mm": 0.007, "x_cf_px": 639.5, "y_cf_px": 511.5}))
    assert main(["calibrate", str(csv), "--method", "ideal", "--out", str(out)]) == 0
    # noise-free ideal-model centroids: the ideal model recovers the angles exactly
    assert load(out).residuals["alpha"]["max_abs"] < 1e-9
