"""Beyond the paper: find and remove the platform fault that makes beta worse than alpha.

Called by ``sunlab reproduce --table platform``. On the identified bench
(:meth:`sunlab.sim.Bench.paper_single_hole`, whose inner axis's zero shifts by
:data:`sunlab.sim.bench.PAPER_BETA_REHOMING_DEG` between the session of experiment I and that
of II and III, and whose experiments are scanned serpentine, :data:`sunlab.plans.PAPER_SCAN`;
it has no backlash, a choice: no hypothesis of the identification carries one; the remedies
for one are shown all the same, as a lab whose stage has one would run them):

1. the paper's protocol: experiments I, II, III of Table 3 scanned as the paper's were,
   polynomial calibration (order chosen on II), statistics on III; plus a zero-pose check
   (:func:`sunlab.plans.zero_check`) before runs I and III, which the paper's statistics leave
   out. Every row fits on I alone, so that the remedies compare like with like; Table 4's
   polynomial is refitted on I + II (:data:`sunlab.calibration.registry.POLYNOMIAL_REFIT`) and
   takes part of the zero shift from II, so its beta mu is below this table's first row;
2. the diagnosis (:func:`sunlab.reproduce.fault.diagnose`) of the polynomial's test
   errors with the run's motion record, beside the shape test applied to the paper's published
   statistics (:func:`sunlab.reproduce.fault.paper_shape`);
3. remedy (a): the same experiments with a unidirectional approach (overshoot and return), and
   with the zero-pose checks correcting the homing offset;
4. remedy (b): on the paper-protocol runs, the backlash fitted jointly with the polynomial
   from the motion record (and the homing offset from the zero-pose checks), with standard
   errors (:func:`sunlab.reproduce.remedy.fit_correction`), the test run's reference
   corrected.

Every row is Table 4's eight statistics for the polynomial on experiment III. The frames go
through the pipeline every table shares (:mod:`sunlab.reproduce.pipeline`, one Dask pass for
every run); quick mode is its :data:`~sunlab.reproduce.pipeline.QUICK`, as for Tables 4 and 5:
every 2nd angle along each grid axis and 2 shots per pose.

Examples
--------
>>> from sunlab.reproduce.platform import ROWS
>>> ROWS[0]
"polynomial (paper's protocol)"
"""

from __future__ import annotations

import dataclasses
import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .. import plans, sim, stats
from ..calibration import Polynomial, table4_methods
from ..errors import ConfigurationError
from . import pipeline as pl
from .fault import diagnose, fault_bench, paper_shape
from .remedy import fit_correction

__all__ = ["reproduce_platform"]

#: The rows of the platform table, in order.
ROWS = (
    "polynomial (paper's protocol)",
    "(a) unidirectional approach",
    "(a) unidirectional approach + zero-pose check",
    "(b) backlash fitted from the motion record",
    "(b) backlash + homing from zero-pose checks",
)
#: The extra row when the diagnosis is a gear error: its term fitted at the periodogram's peak.
GEAR_ROW = "(b) backlash + homing + gear error at the periodogram's frequency"


def bench_fault_values(bench, seed, plans_by_run: dict) -> dict:
    """The bench's own values of what :func:`sunlab.reproduce.remedy.fit_correction`
    estimates.

    ``beta_backlash_deg`` (the platform's), ``beta_homing_difference_deg`` (the test run's
    homing offset minus the calibration run's, as drawn for this seed),
    ``beta_gear_amplitude_deg``.

    Parameters
    ----------
    bench : sunlab.sim.Bench
        The bench the runs are rendered on.
    seed : int
        Seed of the virtual bench (the homing offsets are drawn from it and each run's name).
    plans_by_run : dict of str to sunlab.plans.Plan
        The calibration run ``"I"`` and the test run ``"III"``.

    Returns
    -------
    dict of str to float
        ``beta_backlash_deg``, ``beta_homing_difference_deg``, ``beta_gear_amplitude_deg``
        (deg).

    Examples
    --------
    >>> from sunlab import plans, sim
    >>> v = bench_fault_values(sim.Bench.paper_single_hole(), 0,
    ...                        {"I": plans.experiment("I"), "III": plans.experiment("III")})
    >>> v["beta_backlash_deg"], round(v["beta_homing_difference_deg"], 4)  # I -> III shift
    (0.0, 0.0238)
    """
    from ..sim.platform import homing_offset

    h = {k: homing_offset(bench, seed, p.name) for k, p in plans_by_run.items()}
    return {"beta_backlash_deg": float(bench.platform.beta_backlash_deg),
            "beta_homing_difference_deg": float(h["III"] - h["I"]),
            "beta_gear_amplitude_deg": float(bench.platform.beta_gear_deg)}


