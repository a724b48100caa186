"""Frame-cube I/O: Zarr and NetCDF write/read speed and size beside a raw ``np.save``/``np.load``.

Frames come from the virtual bench (experiment III poses, one hole), so compression sees
realistic noise. Run: ``python benchmarks/bench_io.py [--poses 4] [--shots 8]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from sunlab import io, plans, sim


def _size(path: Path) -> int:
    files = path.rglob("*") if path.is_dir() else [path]
    return sum(f.stat().st_size for f in files if f.is_file())


def _timed(fn):
    t = time.perf_counter()
    out = fn()
    return time.perf_counter() - t, out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=4)
    ap.add_argument("--shots", type=int, default=8)
    args = ap.parse_args(argv)
    plan = plans.experiment("III").subset(361 // args.poses)[: args.poses].with_shots(args.shots)
    cube = sim.simulate(plan, seed=0).compute()
    frames = cube.frames.values
    mb = frames.nbytes / 1e6

    def read(path):
        with io.open_frames(path) as opened:
            return opened.frames.values

    ways = {"np.save / np.load (raw)": ("raw.npy", lambda p: np.save(p, frames), np.load),
            "sunlab.io zarr": ("cube.zarr", lambda p: io.save_frames(cube, p), read),
            "sunlab.io nc": ("cube.nc", lambda p: io.save_frames(cube, p), read)}
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        io.save_frames(cube.isel(pose=[0], shot=[0]), tmp / "warm.zarr")  # imports, codecs
        io.save_frames(cube.isel(pose=[0], shot=[0]), tmp / "warm.nc")
        for name, (file, write, load) in ways.items():
            tw, _ = _timed(lambda: write(tmp / file))  # noqa: B023 - called at once
            tr, back = _timed(lambda: load(tmp / file))  # noqa: B023
            assert np.array_equal(back, frames), name
            rows.append((name, _size(tmp / file), tw, tr))
    raw = rows[0][2:]
    print(f"{frames.shape} uint16 frames from the virtual bench, {mb:.0f} MB raw")
    print(f"{'format':<26}{'MB on disk':>11}{'ratio':>7}{'write s':>9}{'MB/s':>7}"
          f"{'read s':>8}{'MB/s':>7}{'write/raw':>10}{'read/raw':>9}")
    for name, size, tw, tr in rows:
        print(f"{name:<26}{size / 1e6:11.1f}{frames.nbytes / size:7.2f}{tw:9.2f}{mb / tw:7.0f}"
              f"{tr:8.2f}{mb / tr:7.0f}{tw / raw[0]:10.2f}{tr / raw[1]:9.2f}")


if __name__ == "__main__":
    main()
