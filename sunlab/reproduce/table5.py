"""Reproduce the paper's Table 5 (100 holes vs one hole) and Figs. 13-15 on the virtual bench.

Called by ``sunlab reproduce --table 5``. Experiments I (calibration) and III (test) of Table 3
are simulated with the 100-hole mask (:meth:`sunlab.sim.Bench.paper_multi_hole`: platform
per-pose error, mask play, random bad holes) and with the one-hole mask; the spots are centroided
(:func:`sunlab.centroid.locate`), a polynomial calibration is fitted for each strategy of
:mod:`sunlab.multihole` and the paper's statistics are computed on experiment III.

Columns: the paper's three (geometric centre, averaging, 1 hole), each beside our value, and our
extra column: the average after automatic bad-hole rejection with inverse-variance weights and
sigma clipping.

The frames go through the pipeline the other tables share
(:func:`multi_hole_tables`: rendered and centroided once, on one
pool of workers: the one-hole runs, whose spot gives the mounting offset that numbers the 100
spots, then the 100-hole runs I and III, and the per-hole metrics that need the frames);
:func:`table5_statistics` is a function of the centroid tables it returns. Quick mode is the
pipeline's :data:`~sunlab.reproduce.pipeline.QUICK`, as for Table 4: every 2nd angle along each
grid axis (experiments I and III: 100 + 100 poses instead of 400 + 361) and 2 shots per pose
instead of 8.

Examples
--------
>>> from sunlab.reproduce.table5 import COLUMNS
>>> COLUMNS[2]
'1 hole'
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np
import xarray as xr

from .. import multihole as mh
from .. import parallel, sim, stats
from ..calibration import Polynomial
from ..calibration.registry import POLYNOMIAL_REFIT
from ..errors import ConfigurationError
from ..multihole.defects import DEFECT_METRICS, residual_metrics
from . import pipeline as pl
from .intervals import identified, stat_lines

__all__ = ["reproduce_table5"]

#: The paper's column labels (:func:`sunlab.stats.paper_table5`).
COLUMNS = ("100 holes: geometric centre", "100 holes: averaging", "1 hole")
#: Our extra column.
REJECTION_COLUMN = "100 holes: averaging + rejection"


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
        Polynomial order of every calibration. Default: chosen on the one-hole mask's
        experiment II by Table 4's rule (:meth:`sunlab.calibration.Polynomial.select_order`);
        the 100-hole strategies take the larger of its two orders.
    method : str
        Centroid method of every frame (:func:`sunlab.centroid.locate`), the same as Table 4's
        (default ``"projection"``, algorithm B: the paper presents it as its method and names
        no other for its experiments, so we infer it used B for both tables). On the 100-hole
        frames each spot gets the estimator ``pipeline.spot_method`` names (a tight window for the
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
        findings), ``runtime_s``, ``timings_s`` (by stage), ``sizes``,
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
    plans_ = pl.experiment_plans(("I", "II", "III"), quick=quick, step=step, shots=shots)
    tables, hole_metrics, cubes = multi_hole_tables(
        plans_, seed=seed, method=method, progress=progress, address=address,
        scheduler=scheduler, workers=workers)
    timings = {"simulate_and_centroid": time.perf_counter() - t0}
    t = time.perf_counter()
    result = table5_statistics(tables, hole_metrics, order=order)
    timings["calibrate, find bad holes, compare"] = time.perf_counter() - t
    result["data"].update(cube_train=cubes["100 holes I"], cube_test=cubes["100 holes III"])
    result.update(identified("table5"))
    if out is not None:
        t = time.perf_counter()
        result["files"] = _write_figures(result, Path(out))
        timings["figures"] = time.perf_counter() - t
    result["runtime_s"] = time.perf_counter() - t0
    result["timings_s"] = {**{k: round(v, 3) for k, v in timings.items()},
                           "total": round(result["runtime_s"], 3)}
    if out is not None:
        result["files"].append(_write_json(result, Path(out), quick=quick, seed=seed,
                                           method=method))
    return result


def _write_json(result: dict, out: Path, *, quick: bool, seed: int, method: str) -> str:
    """``table5.json``: the table, the bad holes, the budget, sizes, timings and settings."""
    doc = {"table5": pl.cells(result["table"], name=lambda c: f"{c[0]} [{c[1]}]"),
           **{k: result[k] for k in ("bad_holes", "injected", "budget", "sizes", "runtime_s",
                                     "timings_s")},
           "quick": quick, "centroid_status": result["centroid_status"],
           "findings": result["findings"], "seed": seed, "order": result["order"],
           "centroid_method": method, "settings": {"hypothesis": result["hypothesis"]},
           "interval90": result["interval90"], "interval_role": result["interval_role"]}
    return pl.write_json(doc, out / "table5.json")


def multi_hole_tables(plans_: dict, *, seed: int = 0, method: str = "projection",
                      progress: bool = True, address: str | None = None,
                      scheduler: str = "threads", workers: int | None = None) -> tuple:
    """Render and centroid Table 5's runs once, one pool of workers for every pass
    (:func:`sunlab.parallel.worker_pool`): the one-hole runs I, II, III first, whose spot gives
    the mounting offset (:func:`mounting_offset_px`) that numbers the 100 spots; then the
    100-hole runs I and III in one pass; last the per-hole metrics of the 100-hole run I that
    need its frames (spot shape, edge roughness: :func:`sunlab.multihole.defect_metrics`).

    Parameters
    ----------
    plans_ : dict of str to sunlab.plans.Plan
        Experiments ``"I"``, ``"II"``, ``"III"`` (:func:`experiment_plans`); the 100-hole mask
        runs I and III (the order is chosen on the one hole's II).
    seed : int
        Seed of the virtual bench.
    method : str
        Centroid method of the one-hole frames; the 100-hole frames get ``pipeline.spot_method``'s.
    progress : bool
        Show progress bars.
    address, scheduler, workers
        Where the frames are rendered and centroided (:func:`locate_runs`).

    Returns
    -------
    tables : dict of str to xarray.Dataset
        ``centroids/1`` tables keyed ``"1 hole I"``, ``"1 hole II"``, ``"1 hole III"``,
        ``"100 holes I"``, ``"100 holes III"``, every centroid status kept; the 100-hole tables
        on (pose, shot, hole) with the design positions ``hole_x_cf``, ``hole_y_cf`` (px).
    hole_metrics : xarray.Dataset
        :func:`sunlab.multihole.defect_metrics` of the usable 100-hole run I with its frames
        and no strategy (the residual metrics need a fitted calibration: Table 5 adds them).
    cubes : dict of str to xarray.Dataset
        The lazy frame cubes, keyed as ``tables`` and chunked by frame, for figures and
        :class:`sunlab.widgets.HoleExplorer` (the same frames the tables were measured on).

    """

    one = {f"1 hole {k}": (p, sim.Bench.paper_single_hole()) for k, p in plans_.items()}
    many = {f"100 holes {k}": (p, sim.Bench.paper_multi_hole()) for k, p in plans_.items()
            if k != "II"}
    where = {"progress": progress, "address": address, "scheduler": scheduler,
             "workers": workers}
    with parallel.worker_pool(scheduler, workers, address) as pool:
        tables = pl.locate_runs(pl.simulate_runs(one, seed=seed), method=method, pool=pool, **where)
        tables.update(pl.locate_runs(pl.simulate_runs(many, seed=seed),
                                     method=pl.spot_method(method), pool=pool,
                                     hole_offset=pl.mounting_offset_px(tables["1 hole I"]),
                                     **where))
    # the passes take whole poses (one Dask task each); the cubes handed on serve single
    # frames (the metrics sample frames, figures, the explorer), so they are chunked by frame:
    # the same frames either way
    cubes = pl.simulate_runs({**one, **many}, seed=seed, chunks="frame")
    hole_metrics = mh.defect_metrics(pl.usable_table(tables["100 holes I"]),
                                     cube=cubes["100 holes I"])
    return tables, hole_metrics, cubes



def table5_statistics(tables: dict, hole_metrics, *, order: int | None = None) -> dict:
    """Table 5 from the centroid tables: the one hole's polynomial and every strategy of
    :mod:`sunlab.multihole` fitted on I, the bad holes found, each applied to III, and the
    paper's statistics (:mod:`sunlab.stats`) beside the paper's values.

    Nothing is rendered or centroided here: the same tables give the same table.

    Parameters
    ----------
    tables : dict of str to xarray.Dataset
        ``centroids/1`` tables keyed ``"1 hole I"``, ``"1 hole II"``, ``"1 hole III"``,
        ``"100 holes I"``, ``"100 holes III"``, as centroided (every status;
        :func:`~sunlab.reproduce.pipeline.usable_table` selects here):
        :func:`multi_hole_tables`.
    hole_metrics : xarray.Dataset
        The per-hole defect metrics of the 100-hole run I without the residual ones
        (:func:`sunlab.multihole.defect_metrics` with its frames and no strategy); the
        residual metrics of the averaging strategy are added here.
    order : int, optional
        Polynomial order of every calibration. Default: chosen on the one hole's II by the
        rule of Table 4's polynomial (:meth:`sunlab.calibration.Polynomial.select_order`); the
        100-hole strategies take the larger of its two orders.

    Returns
    -------
    dict
        ``table`` (pandas.DataFrame: our value and the paper's per column, deg), ``ours`` (our
        four columns, deg), ``bad_holes`` (rejected), ``injected`` (holes the bench gave
        defects), ``budget`` (common vs hole-specific error), ``metrics`` (every defect
        metric), ``findings`` (the ratios of the paper's findings), ``order``,
        ``centroid_status`` (:func:`~sunlab.reproduce.pipeline.centroid_status`), ``sizes``,
        ``files`` (empty) and ``data`` (centroid tables and the averaging strategy, for figures
        and :class:`sunlab.widgets.HoleExplorer`).
    """

    names = ("100 holes I", "100 holes III", "1 hole I", "1 hole III")
    missing = [k for k in (*names, "1 hole II") if k not in tables]
    if missing:
        raise ConfigurationError(
            f"tables: missing {missing}. Fix: the tables of multi_hole_tables(...).")
    cens = {k: pl.usable_table(tables[k]) for k in (*names, "1 hole II")}
    one_hole, order = _one_hole_polynomial(cens, order)
    cen_tr, cen_te = cens["100 holes I"], cens["100 holes III"]
    s2, metrics, bad, est, preds = _strategies(cen_tr, cen_te, hole_metrics, order)
    preds[COLUMNS[2]] = one_hole.predict(cens["1 hole III"])
    ours = stats.evaluate({k: preds[k] for k in (*COLUMNS, REJECTION_COLUMN)})
    table = stats.side_by_side(ours[list(COLUMNS)], stats.paper_table5())
    table[(REJECTION_COLUMN, "sunlab")] = ours[REJECTION_COLUMN]
    mu = ours.xs("mu", level=1)
    many = (COLUMNS[0], COLUMNS[1], REJECTION_COLUMN)
    size = tables["100 holes I"].sizes
    return {
        "table": table, "ours": ours, "bad_holes": np.flatnonzero(bad).tolist(),
        "injected": (np.flatnonzero(cen_tr["hole_defect"].values).tolist()
                     if "hole_defect" in cen_tr.coords else []),
        "budget": mh.error_budget(est, holes=~bad), "metrics": metrics,
        # the paper's findings: one hole's alpha mu over each 100-hole column's (about 2),
        # each 100-hole column's beta mu over one hole's (above 1)
        "findings": {"alpha_gain": {k: float(mu.loc["alpha", COLUMNS[2]] / mu.loc["alpha", k])
                                    for k in many},
                     "beta_loss": {k: float(mu.loc["beta", k] / mu.loc["beta", COLUMNS[2]])
                                   for k in many}},
        "files": [],
        # what the figures and the hole explorer need (not written); the caller adds the cubes
        "data": {"centroids_train": cen_tr, "centroids_test": cen_te, "strategy": s2,
                 "one_hole_test": cens["1 hole III"]},
        "order": order, "centroid_status": pl.centroid_status({k: tables[k] for k in names}),
        "sizes": {"train_poses": int(size["pose"]),
                  "test_poses": int(tables["100 holes III"].sizes["pose"]),
                  "shots": int(size["shot"]), "holes": int(size["hole"])},
    }


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
    table = result["table"]
    plain = {k: {c.removesuffix(" [sunlab]"): v for c, v in result.get(k, {}).items()}
             for k in ("interval90", "interval_role")}
    lines = stat_lines("Table 5 - polynomial calibration, 100 holes vs one hole (deg)", "column",
                       34, table.xs("paper", axis=1, level=1),
                       table.xs("sunlab", axis=1, level=1)[[*COLUMNS, REJECTION_COLUMN]],
                       plain["interval90"], plain["interval_role"])
    return "\n".join(lines)


def _one_hole_polynomial(cens: dict, order: int | None):
    """The one hole's polynomial on I and the order of every calibration of the table: chosen
    on the one hole's II as Table 4 chooses it (the larger of its orders for the 100-hole
    strategies, which take one order), unless ``order`` is given."""

    if order is not None:
        return Polynomial(order).fit(cens["1 hole I"]), int(order)
    best, _ = Polynomial.select_order(cens["1 hole I"], cens["1 hole II"], refit=POLYNOMIAL_REFIT)
    return best, int(max(best.orders))


def _strategies(cen_tr, cen_te, hole_metrics, order: int):
    """The strategies of :mod:`sunlab.multihole` fitted on I, the bad holes found from the
    training run's defect metrics (spot shape and the edge roughness that finds burrs, with the
    averaging's residual metrics added as :func:`sunlab.multihole.defect_metrics` adds them),
    the per-hole estimates on III and each 100-hole column's estimate."""

    s2 = mh.PerHoleAverage(order=order).fit(cen_tr)
    metrics = _with_residual_metrics(hole_metrics, s2, cen_tr)
    bad = mh.reject_bad_holes(metrics).values
    s2r = mh.PerHoleAverage(order=order, holes=~bad, weighting="inverse_variance", clip=4.0,
                            calibrations_=s2.calibrations_, variance_=s2.variance_)
    est = s2.predict_holes(cen_te)
    return s2, metrics, bad, est, {
        COLUMNS[0]: mh.GeometricCentre(order=order).fit(cen_tr).predict(cen_te),
        COLUMNS[1]: s2.combine(est), REJECTION_COLUMN: s2r.combine(est)}


def _with_residual_metrics(hole_metrics, strategy, cen):
    """``hole_metrics`` (:func:`sunlab.multihole.defect_metrics` without a strategy) with the
    residual metrics of the fitted ``strategy`` on ``cen`` added: the dataset that
    ``defect_metrics(cen, strategy=strategy, ...)`` gives, variables in its order (the data,
    then the hole coordinates: the columns of ``hole_metrics.csv``)."""


    rm = residual_metrics(strategy.predict_holes(cen))
    data = {k: hole_metrics[k].variable for k in hole_metrics.data_vars}
    data.update({k: ("hole", rm[k].values, {**rm[k].attrs, "long_name": DEFECT_METRICS[k]})
                 for k in rm.data_vars})
    return xr.Dataset(data, coords={k: hole_metrics[k].variable for k in hole_metrics.coords})


def _write_figures(result: dict, out: Path) -> list[str]:
    """``table5.csv``, ``hole_metrics.csv`` and Figs. 13-15 under ``out``; the paths."""
    from .. import plots

    metrics, ours = result["metrics"], result["ours"]
    bad = np.isin(np.arange(metrics.sizes["hole"]), result["bad_holes"])
    show = (result["bad_holes"] or result["injected"])[:5]
    cen, frames = result["data"]["centroids_test"], result["data"]["cube_test"]["frames"]
    p13 = int(np.argmax(mh.holes.usable(cen).values[:, 0, :].sum(axis=1)))  # the most spots whole
    p14, ref = _fig14_pose(cen, show, bad)
    return pl.write_files(out, {
        "fig13.png": plots.fig13_frame(frames.isel(pose=p13, shot=0).values,
                                       cen.isel(pose=p13, shot=0), bad=bad),
        "fig14.png": plots.fig14_bad_holes(frames.isel(pose=p14, shot=0).values,
                                           cen.isel(pose=p14, shot=0), show, reference=ref,
                                           metrics=metrics),
        "fig15.png": plots.fig15_rectangles(
            {k: {a: {"M": float(ours.loc[(a, "M"), k]),
                     "sigma_M": float(ours.loc[(a, "sigma_M"), k])} for a in ("alpha", "beta")}
             for k in ours.columns}),
        "table5.csv": result["table"].to_csv,
        "hole_metrics.csv": lambda path: metrics.to_dataframe().to_csv(path)})


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

    seen = mh.holes.usable(cen).values[:, 0, :]  # (pose, hole)
    p = int(np.argmax(seen[:, list(holes)].sum(axis=1))) if len(holes) else 0
    good = np.flatnonzero(~np.asarray(bad) & seen[p])
    return p, int(good[0] if good.size else np.flatnonzero(~np.asarray(bad))[0])