def _centroids(bench, sets: dict, *, seed, method, engine, progress, where) -> dict:
    """Usable centroid tables of every named plan: rendered and centroided, or the surrogate's."""
    if engine == "surrogate":
        from ..sim.surrogate import surrogate_centroids

        cens = {k: surrogate_centroids(bench, p, seed) for k, p in sets.items()}
    else:
        if progress:
            print(f"rendering and centroiding {sum(len(p) * p.shots for p in sets.values())} "
                  f"frames ({method})", flush=True)
        cens = pl.locate_runs(pl.simulate_runs({k: (p, bench) for k, p in sets.items()}, seed=seed),
                           method=method, progress=progress, **where)
    return {k: pl.usable_table(v) for k, v in cens.items()}


def reproduce_platform(*, quick: bool = False, seed: int = 0, method: str = "projection",
                       out: str | Path | None = "results", progress: bool = True,
                       engine: str = "render", bench=None, checks: int = 4,
                       address: str | None = None, scheduler: str = "threads",
                       workers: int | None = None, step: int | None = None,
                       shots: int | None = None) -> dict:
    """The platform table: the paper's protocol, the diagnosis, and each remedy.

    Parameters
    ----------
    quick : bool
        Quick mode, as every table's (:data:`sunlab.reproduce.pipeline.QUICK`).
    seed : int
        Seed of the virtual bench.
    method : str
        Centroid method (rendered frames).
    out : path or None
        Folder for ``platform.json``; None writes nothing.
    progress : bool
        Print stages and progress bars.
    engine : {"render", "surrogate"}
        Rendered frames (default) or the centroid-level surrogate
        (:func:`sunlab.sim.surrogate.surrogate_centroids`, seconds instead of minutes).
    bench : sunlab.sim.Bench, optional
        Default :meth:`sunlab.sim.Bench.paper_single_hole`; ``settings["bench"]`` names that
        constructor, or holds a passed bench's parameters (:meth:`sunlab.sim.Bench.to_json`).
    checks : int
        Zero-pose visits per run (:func:`sunlab.plans.zero_check`).
    address, scheduler, workers
        Where the frames are rendered and centroided
        (:func:`sunlab.reproduce.pipeline.locate_runs`).
    step, shots : int, optional
        Keep every ``step``-th angle and take ``shots`` frames per pose (override ``quick``).

    Returns
    -------
    dict
        ``rows`` (name -> the eight statistics, as ``table4.json``'s ``ours``),
        ``parameters`` (name -> ``fitted``, ``stderr``, ``bench``, ``z``), ``diagnosis``,
        ``paper_shape``, ``must_show``, ``settings``, ``files``.

    Examples
    --------
    >>> res = reproduce_platform(engine="surrogate", quick=True, out=None, progress=False)
    >>> res["diagnosis"]["candidate"]  # the run's offset, the drift of the zero, leads
    'homing'
    """

    if engine not in ("render", "surrogate"):
        raise ConfigurationError(f"engine: found {engine!r}; expected 'render' or 'surrogate'.")
    t0 = time.perf_counter()
    used = "sunlab.sim.Bench.paper_single_hole()" if bench is None else json.loads(bench.to_json())
    bench = sim.Bench.paper_single_hole() if bench is None else bench
    paper = pl.experiment_plans(quick=quick, step=step, shots=shots)
    protocols = {"paper": paper,
                 "uni": {k: p.with_motion(approach="unidirectional") for k, p in paper.items()}}
    # every run of both protocols, and one zero-pose check per run, taken after homing (its
    # plan is the same for both protocols)
    sets = {f"{tag} {k}": p for tag, ps in protocols.items() for k, p in ps.items()}
    sets.update({f"zero {k}": plans.zero_check(paper[k], checks) for k in ("I", "III")})
    cens = _centroids(bench, sets, seed=seed, method=method, engine=engine, progress=progress,
                      where={"address": address, "scheduler": scheduler, "workers": workers})
    t_sim = time.perf_counter() - t0
    rows, orders, diag, jc, from_row = _rows(cens, protocols)
    truth = bench_fault_values(bench, seed, paper)
    table = pd.concat([stats.evaluate({k: e}, reference=r) for k, (e, r) in rows.items()], axis=1)
    result = {**_platform_doc(table, jc, truth, from_row, diag),
              "polynomial_order": orders,
              "settings": {"seed": seed, "quick": quick, "engine": engine,
                           "centroid_method": method, "scan": paper["III"].scan,
                           "zero_checks": checks, "poses": {k: len(p) for k, p in paper.items()},
                           "shots": paper["III"].shots,
                           "bench": used},
              "timings_s": {"simulate_and_centroid": round(t_sim, 2),
                            "total": round(time.perf_counter() - t0, 2)},
              "files": []}
    if out is not None:
        Path(out).mkdir(parents=True, exist_ok=True)
        result["files"] = [pl.write_json(result, Path(out) / "platform.json")]
    return result


