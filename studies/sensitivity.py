"""The verdicts' sensitivity: the shipped evidence rescored row by row.

Run as ``python -m studies.sensitivity``. The protocol's ``sensitivity`` section
(``studies/protocol.json``; docs/identification.md, declared before this table was computed)
names the rows: the score as written; Table 4's
held-out cells only; Table 5's only; mu and sigma only; without Table 5's two 100-hole beta
M - mu; tau's variants; a pooled predictive density bootstrapped over seeds. Each row rescores
the shipped version 4 predictions (``studies/results/evidence_cells.csv``: no rerun) and applies
the one-standard-error rule to its own scores (:func:`sensitivity_table`). A component (F; the
gear error) is *identified* only where every row gives it the same value (:func:`verdicts`).

Examples
--------
>>> t = sensitivity_table()
>>> t.loc[t["row"] == "protocol", "pick"].item()
'F5'
>>> verdicts(t)["F"]
'not identified'
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
import pandas as pd

from .evidence import (
    Z90,
    _data,
    _fitted_count,
    one_se_rule,
    scored_arrays,
    seed_scores,
    tau2,
)
from .identification import HERE, load_protocol

__all__ = ["interval_coverage", "quantity_z", "sensitivity_table", "verdicts"]

#: The bootstrap of the pooled row: resamples and the generator's seed (declared in the
#: protocol's ``sensitivity`` section).
BOOTSTRAP = 2000
BOOTSTRAP_SEED = 46

#: The seed-paired differences each row reports (first minus second, nats).
PAIRS = (("F5", "F17"), ("F5-gear", "F17-gear"), ("F5-gear", "F5"), ("F17-gear", "F17"))


def _selections(quantities: list) -> dict:
    """The rows' subsets of the held-out quantities (boolean masks)."""
    q = quantities
    beta_mm = {("table5", c, "beta", "M-mu") for c in
               ("100 holes: geometric centre", "100 holes: averaging")}
    return {
        "table4 held-out only": np.array([x[0] == "table4" for x in q]),
        "table5 only": np.array([x[0] == "table5" for x in q]),
        "mu and sigma only": np.array([x[3] in ("mu", "sigma") for x in q]),
        "without the 100-hole beta M - mu": np.array([tuple(x) not in beta_mm for x in q]),
    }


#: tau's variants (row -> tau^2 of the fit-side sums, the fitted count and the fit side's size).
TAU_ROWS = {
    "tau dof 12 - 6 for the gear": lambda ss, k, n: tau2(ss, min(k, 6), n),
    "tau without dof correction": lambda ss, k, n: tau2(ss, 0, n),
    "tau x 2": lambda ss, k, n: 4.0 * tau2(ss, k, n),
    "tau x 3": lambda ss, k, n: 9.0 * tau2(ss, k, n),
}


def _per_seed_scores(a: dict, protocol: dict, mask, tau2_of) -> dict[str, np.ndarray]:
    """Each hypothesis's score on each seed under a row (the protocol's formula)."""
    sel = np.ones(len(a["paper"]), bool) if mask is None else mask
    return {h: seed_scores(v["held"][:, sel], a["paper"][sel],
                           tau2_of(v["ss"], _fitted_count(protocol, h), a["n_fit"]))
            for h, v in a["by_h"].items()}


def _pooled(v: dict, paper: np.ndarray, idx: np.ndarray, k: int, n_fit: int) -> float:
    """The pooled predictive density of the seeds ``idx``: per quantity the mixture of
    N(log pred_s, tau^2) over them, tau from the same seeds; summed over quantities."""
    t2 = tau2(v["ss"][idx], k, n_fit)
    r = paper[None, :] - v["held"][idx]
    logn = -0.5 * r**2 / t2 - 0.5 * math.log(2 * math.pi * t2)
    m = logn.max(axis=0)
    return float(np.sum(m + np.log(np.mean(np.exp(logn - m), axis=0))))


def _component(protocol: dict, eligible: list[str], pick: str) -> dict:
    hyps = protocol["hypotheses"]
    out = {}
    for comp, get, fmt in (("F", lambda h: float(hyps[h]["F_mm"]), lambda v: f"{v:g} mm"),
                           ("gear", lambda h: bool(hyps[h]["gear"]),
                            lambda v: "gear error" if v else "no gear error")):
        values = {get(h) for h in eligible}
        out[comp] = fmt(get(pick)) if len(values) == 1 else "not identified"
    return out


