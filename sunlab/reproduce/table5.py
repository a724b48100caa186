"""Reproduce the paper's Table 5 (100 holes vs one hole) and Figs. 13-15 on the virtual bench.

Called by ``sunlab reproduce --table 5``. Experiments I (calibration) and III (test) of Table 3
are simulated with the 100-hole mask (:meth:`sunlab.sim.Bench.paper_multi_hole`: platform
per-pose error, mask play, random bad holes) and with the one-hole mask; the spots are centroided
(:func:`sunlab.centroid.locate`), a polynomial calibration is fitted for each strategy of
:mod:`sunlab.multihole` and the paper's statistics are computed on experiment III.

Columns: the paper's three (geometric centre, averaging, 1 hole), each beside our value, and our
extra column: the average after automatic bad-hole rejection with inverse-variance weights and
sigma clipping.

The frames go through the pipeline the other tables share (:mod:`sunlab.reproduce.pipeline`),
all passes on one pool of workers: one Dask pass for the one-hole runs (whose spot gives the
mounting offset that numbers the 100 spots), one for the 100-hole run I, then the 100-hole run
III while the calibrations are fitted on I. Quick mode is the pipeline's
:data:`~sunlab.reproduce.pipeline.QUICK`, as for Table 4: every 2nd angle along each grid axis
(experiments I and III: 100 + 100 poses instead of 400 + 361) and 2 shots per pose instead of 8.

Examples
--------
>>> from sunlab.reproduce.table5 import spot_method
>>> spot_method("projection"), spot_method("fit")
('tight', 'fit')
"""

from __future__ import annotations

import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from .. import parallel
from ..errors import ConfigurationError
from .pipeline import (
    centroid_status,
    experiment_plans,
    locate_runs,
    simulate_runs,
    usable_table,
    write_json,
)

__all__ = ["reproduce_table5", "mounting_offset_px", "COLUMNS", "REJECTION_COLUMN", "format_table5"]

#: The paper's column labels (:func:`sunlab.stats.paper_table5`).
COLUMNS = ("100 holes: geometric centre", "100 holes: averaging", "1 hole")
#: Our extra column.
REJECTION_COLUMN = "100 holes: averaging + rejection"
#: The per-spot centroid estimator on the 100-hole frames for each method of the table: the
#: single-spot algorithms (B's profiles run over the whole frame) cannot separate 100 spots, so
#: there each spot gets its own tight window (:func:`sunlab.centroid.locate_spots`).
SPOT_METHODS = {"projection": "tight", "threshold": "tight", "tight": "tight", "fit": "fit"}


def spot_method(method: str) -> str:
    """The centroid estimator of the 100-hole frames for the table's ``method``
    (:data:`SPOT_METHODS`); an unknown method raises, naming the choices.

    Examples
    --------
    >>> spot_method("threshold")
    'tight'
    >>> spot_method("nearest")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    sunlab.errors.ConfigurationError: method: found 'nearest'; expected one of [...]
    """
    if method not in SPOT_METHODS:
        raise ConfigurationError(
            f"method: found {method!r}; expected one of {sorted(SPOT_METHODS)}"
        )
    return SPOT_METHODS[method]


def mounting_offset_px(one_hole) -> tuple[float, float]:
    """Where the one-hole spot falls relative to its design track, px (median over poses).

    The sensor's mounting on the platform (alpha0, beta0) moves every spot off its design
    place, by about 80 px at F = 17 mm, more than half the 71 px hole pitch of the 100-hole mask
    (16 px at the presets' F = 5 mm), so design positions alone can give spots to the wrong
    holes. The mounting is the platform's, common to both
    masks: the offset measured with the one hole (calibrated first, as in the paper) is the
    prior that :func:`sunlab.centroid.locate` needs to number the 100 spots.

    Examples
    --------
    >>> from sunlab import sim
    >>> cen = sim.synthetic_centroids([0.0, -5.0], [0.0, 3.0], mask_distance_mm=17.0,
    ...                                    hole_offset_px=(80.0, 18.0))
    >>> [round(v, 6) for v in mounting_offset_px(cen)]
    [80.0, 18.0]
    """
    from ..geometry import ideal_centroid

    a = one_hole["alpha"].values[:, None]
    b = one_hole["beta"].values[:, None]
    x0, y0 = ideal_centroid(a, b, float(one_hole.attrs["mask_distance_mm"]),
                            float(one_hole.attrs["pixel_pitch_mm"]),
                            float(one_hole.attrs["x_cf_px"]), float(one_hole.attrs["y_cf_px"]))
    return (float(np.nanmedian(one_hole["x"].values - x0)),
            float(np.nanmedian(one_hole["y"].values - y0)))


