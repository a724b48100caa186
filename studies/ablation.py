"""The identified bench with each component turned off: what each carries of the score.

The bench is the chosen hypothesis's with a seed's nuisance draw and fit as the evidence
recorded them (no refit), each :data:`ABLATIONS` entry applied in turn to both the one-hole and
the 100-hole bench, and scored like :func:`studies.evidence.score_table` with the
hypothesis's own spread over seeds and its discrepancy tau (protocol: docs/identification.md).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .evidence import (
    _data,
    _log_density,
    chosen_hypothesis,
    load_evidence,
    recorded_draw,
    scored_arrays,
)
from .identification import _quantity, load_protocol, predict_cells, run_all

__all__ = ["ablation"]

#: Each component of the identified bench and how :func:`ablation` turns it off.
ABLATIONS = {
    "glass lid": {"detector__lid_thickness_mm": 0.0},
    "pixel response (PRNU)": {"detector__prnu": 0.0, "detector__prnu_correlated": 0.0},
    "one-hole mask's play": {"mask__play_x_mm": 0.0},
    "100-hole mask's play": {"mask__play_y_mm": 0.0},
    "gear error": {"platform__beta_gear_deg": 0.0},
    "rehoming (a drift per run instead)": "drift",
    "boresight rotation gamma0": {"platform__gamma0_deg": 0.0},
}


def ablation(name: str | None = None, seeds=None, evidence: pd.DataFrame | None = None,
             cells: pd.DataFrame | None = None, *, jobs: int = 1) -> pd.DataFrame:
    """The held-out score of the identified bench with each component turned off.

    The bench is the hypothesis's with its seed's nuisance draw and fit (no refit: what the
    component contributes to the predictions), each :data:`ABLATIONS` entry applied in turn,
    scored like :func:`studies.evidence.score_table` with the hypothesis's own
    spread and tau.

    Parameters
    ----------
    name : str, optional
        The hypothesis (default :func:`identified_hypothesis`).
    seeds : iterable of int, optional
        Confirmation seeds (default the protocol's first).
    evidence, cells : pandas.DataFrame, optional
        The evidence and its cells (default the shipped ones).
    jobs : int
        Processes that predict the ablated benches side by side.

    Returns
    -------
    pandas.DataFrame
        One row per component and seed: ``component``, ``seed``, ``score`` and
        ``held_out_rms_log``; the component ``none`` is the full bench.
    """
    protocol = load_protocol()
    evidence = load_evidence() if evidence is None else evidence
    cells = _data("evidence_cells.csv") if cells is None else cells
    name = name or chosen_hypothesis(evidence, protocol)
    seeds = protocol["confirmation_seeds"][:1] if seeds is None else seeds
    a = scored_arrays(cells[cells["hypothesis"] == name], protocol)
    q, log_paper = a["quantities"], a["paper"]
    sd2 = a["by_h"][name]["held"].std(axis=0, ddof=1) ** 2
    tau = float(evidence.loc[evidence["hypothesis"] == name, "tau"].iloc[0])
    var = sd2 + tau**2
    tasks = []
    for seed in seeds:
        rec, nuis, fitted = recorded_draw(protocol, evidence, name, seed)
        # "drift": the fitted zero shift at a new homing as a drift per run of half its size
        drift = {"platform__beta_rehoming_deg": 0.0,
                 "platform__beta_drift_deg": fitted["beta_zero_shift_deg"] / 2}
        tasks += [(comp, int(seed), (protocol, name, nuis, fitted, int(seed),
                                     float(rec["noise_px"]), drift if ch == "drift" else ch))
                  for comp, ch in {"none": {}, **ABLATIONS}.items()]
    preds = dict(run_all(predict_cells, [t[2] for t in tasks], jobs))
    preds = [preds[i] for i in range(len(tasks))]
    rows = []
    for (comp, seed, _), pred in zip(tasks, preds, strict=True):
        lp = np.array([math.log(max(_quantity(pred, *x), 1e-9)) for x in q])
        r = log_paper - lp
        rows.append({"component": comp, "seed": seed,
                     "score": _log_density(r, var),
                     "held_out_rms_log": float(np.sqrt(np.mean(r**2)))})
    return pd.DataFrame(rows)