def sensitivity_table(cells: pd.DataFrame | None = None, protocol: dict | None = None
                      ) -> pd.DataFrame:
    """The sensitivity table of the verdicts, from the per-cell evidence.

    Parameters
    ----------
    cells : pandas.DataFrame, optional
        ``evidence_cells.csv`` (default the shipped one, ``studies/results/``).
    protocol : dict, optional
        Default :func:`studies.identification.load_protocol`.

    Returns
    -------
    pandas.DataFrame
        One row per row of the protocol's ``sensitivity`` section: ``row``, ``quantities``
        (held-out quantities scored), ``score_H`` and ``se_H`` (mean score over the seeds and
        its standard error, nats) for each hypothesis H, ``eligible`` (``;``-joined), ``pick``
        (the one-standard-error rule's), ``d_A_B`` and ``se_d_A_B`` (seed-paired differences,
        A minus B; bootstrap standard errors in the pooled row), ``F`` and ``gear`` (the row's
        value of each component, or ``not identified``).
    """
    protocol = protocol or load_protocol()
    cells = _data("evidence_cells.csv") if cells is None else cells
    a = scored_arrays(cells, protocol)
    names = sorted(a["by_h"])
    params = {h: int(protocol["hypotheses"][h]["parameters"]) for h in names}
    rows = [("protocol", None, tau2),
            *[(name, mask, tau2) for name, mask in _selections(a["quantities"]).items()],
            *[(name, None, f) for name, f in TAU_ROWS.items()]]
    out = []
    for name, mask, tau2_of in rows:
        s = _per_seed_scores(a, protocol, mask, tau2_of)
        n = {h: len(s[h]) for h in names}
        mean = {h: float(np.mean(s[h])) for h in names}
        se = {h: float(np.std(s[h], ddof=1) / math.sqrt(n[h])) for h in names}
        diffs = {p: s[p[0]] - s[p[1]] for p in PAIRS if set(p) <= set(names)}
        d = {p: (float(np.mean(x)), float(np.std(x, ddof=1) / math.sqrt(len(x))))
             for p, x in diffs.items()}
        nq = int(len(a["paper"]) if mask is None else mask.sum())
        out.append(_record(protocol, name, nq, mean, se, d, params))
    out.append(_pooled_row(a, protocol, names, params))
    return pd.DataFrame(out)


def _pooled_row(a: dict, protocol: dict, names: list[str], params: dict) -> dict:
    """The pooled density's row: point values on all seeds, standard errors by bootstrap."""
    n_seeds = {len(a["by_h"][h]["seeds"]) for h in names}
    if len(n_seeds) != 1 or any(a["by_h"][h]["seeds"] != a["by_h"][names[0]]["seeds"]
                                for h in names):
        raise ValueError("the pooled row pairs the hypotheses by seed: every hypothesis needs "
                         "the same seeds")
    n = n_seeds.pop()
    k = {h: _fitted_count(protocol, h) for h in names}
    every = np.arange(n)
    point = {h: _pooled(a["by_h"][h], a["paper"], every, k[h], a["n_fit"]) for h in names}
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    boot = {h: [] for h in names}
    for _ in range(BOOTSTRAP):
        idx = rng.integers(0, n, n)
        for h in names:
            boot[h].append(_pooled(a["by_h"][h], a["paper"], idx, k[h], a["n_fit"]))
    boot = {h: np.array(v) for h, v in boot.items()}
    se = {h: float(np.std(boot[h], ddof=1)) for h in names}
    d = {p: (point[p[0]] - point[p[1]], float(np.std(boot[p[0]] - boot[p[1]], ddof=1)))
         for p in PAIRS if set(p) <= set(names)}
    return _record(protocol, "pooled density, bootstrap over seeds", len(a["paper"]), point,
                   se, d, params)


def _record(protocol, name, nq, mean, se, d, params) -> dict:
    pick, eligible = one_se_rule(mean, se, params)
    rec = {"row": name, "quantities": nq}
    for h in sorted(mean):
        rec[f"score_{h}"], rec[f"se_{h}"] = mean[h], se[h]
    rec.update(eligible=";".join(eligible), pick=pick)
    for (x, y), (m, e) in d.items():
        rec[f"d_{x}_{y}"], rec[f"se_d_{x}_{y}"] = m, e
    rec.update(_component(protocol, eligible, pick))
    return rec


