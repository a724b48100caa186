"""Rendering and centroiding Table 4's frames on threads, on processes and on a local cluster.

Prints the floor u of issue 16 (best of 5 of drawing one 1024 x 1280 frame of float32 standard
normals with numpy) and ``np.copy`` of a frame, the time of one rendered frame, then the wall
time of :func:`sunlab.reproduce.pipeline.simulate_and_locate` (thinned plans, 8 shots) on 1 and 2
threads, on Dask's processes scheduler with 1 and 2 processes (sunlab's pool, its workers
forked warm from a fork server, as ``sunlab reproduce`` runs it) and on a
:func:`sunlab.parallel.local_cluster` of 1 and 2 worker processes, with the speed-up from 1 to
2 workers and each worker's peak memory (RSS). The machine's load average is printed beside,
as the timings depend on it.

    python benchmarks/bench_scaling.py [--step 3]
"""

from __future__ import annotations

import argparse
import os
import resource
import time

import _timing
import numpy as np

from sunlab import parallel, sim
from sunlab.reproduce.pipeline import (
    experiment_plans,
    locate_runs,
    simulate_and_locate,
    simulate_runs,
)
from sunlab.sim import render


def floor_u() -> float:
    """The floor u of issue 16, s: best of 5 of one frame of float32 standard normals."""
    return _timing.noise_ms() / 1e3


def _rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def _run(sched: str, workers: int, step: int, bench):
    """One reproduction's frames on ``workers`` of ``sched``: (tables, CPU s, memory text)."""
    c0 = time.process_time()
    if sched == "cluster":
        from distributed import Client

        with parallel.local_cluster(workers) as cluster, Client(cluster) as client:
            w0 = client.run(time.process_time)
            got = simulate_and_locate(step=step, progress=False, address=cluster.scheduler_address)
            w1 = client.run(time.process_time)
            mem = client.run(_rss_mb)
        rss = ", ".join(f"{v:.0f}" for v in mem.values())
        return got, sum(w1[k] - w0[k] for k in w0), f"peak RSS per worker {rss} MB"
    if sched == "processes":
        # as sunlab reproduce runs it: one pool, its workers forked warm from the fork server
        # (parallel.worker_pool), whose children they are: their CPU and memory are read from
        # /proc before the pool closes
        with parallel.worker_pool(sched, workers) as pool:
            cubes = simulate_runs({k: (p, bench) for k, p in experiment_plans(step=step).items()})
            got = locate_runs(cubes, progress=False, scheduler=sched, workers=workers, pool=pool)
            cpu, rss = _pool_usage()
        return got, cpu, f"peak RSS per worker {rss} MB"
    got = simulate_and_locate(step=step, progress=False, scheduler=sched, workers=workers)
    return got, time.process_time() - c0, f"peak RSS of this process {_rss_mb():.0f} MB"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=3, help="keep every step-th angle per axis")
    args = ap.parse_args(argv)

    bench = sim.Bench.paper_single_hole()
    sim.render_frame(bench, -5.0, 5.0, seed=0)
    best = _timing.times(lambda i: sim.render_frame(bench, -5.0, 5.0, seed=0, pose=i), 10,
                         warm=False)["wall"][1] / 1e3
    cp, u = _timing.copy_ms() / 1e3, floor_u()
    n = sum(len(p) * p.shots for p in experiment_plans(step=args.step).values())
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    print(f"u (float32 standard normals, one frame) {u * 1e3:.2f} ms; np.copy of a frame "
          f"{cp * 1e3:.3f} ms; render_frame {best * 1e3:.2f} ms = {best / u:.2f} u")
    print(f"simulate_and_locate: {n} frames (step {args.step}, 8 shots)")
    simulate_and_locate(step=9, shots=1, progress=False)  # warm-up: caches, compiled kernels
    t = time.perf_counter()  # the process pool's fork server, once per process (a reproduce)
    with parallel.worker_pool("processes", 1) as pool:
        pool.submit(int).result()
    print(f"fork server of the process pool ready in {time.perf_counter() - t:.2f} s (once per "
          "process, in parallel with the caller's own start in sunlab reproduce)")
    ref, walls = None, {}
    for sched in ("threads", "processes", "cluster"):
        for workers in (1, 2):
            # every run renders the same frames: empty the geometry cache of this process so
            # that no run reuses the spot geometry of the one before (worker processes start
            # empty)
            render._spot_geometry_cached.cache_clear()
            t = time.perf_counter()
            got, cpu, mem_txt = _run(sched, workers, args.step, bench)
            wall = walls[(sched, workers)] = time.perf_counter() - t
            xy = np.concatenate([np.r_[c.x.values.ravel(), c.y.values.ravel()]
                                 for c in got.values()])
            same = ref is None or np.array_equal(xy, ref, equal_nan=True)
            ref = xy if ref is None else ref
            who = "process" if sched == "threads" else "workers"
            print(f"  {sched:8s} x {workers}: {wall:6.2f} s wall = {wall / n * 1e3:5.2f} ms/frame "
                  f"= {wall / n / u:4.2f} u; CPU of the {who} {cpu / n * 1e3:5.2f} ms/frame; "
                  f"{mem_txt}; centroids identical: {same}", flush=True)
        print(f"  {sched}: speed-up 1 -> 2 workers "
              f"{walls[(sched, 1)] / walls[(sched, 2)]:.2f}x")
    print(f"load average {os.getloadavg()[0]:.2f} at the end")


def _pool_usage() -> tuple[float, str]:
    """CPU seconds and peak RSS (MB, each) of the running workers of sunlab's process pool:
    the children of the fork server (Linux /proc)."""
    from multiprocessing import forkserver

    server = forkserver._forkserver._forkserver_pid
    tick = os.sysconf("SC_CLK_TCK")
    cpu, rss = 0.0, []
    for pid in filter(str.isdigit, os.listdir("/proc")):
        try:
            stat = open(f"/proc/{pid}/stat").read()
            status = open(f"/proc/{pid}/status").read()
        except OSError:
            continue
        fields = stat[stat.rindex(")") + 2:].split()
        if int(fields[1]) == server:
            cpu += (int(fields[11]) + int(fields[12])) / tick
            rss += [int(ln.split()[1]) / 1024 for ln in status.splitlines()
                    if ln.startswith("VmHWM")]
    return cpu, ", ".join(f"{v:.0f}" for v in rss)


if __name__ == "__main__":
    main()
