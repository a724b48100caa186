"""Wall time of the full reproductions against the limits of issue 16, in units of a floor.

The floor u is the best of 5 of drawing one 1024 x 1280 frame of float32 standard normals
with numpy, measured before and after each run (the machine's speed drifts; both are printed).
The limits are those of issue 16:

* ``sunlab reproduce`` (Table 4, full: 7,440 frames): at most 0.4 x (7,440 u / 2);
* ``sunlab reproduce --table 5`` (full: 6,088 frames of 100 spots and as many of one): at
  most 1.6 x (6,088 u / 2).

Each is also printed in the frame-noise unit ``frames x u / 2`` against issue 45's targets
(:data:`TARGETS`: Table 4 at most 0.3, Table 5 at most 1.0).

Each command runs in its own process, as a user runs it (imports, figures and files included),
writing to a temporary folder; its own timing summary is printed beside.

    python benchmarks/bench_reproduce.py [--table 4 5] [--scheduler processes]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scaling import floor_u  # the floor u of issue 16, one definition

#: (frames in the limit's formula, factor) of each table's limit: factor x (frames x u / 2).
LIMITS = {"4": (7440, 0.4), "5": (6088, 1.6)}
#: Issue 45's targets in the frame-noise unit frames x u / 2: the speed before the reproduction
#: became linear.
TARGETS = {"4": 0.3, "5": 1.0}


def run_table(table: str, scheduler: str) -> dict:
    """Run ``sunlab reproduce --table T`` (full) in a subprocess; wall time and its summary."""
    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "sunlab.cli", "reproduce", "--table", table,
               "--no-progress", "--out", tmp] + (["--scheduler", scheduler] if scheduler else [])
        u0 = floor_u()
        t = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        wall = time.perf_counter() - t
        u1 = floor_u()
        doc = json.loads((Path(tmp) / f"table{table}.json").read_text())
    timings = doc.get("timings_s") or {"runtime": doc.get("runtime_s")}
    return {"wall": wall, "u": (u0, u1), "timings": timings}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", nargs="+", default=["4", "5"], choices=sorted(LIMITS))
    ap.add_argument("--scheduler", default=None,
                    help="as sunlab reproduce --scheduler (default: the command's own)")
    args = ap.parse_args(argv)
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs; "
          f"scheduler {args.scheduler or 'the command default'}")
    for table in args.table:
        r = run_table(table, args.scheduler)
        frames, factor = LIMITS[table]
        u = min(r["u"])
        limit = factor * frames * u / 2
        print(f"Table {table}: {r['wall']:.1f} s wall; u {r['u'][0] * 1e3:.2f} / "
              f"{r['u'][1] * 1e3:.2f} ms (before / after); limit {factor} x ({frames} u / 2) "
              f"= {limit:.1f} s; wall / limit = {r['wall'] / limit:.2f}")
        units, target = r["wall"] / (frames * u / 2), TARGETS[table]
        print(f"  in the frame-noise unit ({frames} u / 2 = {frames * u / 2:.1f} s): {units:.2f} "
              f"(issue 45's target: at most {target}: {'met' if units <= target else 'not met'})")
        parts = ", ".join(f"{k} {v:.1f} s" for k, v in r["timings"].items() if v is not None)
        print(f"  its own timings: {parts}")


if __name__ == "__main__":
    main()
