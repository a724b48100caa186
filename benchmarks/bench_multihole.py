"""How far 100 holes get toward sqrt(N) on a bench with a perfect platform and bad holes.

The virtual bench of Table 5 with the platform's errors switched off (``ideal_platform()``) and
the mask held without play, so that no common-mode error is injected; ``--bad`` holes get random
defects. Experiments I and III are simulated and centroided, and
:func:`sunlab.multihole.gain_study` compares one hole (the median good hole alone) with the
100-hole strategies, with and without bad-hole rejection, and prints the error budget.

``--defects moving|parallax|static`` runs a second study on the same perfect-platform bench,
where ``--bad`` holes carry dust chosen so that a per-hole calibration can or cannot absorb it:

* ``moving``: a dust particle lies in the hole's plane during calibration (experiment I) and has
  settled elsewhere in the same hole by the test (experiment III): the calibration learnt an
  offset that is no longer there, so the hole's estimate is biased by a constant.
* ``parallax``: a tall particle (a fibre) stands 0.2-0.5 mm above the hole, identical in I and
  III; its shadow slides over the aperture with the sun angle, so the centroid error is a
  (non-polynomial) function of the pose.
* ``static``: the same particles as ``moving`` but lying still (identical in I and III): the
  error is a fixed offset that each hole's calibration absorbs -- the control case.

For each it prints one hole (the median over the good holes), the average of all 100 holes and
the average with the flagged holes left out (equal weights, then the robust variant of
:func:`~sunlab.multihole.gain_study`: inverse-variance weights and clipping), and which holes
were flagged vs injected.

Usage::

    python benchmarks/bench_multihole.py              # every other pose, 2 shots
    python benchmarks/bench_multihole.py --step 1 --shots 8   # full size
    python benchmarks/bench_multihole.py --defects moving --step 3 --shots 1
"""

import argparse
import json
import math
import time

import numpy as np

from sunlab import centroid, plans, sim
from sunlab import multihole as mh
from sunlab.stats import error_summary

ORDER, KAPPA, SEED = 5, 5.0, 0  # per-hole calibration order, rejection threshold (robust z)


def dust_masks(mask, kind: str, n_bad: int, seed: int = SEED, height_mm=(0.2, 0.5)):
    """Calibration and test masks with ``n_bad`` dusty holes of the given ``kind``.

    Returns ``(mask_I, mask_III, holes)``. Particles are 0.05-0.08 mm across on 0.2 mm holes
    (a quarter of the aperture at most). ``moving``/``static``: in the hole's plane, centre
    0.05-0.08 mm off the hole centre; for ``moving`` the particle of experiment III sits at
    another azimuth (90-270 deg away) at the same distance. ``parallax``: the particle stands
    ``height_mm`` (default 0.2-0.5 mm) above the mask at 0.08-0.13 mm from the hole centre, so
    that its shadow (moving by height x tan(angle)) enters and leaves the aperture over the
    test's 18 deg range.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xD057]))
    holes = sorted(rng.choice(mask.n_holes, size=n_bad, replace=False).tolist())
    cal, test = {}, {}
    for k in holes:
        ang, size = rng.uniform(0, 2 * np.pi), rng.uniform(0.05, 0.08)
        if kind == "parallax":
            dist, height = rng.uniform(0.08, 0.13), rng.uniform(*height_mm)
        else:
            dist, height = rng.uniform(0.05, 0.08), 0.0
        cal[k] = test[k] = sim.holes.Dust(dist * math.cos(ang), dist * math.sin(ang), size, height)
        if kind == "moving":
            ang2 = ang + rng.uniform(0.5 * np.pi, 1.5 * np.pi)
            test[k] = sim.holes.Dust(dist * math.cos(ang2), dist * math.sin(ang2), size, height)
    return mask.with_defects(cal), mask.with_defects(test), holes


def centroid_runs(bench, masks, args, seed_step=0):
    """Experiments I and III on ``bench`` with ``masks`` (one per run), simulated and centroided;
    returns the two tables and the seconds taken."""
    t0 = time.perf_counter()
    tabs = [centroid.locate(sim.simulate(plans.experiment(exp, shots=args.shots).subset(
        args.step), bench.replace(mask=mask), seed=SEED + k * seed_step), "tight",
        progress=False) for k, (exp, mask) in enumerate(zip(("I", "III"), masks, strict=True))]
    return tabs, time.perf_counter() - t0


def _perfect_bench(n_bad: int):
    """Table 5's bench with a perfect platform and the mask held without play."""
    return (sim.Bench.paper_multi_hole(n_bad=n_bad).ideal_platform()
            .replace(mask__play_x_mm=0.0, mask__play_y_mm=0.0))


