"""How far 100 holes get toward sqrt(N) on a bench with a perfect platform and bad holes.

The virtual bench of Table 5 with the platform's errors switched off (``ideal_platform()``) and
the mask held without play, so that no common-mode error is injected; ``--bad`` holes get random
defects. Experiments I and III are simulated and centroided, and
:func:`sunlab.multihole.gain_study` compares one hole (the median good hole alone) with the
100-hole strategies, with and without bad-hole rejection, and prints the error budget.

Usage::

    python benchmarks/bench_multihole.py              # every other pose, 2 shots
    python benchmarks/bench_multihole.py --step 1 --shots 8   # full size
"""

import argparse
import json
import time

import numpy as np


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=2, help="take every step-th pose")
    ap.add_argument("--shots", type=int, default=2)
    ap.add_argument("--bad", type=int, default=10, help="holes with random defects")
    ap.add_argument("--order", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--platform", action="store_true", help="keep the paper's platform errors")
    args = ap.parse_args(argv)

    from sunlab import centroid, plans, sim
    from sunlab import multihole as mh

    bench = sim.Bench.paper_multi_hole(n_bad=args.bad)
    if not args.platform:
        bench = bench.ideal_platform().replace(mask__play_x_mm=0.0, mask__play_y_mm=0.0)
    t0 = time.perf_counter()
    tabs = []
    for exp in ("I", "III"):
        plan = plans.experiment(exp, shots=args.shots).subset(args.step)
        cube = sim.simulate(plan, bench, seed=args.seed)
        tabs.append(centroid.locate(cube, "tight", progress=False))
    t_sim = time.perf_counter() - t0
    g = mh.gain_study(tabs[0], tabs[1], order=args.order)
    injected = np.flatnonzero(tabs[0]["hole_defect"].values).tolist()
    print(f"frames: {tabs[0].sizes['pose'] * args.shots} + {tabs[1].sizes['pose'] * args.shots}"
          f" of 100 spots, simulated and centroided in {t_sim:.0f} s")
    print(f"injected bad holes: {injected}; rejected: {g['bad']}")
    one = g["stats"]["one_hole_median"]
    print(f"{'strategy':32s} {'alpha mu':>9s} {'alpha sig':>9s} {'alpha rms':>9s} "
          f"{'gain sig':>8s} {'gain rms':>8s} {'beta rms':>9s} {'gain rms':>8s}")
    for k, s in g["stats"].items():
        gn = g["gain"].get(k, {"alpha": {"sigma": 1, "rms": 1}, "beta": {"rms": 1}})
        print(f"{k:32s} {s['alpha']['mu']:9.5f} {s['alpha']['sigma']:9.5f} "
              f"{s['alpha']['rms']:9.5f} {gn['alpha']['sigma']:8.2f} {gn['alpha']['rms']:8.2f} "
              f"{s['beta']['rms']:9.5f} {gn['beta']['rms']:8.2f}")
    del one
    for name in ("budget_all", "budget"):
        print(name, json.dumps({a: {k: round(v, 5) for k, v in b.items()}
                                for a, b in g[name].items()}))


if __name__ == "__main__":
    main()
