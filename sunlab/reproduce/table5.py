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
(:func:`sunlab.reproduce.pipeline.multi_hole_tables`: rendered and centroided once, on one
pool of workers: the one-hole runs, whose spot gives the mounting offset that numbers the 100
spots, then the 100-hole runs I and III, and the per-hole metrics that need the frames);
:func:`table5_statistics` is a function of the centroid tables it returns. Quick mode is the
pipeline's :data:`~sunlab.reproduce.pipeline.QUICK`, as for Table 4: every 2nd angle along each
grid axis (experiments I and III: 100 + 100 poses instead of 400 + 361) and 2 shots per pose
instead of 8.

Examples
--------
>>> from sunlab.reproduce.table5 import spot_method
>>> spot_method("projection"), spot_method("fit")
('tight', 'fit')
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..errors import ConfigurationError
from .pipeline import (
    SPOT_METHODS,  # noqa: F401 (where Table 5's readers look for them)
    centroid_status,
    experiment_plans,
    mounting_offset_px,  # noqa: F401
    multi_hole_tables,
    spot_method,  # noqa: F401
    usable_table,
    write_json,
)

__all__ = ["reproduce_table5", "COLUMNS", "REJECTION_COLUMN", "format_table5"]

#: The paper's column labels (:func:`sunlab.stats.paper_table5`).
COLUMNS = ("100 holes: geometric centre", "100 holes: averaging", "1 hole")
#: Our extra column.
REJECTION_COLUMN = "100 holes: averaging + rejection"


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
        Polynomial order of every calibration. Default: chosen on the one-hole mask's
        experiment II by Table 4's rule (:meth:`sunlab.calibration.Polynomial.select_order`);
        the 100-hole strategies take the larger of its two orders.
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
    tables, hole_metrics, cubes = multi_hole_tables(
        plans_, seed=seed, method=method, progress=progress, address=address,
        scheduler=scheduler, workers=workers)
    timings = {"simulate_and_centroid": time.perf_counter() - t0}
    t = time.perf_counter()
    result = table5_statistics(tables, hole_metrics, order=order)
    timings["calibrate, find bad holes, compare"] = time.perf_counter() - t
    result["data"].update(cube_train=cubes["100 holes I"], cube_test=cubes["100 holes III"])
    result.update(_identification())
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
        :func:`~sunlab.reproduce.pipeline.multi_hole_tables`.
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

    Examples
    --------
    Its tables come from 100-hole frames (minutes even thinned), so not run here:

    >>> from sunlab.reproduce.pipeline import experiment_plans, multi_hole_tables
    >>> plans_ = experiment_plans(step=4, shots=1)
    >>> res = table5_statistics(*multi_hole_tables(plans_, progress=False)[:2])  # doctest: +SKIP
    >>> res["table"].loc[("alpha", "mu")]  # doctest: +SKIP
    """
    names = ("100 holes I", "100 holes III", "1 hole I", "1 hole III")
    missing = [k for k in (*names, "1 hole II") if k not in tables]
    if missing:
        raise ConfigurationError(
            f"tables: missing {missing}. Fix: the tables of multi_hole_tables(...).")
    one_hole, order = _one_hole_polynomial(tables, order)
    cens = {k: usable_table(tables[k]) for k in names}
    fitted = _calibrate(cens["100 holes I"], hole_metrics, order=order)
    result = _compare(fitted, cens, one_hole=one_hole)
    result["order"] = order
    result["centroid_status"] = centroid_status({k: tables[k] for k in names})
    result["sizes"] = {"train_poses": int(tables["100 holes I"].sizes["pose"]),
                       "test_poses": int(tables["100 holes III"].sizes["pose"]),
                       "shots": int(tables["100 holes I"].sizes["shot"]),
                       "holes": int(tables["100 holes I"].sizes["hole"])}
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


def _calibrate(cen_tr, hole_metrics, *, order: int) -> dict:
    """The strategies of :mod:`sunlab.multihole` fitted on I, and the bad holes found from
    the training run's defect metrics (``hole_metrics``, which hold the spot-shape metrics and
    the edge roughness that finds burrs, and the averaging strategy's residual metrics added
    here, as :func:`sunlab.multihole.defect_metrics` adds them)."""
    from .. import multihole as mh

    s1 = mh.GeometricCentre(order=order).fit(cen_tr)
    s2 = mh.PerHoleAverage(order=order).fit(cen_tr)
    metrics = _with_residual_metrics(hole_metrics, s2, cen_tr)
    bad = mh.reject_bad_holes(metrics).values
    s2r = mh.PerHoleAverage(order=order, holes=~bad, weighting="inverse_variance", clip=4.0,
                            calibrations_=s2.calibrations_, variance_=s2.variance_)
    return {"geometric centre": s1, "averaging": s2, "rejection": s2r, "metrics": metrics,
            "bad": bad}


def _with_residual_metrics(hole_metrics, strategy, cen):
    """``hole_metrics`` (:func:`sunlab.multihole.defect_metrics` without a strategy) with the
    residual metrics of the fitted ``strategy`` on ``cen`` added: the dataset that
    ``defect_metrics(cen, strategy=strategy, ...)`` gives, variables in its order (the data,
    then the hole coordinates: the columns of ``hole_metrics.csv``)."""
    import xarray as xr

    from ..multihole.defects import DEFECT_METRICS, residual_metrics

    rm = residual_metrics(strategy.predict_holes(cen))
    data = {k: hole_metrics[k].variable for k in hole_metrics.data_vars}
    data.update({k: ("hole", rm[k].values, {**rm[k].attrs, "long_name": DEFECT_METRICS[k]})
                 for k in rm.data_vars})
    return xr.Dataset(data, coords={k: hole_metrics[k].variable for k in hole_metrics.coords})


def _one_hole_polynomial(cens: dict, order: int | None):
    """The one hole's polynomial on I and the order of every calibration of the table: chosen
    on the one hole's II as Table 4 chooses it (the larger of its orders for the 100-hole
    strategies, which take one order), unless ``order`` is given."""
    from ..calibration import Polynomial
    from ..calibration.registry import POLYNOMIAL_REFIT

    train = usable_table(cens["1 hole I"])
    if order is not None:
        return Polynomial(order).fit(train), int(order)
    best, _ = Polynomial.select_order(train, usable_table(cens["1 hole II"]),
                                      refit=POLYNOMIAL_REFIT)
    return best, int(max(best.orders))


def _compare(fitted: dict, cens: dict, *, one_hole) -> dict:
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
    ours = stats.evaluate(preds)
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
        # what the figures and the hole explorer need (not written to disk); the caller adds
        # the lazy frame cubes
        "data": {"centroids_train": cen_tr, "centroids_test": cen_te,
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