def _findings(ours) -> dict:
    """The ratios behind the paper's Table 5 findings, from our columns (deg / deg).

    ``alpha_gain``: 1-hole alpha mu over each 100-hole column's (the paper: about 2);
    ``beta_loss``: each 100-hole column's beta mu over the 1-hole beta mu (the paper: above 1).
    """
    one = COLUMNS[2]
    return {
        "alpha_gain": {k: float(ours.loc[("alpha", "mu"), one] / ours.loc[("alpha", "mu"), k])
                       for k in (COLUMNS[0], COLUMNS[1], REJECTION_COLUMN)},
        "beta_loss": {k: float(ours.loc[("beta", "mu"), k] / ours.loc[("beta", "mu"), one])
                      for k in (COLUMNS[0], COLUMNS[1], REJECTION_COLUMN)},
    }


def reproduce_table5(quick: bool = True, seed: int = 0, out: Path | str | None = None,
                     progress: bool = True, *, order: int | None = None,
                     method: str = "projection", address: str | None = None,
                     scheduler: str = "threads", workers: int | None = None,
                     step: int | None = None, shots: int | None = None) -> dict:
    """Table 5 and Figs. 13-15, simulated, with the paper's values beside ours.

    Parameters
    ----------
    quick : bool
        Quick mode, the same for every table (:data:`sunlab.reproduce.pipeline.QUICK`): every
        2nd angle along each grid axis (100 + 100 poses) and 2 shots per pose (full: 400 + 361
        poses x 8 shots).
    seed : int
        Seed of the virtual bench.
    out : path, optional
        Folder for ``table5.csv``, ``table5.json``, ``hole_metrics.csv``, ``fig13.png``,
        ``fig14.png``, ``fig15.png``.
    progress : bool
        Show progress bars.
    order : int, optional
        Polynomial order of every calibration. Default: chosen on experiment II of the one-hole
        mask by the rule of Table 4's polynomial
        (:meth:`sunlab.calibration.Polynomial.select_order`, the paper's procedure): the one-hole
        column is that very calibration,
        and the 100-hole strategies take the larger of its two orders.
    method : str
        Centroid method of every frame (:func:`sunlab.centroid.locate`), the same as Table 4's
        (default ``"projection"``, algorithm B: the paper presents it as its method and names
        no other for its experiments, so we infer it used B for both tables). On the 100-hole
        frames each spot gets the estimator :func:`spot_method` names (a tight window for the
        single-spot algorithms); ``"fit"`` or ``"tight"`` apply to both masks.
    address : str, optional
        A ``dask.distributed`` scheduler address (workers started separately).
    scheduler, workers
        Local scheduler without ``address`` and its threads or processes
        (:func:`sunlab.parallel.compute`).
    step, shots : int, optional
        Keep every ``step``-th angle and take ``shots`` frames per pose (override ``quick``).

    Returns
    -------
    dict
        ``table`` (pandas.DataFrame: our value and the paper's per column, deg), ``ours`` (our
        four columns), ``bad_holes`` (rejected), ``injected`` (holes the bench gave defects),
        ``budget`` (common vs hole-specific error), ``findings`` (the ratios of the paper's
        findings, ``_findings``), ``runtime_s``, ``timings_s`` (by stage), ``sizes``,
        ``files`` and ``data`` (the lazy frame cubes, centroid tables and per-hole
        calibrations, for figures and :class:`sunlab.widgets.HoleExplorer`; not written).

    Examples
    --------
    The columns (a run renders 100-hole frames: minutes even thinned, so not run here):

    >>> COLUMNS[2], REJECTION_COLUMN
    ('1 hole', '100 holes: averaging + rejection')
    >>> res = reproduce_table5(step=4, shots=1, progress=False)  # doctest: +SKIP
    >>> res["table"].loc[("alpha", "mu")]  # doctest: +SKIP
    """
    t0 = time.perf_counter()
    plans_ = experiment_plans(("I", "II", "III"), quick=quick, step=step, shots=shots)
    where, timings = {"address": address, "scheduler": scheduler, "workers": workers}, {}
    with parallel.worker_pool(scheduler, workers, address) as pool:  # warms up meanwhile
        result, cens, status = _simulate_locate_calibrate(
            plans_, seed=seed, method=method, progress=progress, where=where, pool=pool,
            timings=timings, order=order)
    result.update(_identification(), centroid_status=status)
    result["sizes"] = {"train_poses": len(plans_["I"]), "test_poses": len(plans_["III"]),
                       "shots": plans_["I"].shots, "holes": int(cens["100 holes I"].sizes["hole"])}
    if out is not None:
        t = time.perf_counter()
        result["files"] = _write_figures(result, Path(out))
        timings["figures"] = time.perf_counter() - t
    result["runtime_s"] = time.perf_counter() - t0
    result["timings_s"] = {**{k: round(v, 3) for k, v in timings.items()},
                           "total": round(result["runtime_s"], 3)}
    if out is not None:
        result["files"].append(_write_json(result, Path(out), {
            "quick": quick, "seed": seed, "order": result["order"], "centroid_method": method}))
    return result


