"""Frame-cube I/O: Zarr and NetCDF write/read speed and size beside a raw ``np.save``/``np.load``.

Frames come from the virtual bench (experiment III poses, one hole), so compression sees
realistic noise. Run: ``python benchmarks/bench_io.py [--poses 4] [--shots 8]``.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np


def _size(path: Path) -> int:
    if path.is_dir():
        return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    return path.stat().st_size


def main(argv=None) -> None:
    from sunlab import io, plans, sim

    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--poses", type=int, default=4)
    ap.add_argument("--shots", type=int, default=8)
    args = ap.parse_args(argv)
    plan = plans.experiment("III").subset(361 // args.poses)[: args.poses].with_shots(args.shots)
    cube = sim.simulate(plan, seed=0).compute()
    frames = cube.frames.values
    mb = frames.nbytes / 1e6
    tmp = Path(tempfile.mkdtemp())
    try:
        io.save_frames(cube.isel(pose=[0], shot=[0]), tmp / "warm.zarr")  # imports, codecs
        io.save_frames(cube.isel(pose=[0], shot=[0]), tmp / "warm.nc")
        rows = []
        t = time.perf_counter()
        np.save(tmp / "raw.npy", frames)
        tw = time.perf_counter() - t
        t = time.perf_counter()
        back = np.load(tmp / "raw.npy")
        tr = time.perf_counter() - t
        assert np.array_equal(back, frames)
        raw = (tw, tr)
        rows.append(("np.save / np.load (raw)", _size(tmp / "raw.npy"), tw, tr))
        for name in ("cube.zarr", "cube.nc"):
            t = time.perf_counter()
            io.save_frames(cube, tmp / name)
            tw = time.perf_counter() - t
            t = time.perf_counter()
            with io.open_frames(tmp / name) as opened:
                data = opened.frames.values
            tr = time.perf_counter() - t
            assert np.array_equal(data, frames), name
            rows.append((f"sunlab.io {name.split('.')[1]}", _size(tmp / name), tw, tr))
    finally:
        shutil.rmtree(tmp)
    print(f"{frames.shape} uint16 frames from the virtual bench, {mb:.0f} MB raw")
    print(f"{'format':<26}{'MB on disk':>11}{'ratio':>7}{'write s':>9}{'MB/s':>7}"
          f"{'read s':>8}{'MB/s':>7}{'write/raw':>10}{'read/raw':>9}")
    for name, size, tw, tr in rows:
        print(f"{name:<26}{size / 1e6:11.1f}{frames.nbytes / size:7.2f}{tw:9.2f}{mb / tw:7.0f}"
              f"{tr:8.2f}{mb / tr:7.0f}{tw / raw[0]:10.2f}{tr / raw[1]:9.2f}")


if __name__ == "__main__":
    main()
