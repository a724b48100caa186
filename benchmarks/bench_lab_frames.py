"""A lab's frames, as the must-show of the calibration-frames work measures them.

The frames of ``tests/test_lab_frames.py`` (made there with NumPy, Pillow and tifffile, not
``sunlab.sim``): pinhole spots at F = 5 mm, 7 um pixels, a dark-offset ramp up to a quarter of
full scale, vignetting and a flat-field ripple, written as 10-bit right-aligned PNG, 12-bit
left-aligned PNG and 16-bit multi-page TIFF stacks per pose. For each camera, with and without
``--dark --flat``, it runs ``sunlab import -> centroid [--method] -> calibrate --method
polynomial --order 3 -> evaluate`` and prints the usable shots, the RMS distance of the
centroids from the true spot centres after the best affine map, and the evaluation's mu.

    python benchmarks/bench_lab_frames.py [--method projection|tight]
"""

from __future__ import annotations

import argparse
import contextlib
import io as _io
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

import test_lab_frames as lab  # noqa: E402 - the frame maker of the must-show test

from sunlab import io  # noqa: E402
from sunlab.cli import main  # noqa: E402


def _run(root: Path, camera: str, correct: bool, method: str) -> str:
    bits, left, kind = lab.CAMERAS[camera]
    rng = np.random.default_rng(len(camera))
    train, _ = lab._recording(root, "train", lab._grid(lab.TRAIN), bits, left, kind, rng)
    test, test_truth = lab._recording(root, "test", lab._grid(lab.TEST), bits, left, kind, rng)
    cal = lab._calibration_frames(root, bits, left, kind, rng)
    extra = ["--dark", str(cal["dark"]), "--flat", str(cal["flat"])] if correct else []
    quiet = _io.StringIO()
    with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):
        for folder, name in ((train, "train"), (test, "test")):
            main(["import", str(folder), "--out", str(root / f"{name}.zarr"), *extra,
                  "--no-progress"])
            main(["centroid", str(root / f"{name}.zarr"), "--out", str(root / f"{name}.nc"),
                  "--method", method, "--no-progress"])
        fitted = main(["calibrate", str(root / "train.nc"), "--method", "polynomial",
                       "--order", "3", "--out", str(root / "p.json")]) == 0
        evaluated = fitted and main(["evaluate", str(root / "p.json"), str(root / "test.nc"),
                                     "--out", str(root / "ev")]) == 0
    cen = io.open_centroids(root / "test.nc")
    ok = cen.status.values == 0
    measured = np.stack([cen.x.values, cen.y.values], axis=-1)[ok]
    rms = lab._affine_rms(measured, test_truth[ok]) if ok.any() else float("nan")
    mu = "calibrate refused (no usable shot)"
    if evaluated:
        doc = json.loads((root / "ev" / "evaluation.json").read_text())
        mu = f"mu alpha {doc['alpha.mu']:.5f} beta {doc['beta.mu']:.5f} deg"
    return (f"{camera:13s} {'dark+flat' if correct else 'raw':9s} ok {int(ok.sum()):2d}/{ok.size} "
            f"affine RMS {rms:.4f} px  {mu}")


def main_(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--method", default="projection", choices=["projection", "tight"])
    args = p.parse_args(argv)
    print(f"test grid {lab.TEST.size}x{lab.TEST.size} poses x {lab.SHOTS} shots; limits: mu < "
          "0.004 deg, affine RMS < 0.05 px")
    for camera in sorted(lab.CAMERAS):
        for correct in (True, False):
            with tempfile.TemporaryDirectory() as tmp:
                print(_run(Path(tmp), camera, correct, args.method))
    return 0


if __name__ == "__main__":
    raise SystemExit(main_())