def interval_coverage(intervals: pd.DataFrame | None = None) -> pd.DataFrame:
    """The paper's cells inside each hypothesis's 90 % intervals: held-out apart from the whole.

    Parameters
    ----------
    intervals : pandas.DataFrame, optional
        ``intervals.csv`` with its ``role`` column (default the shipped one, ``sunlab/data/``).

    Returns
    -------
    pandas.DataFrame
        One row per hypothesis and set of cells (``held-out``, ``all``): ``inside``, ``cells``
        and ``median_half_width`` ((hi - lo) / 2 / paper, the median over the cells).
    """
    from .evidence import load_intervals, with_roles

    ints = with_roles(load_intervals() if intervals is None else intervals)
    rows = []
    for h, g in ints.groupby("hypothesis"):
        for name, sel in (("held-out", g[g["role"] == "held-out"]), ("all", g)):
            hw = (sel["hi"] - sel["lo"]) / 2 / sel["paper"]
            rows.append({"hypothesis": h, "cells": name, "inside": int(sel["inside"].sum()),
                         "of": len(sel), "median_half_width": float(hw.median())})
    return pd.DataFrame(rows)


def quantity_z(cells: pd.DataFrame | None = None, hypothesis: str = "F5",
               protocol: dict | None = None) -> pd.DataFrame:
    """Each held-out scored quantity's z under a hypothesis: (log paper - mean log pred) /
    sqrt(seed spread^2 + tau^2), the protocol's predictive distribution.

    Returns
    -------
    pandas.DataFrame
        ``table``, ``column``, ``angle``, ``stat``, ``z``, ``inside`` (|z| <= 1.645).
    """
    protocol = protocol or load_protocol()
    cells = _data("evidence_cells.csv") if cells is None else cells
    a = scored_arrays(cells[cells["hypothesis"] == hypothesis], protocol)
    v = a["by_h"][hypothesis]
    sd = np.sqrt(v["held"].std(axis=0, ddof=1) ** 2
                 + tau2(v["ss"], _fitted_count(protocol, hypothesis), a["n_fit"]))
    z = (a["paper"] - v["held"].mean(axis=0)) / sd
    return pd.DataFrame([(*q, float(zi), bool(abs(zi) <= Z90))
                         for q, zi in zip(a["quantities"], z, strict=True)],
                        columns=["table", "column", "angle", "stat", "z", "inside"])


def verdicts(table: pd.DataFrame) -> dict[str, str]:
    """Each component's verdict: its value where every row of the table gives the same one,
    otherwise ``"not identified"``.

    Examples
    --------
    >>> verdicts(pd.DataFrame({"F": ["5 mm", "5 mm"], "gear": ["no gear error", "gear error"]}))
    {'F': 'identified: 5 mm', 'gear': 'not identified'}
    """
    out = {}
    for comp in ("F", "gear"):
        values = set(table[comp])
        out[comp] = (f"identified: {values.pop()}" if len(values) == 1
                     and "not identified" not in values else "not identified")
    return out


def build_parser() -> argparse.ArgumentParser:
    """The arguments of ``python -m studies.sensitivity``."""
    p = argparse.ArgumentParser(prog="python -m studies.sensitivity",
                                description="the verdicts' sensitivity table from the "
                                            "shipped per-cell evidence")
    p.add_argument("--out", default=str(HERE / "results" / "sensitivity.csv"), metavar="CSV")
    return p


def main(argv=None) -> int:
    """Write the sensitivity table (``--out``, default ``studies/results/sensitivity.csv``) and
    print it with the verdicts.

    Returns
    -------
    int
        0.
    """
    args = build_parser().parse_args(argv)
    t = sensitivity_table()
    t.to_csv(args.out, index=False, float_format="%.4g")
    cols = ["row", "quantities", *[c for c in t.columns if c.startswith("score_")], "pick",
            *[c for c in t.columns if c.startswith("d_")], "F", "gear"]
    with pd.option_context("display.width", 250, "display.max_columns", 30):
        print(t[cols].round(2).to_string(index=False))
        print("\nstandard errors of the differences:")
        print(t[["row", *[c for c in t.columns if c.startswith("se_d_")]]].round(2)
              .to_string(index=False))
    print(f"\nverdicts: {verdicts(t)}  (written to {args.out})")
    print("\nthe paper's cells inside each hypothesis's 90 % intervals (intervals.csv):")
    print(interval_coverage().round(3).to_string(index=False))
    z = quantity_z()
    print(f"\nF5 by held-out scored quantity: {int(z['inside'].sum())} of {len(z)} inside "
          f"(|z| <= 1.645), {int((z['z'].abs() > 3).sum())} beyond |z| = 3:")
    print(z[~z["inside"]].round(2).to_string(index=False))
    return 0


if __name__ == "__main__":
    sys.exit(main())
