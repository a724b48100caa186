"""Identification of the virtual bench from the paper's tables, under a fixed protocol.

The paper publishes statistics, not its bench. This study asks which physically different bench
(a *hypothesis*) predicts the published numbers it was *not* fitted on, under the protocol of
``studies/protocol.json`` (prose: docs/identification.md), which was committed before any of
its scores:

* every hypothesis is fitted on Table 4's polynomial and linear-interpolation columns (its
  fitted parameters, each pinned by one cell) and predicts the rest: Table 4's cubic
  interpolation and NN strategy 4, and Table 5's two 100-hole columns;
* parameters the fit side cannot pin (the pixel response, the 100-hole mask's play, how the
  one hole's alpha error divides between platform and mask, the gear's period) are nuisances,
  drawn from their priors once per seed; the fit follows each draw, so the spread of a
  prediction over the seeds is its spread over noise *and* parameters;
* the score of a hypothesis on a seed is the held-out log predictive density
  (:func:`studies.evidence.score_table`), the rule (:func:`studies.evidence.chosen_hypothesis`)
  is the one-standard-error rule, and each published cell gets a 90 % predictive interval
  (:func:`studies.evidence.intervals`).

The predictions come from the centroid-level surrogate of :mod:`sunlab.sim.surrogate` (geometry,
platform table and pixel-response maps, no frames rendered). The protocol is
``studies/protocol.json``; the evidence is written by ``python -m studies.identify`` into
``studies/results/`` (the evidence tables) and ``sunlab/data/`` (``presets.json`` and
``intervals.csv``, which the library reads).

Examples
--------
>>> p = load_protocol()
>>> sorted(p["hypotheses"]), p["confirmation_seeds"][:2]
(['F17', 'F17-gear', 'F5', 'F5-gear'], [3000, 3001])
>>> len(scored_quantities(p)["fit"]), len(scored_quantities(p)["held_out"])
(12, 24)
"""

from __future__ import annotations

import json
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from sunlab.errors import ConfigurationError

__all__ = ["load_protocol", "run_hypothesis"]

#: This folder: the protocol, and the evidence tables under ``results/``.
HERE = Path(__file__).resolve().parent
#: The library's data: the presets and intervals the studies write for it.
LIBRARY_DATA = HERE.parent / "sunlab" / "data"



def load_protocol(path=None) -> dict:
    """The identification protocol (``studies/protocol.json``, or the file at ``path``).

    Parameters
    ----------
    path : str or pathlib.Path, optional
        A protocol file of the same form.

    Returns
    -------
    dict
        ``hypotheses`` (name -> ``F_mm``, ``gear``, ``parameters``), ``priors``, ``cells``,
        ``score``, ``rule``, ``confirmation_seeds``, ``history``.
    """
    return read_json(HERE / "protocol.json" if path is None else path, "restore the file from "
                     "git; a change of protocol is a new dated entry, never an edit.")


def read_json(path, fix: str):
    """The JSON file at ``path``; one that is not JSON is refused with ``fix``.

    Parameters
    ----------
    path : str or pathlib.Path
    fix : str
        What to do about a file that is not JSON (the error's ``Fix:``).

    Returns
    -------
    object
        The parsed document.
    """
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except json.JSONDecodeError as err:
        raise ConfigurationError(f"{path}: not JSON ({err}). Fix: {fix}") from None


def run_all(fn, tasks, jobs: int = 1):
    """Yield ``(i, fn(*tasks[i]))`` as each task finishes, in this process (``jobs`` 1) or in
    ``jobs`` processes; BLAS on one thread (the many small solves of a fit are slowed
    several-fold by idle BLAS threads on a busy machine; the results are the same)."""
    from sunlab.parallel import single_threaded_blas

    if jobs <= 1:
        with single_threaded_blas():
            yield from ((i, fn(*t)) for i, t in enumerate(tasks))
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed

    with ProcessPoolExecutor(jobs, initializer=single_threaded_blas) as pool:
        futures = {pool.submit(fn, *t): i for i, t in enumerate(tasks)}
        yield from ((futures[f], f.result()) for f in as_completed(futures))


# ----------------------------------------------------------------------------- cells
def _cells(**tables) -> dict[tuple, float]:
    """``(table, column, angle, stat) -> value`` of tables laid out as
    :func:`sunlab.stats.evaluate` lays them out, keyed by table name (``table4=...``)."""
    return {(name, col, angle, stat): float(v) for name, table in tables.items()
            for col in table.columns for (angle, stat), v in table[col].items()}


