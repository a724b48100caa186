"""Tests of sunlab.reproduce.learned: the benches, their seeds, the records, the files, a
saved model applied to a cube written by ``sunlab simulate``, a stopped run resumed, and the
shipped docs/learned written by the command it names.

One tiny run (good-platform bench, every 4th angle, one shot, one epoch) serves every test of
the files; the accuracy of a real run is ``sunlab reproduce --table learned``'s to measure.
"""

import json
import shlex
from pathlib import Path

import numpy as np
import pytest

from sunlab import calibration, io, sim, stats
from sunlab.cli import build_parser, main
from sunlab.errors import ConfigurationError
from sunlab.reproduce import learned
from sunlab.reproduce.learned import (
    BENCHES,
    DEFAULT_BENCHES,
    bench,
    bench_seeds,
    learned_figure,
    records_of,
    records_table,
    reproduce_learned,
    run_settings,
)

SHIPPED = Path(__file__).resolve().parents[2] / "docs" / "learned"

pytest.importorskip("torch")


@pytest.fixture(scope="module")
def run(tmp_path_factory):
    out = tmp_path_factory.mktemp("learned")
    res = reproduce_learned(benches=["good-platform"], step=4, shots=1, epochs=1, out=out,
                            progress=False)
    return res, out


def test_every_bench_builds_and_the_stress_is_what_its_name_says():
    one = sim.Bench.paper_single_hole()
    assert bench("paper") == one
    good = bench("good-platform")
    assert good.platform.alpha_pose_error_deg == 0 and good.mask.play_x_mm == 0
    assert bench("hot-pixels").detector.hot_pixel_fraction == 50 * one.detector.hot_pixel_fraction
    assert bench("dust").mask.holes[0].defect_flags != 0
    assert bench("100-holes").n_holes == 100
    edge = [h.y_mm for h in bench("100-holes-edge").mask.holes]
    preset = [h.y_mm for h in sim.Bench.paper_multi_hole().mask.holes]
    np.testing.assert_allclose(np.subtract(edge, preset), 1.2)
    with pytest.raises(ConfigurationError, match="bench"):
        bench("perfect")


def test_no_seed_is_shared_between_experiments_or_benches():
    seeds = [s for name in BENCHES for s in bench_seeds(name).values()]
    seeds += [s for name in BENCHES for s in bench_seeds(name, seed=1).values()]
    assert len(seeds) == len(set(seeds))


def test_the_records_hold_every_statistic_of_every_method(run):
    res, out = run
    doc = json.loads((out / "learned.json").read_text())
    recs = records_of(doc)
    assert recs == json.loads(json.dumps(res["records"]))
    assert doc["command"].startswith("sunlab.reproduce.learned.reproduce_learned(")
    assert doc["settings"]["benches"]["good-platform"]["plans"]["I"] == [25, 1]
    assert all(set(r) == {"bench", "method", "angle", "stat", "value"} for r in recs)
    methods = {r["method"] for r in recs}
    assert {"learned", "polynomial", "polynomial (I only)", "disk fit + polynomial",
            "CRLB floor"} <= methods
    mu = records_table(recs, "mu")
    assert np.isfinite(mu.loc[("good-platform", "alpha"), "learned"])
    # the floor is below what any method reaches on the sensor's own bench
    assert (mu.loc["good-platform", "CRLB floor"] < mu.loc["good-platform", "polynomial"]).all()
    train = records_table(recs, "train_s")
    assert train.loc["good-platform", "learned"] > 0


def test_each_model_is_saved_and_loads_through_the_registry(run, tmp_path):
    res, out = run
    cal = calibration.load(out / "models" / "good-platform.json")
    assert cal.kind == "learned-frames"
    # the loaded model reads a cube as `sunlab simulate` writes it
    cube_path = tmp_path / "iii.zarr"
    assert main(["simulate", "--experiment", "III", "--mask", "single", "--seed", "77",
                 "--subset", "6", "--shots", "1", "--ideal-platform", "--out", str(cube_path),
                 "--no-progress"]) == 0
    est = cal.predict_frames(io.open_frames(cube_path))
    table = stats.evaluate(est)
    assert np.isfinite(table.values).all()


def test_the_figure_draws_each_angle(run):
    fig = learned_figure(run[0]["records"])
    assert [ax.get_title().split(":")[0] for ax in fig.axes] == ["alpha", "beta"]
    assert (run[1] / "learned.png").stat().st_size > 10_000


def test_the_command_line_offers_the_table():
    args = build_parser().parse_args(["reproduce", "--table", "learned", "--quick"])
    assert args.table == "learned" and args.quick


def test_the_default_run_is_the_two_benches_at_the_quick_plans_and_full_is_every_bench():
    settings, _, _ = run_settings(out="DIR")
    assert settings["command"] == "sunlab reproduce --table learned --out DIR"
    assert tuple(settings["benches"]) == DEFAULT_BENCHES == ("paper", "good-platform")
    assert settings["benches"]["paper"]["plans"] == {"I": [100, 2], "II": [49, 2], "III": [100, 2]}
    full, _, _ = run_settings(full=True, out="DIR")
    assert full["command"] == "sunlab reproduce --table learned --full --out DIR"
    assert list(full["benches"]) == list(BENCHES)
    assert full["benches"]["paper"]["plans"]["I"][1] == 8
    assert full["benches"]["100-holes"]["plans"]["I"][1] == learned.MULTI_SHOTS
    every, _, _ = run_settings(benches=["all"], out="DIR")
    assert list(every["benches"]) == list(BENCHES)
    assert every["command"] == "sunlab reproduce --table learned --benches all --out DIR"
    with pytest.raises(ConfigurationError, match="quick"):
        run_settings(full=True, quick=True)


