"""Reproduce the paper's Table 4 on the virtual bench: simulate, centroid, calibrate, compare.

The pipeline of docs/paper.md sec. 5, end to end, each step once and in order:

1. simulate experiments I (calibration), II (validation) and III (test) of Table 3 on
   :meth:`sunlab.sim.Bench.paper_single_hole` (full 1280 x 1024 frames, 8 shots per pose), each
   experiment with its own platform errors (a per-pose error that differs between experiments
   cannot be calibrated away, which is what limits every method to about 0.01 deg);
2. centroid every frame (:func:`sunlab.centroid.locate`, algorithm B by default), frames
   rendered and reduced chunk by chunk by Dask so the 7,440 frames never sit in memory at once;
   steps 1-2 are the shared pipeline
   (:func:`sunlab.reproduce.pipeline.simulate_and_locate`), which returns the centroid tables;
3. :func:`table4_statistics`, a function of those tables: fit every calibration of sec. 4
   on experiment I (the ideal model (1), the optimised model (3)-(4), linear and cubic
   interpolation, the polynomial (order chosen on experiment II), the trigonometric expansion
   and the four neural-network strategies of Table 2, early stopping on II), apply each to
   experiment III, and compute the paper's statistics (:mod:`sunlab.stats`).

Quick mode is the pipeline's :data:`~sunlab.reproduce.pipeline.QUICK` (every 2nd angle along
each grid axis, 2 shots per pose).

The numbers are ours, from the virtual bench, printed beside the paper's.

Examples
--------
>>> from sunlab.reproduce.table4 import PAPER_OPTIMISED
>>> PAPER_OPTIMISED["delta_f_mm"]
0.094
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from .. import __version__, parallel, stats
from ..calibration import table4_methods
from ..errors import ConfigurationError
from . import pipeline as pl
from .intervals import identified, stat_lines

__all__ = ["reproduce_table4"]

#: Where the strategy-4 network zeroes model (1): on each run's zero-pose check (strategy 2
#: keeps model (1) as fitted, :func:`sunlab.calibration.table4_methods`).
#: Model (1) puts (x_cf, y_cf) at the zero-orientation centroid (docs/paper.md sec. 4.1), which
#: a bench measures with each run; a strategy-4 network that adds its learned correction to
#: model (1) re-zeroed on the test run's zero pose carries that one pose's platform error as a
#: constant offset of the whole run (the paper's NN 4: alpha sigma / mu 0.34), and sheds an
#: offset the inner axis's homing gives the whole run (docs/paper.md sec. 5; notebook 05).
NN_REFERENCE = "zero_pose"

#: The paper's optimised-model parameters (docs/paper.md sec. 4.1).
PAPER_OPTIMISED = {"alpha0": 1.864, "beta0": 0.415, "delta_f_mm": 0.094}


@dataclass
class Table4Result:
    """Everything :func:`reproduce_table4` measured.

    Attributes
    ----------
    table : pandas.DataFrame
        Our global statistics on experiment III, index ``(angle, stat)``, one column per method.
    paper : pandas.DataFrame
        The paper's Table 4 (:func:`sunlab.stats.paper_table4`).
    rectangles : pandas.DataFrame
        The [M - 3 sigma_M, M + 3 sigma_M] rectangles and their areas (Fig. 12).
    local : dict of str to xarray.Dataset
        Local and maximum errors per pose of experiment III, per method.
    optimised : dict
        Fitted optimised-model parameters, the bench's true values and the paper's.
    polynomial_order : tuple of int
        The polynomial orders (alpha, beta) chosen on experiment II.
    centroid_status : dict
        Counts of centroid status codes per experiment.
    timings : dict
        Seconds spent per stage.
    settings : dict
        Seed, quick mode, centroid method, plan sizes.
    """

    table: pd.DataFrame
    paper: pd.DataFrame
    rectangles: pd.DataFrame
    local: dict
    optimised: dict
    polynomial_order: tuple
    centroid_status: dict
    timings: dict
    settings: dict
    files: list = field(default_factory=list)

    def to_dict(self) -> dict:
        """A JSON-ready summary (no pickles): tables as nested dicts, numbers as floats.

        Returns
        -------
        dict
            What ``table4.json`` holds: ``ours`` and ``paper`` (method -> ``"angle.stat"`` ->
            deg, None where not finite), ``rectangle_area_deg2``, ``optimised_model``,
            ``polynomial_order``, ``centroid_status``, ``timings_s``, ``settings`` and, for
            the identified bench, ``interval90`` and ``interval_role`` (each cell's role:
            fit, held-out or duplicate; :func:`sunlab.reproduce.intervals.identified`).
        """

        tops = ("interval90", "interval_role")
        settings = {k: v for k, v in self.settings.items() if k not in tops}
        return {
            "sunlab_version": __version__, "table": "4",
            "source": "sunlab virtual bench (ours) beside docs/paper.md Table 4 (paper)",
            "ours": pl.cells(self.table, value=pl.finite),
            "paper": pl.cells(self.paper, value=pl.finite),
            "rectangle_area_deg2": {str(k): pl.finite(v)
                                    for k, v in self.rectangles["area"].items()},
            "optimised_model": self.optimised,
            "polynomial_order": [int(n) for n in self.polynomial_order],
            "centroid_status": self.centroid_status,
            "timings_s": {k: round(float(v), 3) for k, v in self.timings.items()},
            "settings": settings,
            **{k: self.settings[k] for k in tops if k in self.settings},
        }


def bench_optimised_truth(bench) -> dict:
    """The bench's own values of what the optimised model (3)-(4) estimates.

    alpha0, beta0: the platform's mounting rotation; ``delta_f_mm``: the hole's true height
    above the focal plane minus the nominal F (the mask's dF plus what its tilt adds at the
    hole's off-centre place) less what the detector's glass lid takes off a paraxial ray's
    apparent height, the distance a pinhole model sees.

    Parameters
    ----------
    bench : sunlab.sim.Bench
        A one-hole bench.

    Returns
    -------
    dict of str to float
        ``alpha0``, ``beta0`` (deg) and ``delta_f_mm`` (mm), the keys of
        :data:`PAPER_OPTIMISED`.

    Examples
    --------
    >>> from sunlab import sim
    >>> t = bench_optimised_truth(sim.Bench.paper_single_hole())
    >>> t["alpha0"], t["beta0"], round(t["delta_f_mm"], 4)
    (1.274, 0.294, 0.092)
    """
    from ..sim.render import spot_geometry

    height = float(spot_geometry(bench, 0.0, 0.0).height_mm[0])
    height -= bench.detector.lid_height_loss_mm  # what a glass lid takes off a paraxial ray
    return {"alpha0": float(bench.platform.alpha0_deg), "beta0": float(bench.platform.beta0_deg),
            "delta_f_mm": height - float(bench.mask_distance_mm)}


def reproduce_table4(*, quick: bool = False, seed: int = 0, method: str = "projection",
                     neural: bool = True, out: str | Path | None = "results",
                     progress: bool = True, address: str | None = None, bench=None,
                     step: int | None = None, shots: int | None = None,
                     scheduler: str = "threads", workers: int | None = None) -> Table4Result:
    """Reproduce Table 4 (one hole, experiment III) on the virtual bench.

    The pipeline renders and centroids I, II, III and their zero-pose checks once
    (:func:`~sunlab.reproduce.pipeline.simulate_and_locate`), :func:`table4_statistics` fits
    and scores every method on those tables, then the files are written.

    Parameters
    ----------
    quick : bool
        Quick mode (:data:`sunlab.reproduce.pipeline.QUICK`): every 2nd angle of each grid
        axis (100 + 49 + 100 poses instead of 930) and 2 shots per pose instead of 8.
    seed : int
        Seed of the virtual bench.
    method : str
        Centroid method (``"projection"``: the paper's algorithm B).
    neural : bool
        Include the four neural-network strategies (torch).
    out : path or None
        Folder for ``table4.csv``, ``table4.json`` and the figures; None writes nothing.
    progress : bool
        Print stages and progress bars.
    address : str, optional
        ``dask.distributed`` scheduler address.
    bench : sunlab.sim.Bench, optional
        Default :meth:`sunlab.sim.Bench.paper_single_hole`.
    step, shots : int, optional
        Keep every ``step``-th pose and take ``shots`` frames per pose (override ``quick``).
    scheduler, workers
        Local scheduler and its threads or processes (``pipeline.simulate_and_locate``).

    Returns
    -------
    Table4Result
        :func:`table4_statistics`'s result; ``settings`` adds the run's and the bench's
        hypothesis (and ``interval90`` for the identified bench), ``files`` the paths written.

    Examples
    --------
    A thinned run (every 4th angle of each axis, one frame per pose) in a few seconds:

    >>> res = reproduce_table4(step=4, shots=1, neural=False, out=None, progress=False)
    >>> bool(res.table.loc[("alpha", "mu"), "polynomial"] < 0.05)
    True
    >>> bool(res.table.loc[("alpha", "mu"), "ideal model (1)"] > 1.0)  # mounting errors
    True
    """
    from .. import sim

    custom, bench = bench, sim.Bench.paper_single_hole() if bench is None else bench
    t0 = time.perf_counter()
    cens = pl.simulate_and_locate(bench, seed=seed, quick=quick, step=step, shots=shots,
                               method=method, progress=progress, address=address,
                               scheduler=scheduler, workers=workers, zero_pose=True)
    centroided = time.perf_counter() - t0
    result = table4_statistics(cens, bench, neural=neural, seed=seed)
    result.timings = {"simulate_and_centroid": centroided, **result.timings,
                      "total": time.perf_counter() - t0}
    result.settings = {"seed": seed, "quick": quick, "centroid_method": method,
                       **result.settings, **(identified("table4") if custom is None else
                                             {"hypothesis": "custom bench (not identified)"})}
    for label in result.local if progress else ():
        print(f"  fitted {label:<24s} in {result.timings[f'fit {label}']:6.2f} s", flush=True)
    if out is not None:
        result.files = _write_outputs(result, Path(out))
    return result


def table4_statistics(cens: dict, bench, *, neural: bool = True, seed: int = 0) -> Table4Result:
    """Table 4 from the centroid tables: every method fitted on I (II for model selection),
    applied to III, and the paper's statistics (:mod:`sunlab.stats`).

    Nothing is rendered or centroided here: the same tables give the same table.

    Parameters
    ----------
    cens : dict of str to xarray.Dataset
        ``centroids/1`` tables keyed ``"I"``, ``"II"``, ``"III"`` as centroided (every status;
        :func:`~sunlab.reproduce.pipeline.usable_table` selects here), with the zero-pose
        attributes ``zero_pose_x_px``, ``zero_pose_y_px`` (px) that the strategy-4 network
        reads (:func:`~sunlab.reproduce.pipeline.simulate_and_locate` with ``zero_pose``).
    bench : sunlab.sim.Bench
        The bench the tables were measured on: its own values of what the optimised model
        (3)-(4) estimates (:func:`bench_optimised_truth`) and its settings, recorded.
    neural : bool
        Include the four neural-network strategies (torch).
    seed : int
        Seed of the networks' initial weights.

    Returns
    -------
    Table4Result
        ``timings`` holds the seconds of each fit (``"fit <method>"``); ``settings`` holds
        ``not_run`` (methods whose extra is not installed), the runs' ``poses`` and ``shots``,
        the ``bench`` and the networks' zero reference.

    Examples
    --------
    >>> from sunlab import sim
    >>> from sunlab.reproduce.pipeline import simulate_and_locate
    >>> bench = sim.Bench.paper_single_hole()
    >>> cens = simulate_and_locate(bench, step=4, shots=1, progress=False, zero_pose=True)
    >>> res = table4_statistics(cens, bench, neural=False)
    >>> bool(res.table.loc[("alpha", "mu"), "polynomial"] < 0.05), res.settings["poses"]["III"]
    (True, 25)
    """
    if not {"I", "II", "III"} <= set(cens):
        raise ConfigurationError(
            f"cens: found runs {sorted(cens)}; expected 'I', 'II' and 'III'. Fix: the "
            "tables of simulate_and_locate(..., zero_pose=True).")
    train, val, test = (pl.usable_table(cens[k]) for k in ("I", "II", "III"))
    # every method fitted on I (II for model selection), BLAS on one thread (small problems, a
    # busy machine: idle BLAS threads slow them several-fold); a method whose extra is not
    # installed goes into not_run, with the ImportError's message (which names the extra)
    fitted, timings, not_run = {}, {}, {}
    with parallel.single_threaded_blas():
        for label, fit in table4_methods(neural=neural, seed=seed,
                                         reference=NN_REFERENCE).items():
            t = time.perf_counter()
            try:
                fitted[label] = fit(train, val)
            except ImportError as err:
                not_run[label] = str(err)
                continue
            timings[f"fit {label}"] = time.perf_counter() - t
    table, _, local = stats.evaluate(fitted, test, return_errors=True)
    opt, truth = fitted["optimised model (3)-(4)"].result, bench_optimised_truth(bench)
    optimised = {k: {"fitted": float(getattr(opt, k)),
                     "stderr": pl.finite(opt.stderr.get(k, np.nan)),
                     "bench": float(truth[k]), "paper": PAPER_OPTIMISED[k],
                     "stderr_method": opt.stderr_method} for k in PAPER_OPTIMISED}
    return Table4Result(
        table=table, paper=stats.paper_table4(), rectangles=stats.rectangles(table), local=local,
        optimised=optimised, polynomial_order=tuple(int(n) for n in fitted["polynomial"].orders),
        centroid_status=pl.centroid_status(cens), timings=timings,
        settings={"not_run": not_run, "poses": {k: int(v.sizes["pose"]) for k, v in cens.items()},
                  "shots": int(test.sizes["shot"]), "bench": json.loads(bench.to_json()),
                  "network_reference": NN_REFERENCE})


def comparable_methods(table: pd.DataFrame, factor: float = 10.0) -> list[str]:
    """The methods drawn in Fig. 12: those whose M is within ``factor`` of the best method's on
    both angles (the ideal model (1) and the classical Fourier series are orders of magnitude
    off and would hide the others' rectangles).

    Parameters
    ----------
    table : pandas.DataFrame
        Global statistics, index ``(angle, stat)`` with ``"M"`` among the stats, one column
        per method (deg).
    factor : float
        How many times the best method's M a method's M may be, on each angle.

    Returns
    -------
    list of str
        The methods kept, in the table's column order.

    Examples
    --------
    >>> import pandas as pd
    >>> t = pd.DataFrame({"a": [0.01, 0.02], "b": [1.0, 0.5]},
    ...                  index=pd.MultiIndex.from_tuples([("alpha", "M"), ("beta", "M")]))
    >>> comparable_methods(t)
    ['a']
    """
    m = table.xs("M", level=1)
    keep = (m <= factor * m.min(axis=1).to_numpy()[:, None]).all(axis=0)
    return [c for c in table.columns if keep[c]]


def _write_outputs(res: Table4Result, out: Path) -> list[str]:
    import matplotlib

    matplotlib.use("Agg", force=False)
    from .. import plots

    local, table = res.local["polynomial"], res.table
    side = stats.side_by_side(table, res.paper, names=("sunlab", "paper"))
    return pl.write_files(out, {
        "table4_sunlab.csv": table.to_csv, "table4_side_by_side.csv": side.to_csv,
        "table4.json": lambda path: pl.write_json(res.to_dict(), path),
        "fig10_error_maps_polynomial.png": plots.error_maps(
            local, title="Fig. 10: local errors, polynomial (virtual bench)"),
        "fig11_alpha_histogram_polynomial.png": plots.error_histogram(
            local, angle="alpha", title="Fig. 11: alpha local error, polynomial (virtual bench)"),
        "fig12_rectangles.png": plots.error_rectangles(
            table[comparable_methods(table)],
            title="Fig. 12: [M - 3 sigma_M, M + 3 sigma_M],\nexperiment III (virtual bench)")})


def format_table(res: Table4Result) -> str:
    """Table 4 as text: each of our values beside the paper's, then the optimised model.

    Parameters
    ----------
    res : Table4Result
        :func:`reproduce_table4`'s result.

    Returns
    -------
    str
        The eight statistics of each method (deg), paper and ours and our 90 % interval, the
        rectangle areas (deg^2), the optimised model's parameters, the polynomial's orders,
        the centroid status counts and the run's times (s), one line each.

    Examples
    --------
    >>> res = reproduce_table4(step=4, shots=1, neural=False, out=None, progress=False)
    >>> print(format_table(res).splitlines()[0])
    Table 4 - global statistics on experiment III, one hole (deg)
    """
    if not isinstance(res, Table4Result):
        raise ConfigurationError(f"res: found {type(res).__name__}; expected a Table4Result")
    lines = stat_lines("Table 4 - global statistics on experiment III, one hole (deg)",
                       "method", 26, res.paper, res.table, res.settings.get("interval90", {}),
                       res.settings.get("interval_role", {}))
    not_run = res.settings.get("not_run", {})
    lines += [f"{label:<26s}not run: its extra is not installed" for label in not_run]
    lines += [f"  ({why})" for why in dict.fromkeys(not_run.values())]
    lines += ["", "Fig. 12: rectangle area 36 sigma_M(alpha) sigma_M(beta), deg^2 "
              "(smaller is better)"]
    paper_areas = stats.rectangles(res.paper)["area"]
    for c, area in res.rectangles["area"].items():
        paper = f"   (paper {paper_areas[c]:.2e})" if c in paper_areas.index else ""
        lines.append(f"  {c:<26s} {area:.2e}{paper}")
    lines += ["", "Optimised model (3)-(4): fitted on experiment I (+- 1 s.e.) | bench | paper"]
    for k, v in res.optimised.items():
        unit = "mm" if k.endswith("_mm") else "deg"
        se = float("nan") if v["stderr"] is None else v["stderr"]
        lines.append(f"  {k:<11s} {v['fitted']:8.4f} +- {se:.4f} | {v['bench']:7.4f} | "
                     f"{v['paper']:7.4f} {unit}")
    method = next(iter(res.optimised.values())).get("stderr_method", "jacobian")
    lines += [f"  (s.e. by {method} over 2 x 2-degree blocks of poses; mounting as the bench's "
              "rotation R_y(-alpha0) R_x(beta0);\n   bench dF = the hole's true height "
              "above the focal plane minus F)",
              f"Polynomial order chosen on experiment II (alpha, beta): {res.polynomial_order}"]
    lines.append("Centroid status: " + "; ".join(
        f"{k}: " + ", ".join(f"{n} {s}" for s, n in v.items() if s != "removed")
        for k, v in res.centroid_status.items()))
    lines.append(removed_line(res.centroid_status))
    lines.append(f"Time: {res.timings['simulate_and_centroid']:.1f} s simulate + centroid, "
                 f"{res.timings['total']:.1f} s in all")
    return "\n".join(lines)


def removed_line(status: dict) -> str:
    """The frames each run's statistics leave out, by status, on one line (Tables 4 and 5).

    Parameters
    ----------
    status : dict of str to dict
        Per run, :func:`sunlab.reproduce.pipeline.centroid_status`'s counts; its ``removed``
        maps a status name to a number of frames.

    Returns
    -------
    str
        ``Frames removed (status: count): `` then ``run: count status, ...`` (``none`` where
        nothing was removed), runs separated by ``; ``.

    Examples
    --------
    >>> removed_line({"I": {"ok": 8, "removed": {"saturated": 2, "no_spot": 1}},
    ...               "II": {"ok": 9, "removed": {}}})
    'Frames removed (status: count): I: 2 saturated, 1 no_spot; II: none'
    """
    return "Frames removed (status: count): " + "; ".join(
        f"{k}: " + (", ".join(f"{n} {s}" for s, n in v["removed"].items()) or "none")
        for k, v in status.items())