def _median_summary(summaries):
    return {a: {k: float(np.median([s[a][k] for s in summaries])) for k in summaries[0][a]}
            for a in ("alpha", "beta")}


def defect_study(args):
    """The second study: dust that a per-hole calibration cannot absorb (or, control, can)."""
    bench = _perfect_bench(0)
    m1, m3, injected = dust_masks(bench.mask, args.defects, args.bad)
    (train, test), t_sim = centroid_runs(bench, (m1, m3), args, seed_step=1)
    s2 = mh.PerHoleAverage(order=ORDER).fit(train)
    bad = mh.reject_bad_holes(mh.defect_metrics(train, strategy=s2), kappa=KAPPA).values
    est = s2.predict_holes(test)
    good = np.ones(100, bool)
    good[injected] = False
    robust = mh.PerHoleAverage(order=ORDER, holes=~bad, weighting="inverse_variance", clip=4.0,
                               calibrations_=s2.calibrations_, variance_=s2.variance_)
    rows = {
        "one hole (median good hole)": _median_summary(
            [error_summary(est.isel(hole=h)) for h in np.flatnonzero(good)]),
        "one bad hole (median)": _median_summary(
            [error_summary(est.isel(hole=h)) for h in injected]),
        "average of all 100": error_summary(s2.combine(est)),
        "average, flagged left out": error_summary(s2.combine(est, holes=~bad)),
        "average, flagged out + robust": error_summary(robust.combine(est)),
        "average, injected left out": error_summary(s2.combine(est, holes=good)),
    }
    flagged = np.flatnonzero(bad).tolist()
    print(f"defects: {args.defects}; frames: {train.sizes['pose'] * args.shots} (I) + "
          f"{test.sizes['pose'] * args.shots} (III) of 100 spots, simulated and centroided in "
          f"{t_sim:.0f} s; per-hole calibration order {ORDER}")
    print(f"injected: {injected}")
    print(f"flagged:  {flagged}  (missed {sorted(set(injected) - set(flagged))}, false "
          f"{sorted(set(flagged) - set(injected))})")
    one = rows["one hole (median good hole)"]
    print(f"{'strategy':32s} {'alpha mu':>9s} {'alpha rms':>9s} {'gain mu':>7s} {'gain rms':>8s}"
          f" {'beta mu':>9s} {'beta rms':>9s} {'gain mu':>7s} {'gain rms':>8s}   (deg)")
    for k, s in rows.items():
        print(f"{k:32s}" + "".join(
            f" {s[a]['mu']:9.5f} {s[a]['rms']:9.5f} {one[a]['mu'] / s[a]['mu']:7.2f}"
            f" {one[a]['rms'] / s[a]['rms']:8.2f}" for a in ("alpha", "beta")))
    return rows, injected, flagged


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--step", type=int, default=2, help="take every step-th pose")
    ap.add_argument("--shots", type=int, default=2)
    ap.add_argument("--bad", type=int, default=10, help="holes with random defects")
    ap.add_argument("--defects", choices=("moving", "parallax", "static"), default=None,
                    help="run the dust study instead (see the module notes)")
    args = ap.parse_args(argv)
    if args.defects:
        defect_study(args)
        return
    bench = _perfect_bench(args.bad)
    tabs, t_sim = centroid_runs(bench, (bench.mask, bench.mask), args)
    g = mh.gain_study(tabs[0], tabs[1], order=ORDER, kappa=KAPPA)
    injected = np.flatnonzero(tabs[0]["hole_defect"].values).tolist()
    print(f"frames: {tabs[0].sizes['pose'] * args.shots} + {tabs[1].sizes['pose'] * args.shots}"
          f" of 100 spots, simulated and centroided in {t_sim:.0f} s")
    print(f"injected bad holes: {injected}; rejected: {g['bad']}")
    print(f"{'strategy':32s} {'alpha mu':>9s} {'alpha sig':>9s} {'alpha rms':>9s} "
          f"{'gain sig':>8s} {'gain rms':>8s} {'beta rms':>9s} {'gain rms':>8s}")
    for k, s in g["stats"].items():
        gn = g["gain"].get(k, {"alpha": {"sigma": 1, "rms": 1}, "beta": {"rms": 1}})
        print(f"{k:32s} {s['alpha']['mu']:9.5f} {s['alpha']['sigma']:9.5f} "
              f"{s['alpha']['rms']:9.5f} {gn['alpha']['sigma']:8.2f} {gn['alpha']['rms']:8.2f} "
              f"{s['beta']['rms']:9.5f} {gn['beta']['rms']:8.2f}")
    for name in ("budget_all", "budget"):
        print(name, json.dumps({a: {k: round(v, 5) for k, v in b.items()}
                                for a, b in g[name].items()}))


if __name__ == "__main__":
    main()
