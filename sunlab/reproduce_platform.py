"""Beyond the paper: find and remove the platform fault that makes beta worse than alpha.

Called by ``sunlab reproduce --table platform``. On the identified bench
(:meth:`sunlab.sim.Bench.paper_single_hole`, whose inner axis has a backlash of
:data:`sunlab.sim.bench.PAPER_BETA_BACKLASH_DEG` and whose experiments are scanned serpentine,
:data:`sunlab.plans.PAPER_SCAN`):

1. the paper's protocol: experiments I, II, III of Table 3 scanned as the paper's were,
   polynomial calibration (order chosen on II), statistics on III; plus a zero-pose check
   (:func:`sunlab.plans.zero_check`) before runs I and III, which the paper's statistics leave
   out;
2. the diagnosis (:func:`sunlab.platform_fault.diagnose`) of the polynomial's test errors with
   the run's motion record, beside the shape test applied to the paper's published statistics
   (:func:`sunlab.platform_fault.paper_shape`);
3. remedy (a): the same experiments with a unidirectional approach (overshoot and return), and
   with the zero-pose checks correcting the homing offset;
4. remedy (b): on the paper-protocol runs, the backlash fitted jointly with the polynomial
   from the motion record (and the homing offset from the zero-pose checks), with standard
   errors (:func:`sunlab.platform_fault.fit_correction`), the test run's reference corrected.

Every row is Table 4's eight statistics for the polynomial on experiment III.

Examples
--------
>>> from sunlab.reproduce_platform import ROWS
>>> ROWS[0]
"polynomial (paper's protocol)"
"""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

__all__ = ["ROWS", "GEAR_ROW", "reproduce_platform", "format_platform", "bench_fault_values"]

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
    """The bench's own values of what :func:`sunlab.platform_fault.fit_correction` estimates.

    ``beta_backlash_deg`` (the platform's), ``beta_homing_difference_deg`` (the test run's
    homing offset minus the calibration run's, as drawn for this seed),
    ``beta_gear_amplitude_deg``.

    Examples
    --------
    >>> from sunlab import plans, sim
    >>> v = bench_fault_values(sim.Bench.paper_single_hole(), 0,
    ...                        {"I": plans.experiment("I"), "III": plans.experiment("III")})
    >>> v["beta_backlash_deg"], v["beta_homing_difference_deg"]
    (0.017, 0.0)
    """
    from .sim.bench import _homing
    from .sim.render import _entropy

    key = _entropy(seed)
    h = {k: _homing(bench.platform, key, p.name) for k, p in plans_by_run.items()}
    return {"beta_backlash_deg": float(bench.platform.beta_backlash_deg),
            "beta_homing_difference_deg": float(h["III"] - h["I"]),
            "beta_gear_amplitude_deg": float(bench.platform.beta_gear_deg)}


def _centroids(bench, plan_sets: dict, *, seed, method, engine, progress):
    """Centroid tables for every named plan: rendered and centroided, or from the surrogate."""
    if engine == "surrogate":
        from .sim.identify import surrogate_centroids

        return {k: surrogate_centroids(bench, p, seed) for k, p in plan_sets.items()}
    from . import centroid, parallel, sim

    lazy = {k: centroid.locate(sim.simulate(p, bench, seed=seed, chunks="pose"), method=method,
                               compute=False)
            for k, p in plan_sets.items()}
    if progress:
        n = sum(len(p) * p.shots for p in plan_sets.values())
        print(f"rendering and centroiding {n} frames ({method})", flush=True)
    done = parallel.compute(*lazy.values(), progress=progress)
    return dict(zip(lazy, done, strict=True))


