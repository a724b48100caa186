"""Regenerate the example recording shipped in ``sunlab/data/example/`` (run from the repo root).

A small run of the virtual bench as a lab's camera would leave it on disk: 16-bit PNG frames,
``manifest.csv`` (file, alpha, beta, shot) and ``sensor.json``. ``train/``: a 5 x 5 grid of
poses, alpha -10..-6 deg and beta 5..9 deg in 1-degree steps; ``test/``: the 4 x 4 grid between
them (half-degree offsets). Two shots per pose, the paper's one-hole bench
(:meth:`sunlab.sim.Bench.paper_single_hole`, seed 2005). Frames are cropped to the region the
spot crosses (the frames/1 contract allows any frame size; ``x_cf_px``, ``y_cf_px`` in
``sensor.json`` are given in the cropped frame and the crop origin is recorded).

Usage::

    .venv/bin/python sunlab/data/make_example.py
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
from PIL import Image

from sunlab import plans, sim

__all__ = []

HERE = Path(__file__).resolve().parent / "example"
SEED = 2005
MARGIN_PX = 36  # spot radius (~26 px) + a few pixels of background


def _plans():
    return {
        "train": plans.grid(-10.0, -6.0, 1.0, 5.0, 9.0, 1.0, shots=2, name="example-train"),
        "test": plans.grid(-9.5, -6.5, 1.0, 5.5, 8.5, 1.0, shots=2, name="example-test"),
    }


def write_example() -> None:
    """Simulate the example recording and write it under ``sunlab/data/example/``."""
    bench = sim.Bench.paper_single_hole()
    cubes = {k: sim.simulate(p, bench, seed=SEED + i) for i, (k, p) in enumerate(_plans().items())}
    tx = np.concatenate([c.true_x.values.ravel() for c in cubes.values()])
    ty = np.concatenate([c.true_y.values.ravel() for c in cubes.values()])
    x0, x1 = int(tx.min()) - MARGIN_PX, int(np.ceil(tx.max())) + MARGIN_PX + 1
    y0, y1 = int(ty.min()) - MARGIN_PX, int(np.ceil(ty.max())) + MARGIN_PX + 1
    for name, cube in cubes.items():
        folder = HERE / name
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.glob("*.png"):
            old.unlink()
        rows = ["file,alpha,beta,shot"]
        frames = cube.frames[:, :, y0:y1, x0:x1].values
        for p in range(cube.sizes["pose"]):
            a, b = float(cube.alpha[p]), float(cube.beta[p])
            for s in range(cube.sizes["shot"]):
                file = f"pose{p:03d}_shot{s}.png"
                Image.fromarray(np.ascontiguousarray(frames[p, s], dtype=np.uint16)).save(
                    folder / file, optimize=True)
                rows.append(f"{file},{a:g},{b:g},{s}")
        (folder / "manifest.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
        sensor = {
            "comment": "sunlab virtual bench, paper one-hole bench (seed "
                       f"{SEED}), frames cropped to rows {y0}:{y1}, columns {x0}:{x1} of the "
                       "1280 x 1024 detector; regenerate with sunlab/data/make_example.py",
            "pixel_pitch_mm": cube.attrs["pixel_pitch_mm"],
            "mask_distance_mm": cube.attrs["mask_distance_mm"],
            "x_cf_px": cube.attrs["x_cf_px"] - x0,
            "y_cf_px": cube.attrs["y_cf_px"] - y0,
            "bit_depth": cube.attrs["bit_depth"],
            "mask": cube.attrs.get("mask", "single"),
            "experiment": f"example-{name}",
            "attrs": {"crop_x0_px": x0, "crop_y0_px": y0},
        }
        (folder / "sensor.json").write_text(json.dumps(sensor, indent=1) + "\n",
                                            encoding="utf-8")


if __name__ == "__main__":
    write_example()