def _paper_cells() -> dict[tuple, float]:
    from sunlab import stats

    return _cells(table4=stats.paper_table4(), table5=stats.paper_table5())


def _quantity(cells: dict, table: str, col: str, angle: str, stat: str) -> float:
    """A scored quantity from a dict of cells: mu, sigma, or M - mu."""
    if stat == "M-mu":
        return cells[(table, col, angle, "M")] - cells[(table, col, angle, "mu")]
    return cells[(table, col, angle, stat)]


def scored_quantities(protocol: dict) -> dict[str, list[tuple]]:
    """The fit-side and held-out quantities ``(table, column, angle, stat)`` of the protocol.

    Parameters
    ----------
    protocol : dict
        As :func:`load_protocol` returns it.

    Returns
    -------
    dict
        ``"fit"`` and ``"held_out"``, lists of 4-tuples; ``stat`` is ``mu``, ``sigma`` or
        ``M-mu``.
    """
    stats_ = protocol["cells"]["scored_stats"]
    out = {}
    for side in ("fit", "held_out"):
        out[side] = [(table, col, angle, stat)
                     for table, cols in protocol["cells"][side].items()
                     for col in cols for angle in ("alpha", "beta") for stat in stats_]
    return out


# ----------------------------------------------------------------------------- priors
def _draw(prior: dict, rng: np.random.Generator) -> float:
    lo, hi = float(prior["low"]), float(prior["high"])
    u = rng.uniform()
    if prior["kind"] == "uniform":
        return lo + u * (hi - lo)
    if prior["kind"] == "log-uniform":
        return math.exp(math.log(lo) + u * (math.log(hi) - math.log(lo)))
    raise ConfigurationError(
        f"protocol prior kind {prior['kind']!r}; expected 'uniform' or 'log-uniform'.")


def _median(prior: dict) -> float:
    lo, hi = float(prior["low"]), float(prior["high"])
    return 0.5 * (lo + hi) if prior["kind"] == "uniform" else math.sqrt(lo * hi)


def draw_nuisances(protocol: dict, seed: int | None) -> dict[str, float]:
    """One draw of every nuisance parameter from its prior (``seed=None``: the prior medians).

    The same seed gives the same draw to every hypothesis (a paired comparison); the priors
    are drawn in the sorted order of their names.

    Examples
    --------
    >>> p = load_protocol()
    >>> d = draw_nuisances(p, 1000)
    >>> 0.005 <= d["prnu_total"] <= 0.03, draw_nuisances(p, 1000) == d
    (True, True)
    >>> round(draw_nuisances(p, None)["alpha_platform_share"], 2)
    0.5
    """
    priors = protocol["priors"]
    if seed is None:
        return {k: _median(priors[k]) for k in sorted(priors)}
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x1DE17]))
    return {k: _draw(priors[k], rng) for k in sorted(priors)}


