"""Beyond the paper: a calibration learned from the frames, measured against the classical one.

``sunlab reproduce --table learned`` runs, on the benches :data:`DEFAULT_BENCHES` at the quick
plans (minutes on 2 cores), or with ``--full`` on every bench of :data:`BENCHES` at the full
plans (the paper-size run; docs/learned/README.md gives both times), the protocol of Table 4:
experiments I (train), II (stop) and III (test) rendered with three seeds of the bench's own,
so the test frames are never seen in training. On each:

* ``learned``: :class:`sunlab.calibration.FrameNet` trained on I's frames, stopped on II's;
* one hole: ``polynomial``, Table 4's recipe on algorithm B's centroids (order chosen on II,
  refitted on I + II) and ``polynomial (I only)``, the same order fitted on I alone (the
  learned route sees II only to stop: that is the like-for-like comparison); on the
  good-platform bench also ``disk fit + polynomial`` (the estimator that reaches the
  Cramér-Rao bound, :func:`sunlab.centroid.disk_fit`) and ``CRLB floor``: the mean ``|error|`` an
  unbiased centroid at the Cramér-Rao bound of the bench's spot would give, through the
  polynomial's local slope (:func:`crlb_floor`);
* 100 holes: ``geometric centre`` (:class:`sunlab.multihole.GeometricCentre`, order 5, the
  spots numbered with the one-hole paper bench's mounting offset, as Table 5 does).

Each bench's model is saved as ``models/<bench>.json`` (``calibration/1``, loadable by
:func:`sunlab.calibration.load`) and its records as ``benches/<bench>.json`` as soon as the
bench is done, so a stopped run resumes after the last bench it finished. ``learned.json``
holds the ``command`` that wrote it, its ``settings`` and the ``records`` ``{bench, method,
angle, stat, value}``: mu, sigma, M, sigma_M per angle (deg), and per method the seconds of training
(``train_s``, wall clock, angle null; for the learned route also ``train_cpu_s``, the CPU
seconds of every thread, which a shared machine does not inflate) and of inference per frame
(``infer_s_per_frame``, wall clock: detection,
windows and network for the learned route; detection, which is the centroid, and the
polynomial for the classical one); ``learned.png`` draws the mu's.

The 100-hole benches take at most :data:`MULTI_SHOTS` shots per pose (100 windows a frame) and
:data:`MULTI_EPOCHS` epochs.

Examples
--------
>>> list(BENCHES)[:3]
['paper', 'good-platform', '100-holes-edge']
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time
from pathlib import Path

import numpy as np

from .. import centroid, sim, stats
from ..calibration import Polynomial
from ..errors import ConfigurationError
from ..multihole import GeometricCentre
from .learned_files import learned_figure, records_of, records_table  # noqa: F401 (users import them here)
from .pipeline import experiment_plans, finite, locate_runs, mounting_offset_px, usable_table

__all__ = ["reproduce_learned"]

#: The benches, in the order they run: name -> what it is (the factory is :func:`bench`).
BENCHES = {
    "paper": "the identified one-hole bench (sunlab.sim.Bench.paper_single_hole)",
    "good-platform": "the paper bench with the platform ideal and the mask's play off: the "
                     "sensor's own limit",
    "100-holes-edge": "the 100-hole bench with its holes placed 1.2 mm further along y, so "
                      "that up to two rows of spots leave the field at the end of the range",
    "100-holes": "the identified 100-hole bench (paper_multi_hole, its 6 bad holes)",
    "prnu-x3": "the paper bench with three times its pixel response non-uniformity",
    "hot-pixels": "the paper bench with 50 times its hot pixels",
    "dust": "the paper bench's hole partly shadowed by a dust grain standing above the mask",
}
#: The benches of the default run (``sunlab reproduce --table learned``: minutes on 2 cores);
#: ``--full`` or ``--benches all`` runs every bench of :data:`BENCHES`.
DEFAULT_BENCHES = ("paper", "good-platform")
#: Most shots per pose on the 100-hole benches (each frame is 100 windows in memory).
MULTI_SHOTS = 2
#: Most epochs on the 100-hole benches (an epoch there costs 16 windows a training frame and
#: every window of the validation frames: about 8 one-hole epochs).
MULTI_EPOCHS = 12
#: Runs whose frames take less memory than this are rendered once and kept, bytes.
IN_MEMORY_BYTES = 2 * 2**30
#: How far the 100-hole-edge bench's holes are placed from the preset's along y, mm.
EDGE_SHIFT_MM = 1.2


def bench(name: str):
    """The virtual bench called ``name`` (:data:`BENCHES`), built from the library's presets.

    Parameters
    ----------
    name : str
        A key of :data:`BENCHES`.

    Returns
    -------
    sunlab.sim.Bench
        The bench: :meth:`sunlab.sim.Bench.paper_single_hole` or
        :meth:`sunlab.sim.Bench.paper_multi_hole` with the change its name describes.

    Examples
    --------
    >>> b = bench("prnu-x3")
    >>> from sunlab import sim
    >>> round(b.detector.prnu / sim.Bench.paper_single_hole().detector.prnu, 6)
    3.0
    """
    from .. import sim

    one = sim.Bench.paper_single_hole()
    if name == "paper":
        return one
    if name == "good-platform":
        return one.ideal_platform().replace(mask__play_x_mm=0.0)
    if name == "prnu-x3":
        return one.replace(detector__prnu=3 * one.detector.prnu,
                           detector__prnu_correlated=3 * one.detector.prnu_correlated)
    if name == "hot-pixels":
        return one.replace(detector__hot_pixel_fraction=50 * one.detector.hot_pixel_fraction)
    if name == "dust":
        r = one.mask.holes[0].diameter_mm / 2
        return one.replace(mask=one.mask.with_defects({0: sim.holes.Dust(0.75 * r, 0.0, 0.6 * r,
                                                                   0.04)}))
    many = sim.Bench.paper_multi_hole()
    if name == "100-holes":
        return many
    if name == "100-holes-edge":  # the holes' design places move: the cube knows them
        return many.replace(mask__holes=tuple(
            dataclasses.replace(h, y_mm=h.y_mm + EDGE_SHIFT_MM) for h in many.mask.holes))
    raise ConfigurationError(f"bench: found {name!r}, expected one of {sorted(BENCHES)}")


def bench_seeds(name: str, seed: int = 0) -> dict:
    """The seeds of experiments I, II, III on bench ``name``: three of its own, none shared
    with another experiment or bench.

    Parameters
    ----------
    name : str
        A key of :data:`BENCHES`.
    seed : int
        The run's seed; each unit adds 1000 to every experiment's seed.

    Returns
    -------
    dict of str to int
        The seeds keyed ``"I"``, ``"II"``, ``"III"``.

    Examples
    --------
    >>> bench_seeds("paper"), bench_seeds("good-platform", seed=1)
    ({'I': 101, 'II': 102, 'III': 103}, {'I': 1211, 'II': 1212, 'III': 1213})
    """
    k = list(BENCHES).index(name)
    base = 1000 * int(seed) + 100 * (k + 1) + 10 * (k > 0)
    return {"I": base + 1, "II": base + 2, "III": base + 3}


def crlb_floor(bench_, cen_test, calibration) -> dict:
    """The mean ``|error|`` per angle (deg) of an unbiased centroid at the Cramér-Rao bound.

    The bound (:func:`sunlab.centroid.crlb`) of the bench's spot: a disk of the hole's radius
    whose edge the sun's disk blurs, the median flux of the test spots (DN), the dark signal and
    the read noise of the detector, its gain; the centroid's scatter becomes the angles'
    through the calibration's local slope (finite differences, 0.01 px) at every test pose,
    and a Gaussian error of standard deviation s has a mean ``|error|`` of s sqrt(2 / pi). The
    floor leaves out everything the bound does not see: the pixel response's fixed pattern,
    jitter, the platform.

    Parameters
    ----------
    bench_ : sunlab.sim.Bench
        The bench of the test run: its hole, detector and source give the bound.
    cen_test : xarray.Dataset
        One-hole ``centroids/1`` table of the test run (``status``, ``flux`` in DN, ``x``,
        ``y`` in px).
    calibration : sunlab.calibration.Calibration
        A fitted calibration with ``predict_xy`` (px to deg).

    Returns
    -------
    dict
        ``sigma_px`` (the bound's standard deviations in x and y, px), ``flux_dn`` (the median
        test flux, DN), ``alpha`` and ``beta`` (the floor's mean ``|error|``, deg).
    """

    det, src, mask = bench_.detector, bench_.source, bench_.mask
    radius = mask.holes[0].diameter_mm / 2 / det.pixel_pitch_mm
    edge = bench_.mask_distance_mm * math.tan(math.radians(src.diameter_deg / 2))
    edge /= det.pixel_pitch_mm
    ok = cen_test["status"].values == 0
    flux = float(np.median(cen_test["flux"].values[ok]))
    bound = centroid.crlb(flux, det.dark_signal_e / det.gain_e_per_dn,
                          det.read_noise_e / det.gain_e_per_dn, gain=det.gain_e_per_dn,
                          radius=radius, edge=edge)
    x = np.nanmean(np.where(ok, cen_test["x"].values, np.nan), axis=1)
    y = np.nanmean(np.where(ok, cen_test["y"].values, np.nan), axis=1)
    h = 0.01
    a0, b0 = calibration.predict_xy(x, y)
    ax, bx = calibration.predict_xy(x + h, y)
    ay, by = calibration.predict_xy(x, y + h)
    out = {"sigma_px": [bound.sigma_x, bound.sigma_y], "flux_dn": flux}
    for name, dx, dy in (("alpha", (ax - a0) / h, (ay - a0) / h),
                         ("beta", (bx - b0) / h, (by - b0) / h)):
        s = np.hypot(dx * bound.sigma_x, dy * bound.sigma_y)
        out[name] = float(np.nanmean(s) * math.sqrt(2 / math.pi))
    return out


def reproduce_learned(*, full: bool = False, quick: bool = False, seed: int = 0,
                      out: str | Path | None = "results", progress: bool = True,
                      step: int | None = None, shots: int | None = None, benches=None,
                      epochs: int = 40, threads: int = 2, device: str = "cpu",
                      resume: bool = True) -> dict:
    """Train, test and compare the learned route on the benches (module docstring): by default
    :data:`DEFAULT_BENCHES` at the quick plans (minutes on 2 cores), with ``full`` every bench.

    Parameters
    ----------
    full : bool
        Every bench, full plans (8 shots per pose; the 100-hole benches :data:`MULTI_SHOTS`).
    quick : bool
        The tables' quick mode (:data:`sunlab.reproduce.pipeline.QUICK`): the learned table's
        default size already; refused with ``full``.
    step, shots
        Thin the plans (:func:`sunlab.reproduce.pipeline.experiment_plans`; override the above).
    seed : int
        Base of every bench's seeds (:func:`bench_seeds`).
    out : path, optional
        Folder of ``learned.json``, ``learned_settings.json``, ``learned.png``,
        ``models/<bench>.json`` and the per-bench records ``benches/<bench>.json``.
    progress : bool
        Print the estimate, each bench's table and a progress line with the time left.
    benches : sequence of str, optional
        Names of :data:`BENCHES`, or ``["all"]`` (default :data:`DEFAULT_BENCHES`, every bench
        with ``full``).
    epochs, threads, device
        Of :class:`sunlab.calibration.FrameNet`.
    resume : bool
        Read back each bench that ``out`` holds from a run with the same settings (stopped or
        finished) instead of recomputing it.

    Returns
    -------
    dict
        ``records`` (the list written), ``command``, ``settings``, ``tables`` (per bench, a
        DataFrame of the statistics by method), ``floors`` (the CRLB floors), ``models`` (the
        fitted or read-back nets), ``reused`` (benches read back), ``files``.
    """
    from . import learned_files as run

    settings, plans_, thin = run_settings(full=full, quick=quick, seed=seed, out=out, step=step,
                                          shots=shots, benches=benches, epochs=epochs,
                                          threads=threads, device=device)
    per, out = settings["benches"], out if out is None else Path(out)
    olds = {n: run.stored(out, s) if resume else None for n, s in per.items()}
    bar = run.Progress({n: 0.0 if olds[n] else run.estimate_s(s) for n, s in per.items()},
                       progress)
    bar.announce(sum(s["frames"] for n, s in per.items() if not olds[n]),
                 sum(map(bool, olds.values())))
    result = {"records": [], "command": settings["command"], "settings": settings,
              "tables": {}, "floors": {}, "models": {}, "reused": [], "histories": {}}
    for name, s in per.items():
        if (old := olds[name]) is not None:
            res = run.read_back(out, old)
            result["reused"].append(name)
        else:
            t = time.perf_counter()
            res = _run_bench(name, thin if bench(name).n_holes > 1 else plans_, s,
                             lambda what, f, name=name: bar.stage(name, what, f))
            if out is not None:  # the bench is done: a stopped run resumes after it
                run.store(out, s, res, time.perf_counter() - t)
        if progress:
            print(f"{name}:\n{res['table'].round(5).to_string()}", flush=True)
        bar.finished(name, reused=old is not None)
        result["records"] += res["records"]
        result["histories"][name] = res["model"].history
        for key, part in (("tables", "table"), ("models", "model"), ("floors", "floor")):
            if part in res:
                result[key][name] = res[part]
    result["files"] = run.write(result, out) if out is not None else []
    return result


def run_settings(*, full: bool = False, quick: bool = False, seed: int = 0,
                 out: str | Path | None = "results", step: int | None = None,
                 shots: int | None = None, benches=None, epochs: int = 40, threads: int = 2,
                 device: str = "cpu", **_) -> tuple:
    """The settings a :func:`reproduce_learned` call runs with, computed without running it.

    Parameters
    ----------
    full, quick, seed, out, step, shots, benches, epochs, threads, device
        As :func:`reproduce_learned` takes them; other keywords are ignored.

    Returns
    -------
    tuple
        ``settings`` (as ``learned.json`` records them: the ``command``, the options and per
        bench its plans, seeds and epochs), and the plans of the one-hole and the 100-hole
        benches.

    Examples
    --------
    >>> s, _, _ = run_settings(out="r")
    >>> s["command"], list(s["benches"]), s["benches"]["paper"]["plans"]["I"]
    ('sunlab reproduce --table learned --out r', ['paper', 'good-platform'], [100, 2])
    """
    from . import learned_files as run

    if full and quick:
        raise ConfigurationError("quick: found quick and full together, expected one of them")
    names = (list(BENCHES) if full else list(DEFAULT_BENCHES)) if benches is None else \
        (list(BENCHES) if list(benches) == ["all"] else list(benches))
    plans_ = experiment_plans(quick=not full, step=step, shots=shots)
    thin = experiment_plans(quick=not full, step=step,
                            shots=min(MULTI_SHOTS, plans_["I"].shots))
    per = {}
    for name in names:  # an unknown name is refused here, before anything runs
        multi = bench(name).n_holes > 1
        per[name] = run.bench_settings(
            name, {k: (len(p), p.shots) for k, p in (thin if multi else plans_).items()},
            seed=seed, epochs=min(epochs, MULTI_EPOCHS) if multi else epochs, threads=threads,
            device=device)
    cmd = run.command(out=out, full=full, quick=quick, seed=seed, benches=benches,
                      threads=threads, default_benches=DEFAULT_BENCHES, step=step, shots=shots,
                      epochs=epochs, device=device)
    settings = {"command": cmd, "full": full, "quick": quick, "step": step, "shots": shots,
                "seed": seed, "epochs": epochs, "multi_epochs": min(epochs, MULTI_EPOCHS),
                "threads": threads, "device": device, "benches": per}
    return settings, plans_, thin


@functools.cache
def _mounting_offset(seed: int) -> tuple[float, float]:
    """Where the one-hole spot falls off its design track, px, from a thinned experiment I on
    the paper bench: the prior that numbers the 100 spots (as Table 5 does)."""
    from .. import sim

    plan = experiment_plans(("I",), step=4, shots=1)["I"]
    cen = locate_runs({"I": (sim.simulate(plan, sim.Bench.paper_single_hole(),
                                          seed=bench_seeds("paper", seed)["I"]))},
                      progress=False)["I"]
    return mounting_offset_px(usable_table(cen))


def _run_bench(name: str, plans_: dict, opts: dict, stage) -> dict:
    """One bench: render, detect, train and test both routes; records and the table.
    ``opts`` are the bench's settings (:func:`sunlab.reproduce.learned_files.bench_settings`);
    ``stage(what, fraction)`` hears of each stage done and the fraction of the bench done."""
    from ..calibration import FrameNet
    from ..calibration.windows import detect_spots

    b = bench(name)
    multi = b.n_holes > 1
    off = _mounting_offset(opts["seed"]) if multi else (0.0, 0.0)
    cubes = {k: sim.simulate(p, b, seed=opts["seeds"][k]) for k, p in plans_.items()}
    if sum(c["frames"].nbytes for c in cubes.values()) < IN_MEMORY_BYTES:
        # rendered once: the detection, the windows and the disk fit read them again
        cubes = {k: c.load() for k, c in cubes.items()}
    det, secs = {}, {}
    for k, cube in cubes.items():
        t = time.perf_counter()
        det[k] = detect_spots(cube, off, workers=opts["threads"])
        secs[f"detect {k}"] = time.perf_counter() - t
    stage("rendered and detected I, II, III", 0.4)
    tables = {k: usable_table(c) for k, c in det.items()}
    n_test = int(cubes["III"].sizes["pose"] * cubes["III"].sizes["shot"])
    net = FrameNet(epochs=opts["epochs"], threads=opts["threads"], device=opts["device"],
                   seed=opts["seed"], hole_offset=off).fit(
        cubes["I"], cubes["II"], detections=det["I"], val_detections=det["II"])
    train_s = net.timings["train network"]
    stage(f"trained ({net.history['epochs']} epochs)", 0.85)
    est = net.predict_frames(cubes["III"], detections=det["III"])
    ests = {"learned": est}
    timing = {"learned": (train_s, (secs["detect III"] + net.timings["cube windows"]
                                    + net.timings["cube network"]) / n_test,
                          net.history["cpu_seconds"])}
    classical = _classical(multi, tables, cubes, b, opts)
    for method, (cal, fit_s, test_table, det_s) in classical.items():
        t = time.perf_counter()
        ests[method] = cal.predict(test_table)
        timing[method] = (fit_s, ((secs["detect III"] if det_s is None else det_s)
                                  + time.perf_counter() - t) / n_test)
    table = stats.evaluate(ests)
    res = {"table": table, "model": net, "records": _records(name, table, timing)}
    if not multi:
        floor = crlb_floor(b, tables["III"], classical["polynomial"][0])
        res["floor"] = floor
        res["records"] += [{"bench": name, "method": "CRLB floor", "angle": a, "stat": "mu",
                            "value": floor[a]} for a in ("alpha", "beta")]
    return res


def _classical(multi: bool, tables: dict, cubes: dict, bench_, opts) -> dict:
    """The classical routes: method -> (calibration, fit seconds, test table, detection
    seconds of the test run or None when it is the learned route's detection)."""

    def timed(fit, *args, **kw):
        t = time.perf_counter()
        return fit(*args, **kw), time.perf_counter() - t

    if multi:
        gc, sec = timed(GeometricCentre(order=5).fit, tables["I"])
        return {"geometric centre": (gc, sec, tables["III"], None)}
    out = {}
    for method, refit in (("polynomial", True), ("polynomial (I only)", False)):
        (cal, _), sec = timed(Polynomial.select_order, tables["I"], tables["II"], refit=refit)
        out[method] = (cal, sec, tables["III"], None)
    if bench_.platform.alpha_pose_error_deg == 0 and bench_.mask.play_x_mm == 0:
        found, sec = timed(locate_runs, cubes, method="fit", progress=False,
                           workers=opts["threads"])
        fit = {k: usable_table(c) for k, c in found.items()}
        det_s = sec * cubes["III"].sizes["pose"] / sum(c.sizes["pose"] for c in cubes.values())
        (pfit, _), sec = timed(Polynomial.select_order, fit["I"], fit["II"], refit=True)
        out["disk fit + polynomial"] = (pfit, sec, fit["III"], det_s)
    return out


def _records(name: str, table, timing: dict) -> list[dict]:
    def rec(method, angle, stat, value):
        return {"bench": name, "method": str(method), "angle": angle, "stat": stat,
                "value": finite(value)}

    recs = [rec(m, a, s, v) for m in table.columns for (a, s), v in table[m].items()]
    for m, (train_s, infer_s, *cpu) in timing.items():
        recs += [rec(m, None, "train_s", train_s), *[rec(m, None, "train_cpu_s", c) for c in cpu],
                 rec(m, None, "infer_s_per_frame", infer_s)]
    return recs
