"""`sunlab simulate`: the virtual bench from the command line."""

import numpy as np
import pytest

from sunlab import io
from sunlab.cli import main


def test_simulate_writes_a_cube_with_truth(tmp_path, capsys):
    out = tmp_path / "exp3.zarr"
    rc = main(
        [
            "simulate",
            "--experiment",
            "III",
            "--mask",
            "single",
            "--subset",
            "10",
            "--shots",
            "2",
            "--seed",
            "3",
            "--out",
            str(out),
            "--no-progress",
        ]
    )
    assert rc == 0
    assert "experiment III, 4 poses x 2 shots" in capsys.readouterr().out
    with io.open_frames(out) as cube:
        assert dict(cube.frames.sizes) == {"pose": 4, "shot": 2, "y": 1024, "x": 1280}
        assert cube.attrs["experiment"] == "III"
        assert np.all(np.isfinite(cube.true_x.values))
        assert int(cube.frames[0, 0].max()) > 300


def test_simulate_bad_experiment_is_a_clean_error(tmp_path, capsys):
    # a bad choice is a bad argument: argparse names the option and the choices, exit 2
    with pytest.raises(SystemExit) as info:
        main(["simulate", "--experiment", "V", "--out", str(tmp_path / "x.zarr")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "--experiment" in err and "'I', 'II', 'III'" in err
    assert not (tmp_path / "x.zarr").exists()


def test_centroid_of_a_multi_hole_cube_picks_tight_and_refuses_projection(tmp_path, capsys):
    # the default method follows the cube (tight for 100 spots per frame); a single-spot
    # method asked for by name is refused with the fix, never swapped for another silently
    cube = tmp_path / "multi.zarr"
    assert main(["simulate", "--experiment", "III", "--mask", "multi", "--subset", "12",
                 "--shots", "1", "--seed", "1", "--out", str(cube), "--no-progress"]) == 0
    out = tmp_path / "cen.nc"
    assert main(["centroid", str(cube), "--out", str(out), "--no-progress"]) == 0
    assert "by method 'tight'" in capsys.readouterr().out
    with io.open_centroids(out) as cen:
        assert cen.sizes["hole"] == 100
        ok = cen.status.values == 0
        assert ok.mean() > 0.5
        err = np.hypot(cen.x.values - cen.true_x.values, cen.y.values - cen.true_y.values)[ok]
        assert np.nanmedian(err) < 1.0  # px: systematic pixel-response errors, not indexing
    rc = main(["centroid", str(cube), "--out", str(tmp_path / "p.nc"), "--method",
               "projection", "--no-progress"])
    assert rc != 0
    err = capsys.readouterr().err
    assert "projection" in err and "'tight'" in err
    assert not (tmp_path / "p.nc").exists()