def _write_json(result: dict, out: Path, settings: dict) -> str:
    """``table5.json``: the table, the bad holes, the budget, sizes, timings and settings."""
    doc = {"table5": {f"{c[0]} [{c[1]}]": {f"{a}.{st}": float(v) for (a, st), v in
                                            result["table"][c].items()}
                      for c in result["table"].columns},
           **{k: result[k] for k in ("bad_holes", "injected", "budget", "sizes", "runtime_s",
                                     "timings_s")},
           "quick": settings["quick"], "centroid_status": result["centroid_status"],
           "findings": result["findings"], "seed": settings["seed"],
           "order": settings["order"], "centroid_method": settings["centroid_method"],
           "settings": {"hypothesis": result["hypothesis"]},
           "interval90": result["interval90"]}
    return write_json(doc, out / "table5.json")


def _identification() -> dict:
    """The presets' hypothesis and each published cell's 90 % predictive interval
    (docs/identification.md), keyed as table5.json's ``[sunlab]`` rows."""
    from ..studies import identification

    return {"hypothesis": identification.identified_hypothesis(),
            "interval90": identification.interval90("table5")}


def format_table5(result: dict) -> str:
    """Table 5 as text: each published cell as paper / ours / our 90 % interval.

    Parameters
    ----------
    result : dict
        :func:`reproduce_table5`'s result.

    Returns
    -------
    str
    """
    from .. import stats
    from .table4 import _span

    keys = [(a, st) for a in stats.ANGLES for st in stats.STATS]
    lines = ["Table 5 - polynomial calibration, 100 holes vs one hole (deg)",
             "paper = the 2005 preprint; ours = sunlab virtual bench (simulated frames); our 90 % "
             "interval = the identified bench's predictive interval (docs/identification.md)",
             "", f"{'column':<34s}" + "".join(f"{a[0] + ' ' + st:>12s}" for a, st in keys)]
    table, iv = result["table"], result.get("interval90", {})
    for col in (*COLUMNS, REJECTION_COLUMN):
        if (col, "paper") in table.columns:
            lines.append(f"{col:<34s}" + "".join(
                f"{table.loc[k, (col, 'paper')]:12.4f}" for k in keys) + "   paper")
            lines.append(f"{'':<34s}" + "".join(
                f"{table.loc[k, (col, 'sunlab')]:12.4f}" for k in keys) + "   ours")
        else:
            lines.append(f"{col:<34s}" + "".join(
                f"{table.loc[k, (col, 'sunlab')]:12.4f}" for k in keys) + "   ours")
        cell = iv.get(f"{col} [sunlab]")
        if cell:
            lines.append(f"{'':<34s}" + "".join(
                f"{_span(*cell[f'{a}.{st}']):>12s}" for a, st in keys) + "   our 90 % interval")
    return "\n".join(lines)