def _rows(cens: dict, protocols: dict):
    """The estimate and reference angles of every row of the table, the polynomial orders of
    each protocol, the diagnosis, the joint fit whose parameters are reported and its row."""

    zeros = {"zero_train": cens["zero I"], "zero_test": cens["zero III"]}

    def corrected(tag, **kw):
        jc = fit_correction(cens[f"{tag} I"], protocols[tag]["I"], cens[f"{tag} II"], **kw)
        est = jc.predict(cens[f"{tag} III"])
        return jc, (est, jc.reference(est, protocols[tag]["III"]))

    rows, orders = {}, {}
    for tag, row in (("paper", ROWS[0]), ("uni", ROWS[1])):
        cal, _ = Polynomial.select_order(cens[f"{tag} I"], cens[f"{tag} II"])
        orders[tag] = [int(n) for n in cal.orders]
        rows[row] = (cal.predict(cens[f"{tag} III"]), None)
        if tag == "paper":
            diag = diagnose(cal.predict(cens["paper III"]), protocols["paper"]["III"])
    # (a) + zero check: the homing difference from the zero-pose checks, no backlash term;
    # (b) the backlash from the motion record, then with the zero-pose checks
    rows[ROWS[2]] = corrected("uni", backlash=False, **zeros)[1]
    rows[ROWS[3]] = corrected("paper")[1]
    jc, rows[ROWS[4]] = corrected("paper", **zeros)
    if diag.candidate != "gear":
        return rows, orders, diag, jc, ROWS[4]
    # the gear term at the frequency the periodogram found (the alias the grid sees)
    f = diag.evidence["periodogram"]["peak_frequency"]
    jc, rows[GEAR_ROW] = corrected("paper", gear_frequency=f, **zeros)
    return rows, orders, diag, jc, GEAR_ROW


def _platform_doc(table, jc, truth: dict, from_row: str, diag) -> dict:
    """The platform table's results: rows, the joint fit's parameters beside the bench's
    (``truth``) with their z-scores, the diagnosis, the paper's shape test and the must-show
    checks (the orders, settings, timings and files are added by the caller)."""

    parameters = {k: {"fitted": p["fitted"], "stderr": p["stderr"], "bench": truth[k],
                      "z": ((p["fitted"] - truth[k]) / p["stderr"] if p["stderr"] > 0
                            else float("inf")), "from": from_row}
                  for k, p in jc.parameters.items()}
    rows = pl.cells(table)
    poly, remedies = rows[ROWS[0]], {r: rows[r]["beta.mu"] for r in list(rows)[1:]}
    best = min(remedies, key=remedies.get)
    return {
        "table": "platform",
        "source": "sunlab virtual bench (ours); the paper's own statistics for paper_shape",
        "rows": rows, "parameters": parameters,
        "diagnosis": {**dataclasses.asdict(diag), "polynomial_shape": {
            a: poly[f"{a}.sigma"] / poly[f"{a}.mu"] for a in stats.ANGLES}},
        "paper_shape": {f"{m} {a}": {"ratio": float(r["ratio"]),
                                     "below_bound": bool(r["below_bound"])}
                        for (m, a), r in paper_shape().iterrows()},
        "must_show": {
            "best_remedy": best, "best_beta_mu": remedies[best],
            "limit_alpha": 1.3 * poly["alpha.mu"], "limit_beta": 0.6 * poly["beta.mu"],
            "beta_mu_within_1.3x_polynomial_alpha_mu": remedies[best] <= 1.3 * poly["alpha.mu"],
            "beta_mu_within_0.6x_polynomial_beta_mu": remedies[best] <= 0.6 * poly["beta.mu"],
            "parameters_within_2.5_stderr": all(abs(p["z"]) <= 2.5 for p in parameters.values()),
        },
    }