# ----------------------------------------------------------------------------- benches
def hypothesis_bench(protocol: dict, name: str, nuisances: dict, fitted: dict, *,
                     multi: bool = False):
    """The paper's bench under one hypothesis, its nuisance draw and its fitted parameters.

    The geometry (hole place relative to the spot's track, mask tilt and offset, mounting,
    dF as the optimised model sees it) is the presets'; everything the protocol names is set
    here, so the bench does not depend on the identified presets.

    Parameters
    ----------
    protocol : dict
        :func:`load_protocol`.
    name : str
        A hypothesis of the protocol.
    nuisances : dict
        :func:`draw_nuisances`.
    fitted : dict
        ``alpha_total_deg``, ``beta_zero_shift_deg``, ``beta_pose_error_deg``,
        ``alpha_jitter_deg``, ``beta_jitter_deg`` (the presets' when left out) and, for a
        hypothesis with a gear error, ``beta_gear_deg`` and ``gear_period_deg`` (deg).
    multi : bool
        The 100-hole mask instead of the one hole.

    Returns
    -------
    sunlab.sim.Bench
    """
    from sunlab.sim import Bench
    from sunlab.sim.mask import PAPER_DISTANCE_MM

    try:
        hyp = protocol["hypotheses"][name]
    except KeyError:
        raise ConfigurationError(
            f"hypothesis {name!r}: not in the protocol; expected one of "
            f"{sorted(protocol['hypotheses'])}.") from None
    base = Bench.paper_multi_hole() if multi else Bench.paper_single_hole()
    f_mm = float(hyp["F_mm"])
    # the pattern's centre follows the spot's track (scales with F); its 0.5 mm pitch does not
    scale = f_mm / PAPER_DISTANCE_MM - 1.0
    cx = float(np.mean([h.x_mm for h in base.mask.holes]))
    cy = float(np.mean([h.y_mm for h in base.mask.holes]))
    holes = tuple(replace(h, x_mm=h.x_mm + cx * scale, y_mm=h.y_mm + cy * scale)
                  for h in base.mask.holes)
    prnu_part = nuisances["prnu_total"] / math.sqrt(2.0)
    share = nuisances["alpha_platform_share"]
    alpha_total = fitted["alpha_total_deg"]
    single_play_deg = math.sqrt(max(1.0 - share**2, 0.0)) * alpha_total
    gear = bool(hyp["gear"])
    changes = dict(
        mask__distance_mm=f_mm, mask__holes=holes,
        detector__prnu=prnu_part, detector__prnu_correlated=prnu_part,
        detector__prnu_correlation_px=nuisances["prnu_correlation_px"],
        platform__alpha_pose_error_deg=share * alpha_total,
        platform__beta_pose_error_deg=fitted["beta_pose_error_deg"],
        platform__beta_rehoming_deg=fitted["beta_zero_shift_deg"],
        platform__beta_drift_deg=0.0, platform__beta_backlash_deg=0.0,
        platform__beta_wobble_deg=0.0, platform__nonorthogonality_deg=0.0,
        platform__beta_gear_deg=fitted.get("beta_gear_deg", 0.0) if gear else 0.0,
        platform__beta_gear_period_deg=(float(fitted["gear_period_deg"]) if gear
                                        else base.platform.beta_gear_period_deg),
    )
    # per-shot jitter: fitted from protocol version 3 on (earlier fits leave the presets')
    for axis in ("alpha", "beta"):
        if f"{axis}_jitter_deg" in fitted:
            changes[f"platform__{axis}_jitter_deg"] = fitted[f"{axis}_jitter_deg"]
    bench = base.replace(**changes)
    if multi:
        bench = bench.replace(mask__play_x_mm=0.0, mask__play_y_mm=nuisances["multi_play_mm"])
    else:
        play_mm = math.tan(math.radians(single_play_deg)) * bench.mask.true_distance_mm
        bench = bench.replace(mask__play_x_mm=play_mm, mask__play_y_mm=0.0)
    return bench


# ----------------------------------------------------------------------------- surrogate
def surrogate_runs(bench, seed: int = 0, step: int = 1, shots: int = 8,
                   noise_px: float = 0.004) -> dict:
    """Surrogate centroid tables of experiments I-III, each with its run's zero-pose centroid
    in its attributes (what a network re-zeroed on the zero pose reads).

    Parameters
    ----------
    bench : sunlab.sim.Bench
    seed : int
        Seed of the experiments (:func:`sunlab.sim.simulate`'s).
    step, shots : int
        Every ``step``-th angle along each grid axis, ``shots`` frames per pose.
    noise_px : float
        Per-shot centroid noise, px RMS per axis.

    Returns
    -------
    dict of str to xarray.Dataset
        ``centroids/1`` tables keyed ``"I"``, ``"II"``, ``"III"``.
    """
    from sunlab import plans
    from sunlab.reproduce.pipeline import experiment_plans
    from sunlab.sim.surrogate import surrogate_centroids

    out = {}
    for name, plan in experiment_plans(step=step, shots=shots).items():
        cen = surrogate_centroids(bench, plan, seed, noise_px=noise_px)
        zero = surrogate_centroids(bench, plans.zero_check(plan, 1), seed, noise_px=noise_px)
        out[name] = cen.assign_attrs(zero_pose_x_px=float(zero.x.mean()),
                                     zero_pose_y_px=float(zero.y.mean()))
    return out


#: The rescaling power of each fitted parameter (its cell grows about as the parameter to
#: 1 / power: the one-hole's alpha mu adds the pixel response in quadrature, the linear
#: interpolation's beta sigma adds the gear error to the rest in quadrature; M - mu grows
#: linearly with the jitter, 1.4 x jitter over a floor of the centroid noise).
_POWER = {"alpha_total_deg": 1.5, "beta_zero_shift_deg": 1.0, "beta_pose_error_deg": 1.0,
          "beta_gear_deg": 2.0, "alpha_jitter_deg": 1.0, "beta_jitter_deg": 1.0}