def _simulate_locate_calibrate(plans_: dict, *, seed, method, progress, where, pool, timings,
                               order) -> tuple[dict, dict, dict]:
    """Every pass of the table on one pool of workers (:func:`sunlab.parallel.worker_pool`):
    the one-hole runs I and III, whose spot gives the mounting offset that numbers the 100
    spots; the 100-hole run I; then the 100-hole run III on the workers from a background
    thread while the calibrations are fitted on I (:func:`_calibrate`, serial, in this
    process); last the comparison on III. The result of :func:`_compare`, the centroid
    tables (keyed ``"1 hole I"``, ``"100 holes III"`` ...) and their
    :func:`centroid_status`; the stages' times go into ``timings``."""
    from .. import sim

    one = {f"1 hole {k}": (p, sim.Bench.paper_single_hole()) for k, p in plans_.items()}
    many = {f"100 holes {k}": (p, sim.Bench.paper_multi_hole()) for k, p in plans_.items()
            if k != "II"}  # the order is chosen on the one hole's II
    t = time.perf_counter()
    cens = locate_runs(simulate_runs(one, seed=seed, chunks="pose"), method=method,
                       progress=progress, pool=pool, **where)
    timings["simulate_and_centroid 1 hole"] = time.perf_counter() - t
    one_hole, order = _one_hole_polynomial(cens, order)
    # the passes take whole poses (one Dask task each); the cubes handed on serve single
    # frames (defect metrics, figures, the explorer), so they are chunked by frame: the same
    # frames either way
    cubes = simulate_runs({**one, **many}, seed=seed, chunks="frame")
    kw = {"method": spot_method(method), "hole_offset": mounting_offset_px(cens["1 hole I"]),
          "progress": progress, "pool": pool, **where}
    t = time.perf_counter()
    cens.update(locate_runs(simulate_runs({"100 holes I": many["100 holes I"]}, seed=seed,
                                          chunks="pose"), **kw))
    timings["simulate_and_centroid 100 holes I"] = time.perf_counter() - t
    status = centroid_status(cens)
    cens = {k: usable_table(c) for k, c in cens.items()}
    with ThreadPoolExecutor(1, thread_name_prefix="sunlab-100-III") as ex:
        t = time.perf_counter()
        third = ex.submit(locate_runs, simulate_runs({"100 holes III": many["100 holes III"]},
                                                    seed=seed, chunks="pose"), **kw)
        fitted = _calibrate(cens["100 holes I"], cubes["100 holes I"], order=order,
                            beside_pool=pool is not None)
        timings["calibrate, find bad holes (beside 100 holes III)"] = time.perf_counter() - t
        test = third.result()
        timings["simulate_and_centroid 100 holes III"] = time.perf_counter() - t
    status.update(centroid_status(test))
    cens["100 holes III"] = usable_table(test["100 holes III"])
    t = time.perf_counter()
    result = _compare(fitted, cens, cubes, one_hole=one_hole)
    result["order"] = order
    timings["compare"] = time.perf_counter() - t
    names = ("100 holes I", "100 holes III", "1 hole I", "1 hole III")
    return result, {k: cens[k] for k in names}, {k: status[k] for k in names}


def _calibrate(cen_tr, cube_tr, *, order: int, beside_pool: bool = False) -> dict:
    """The strategies of :mod:`sunlab.multihole` fitted on I, and the bad holes found from
    the training frames (spot-shape metrics and the edge roughness that finds burrs).

    ``beside_pool``: a pool of worker processes is busy with another run meanwhile, so the
    frames the metrics sample are rendered here, one after the other (a request to the busy
    pool would wait behind its queue each time: 18 s instead of 8 in Table 5).
    """
    import contextlib

    import dask

    from .. import multihole as mh

    s1 = mh.GeometricCentre(order=order).fit(cen_tr)
    s2 = mh.PerHoleAverage(order=order).fit(cen_tr)
    here = dask.config.set(scheduler="synchronous") if beside_pool else contextlib.nullcontext()
    with here:
        metrics = mh.defect_metrics(cen_tr, strategy=s2, cube=cube_tr)
    bad = mh.reject_bad_holes(metrics).values
    s2r = mh.PerHoleAverage(order=order, holes=~bad, weighting="inverse_variance", clip=4.0,
                            calibrations_=s2.calibrations_, variance_=s2.variance_)
    return {"geometric centre": s1, "averaging": s2, "rejection": s2r, "metrics": metrics,
            "bad": bad}


def _one_hole_polynomial(cens: dict, order: int | None):
    """The one hole's polynomial on I and the order of every calibration of the table: chosen
    on the one hole's II as Table 4 chooses it (the larger of its orders for the 100-hole
    strategies, which take one order), unless ``order`` is given."""
    from ..calibration import Polynomial
    from ..calibration.methods import POLYNOMIAL_REFIT

    train = usable_table(cens["1 hole I"])
    if order is not None:
        return Polynomial(order).fit(train), int(order)
    best, _ = Polynomial.select_order(train, usable_table(cens["1 hole II"]),
                                      refit=POLYNOMIAL_REFIT)
    return best, int(max(best.orders))