def format_platform(res: dict) -> str:
    """The platform table as text: rows, fitted parameters beside the bench's, the diagnosis.

    Parameters
    ----------
    res : dict
        :func:`reproduce_platform`'s result.

    Returns
    -------
    str
        The rows' eight statistics (deg), the fitted fault parameters (deg) beside the
        bench's, the diagnosis and the paper's sigma / mu ratios, one line each.

    Examples
    --------
    >>> res = reproduce_platform(engine="surrogate", quick=True, out=None, progress=False)
    >>> format_platform(res).splitlines()[0]
    'Platform fault - polynomial calibration on experiment III, one hole (deg)'
    """
    lines = ["Platform fault - polynomial calibration on experiment III, one hole (deg)",
             f"ours = sunlab virtual bench ({res['settings']['engine']}); scan "
             f"{res['settings']['scan']}", ""]
    keys = list(next(iter(res["rows"].values())))
    lines.append(f"{'row':<48s}" + "".join(f"{k:>14s}" for k in keys))
    for r, v in res["rows"].items():
        lines.append(f"{r:<48s}" + "".join(f"{v[k]:14.4f}" for k in keys))
    lines += ["", "Fitted fault parameters (deg): fitted +- s.e. | bench | z"]
    for k, p in res["parameters"].items():
        lines.append(f"  {k:<36s} {p['fitted']:9.5f} +- {p['stderr']:.5f} | "
                     f"{p['bench']:8.5f} | {p['z']:+.2f}")
    d = res["diagnosis"]
    lines += ["", f"Diagnosis: {d['candidate']} (z: " + ", ".join(
        f"{k} {v:.1f}" for k, v in d["z"].items()) + ")"]
    ps = res["paper_shape"]
    lines.append("Paper's sigma/mu (bound 1/sqrt(3) = 0.577): " + ", ".join(
        f"{k} {v['ratio']:.2f}" for k, v in ps.items()))
    m = {k: ("yes" if v else "no") if isinstance(v, bool) else v
         for k, v in res["must_show"].items()}
    lines += [f"Best remedy: {m['best_remedy']}: beta mu {m['best_beta_mu']:.4f}",
              f"  beta mu at most 1.3 x the polynomial's alpha mu ({m['limit_alpha']:.4f}): "
              f"{m['beta_mu_within_1.3x_polynomial_alpha_mu']}",
              f"  beta mu at most 0.6 x the polynomial's beta mu ({m['limit_beta']:.4f}): "
              f"{m['beta_mu_within_0.6x_polynomial_beta_mu']}",
              "  every fitted fault parameter within 2.5 s.e. of the bench's value: "
              f"{m['parameters_within_2.5_stderr']}"]
    return "\n".join(lines)