def fit_hypothesis(protocol: dict, name: str, nuisances: dict, *, seed: int,
                   iterations: int | None = None, noise_px: float | None = None,
                   fixed: dict | None = None) -> dict:
    """The fitted parameters of one hypothesis on its pinning cells (Table 4, surrogate).

    Each fitted parameter starts at its pinning cell's paper value (deg) and is rescaled by
    that cell's paper / predicted ratio to the power of :data:`_POWER`, each step's factor and
    the parameter bounded as the protocol's ``fit`` says, ``iterations`` times (the
    protocol's 4 by default); the fit side is then evaluated once more at the result.

    Parameters
    ----------
    protocol : dict
    name : str
        A hypothesis of the protocol.
    nuisances : dict
        :func:`draw_nuisances`.
    seed : int
        Seed of the surrogate's runs.
    iterations : int, optional
    noise_px : float, optional
        Per-shot centroid noise, px (default measured on the hypothesis's bench).
    fixed : dict, optional
        Parameters held at the given values (deg; a profile likelihood's), not fitted; a
        gear hypothesis's ``gear_period_deg`` goes here when the protocol fits it.

    Returns
    -------
    dict
        The fitted parameters (deg), the ``fixed`` ones, ``"pinning"`` (the pinning cells'
        predictions at the result), ``"fit_ssr"`` (the sum over the fit side's quantities of
        squared log residuals, paper against prediction) and ``"noise_px"``.
    """
    fixed = dict(fixed or {})
    pins = {k: tuple(v) for k, v in protocol["cells"]["pinning"].items()}
    if not protocol["hypotheses"][name]["gear"]:
        pins.pop("beta_gear_deg")
    paper = _paper_cells()
    iterations = iterations or int(protocol["fit"].get("iterations", 4))
    target = {k: _quantity(paper, *cell) for k, cell in pins.items()}
    fitted = {**target, **{k: float(v) for k, v in fixed.items()}}
    step_bounds = protocol["fit"]["step_bounds"]
    bounds = protocol["fit"]["parameter_bounds_deg"]
    if noise_px is None:
        from .surrogate_tables import centroid_noise_px

        noise_px = centroid_noise_px(hypothesis_bench(protocol, name, nuisances, fitted),
                                     frames=6)
    for _ in range(iterations):
        table = _fit_side_cells(protocol, name, nuisances, fitted, seed, noise_px)
        fitted = {k: v if k in fixed else
                  float(np.clip(v * np.clip((target[k] / _quantity(table, *pins[k])) ** _POWER[k],
                                            *step_bounds), *bounds))
                  for k, v in fitted.items()}
    table = _fit_side_cells(protocol, name, nuisances, fitted, seed, noise_px)
    fit_q = scored_quantities(protocol)["fit"]
    ssr = float(sum((math.log(_quantity(paper, *q)) - math.log(max(_quantity(table, *q), 1e-9)))
                    ** 2 for q in fit_q))
    return {**fitted, "pinning": {cell: _quantity(table, *cell) for cell in pins.values()},
            "fit_ssr": ssr, "noise_px": noise_px}


def _fit_side_cells(protocol: dict, name: str, nuisances: dict, fitted: dict, seed: int,
                    noise_px: float) -> dict:
    """Table 4's fit-side columns (polynomial, linear interpolation) on the surrogate."""
    from sunlab import stats
    from sunlab.calibration.registry import RECIPES, fit

    setting = protocol["fit"]["surrogate"]
    bench = hypothesis_bench(protocol, name, nuisances, fitted)
    cens = surrogate_runs(bench, seed, setting["step"], setting["shots"], noise_px)
    # Table 4's recipes as `sunlab reproduce` fits them (unscreened), linear interpolation
    # without its leave-one-out diagnostic (the predictions are the same)
    extra = {"polynomial": {}, "linear interp.": {"leave_one_out": False}}
    cols = {m: fit(cens["I"], RECIPES[m][0], cens["II"], outlier_mads=None,
                   **RECIPES[m][1], **extra[m]) for m in extra}
    return _cells(table4=stats.evaluate(cols, cens["III"]))


def fit_draw(protocol: dict, name: str, nuisances: dict, *, seed: int,
             fixed: dict | None = None) -> dict:
    """:func:`fit_hypothesis`, with a gear hypothesis's period profiled on the protocol's grid.

    Under protocol version 4 the gear period is fitted: the other parameters are fitted at
    each period of ``protocol["fit"]["gear_period"]["grid_deg"]`` and the period whose fit
    has the least ``fit_ssr`` is kept (earlier versions drew it as a nuisance).

    Returns
    -------
    dict
        As :func:`fit_hypothesis`, with ``gear_period_deg`` for a gear hypothesis and
        ``period_ssr`` (period -> fit_ssr over the grid).
    """
    fixed = dict(fixed or {})
    grid = protocol["fit"].get("gear_period", {}).get("grid_deg")
    if (not protocol["hypotheses"][name]["gear"] or not grid
            or "gear_period_deg" in fixed):
        return fit_hypothesis(protocol, name, nuisances, seed=seed, fixed=fixed)
    noise = None
    fits = {}
    for period in grid:
        fits[period] = fit_hypothesis(protocol, name, nuisances, seed=seed, noise_px=noise,
                                      fixed={**fixed, "gear_period_deg": float(period)})
        noise = fits[period]["noise_px"]  # the period does not change the frames' noise
    best = min(grid, key=lambda p: fits[p]["fit_ssr"])
    return {**fits[best], "period_ssr": {float(p): fits[p]["fit_ssr"] for p in grid}}


