"""Speed (and error budget) of the virtual bench.

Prints the time per full 1280 x 1024 frame -- one hole and 100 holes -- beside the time numpy
takes to draw one frame of float32 Gaussian noise in the same run (the floor any noisy frame
renderer is measured against), on one core (BLAS and numba single-threaded). Both wall-clock and
process CPU time are reported: on a shared machine the CPU time is the fairer figure. Target:
<= 15 ms per single-hole frame.

With ``--budget`` it also measures the hole-specific centroid error that the detector's fixed
patterns give a single spot (docs/paper.md sec. 8 asks for about 0.1 px): noiseless frames of the
default bench at random poses, a window centroid above the window's border level, minus the true
centroid; the RMS over poses per axis.

Usage::

    python benchmarks/bench_sim.py            # timings
    python benchmarks/bench_sim.py --budget   # timings + error budget (about a minute)
"""

from __future__ import annotations

import argparse

import _timing

_timing.single_thread()

import numpy as np  # noqa: E402

from sunlab import sim  # noqa: E402


def timings(repeat: int = 20) -> None:
    rng = np.random.default_rng(0)
    single, multi = sim.Bench.paper_single_hole(), sim.Bench.paper_multi_hole()
    # a cube's pose: 8 shots with the paper's jitter, sharing the spots' shape (per frame)
    jit = 0.0005 * np.random.default_rng(1).standard_normal((2, 8))

    def frame(bench):
        return lambda i: sim.render_frame(bench, -7.0, 6.0, seed=0, pose=0, shot=i)

    def pose(bench):
        return lambda i: sim.frame.render_pose(bench, -7.0 + jit[0], 6.0 + jit[1], seed=i)

    rows = {
        "numpy float32 Gaussian noise frame": _timing.times(
            lambda i: rng.standard_normal(_timing.FRAME, dtype=np.float32), repeat),
        "render_frame, 1 hole": _timing.times(frame(single), repeat),
        "render_frame, 100 holes": _timing.times(frame(multi), max(3, repeat // 4)),
        "render_pose / 8 shots, 1 hole": _timing.times(pose(single), repeat // 4),
        "render_pose / 8 shots, 100 holes": _timing.times(pose(multi), 3),
    }
    for name in list(rows)[3:]:
        rows[name] = {k: tuple(v / 8 for v in t) for k, t in rows[name].items()}
    noise = rows["numpy float32 Gaussian noise frame"]["cpu"][0]
    print("virtual bench: ms per full 1280 x 1024 frame, one core (median / best)")
    print(f"{'':34s}{'wall':>16s}{'cpu':>16s}{'cpu / noise':>14s}")
    for name, t in rows.items():
        (wm, wb), (cm, cb) = t["wall"], t["cpu"]
        print(f"{name:34s}{wm:8.1f} /{wb:6.1f}{cm:8.1f} /{cb:6.1f}{cm / noise:14.2f}")
    best = rows["render_frame, 1 hole"]["cpu"][1]
    print(f"single-hole target <= 15 ms per frame: best cpu {best:.1f} ms "
          f"({'meets' if best <= 15.0 else 'misses'})")


def budget(n: int = 120) -> None:
    def run(bench):
        rng = np.random.default_rng(1)
        b = bench.replace(detector__temporal_noise=False)
        err = []
        for _ in range(n):
            a, be = rng.uniform(-16.5, 1.5), rng.uniform(-1.5, 16.5)
            tx, ty = sim.spots.spot_truth(b, a, be)
            mean, _ = sim.frame.expected_frame(b, a, be)
            x0, y0 = int(round(tx[0])) - 30, int(round(ty[0])) - 30
            w = mean[y0 : y0 + 61, x0 : x0 + 61].astype(float)
            edge = np.concatenate([w[:2].ravel(), w[-2:].ravel(), w[:, :2].ravel(),
                                   w[:, -2:].ravel()])
            w = np.clip(w - edge.mean(), 0, None)
            yy, xx = np.mgrid[y0 : y0 + 61, x0 : x0 + 61]
            err.append(((w * xx).sum() / w.sum() - tx[0], (w * yy).sum() / w.sum() - ty[0]))
        e = np.array(err)
        return (e - e.mean(axis=0)).std(axis=0)

    base = sim.Bench.paper_single_hole()
    px_deg = np.degrees(base.detector.pixel_pitch_mm / base.mask.true_distance_mm)
    print(f"\nhole-specific centroid error from pixel response ({n} poses, RMS per axis, px):")
    for name, b in (("default detector", base),
                    ("without correlated PRNU", base.replace(detector__prnu_correlated=0.0)),
                    ("ideal detector (fill factor only)",
                     base.replace(detector__fixed_pattern=False))):
        sx, sy = run(b)
        print(f"  {name:34s} x {sx:.4f}  y {sy:.4f}   (= {sx * px_deg:.4f} / {sy * px_deg:.4f} "
              "deg)")
    print("  docs/paper.md sec. 8 target: about 0.1 px (0.008 deg)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=20)
    parser.add_argument("--budget", action="store_true", help="also measure the error budget")
    args = parser.parse_args()
    timings(args.repeat)
    if args.budget:
        budget()


if __name__ == "__main__":
    main()