def candidate_table(sizes: dict, *, bench=None, seed: int = 0, shots: int = 1,
                    experiment_plans: dict | None = None,
                    methods=("polynomial", "linear interp.", "cubic interp.")) -> pd.DataFrame:
    """Which candidate explains the paper's beta statistics: Table 4's beta cells per fault.

    For each fault and size the bench carries that fault alone
    (:func:`sunlab.reproduce.fault.fault_bench`; for ``"homing"`` the size is the test run's
    offset relative to the calibration run, a ``beta_offset_deg`` of the test run), the
    surrogate centroids
    (:func:`sunlab.sim.surrogate.surrogate_centroids`) of experiments I, II and III are
    calibrated by each method as ``sunlab reproduce`` does, and the beta mu and sigma on III are
    set beside the paper's; ``score`` is the RMS of log(ours / paper) over those cells, and
    ``shape_excess`` the mean sigma / mu of the polynomial and linear columns less the paper's
    (0.47 and 0.48: the shape criterion of :func:`sunlab.reproduce.fault.paper_shape`).

    Parameters
    ----------
    sizes : dict
        ``kind -> size_deg``, e.g. sizes that match the paper's polynomial beta mu.
    bench : sunlab.sim.Bench, optional
        The bench that carries each fault; default :meth:`sunlab.sim.Bench.paper_single_hole`.
    seed : int
        Seed of the experiments.
    shots : int
        Frames per pose of the default plans.
    experiment_plans : dict, optional
        Plans ``{"I", "II", "III"}``; default Table 3's with ``shots`` frames per pose.
    methods : sequence of str
        Table 4's columns compared (keys of :func:`sunlab.calibration.table4_methods`).

    Returns
    -------
    pandas.DataFrame
        One row per candidate: ``size_deg``, ``<method> mu``, ``<method> sigma``, ``score``,
        ``shape_excess``.

    Examples
    --------
    >>> from sunlab import plans
    >>> small = {"I": plans.grid(-17, 2, 6, -2, 17, 1, shots=1, name="I", scan="serpentine"),
    ...          "II": plans.grid(-16.25, 1.75, 6, -1.75, 16.25, 1.5, shots=1, name="II",
    ...                           scan="serpentine"),
    ...          "III": plans.grid(-16.5, 1.5, 6, -1.5, 16.5, 1, shots=1, name="III",
    ...                            scan="serpentine")}
    >>> t = candidate_table({"backlash": 0.017}, experiment_plans=small,
    ...                     methods=("polynomial",))
    >>> list(t.columns), bool(0.005 < t.loc["backlash", "polynomial mu"] < 0.03)
    (['size_deg', 'polynomial mu', 'polynomial sigma', 'score', 'shape_excess'], True)
    """
    from ..sim.surrogate import surrogate_centroids

    bench = sim.Bench.paper_single_hole() if bench is None else bench
    exps = experiment_plans or pl.experiment_plans(step=1, shots=shots)
    fits = table4_methods(neural=False, seed=seed)
    rows = {}
    for kind, size in sizes.items():
        b = fault_bench(bench, kind, 0.0 if kind == "homing" else size)
        b_test = b.replace(platform__beta_offset_deg=float(size)) if kind == "homing" else b
        cen = {n: surrogate_centroids(b_test if n == "III" else b, p, seed)
               for n, p in exps.items()}
        rows[kind] = {"size_deg": float(size), **_beta_cells(cen, fits, methods)}
    return pd.DataFrame.from_dict(rows, orient="index").rename_axis("candidate")


def _beta_cells(cen: dict, fits: dict, methods) -> dict:
    """Table 4's beta mu and sigma of each method calibrated on ``cen["I"]`` (order on II) and
    applied to III, their ``score`` against the paper's and the ``shape_excess``."""

    paper = stats.paper_table4()
    row, logs = {}, []
    for m in methods:
        g = stats.evaluate({m: fits[m](cen["I"], cen["II"])}, cen["III"])[m]
        for st in ("mu", "sigma"):
            row[f"{m} {st}"] = float(g[("beta", st)])
            logs.append(math.log(row[f"{m} {st}"] / float(paper.loc[("beta", st), m])))
    row["score"] = float(np.sqrt(np.mean(np.square(logs))))
    # the shape criterion: mean sigma / mu of the polynomial and linear columns, less the
    # paper's (0.47, 0.48); 0 matches the paper's bimodal shape
    shaped = [m for m in methods if m in ("polynomial", "linear interp.")]
    row["shape_excess"] = float(np.mean(
        [row[f"{m} sigma"] / row[f"{m} mu"] - float(paper.loc[("beta", "sigma"), m]
                                                    / paper.loc[("beta", "mu"), m])
         for m in shaped])) if shaped else float("nan")
    return row
