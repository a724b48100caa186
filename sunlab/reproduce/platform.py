"""Beyond the paper: find and remove the platform fault that makes beta worse than alpha.

Called by ``sunlab reproduce --table platform``. On the identified bench
(:meth:`sunlab.sim.Bench.paper_single_hole`, whose inner axis's zero shifts by
:data:`sunlab.sim.bench.PAPER_BETA_REHOMING_DEG` between the session of experiment I and that
of II and III, and whose experiments are scanned serpentine, :data:`sunlab.plans.PAPER_SCAN`;
the identification found no backlash, and the remedies for one are shown all the same, as a
lab whose stage has one would run them):

1. the paper's protocol: experiments I, II, III of Table 3 scanned as the paper's were,
   polynomial calibration (order chosen on II), statistics on III; plus a zero-pose check
   (:func:`sunlab.plans.zero_check`) before runs I and III, which the paper's statistics leave
   out. Every row fits on I alone, so that the remedies compare like with like; Table 4's
   polynomial is refitted on I + II (:data:`sunlab.calibration.registry.POLYNOMIAL_REFIT`) and
   takes part of the zero shift from II, so its beta mu is below this table's first row;
2. the diagnosis (:func:`sunlab.studies.platform_fault.diagnose`) of the polynomial's test
   errors with the run's motion record, beside the shape test applied to the paper's published
   statistics (:func:`sunlab.studies.platform_fault.paper_shape`);
3. remedy (a): the same experiments with a unidirectional approach (overshoot and return), and
   with the zero-pose checks correcting the homing offset;
4. remedy (b): on the paper-protocol runs, the backlash fitted jointly with the polynomial
   from the motion record (and the homing offset from the zero-pose checks), with standard
   errors (:func:`sunlab.studies.platform_fault.fit_correction`), the test run's reference
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

import time
from pathlib import Path

import pandas as pd

from .pipeline import experiment_plans, locate_runs, simulate_runs, usable_table, write_json

__all__ = ["ROWS", "reproduce_platform", "format_platform"]

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
    """The bench's own values of what :func:`sunlab.studies.platform_fault.fit_correction`
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
    from ..sim.bench import homing_offset

    h = {k: homing_offset(bench, seed, p.name) for k, p in plans_by_run.items()}
    return {"beta_backlash_deg": float(bench.platform.beta_backlash_deg),
            "beta_homing_difference_deg": float(h["III"] - h["I"]),
            "beta_gear_amplitude_deg": float(bench.platform.beta_gear_deg)}


def _centroids(bench, plan_sets: dict, *, seed, method, engine, progress, where):
    """Centroid tables for every named plan: rendered and centroided, or from the surrogate."""
    if engine == "surrogate":
        from ..sim.surrogate import surrogate_centroids

        return {k: surrogate_centroids(bench, p, seed) for k, p in plan_sets.items()}
    cubes = simulate_runs({k: (p, bench) for k, p in plan_sets.items()}, seed=seed)
    if progress:
        n = sum(len(p) * p.shots for p in plan_sets.values())
        print(f"rendering and centroiding {n} frames ({method})", flush=True)
    return locate_runs(cubes, method=method, progress=progress, **where)


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
        Quick mode, the same for every table (:data:`sunlab.reproduce.pipeline.QUICK`): every
        2nd angle along each grid axis and 2 shots per pose.
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
        Default :meth:`sunlab.sim.Bench.paper_single_hole`.
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
    from .. import sim, stats
    from ..errors import ConfigurationError

    if engine not in ("render", "surrogate"):
        raise ConfigurationError(
            f"engine: found {engine!r}; expected 'render' or 'surrogate'."
        )
    t0 = time.perf_counter()
    bench = sim.Bench.paper_single_hole() if bench is None else bench
    paper = experiment_plans(quick=quick, step=step, shots=shots)
    uni = {k: p.with_motion(approach="unidirectional") for k, p in paper.items()}
    sets = _plan_sets(paper, uni, checks)
    cens = {k: usable_table(v) for k, v in _centroids(
        bench, sets, seed=seed, method=method, engine=engine, progress=progress,
        where={"address": address, "scheduler": scheduler, "workers": workers}).items()}
    t_sim = time.perf_counter() - t0
    rows, fits, diag, jc_params, from_row = _rows(cens, paper, uni)
    table = pd.concat([stats.evaluate({k: e}, reference=r) for k, (e, r) in rows.items()], axis=1)
    parameters = _fault_parameters(jc_params, bench_fault_values(bench, seed, paper), from_row)
    result = _platform_doc(table, parameters, diag, fits)
    result["settings"] = {"seed": seed, "quick": quick, "engine": engine,
                          "centroid_method": method, "scan": paper["III"].scan,
                          "zero_checks": checks, "poses": {k: len(p) for k, p in paper.items()},
                          "shots": paper["III"].shots,
                          "bench": "sunlab.sim.Bench.paper_single_hole()"}
    result["timings_s"] = {"simulate_and_centroid": round(t_sim, 2),
                           "total": round(time.perf_counter() - t0, 2)}
    result["files"] = []
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        result["files"] = [write_json(result, out / "platform.json")]
    return result


def _plan_sets(paper: dict, uni: dict, checks: int) -> dict:
    """Every run: the paper's protocol and the unidirectional one, and one zero-pose check per
    run, taken after homing (its plan is the same for both protocols)."""
    from .. import plans

    sets = {}
    for tag, ps in (("paper", paper), ("uni", uni)):
        for k, p in ps.items():
            sets[f"{tag} {k}"] = p
    for k in ("I", "III"):
        sets[f"zero {k}"] = plans.zero_check(paper[k], checks)
    return sets