def reproduce_platform(*, quick: bool = False, seed: int = 0, method: str = "projection",
                       out: str | Path | None = "results", progress: bool = True,
                       engine: str = "render", bench=None, checks: int = 4) -> dict:
    """The platform table: the paper's protocol, the diagnosis, and each remedy.

    Parameters
    ----------
    quick : bool
        :data:`sunlab.reproduce.QUICK` settings (every 2nd angle, 2 shots per pose).
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
        (:func:`sunlab.sim.identify.surrogate_centroids`, seconds instead of minutes).
    bench : sunlab.sim.Bench, optional
        Default :meth:`sunlab.sim.Bench.paper_single_hole`.
    checks : int
        Zero-pose visits per run (:func:`sunlab.plans.zero_check`).

    Returns
    -------
    dict
        ``rows`` (name -> the eight statistics, as ``table4.json``'s ``ours``),
        ``parameters`` (name -> ``fitted``, ``stderr``, ``bench``, ``z``), ``diagnosis``,
        ``paper_shape``, ``must_show``, ``settings``, ``files``.

    Examples
    --------
    >>> res = reproduce_platform(engine="surrogate", quick=True, out=None, progress=False)
    >>> res["diagnosis"]["candidate"]
    'backlash'
    """
    from . import plans, sim, stats
    from . import platform_fault as pf
    from .calibration import Polynomial
    from .errors import ConfigurationError
    from .reproduce import experiment_plans, usable_table

    if engine not in ("render", "surrogate"):
        raise ConfigurationError(
            f"engine: found {engine!r}; expected 'render' or 'surrogate'."
        )
    t0 = time.perf_counter()
    bench = sim.Bench.paper_single_hole() if bench is None else bench
    paper = experiment_plans(quick=quick)
    uni = {k: p.with_motion(approach="unidirectional") for k, p in paper.items()}
    sets = {}
    for tag, ps in (("paper", paper), ("uni", uni)):
        for k, p in ps.items():
            sets[f"{tag} {k}"] = p
    # one zero-pose check per run, taken after homing (its plan is the same for both protocols)
    for k in ("I", "III"):
        sets[f"zero {k}"] = plans.zero_check(paper[k], checks)
    cens = {k: usable_table(v) for k, v in _centroids(
        bench, sets, seed=seed, method=method, engine=engine, progress=progress).items()}
    t_sim = time.perf_counter() - t0

    local, fits = {}, {}
    for tag in ("paper", "uni"):
        tr, va, te = (cens[f"{tag} {k}"] for k in ("I", "II", "III"))
        cal, _ = Polynomial.select_order(tr, va)
        fits[tag] = cal
        local[tag] = stats.local_errors(cal.predict(te))
    rows = {ROWS[0]: local["paper"], ROWS[1]: local["uni"]}
    # (a) + zero check: the homing difference from the zero-pose checks, no backlash term
    jc_a = pf.fit_correction(cens["uni I"], uni["I"], cens["uni II"], backlash=False,
                             zero_train=cens["zero I"], zero_test=cens["zero III"])
    est = jc_a.predict(cens["uni III"])
    rows[ROWS[2]] = stats.local_errors(est, jc_a.reference(est, uni["III"]))
    # (b) backlash from the motion record, then with the zero-pose checks
    jc_b = pf.fit_correction(cens["paper I"], paper["I"], cens["paper II"])
    est = jc_b.predict(cens["paper III"])
    rows[ROWS[3]] = stats.local_errors(est, jc_b.reference(est, paper["III"]))
    jc_bh = pf.fit_correction(cens["paper I"], paper["I"], cens["paper II"],
                              zero_train=cens["zero I"], zero_test=cens["zero III"])
    est = jc_bh.predict(cens["paper III"])
    rows[ROWS[4]] = stats.local_errors(est, jc_bh.reference(est, paper["III"]))
    diag = pf.diagnose(fits["paper"].predict(cens["paper III"]), paper["III"])
    jc_params = jc_bh
    if diag.candidate == "gear":
        # the gear term at the frequency the periodogram found (the alias the grid sees)
        f = diag.evidence["periodogram"]["peak_frequency"]
        jc_g = pf.fit_correction(cens["paper I"], paper["I"], cens["paper II"],
                                 gear_frequency=f, zero_train=cens["zero I"],
                                 zero_test=cens["zero III"])
        est = jc_g.predict(cens["paper III"])
        rows[GEAR_ROW] = stats.local_errors(est, jc_g.reference(est, paper["III"]))
        jc_params = jc_g
    table = stats.global_stats(rows)

    truth = bench_fault_values(bench, seed, paper)
    parameters = {}
    for name, p in jc_params.parameters.items():
        z = (p["fitted"] - truth[name]) / p["stderr"] if p["stderr"] > 0 else float("inf")
        parameters[name] = {"fitted": p["fitted"], "stderr": p["stderr"], "bench": truth[name],
                            "z": z, "from": ROWS[4] if jc_params is jc_bh else GEAR_ROW}

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
    result = {
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
        "settings": {"seed": seed, "quick": quick, "engine": engine, "centroid_method": method,
                     "scan": paper["III"].scan, "zero_checks": checks,
                     "poses": {k: len(p) for k, p in paper.items()},
                     "shots": paper["III"].shots,
                     "bench": "sunlab.sim.Bench.paper_single_hole()"},
        "timings_s": {"simulate_and_centroid": round(t_sim, 2),
                      "total": round(time.perf_counter() - t0, 2)},
        "files": [],
    }
    if out is not None:
        out = Path(out)
        out.mkdir(parents=True, exist_ok=True)
        (out / "platform.json").write_text(json.dumps(result, indent=2, default=_jsonable))
        result["files"] = [str(out / "platform.json")]
    return result


def _jsonable(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)


def format_platform(res: dict) -> str:
    """The platform table as text: rows, fitted parameters beside the bench's, the diagnosis.

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
    lines.append(f"Best remedy: {m['best_remedy']}: beta mu {m['best_beta_mu']:.4f} "
                 f"(<= {m['limit_alpha']:.4f} and <= {m['limit_beta']:.4f}: "
                 f"{m['beta_mu_within_1.3x_polynomial_alpha_mu']} and "
                 f"{m['beta_mu_within_0.6x_polynomial_beta_mu']}); parameters within 2.5 s.e.: "
                 f"{m['parameters_within_2.5_stderr']}")
    return "\n".join(lines)