def test_a_stopped_run_resumes_after_the_benches_it_finished(tmp_path, monkeypatch):
    real, calls = learned._run_bench, []

    def stopped(name, *args, **kw):
        if name == "prnu-x3":
            raise KeyboardInterrupt  # the user stops the run after its first bench
        calls.append(name)
        return real(name, *args, **kw)

    opts = {"benches": ["paper", "prnu-x3"], "step": 4, "shots": 1, "epochs": 1,
            "out": tmp_path, "progress": False}
    monkeypatch.setattr(learned, "_run_bench", stopped)
    with pytest.raises(KeyboardInterrupt):
        reproduce_learned(**opts)
    assert calls == ["paper"]
    assert (tmp_path / "benches" / "paper.json").exists()
    assert (tmp_path / "models" / "paper.json").exists()
    assert not (tmp_path / "learned.json").exists()
    first = json.loads((tmp_path / "benches" / "paper.json").read_text())

    def counted(name, *args, **kw):
        calls.append(name)
        return real(name, *args, **kw)

    calls.clear()
    monkeypatch.setattr(learned, "_run_bench", counted)
    res = reproduce_learned(**opts)
    assert calls == ["prnu-x3"] and res["reused"] == ["paper"]  # paper is not recomputed
    recs = records_of(json.loads((tmp_path / "learned.json").read_text()))
    assert [r for r in recs if r["bench"] == "paper"] == first["records"]
    assert {r["bench"] for r in recs} == {"paper", "prnu-x3"}
    assert res["models"]["paper"].kind == "learned-frames"
    # other settings for a bench: it is computed again, not read back (the bench's run is
    # reached, and stopped there: what it computes is the run above's)
    calls.clear()

    def reached(name, *args, **kw):
        calls.append(name)
        raise KeyboardInterrupt

    monkeypatch.setattr(learned, "_run_bench", reached)
    with pytest.raises(KeyboardInterrupt):
        reproduce_learned(**{**opts, "benches": ["paper"], "epochs": 2})
    assert calls == ["paper"]


def test_the_shipped_results_name_the_command_that_wrote_them(monkeypatch):
    doc = json.loads((SHIPPED / "learned.json").read_text())
    argv = shlex.split(doc["command"])
    assert argv[:4] == ["sunlab", "reproduce", "--table", "learned"]
    seen = {}

    def fake(**kw):
        seen.update(kw)
        return {"records": doc["records"], "files": []}

    monkeypatch.setattr(learned, "reproduce_learned", fake)
    assert main(argv[1:]) == 0  # the command exists, and reaches reproduce_learned with ...
    settings, _, _ = run_settings(**seen)
    assert settings == doc["settings"]  # ... the settings the file records
    assert {"paper", "good-platform"} <= {r["bench"] for r in doc["records"]}
    for name in doc["settings"]["benches"]:
        assert calibration.load(SHIPPED / "models" / f"{name}.json").kind == "learned-frames"
    assert json.loads((SHIPPED / "learned_settings.json").read_text())["command"] == \
        doc["command"]


def test_a_long_run_prints_its_estimate_and_the_time_left(capsys):
    from sunlab.reproduce import learned_files

    settings, _, _ = run_settings(out="DIR")
    est = {n: learned_files.estimate_s(s) for n, s in settings["benches"].items()}
    assert 60 < sum(est.values()) < 600  # the default run: announced, and within 10 minutes
    bar = learned_files.Progress(est, show=True)
    bar.announce(996)
    bar.stage("paper", "trained (9 epochs)", 0.85)
    bar.finished("paper")
    bar.finished("good-platform", reused=True)
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].startswith("learned: 2 benches, 996 frames") and " min on 2 idle" in lines[0]
    assert all("min left" in line for line in lines[1:]) and len(lines) == 4
    assert "read back from an earlier run" in lines[-1]
    full, _, _ = run_settings(full=True, out="DIR")
    hours = sum(learned_files.estimate_s(s) for s in full["benches"].values()) / 3600
    assert 2 < hours < 5  # the paper-size run: the hours docs/learned/README.md states


@pytest.mark.parametrize("text", ["[" * 100_000 + "]" * 100_000, "[1, 2]"],
                         ids=["deep", "not-a-record"])
def test_a_bench_record_that_is_not_ours_is_computed_again(tmp_path, text):
    """Issue 47 class 7: a resume folder's record nested past the parser's recursion limit (or
    not a record at all) ended the run in a RecursionError (AttributeError); it is recomputed."""
    from sunlab.reproduce import learned_files

    for folder in ("models", "benches"):
        (tmp_path / folder).mkdir()
    (tmp_path / "models" / "paper.json").write_text("{}")
    (tmp_path / "benches" / "paper.json").write_text(text)
    assert learned_files.stored(tmp_path, {"bench": "paper"}) is None