def _rows(cens: dict, paper: dict, uni: dict):
    """The estimate and reference of every row of the table, the polynomial of each protocol, the
    diagnosis, the joint fit whose parameters are reported and its row."""
    from ..calibration import Polynomial
    from ..studies import platform_fault as pf

    local, fits = {}, {}
    for tag in ("paper", "uni"):
        tr, va, te = (cens[f"{tag} {k}"] for k in ("I", "II", "III"))
        cal, _ = Polynomial.select_order(tr, va)
        fits[tag] = cal
        local[tag] = (cal.predict(te), None)
    rows = {ROWS[0]: local["paper"], ROWS[1]: local["uni"]}
    zeros = {"zero_train": cens["zero I"], "zero_test": cens["zero III"]}

    def corrected(runs, plans_, **kw):
        jc = pf.fit_correction(cens[f"{runs} I"], plans_["I"], cens[f"{runs} II"], **kw)
        est = jc.predict(cens[f"{runs} III"])
        return jc, (est, jc.reference(est, plans_["III"]))

    # (a) + zero check: the homing difference from the zero-pose checks, no backlash term
    _, rows[ROWS[2]] = corrected("uni", uni, backlash=False, **zeros)
    # (b) backlash from the motion record, then with the zero-pose checks
    _, rows[ROWS[3]] = corrected("paper", paper)
    jc_params, rows[ROWS[4]] = corrected("paper", paper, **zeros)
    from_row = ROWS[4]
    diag = pf.diagnose(fits["paper"].predict(cens["paper III"]), paper["III"])
    if diag.candidate == "gear":
        # the gear term at the frequency the periodogram found (the alias the grid sees)
        f = diag.evidence["periodogram"]["peak_frequency"]
        jc_params, rows[GEAR_ROW] = corrected("paper", paper, gear_frequency=f, **zeros)
        from_row = GEAR_ROW
    return rows, fits, diag, jc_params, from_row


def _fault_parameters(jc, truth: dict, from_row: str) -> dict:
    """The fitted fault parameters beside the bench's, with their z-scores."""
    parameters = {}
    for name, p in jc.parameters.items():
        z = (p["fitted"] - truth[name]) / p["stderr"] if p["stderr"] > 0 else float("inf")
        parameters[name] = {"fitted": p["fitted"], "stderr": p["stderr"], "bench": truth[name],
                            "z": z, "from": from_row}
    return parameters


def _platform_doc(table, parameters: dict, diag, fits: dict) -> dict:
    """The platform table's results: rows, parameters, diagnosis, the paper's shape test and
    the must-show checks (settings, timings and files are added by the caller)."""
    from .. import stats
    from ..studies import platform_fault as pf

    def cells(col):
        return {f"{a}.{s}": float(table.loc[(a, s), col]) for a in stats.ANGLES
                for s in stats.STATS}

    poly = cells(ROWS[0])
    names = list(table.columns)
    remedies = {r: cells(r)["beta.mu"] for r in names[1:]}
    best = min(remedies, key=remedies.get)
    must = {
        "best_remedy": best,
        "best_beta_mu": remedies[best],
        "limit_alpha": 1.3 * poly["alpha.mu"],
        "limit_beta": 0.6 * poly["beta.mu"],
        "beta_mu_within_1.3x_polynomial_alpha_mu": remedies[best] <= 1.3 * poly["alpha.mu"],
        "beta_mu_within_0.6x_polynomial_beta_mu": remedies[best] <= 0.6 * poly["beta.mu"],
        "parameters_within_2.5_stderr": all(abs(p["z"]) <= 2.5 for p in parameters.values()),
    }
    shape = pf.paper_shape()
    return {
        "table": "platform",
        "source": "sunlab virtual bench (ours); the paper's own statistics for paper_shape",
        "rows": {r: cells(r) for r in names},
        "parameters": parameters,
        "diagnosis": {**diag.to_dict(), "polynomial_shape": {
            a: float(table.loc[(a, "sigma"), ROWS[0]] / table.loc[(a, "mu"), ROWS[0]])
            for a in stats.ANGLES}},
        "paper_shape": {f"{m} {a}": {"ratio": float(r["ratio"]),
                                     "below_bound": bool(r["below_bound"])}
                        for (m, a), r in shape.iterrows()},
        "must_show": must,
        "polynomial_order": {k: [int(n) for n in c.orders] for k, c in fits.items()},
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
    m = res["must_show"]
    def yes(flag) -> str:
        return "yes" if flag else "no"

    lines.append(f"Best remedy: {m['best_remedy']}: beta mu {m['best_beta_mu']:.4f}")
    lines.append(f"  beta mu at most 1.3 x the polynomial's alpha mu ({m['limit_alpha']:.4f}): "
                 f"{yes(m['beta_mu_within_1.3x_polynomial_alpha_mu'])}")
    lines.append(f"  beta mu at most 0.6 x the polynomial's beta mu ({m['limit_beta']:.4f}): "
                 f"{yes(m['beta_mu_within_0.6x_polynomial_beta_mu'])}")
    lines.append("  every fitted fault parameter within 2.5 s.e. of the bench's value: "
                 f"{yes(m['parameters_within_2.5_stderr'])}")
    return "\n".join(lines)