def _compare(fitted: dict, cens: dict, cubes: dict, *, one_hole) -> dict:
    """The fitted strategies applied to III beside the one hole's polynomial; the statistics,
    the bad holes, the error budget and what the figures need."""
    from .. import multihole as mh
    from .. import stats

    cen_tr, cen_te = cens["100 holes I"], cens["100 holes III"]
    s2, bad, metrics = fitted["averaging"], fitted["bad"], fitted["metrics"]
    est = s2.predict_holes(cen_te)
    preds = {
        COLUMNS[0]: fitted["geometric centre"].predict(cen_te),
        COLUMNS[1]: s2.combine(est),
        COLUMNS[2]: one_hole.predict(cens["1 hole III"]),
        REJECTION_COLUMN: fitted["rejection"].combine(est),
    }
    ours = stats.global_stats({k: stats.local_errors(v) for k, v in preds.items()})
    table = stats.side_by_side(ours[list(COLUMNS)], stats.paper_table5())
    table[(REJECTION_COLUMN, "sunlab")] = ours[REJECTION_COLUMN]
    injected = (np.flatnonzero(cen_tr["hole_defect"].values).tolist()
                if "hole_defect" in cen_tr.coords else [])
    return {
        "table": table,
        "ours": ours,
        "bad_holes": np.flatnonzero(bad).tolist(),
        "injected": injected,
        "budget": mh.error_budget(est, holes=~bad),
        "metrics": metrics,
        "findings": _findings(ours),
        "files": [],
        # what the figures and the hole explorer need (lazy cubes, not written to disk)
        "data": {"cube_train": cubes["100 holes I"], "centroids_train": cen_tr,
                 "cube_test": cubes["100 holes III"], "centroids_test": cen_te,
                 "strategy": s2, "one_hole_test": cens["1 hole III"]},
    }


def _write_figures(result: dict, out: Path) -> list[str]:
    """``table5.csv``, ``hole_metrics.csv`` and Figs. 13-15 under ``out``; the paths."""
    import matplotlib.pyplot as plt

    from .. import atomic, plots
    from .. import multihole as mh

    metrics, ours = result["metrics"], result["ours"]
    bad = np.isin(np.arange(metrics.sizes["hole"]), result["bad_holes"])
    show = (result["bad_holes"] or result["injected"])[:5]
    cen, frames = result["data"]["centroids_test"], result["data"]["cube_test"]["frames"]
    p13 = int(np.argmax(mh.usable(cen).values[:, 0, :].sum(axis=1)))  # the most spots whole
    p14, ref = _fig14_pose(cen, show, bad)
    figs = {
        "fig13.png": plots.fig13_frame(frames.isel(pose=p13, shot=0).values,
                                       cen.isel(pose=p13, shot=0), bad=bad),
        "fig14.png": plots.fig14_bad_holes(frames.isel(pose=p14, shot=0).values,
                                           cen.isel(pose=p14, shot=0), show, reference=ref,
                                           metrics=metrics),
        "fig15.png": plots.fig15_rectangles(
            {k: {a: {"M": float(ours.loc[(a, "M"), k]),
                     "sigma_M": float(ours.loc[(a, "sigma_M"), k])} for a in ("alpha", "beta")}
             for k in ours.columns}),
    }
    names = [*figs, "table5.csv", "hole_metrics.csv"]
    out.parent.mkdir(parents=True, exist_ok=True)
    # every file or none: an interrupted run leaves the previous results (sunlab.atomic)
    with atomic.atomic_files(out, names, overwrite=True, flag="") as tmp:
        for name, fig in figs.items():
            fig.savefig(tmp / name, dpi=110)
            plt.close(fig)
        result["table"].to_csv(tmp / "table5.csv")
        metrics.to_dataframe().to_csv(tmp / "hole_metrics.csv")
    return [str(out / name) for name in names]


def _fig14_pose(cen, holes, bad) -> tuple[int, int]:
    """The pose whose first shot shows the most of ``holes`` whole on the detector (the
    mask's spots do not all fit on it at any one pose), and a good hole seen whole there as the
    reference of Fig. 14.

    Examples
    --------
    >>> from sunlab import schema
    >>> st = np.zeros((3, 1, 4), int); st[0, 0, 2] = st[2, 0, 0] = schema.STATUS["no_spot"]
    >>> cen = schema.centroids_dataset(np.ones((3, 1, 4)), np.ones((3, 1, 4)), status=st)
    >>> _fig14_pose(cen, [2, 3], np.array([False, False, True, True]))
    (1, 0)
    """
    from .. import multihole as mh

    seen = mh.usable(cen).values[:, 0, :]  # (pose, hole)
    p = int(np.argmax(seen[:, list(holes)].sum(axis=1))) if len(holes) else 0
    good = np.flatnonzero(~np.asarray(bad) & seen[p])
    return p, int(good[0] if good.size else np.flatnonzero(~np.asarray(bad))[0])