def predict_cells(protocol: dict, name: str, nuisances: dict, fitted: dict, seed: int,
                  noise_px: float, change: dict | None = None) -> dict[tuple, float]:
    """Every published cell of Tables 4 and 5 as one fitted hypothesis predicts it.

    Table 4's four columns (the paper's recipes, NN strategy 4 re-zeroed on each run's zero
    pose) and Table 5's three (the 100-hole calibrations take the order Table 4's polynomial
    chose, as ``sunlab reproduce --table 5`` does), on the protocol's surrogate settings.
    ``change`` (:meth:`sunlab.sim.Bench.replace`'s keywords) is applied to both benches, the
    one-hole and the 100-hole (an ablation's, :mod:`studies.ablation`).

    Parameters
    ----------
    protocol : dict
    name : str
        A hypothesis of the protocol.
    nuisances, fitted : dict
        :func:`draw_nuisances` and the fitted parameters (deg).
    seed : int
        Seed of the surrogate's runs.
    noise_px : float
        Per-shot centroid noise, px.
    change : dict, optional
        Bench changes applied to both benches.

    Returns
    -------
    dict
        ``(table, column, angle, stat) -> value`` (deg).
    """
    from sunlab import stats
    from sunlab.calibration import table4_methods
    from sunlab.calibration.registry import RECIPES, fit

    from .surrogate_tables import surrogate_table5

    single, multi = (hypothesis_bench(protocol, name, nuisances, fitted, multi=m)
                     for m in (False, True))
    if change:
        single, multi = single.replace(**change), multi.replace(**change)
    setting = protocol["fit"]["predict"]
    cens = surrogate_runs(single, seed, setting["step"], setting["shots"], noise_px)
    fits = table4_methods(seed=seed, reference="zero_pose")
    # the interpolations without their leave-one-out diagnostic (it enters no cell)
    fitted_cal = {m: fit(cens["I"], RECIPES[m][0], cens["II"], outlier_mads=None,
                         leave_one_out=False) if m.endswith("interp.")
                  else fits[m](cens["I"], cens["II"]) for m in stats.paper_table4().columns}
    t4 = stats.evaluate(fitted_cal, cens["III"])
    t5 = surrogate_table5(multi, single, seed, step=setting["table5_step"],
                          shots=setting["shots"], order=int(max(fitted_cal["polynomial"].orders)),
                          one_hole=fitted_cal["polynomial"], noise_px=noise_px)
    return _cells(table4=t4, table5=t5)


def run_hypothesis(protocol: dict, name: str, seed: int) -> pd.DataFrame:
    """One hypothesis on one seed: draw, fit, predict; a long table of every cell.

    Parameters
    ----------
    protocol : dict
    name : str
        A key of ``protocol["hypotheses"]``.
    seed : int
        Seed of the nuisance draw (:func:`draw_nuisances`) and of the surrogate's runs.

    Returns
    -------
    pandas.DataFrame
        One row per published cell: ``hypothesis``, ``seed``, ``table``, ``column``,
        ``angle``, ``stat``, ``value`` (deg), plus the draw and the fit as columns.
    """
    nuis = draw_nuisances(protocol, seed)
    fit = fit_draw(protocol, name, nuis, seed=seed)
    fitted = _parameters(fit)
    cells = predict_cells(protocol, name, nuis, fitted, seed=seed, noise_px=fit["noise_px"])
    rows = [{"hypothesis": name, "seed": int(seed), "table": t, "column": c, "angle": a,
             "stat": s, "value": v} for (t, c, a, s), v in cells.items()]
    extra = {**nuis, **fitted, "fit_ssr": fit["fit_ssr"], "noise_px": fit["noise_px"]}
    return pd.DataFrame(rows).assign(**extra)


def _parameters(fit: dict) -> dict:
    """The bench's parameters of a fit (deg), without its diagnostics."""
    return {k: v for k, v in fit.items()
            if k not in ("pinning", "noise_px", "fit_ssr", "period_ssr")}
