"""Reproduce the paper's Table 5 (100 holes vs one hole) and Figs. 13-15 on the virtual bench.

Called by ``sunlab reproduce --table 5``. Experiments I (calibration) and III (test) of Table 3
are simulated with the 100-hole mask (:meth:`sunlab.sim.Bench.paper_multi_hole`: platform
per-pose error, mask play, random bad holes) and with the one-hole mask; the spots are centroided
(:func:`sunlab.centroid.locate`), a polynomial calibration is fitted for each strategy of
:mod:`sunlab.multihole` and the paper's statistics are computed on experiment III.

Columns: the paper's three (geometric centre, averaging, 1 hole), each beside our value, and our
extra column: the average after automatic bad-hole rejection with inverse-variance weights and
sigma clipping.

Examples
--------
>>> from sunlab.reproduce_table5 import reproduce_table5
>>> callable(reproduce_table5)
True
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

__all__ = ["reproduce_table5", "COLUMNS", "REJECTION_COLUMN"]

#: The paper's column labels (:func:`sunlab.stats.paper_table5`).
COLUMNS = ("100 holes: geometric centre", "100 holes: averaging", "1 hole")
#: Our extra column.
REJECTION_COLUMN = "100 holes: averaging + rejection"


def _plans(quick: bool):
    from . import plans

    shots = 2 if quick else 8
    train = plans.experiment("I", shots=shots)
    test = plans.experiment("III", shots=shots)
    if quick:
        train, test = train.subset(2), test.subset(2)
    return train, test


def reproduce_table5(quick: bool = True, seed: int = 0, out: Path | str | None = None,
                     progress: bool = True, *, order: int = 5, method: str = "tight") -> dict:
    """Table 5 and Figs. 13-15, simulated, with the paper's values beside ours.

    Parameters
    ----------
    quick : bool
        Every other pose and 2 shots per pose (full: 400 + 361 poses x 8 shots).
    seed : int
        Seed of the virtual bench.
    out : path, optional
        Folder for ``table5.csv``, ``table5.json``, ``hole_metrics.csv``, ``fig13.png``,
        ``fig14.png``, ``fig15.png``.
    progress : bool
        Show progress bars.
    order : int
        Polynomial order of every calibration (the paper picks it on experiment II; 5 here).
    method : str
        Centroid method of the 100-hole frames (:func:`sunlab.centroid.locate`); the one-hole
        frames use the paper's algorithm B (``"projection"``).

    Returns
    -------
    dict
        ``table`` (pandas.DataFrame: our value and the paper's per column, deg), ``ours`` (our
        four columns), ``bad_holes`` (rejected), ``injected`` (holes the bench gave defects),
        ``budget`` (common vs hole-specific error), ``runtime_s``, ``sizes`` and ``files``.
    """
    import matplotlib.pyplot as plt
    import pandas as pd

    from . import centroid, sim, stats
    from . import multihole as mh

    t0 = time.perf_counter()
    train_plan, test_plan = _plans(quick)
    bench_m = sim.Bench.paper_multi_hole()
    bench_1 = sim.Bench.paper_single_hole()

    def run(plan, bench, meth):
        cube = sim.simulate(plan, bench, seed=seed)
        return cube, centroid.locate(cube, meth, progress=progress)

    cube_tr, cen_tr = run(train_plan, bench_m, method)
    cube_te, cen_te = run(test_plan, bench_m, method)
    _, one_tr = run(train_plan, bench_1, "projection")
    _, one_te = run(test_plan, bench_1, "projection")

    from .calibration import Polynomial

    s1 = mh.GeometricCentre(order=order).fit(cen_tr)
    s2 = mh.PerHoleAverage(order=order).fit(cen_tr)
    metrics = mh.defect_metrics(cen_tr, strategy=s2)
    bad = mh.reject_bad_holes(metrics).values
    s2r = mh.PerHoleAverage(order=order, holes=~bad, weighting="inverse_variance", clip=4.0,
                            calibrations_=s2.calibrations_, variance_=s2.variance_)
    est = s2.predict_holes(cen_te)
    preds = {
        COLUMNS[0]: s1.predict(cen_te),
        COLUMNS[1]: s2.combine(est),
        COLUMNS[2]: Polynomial(order).fit(one_tr).predict(one_te),
        REJECTION_COLUMN: s2r.combine(est),
    }
    ours = stats.global_stats({k: stats.local_errors(v) for k, v in preds.items()})
    table = stats.side_by_side(ours[list(COLUMNS)], stats.paper_table5())
    table[(REJECTION_COLUMN, "sunlab")] = ours[REJECTION_COLUMN]
    injected = (np.flatnonzero(cen_tr["hole_defect"].values).tolist()
                if "hole_defect" in cen_tr.coords else [])
    budget = mh.error_budget(est, holes=~bad)
    result = {
        "table": table,
        "ours": ours,
        "bad_holes": np.flatnonzero(bad).tolist(),
        "injected": injected,
        "budget": budget,
        "metrics": metrics,
        "sizes": {"train_poses": len(train_plan), "test_poses": len(test_plan),
                  "shots": train_plan.shots, "holes": int(cen_tr.sizes["hole"])},
        "files": [],
    }
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        table.to_csv(out / "table5.csv")
        metrics.to_dataframe().to_csv(out / "hole_metrics.csv")
        p, s = 0, 0
        frame = cube_te["frames"].isel(pose=p, shot=s).values
        cf = cen_te.isel(pose=p, shot=s)
        figs = {
            "fig13.png": mh.fig13_frame(frame, cf, bad=bad),
            "fig14.png": mh.fig14_bad_holes(
                frame, cf, (np.flatnonzero(bad).tolist() or injected)[:5],
                reference=int(np.flatnonzero(~bad)[0]), metrics=metrics),
            "fig15.png": mh.fig15_rectangles(
                {k: {a: {"M": float(ours.loc[(a, "M"), k]),
                         "sigma_M": float(ours.loc[(a, "sigma_M"), k])} for a in ("alpha", "beta")}
                 for k in ours.columns}),
        }
        for name, fig in figs.items():
            fig.savefig(out / name, dpi=110)
            plt.close(fig)
            result["files"].append(str(out / name))
        result["files"] += [str(out / "table5.csv"), str(out / "hole_metrics.csv")]
    result["runtime_s"] = time.perf_counter() - t0
    if out is not None:
        doc = {"table5": {f"{c[0]} [{c[1]}]": {f"{a}.{st}": float(v) for (a, st), v in
                                                table[c].items()} for c in table.columns},
               "bad_holes": result["bad_holes"], "injected": injected, "budget": budget,
               "sizes": result["sizes"], "runtime_s": result["runtime_s"], "quick": quick,
               "seed": seed, "order": order, "centroid_method": method}
        (out / "table5.json").write_text(json.dumps(doc, indent=2))
        result["files"].append(str(out / "table5.json"))
    pd.set_option("display.width", 160)
    return result
