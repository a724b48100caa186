"""The evidence of the identification: every (hypothesis, seed) run, scored, written and read.

:func:`regenerate` runs the protocol of ``studies/protocol.json`` on its confirmation seeds
(:func:`run_protocol`) and :func:`write_evidence` scores the predictions (:func:`score_table`:
the held-out log predictive density), applies the rule (:func:`chosen_hypothesis`: the
one-standard-error rule), gives each published cell its 90 % predictive interval
(:func:`intervals`) and writes the shipped tables (``python -m studies.identify``), which
:func:`load_evidence` and :func:`load_intervals` read back; the model is in
:mod:`studies.identification`, the presets and profiles in :mod:`.profiles`, the ablations in
:mod:`.ablation`.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from sunlab.errors import ConfigurationError

from .identification import (
    HERE,
    LIBRARY_DATA,
    _paper_cells,
    _quantity,
    load_protocol,
    run_all,
    run_hypothesis,
    scored_quantities,
)

__all__ = ["regenerate", "write_evidence", "identified_hypothesis", "interval_role"]

#: The standard normal quantile of 95 %: a central 90 % interval is mean +- Z90 sd.
Z90 = 1.6448536269514722


#: CPU seconds of one (hypothesis, seed) run, without and with a gear (its period profiled on
#: 7 grid points), and of the presets, profiles and ablations after the runs, measured on the
#: project's machine (2026-11-28, BLAS on one thread: F5 5.9 s, F5-gear 21.0 s once a process
#: is warm, 7 s more for its first; the three stages whole 104 s, with 2 processes): the
#: estimate printed before a run.
RUN_SECONDS = {False: 7.0, True: 22.0}
STAGES_SECONDS = 110.0


def run_protocol(protocol: dict, names=None, seeds=None, *, jobs: int = 1, parts=None,
                 progress: Callable | None = None, after_s: float = 0.0) -> pd.DataFrame:
    """Every (hypothesis, seed) of the protocol: the long table of predicted cells.

    ``jobs`` > 1 runs them in that many processes (each builds its own surrogate maps). With
    ``parts`` (a folder), each run's cells are written there as it finishes
    (``HYPOTHESIS-SEED.csv``, atomically, beside ``stamp.json``: the protocol's version and a
    digest of the code) and a later call skips the runs found there: an interrupted run
    resumes. Parts of another protocol version or code are refused. ``progress(line,
    always)`` gets the estimate first (``always`` True; ``after_s``: CPU seconds of the work
    that follows the runs), then a line as each run ends.
    """
    from sunlab.atomic import write_text

    names = list(names or protocol["hypotheses"])
    seeds = list(seeds if seeds is not None else protocol["confirmation_seeds"])
    tasks = [(h, int(s)) for h in names for s in seeds]
    gear = {h: bool(protocol["hypotheses"][h]["gear"]) for h in names}
    path = {t: Path(parts) / f"{t[0]}-{t[1]}.csv" for t in tasks} if parts else {}
    if parts:
        _check_parts(Path(parts), protocol)
    todo = sorted((t for t in tasks if not path or not path[t].exists()),
                  key=lambda t: not gear[t[0]])  # the long runs first: the processes end together
    left = sum(RUN_SECONDS[gear[h]] for h, _ in todo)
    if progress:
        progress(f"{len(todo)} of {len(tasks)} runs to go: about "
                 f"{(left + after_s) / 60 / jobs:.1f} min on {jobs} idle cores", True)
    start, done, cells = time.monotonic(), 0.0, {}
    for i, df in run_all(run_hypothesis, [(protocol, h, s) for h, s in todo], jobs):
        if parts:
            write_text(path[todo[i]], df.to_csv(index=False), overwrite=True)
        cells[todo[i]] = df
        done += RUN_SECONDS[gear[todo[i][0]]]
        if progress:
            rest = (time.monotonic() - start) * (left - done) / done
            progress(f"{len(cells)}/{len(todo)} runs: {todo[i][0]} seed {todo[i][1]} done, "
                     f"about {rest / 60:.1f} min of runs left", False)
    if parts:  # every run as its file has it: a resumed run's table is an uninterrupted one's
        cells = {t: pd.read_csv(path[t]) for t in tasks}
    return pd.concat([cells[t] for t in tasks], ignore_index=True)


def _check_parts(folder: Path, protocol: dict) -> None:
    """Make the parts' folder and its stamp, or refuse a folder of another protocol or code."""
    from sunlab.atomic import write_text

    stamp = {"protocol_version": protocol["version"], "source_sha256": source_digest(),
             **code_commit()}
    file = folder / "stamp.json"
    if file.exists():
        old = json.loads(file.read_text(encoding="utf-8"))
        if [old.get(k) for k in ("protocol_version", "source_sha256")] != [
                stamp["protocol_version"], stamp["source_sha256"]]:
            raise ConfigurationError(
                f"{folder}: runs of another protocol version or code (protocol "
                f"{old.get('protocol_version')}, code {old.get('code_commit')}). Fix: remove "
                "the folder to run them again under this one.")
        return
    if folder.is_dir() and any(folder.iterdir()):  # not ours: it would go with the runs
        raise ConfigurationError(f"{folder}: a folder that holds no runs (no stamp.json). Fix: "
                                 "move it away or choose another --out.")
    folder.mkdir(parents=True, exist_ok=True)
    write_text(file, json.dumps(stamp, indent=2) + "\n")


def source_digest() -> str:
    """SHA-256 of the code a run depends on: ``sunlab/**/*.py``, ``studies/**/*.py`` and
    ``studies/protocol.json``, their paths and contents in path order."""
    import hashlib

    root = HERE.parent
    h = hashlib.sha256()
    for f in sorted([*root.glob("sunlab/**/*.py"), *root.glob("studies/**/*.py"),
                     root / "studies" / "protocol.json"]):
        h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def regenerate(out_dir, *, names=None, seeds=None, jobs: int = 2, overwrite: bool = False,
               presets: bool = True, progress: Callable | None = None,
               command: str = "python -m studies.identify --out DIR") -> dict:
    """Run the whole protocol and write its evidence into ``out_dir`` (:func:`write_evidence`).

    Each run's cells go to ``out_dir/runs/`` as it finishes (:func:`run_protocol`), so that a
    stopped regeneration started again resumes; the folder is removed once the tables are
    written. ``progress(line, always)`` is called with the estimate (``always`` True) before
    the runs and a line as each run or stage ends. ``command`` (the command line that runs
    this) is recorded in ``evidence_provenance.json`` and ``presets.json``.

    Returns
    -------
    dict
        As :func:`write_evidence`.
    """
    import shutil

    from sunlab.atomic import check_folder

    protocol = load_protocol()
    files = _evidence_files(protocol, presets)
    check_folder(out_dir, files, overwrite=overwrite, flag="--overwrite")
    # the code the runs start from, before the first run
    started = {**code_commit(), "command": command}
    cells = run_protocol(protocol, names, seeds, jobs=jobs, progress=progress,
                         parts=Path(out_dir) / "runs",
                         after_s=STAGES_SECONDS if len(files) > 4 else 0.0)
    out = write_evidence(out_dir, cells, jobs=jobs, overwrite=overwrite, presets=presets,
                         progress=progress and (lambda m: progress(m, False)),
                         provenance=started)
    shutil.rmtree(Path(out_dir) / "runs")
    return out


def code_commit(root=None) -> dict:
    """The commit of the code that runs now: ``{"code_commit": 40 hex, "dirty": bool}``.

    ``dirty`` is true where tracked files differ from that commit (the code that ran is then
    not the commit's; say so in the record). Outside a git checkout both are None.

    Examples
    --------
    >>> c = code_commit()
    >>> c["code_commit"] is None or len(c["code_commit"]) == 40
    True
    """
    import subprocess

    root = Path(root) if root is not None else HERE.parent
    try:
        head = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], check=True,
                              capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain",
                                "--untracked-files=no"], check=True, capture_output=True,
                               text=True).stdout.strip() != ""
    except (OSError, subprocess.CalledProcessError):
        return {"code_commit": None, "dirty": None}
    return {"code_commit": head, "dirty": dirty}


def _evidence_files(protocol: dict, presets: bool) -> tuple[str, ...]:
    files = ("evidence_cells.csv", "evidence.csv", "intervals.csv", "evidence_provenance.json")
    return files + (("presets.json", "profiles.csv", "ablation.csv")
                    if presets and "presets" in protocol else ())


def write_evidence(out_dir, cells: pd.DataFrame, *, jobs: int = 2, overwrite: bool = False,
                   presets: bool = True, progress: Callable | None = None,
                   provenance: dict | None = None) -> dict:
    """Score the predicted cells of every (hypothesis, seed) and write the evidence.

    Writes ``evidence_cells.csv`` (every predicted cell of every hypothesis and seed),
    ``evidence.csv`` (:func:`score_table`), ``intervals.csv`` (:func:`intervals` for every
    hypothesis), ``evidence_provenance.json`` (:func:`code_commit`) and, with ``presets``
    and a protocol that names them, ``presets.json``, ``profiles.csv``
    (:mod:`studies.profiles`) and ``ablation.csv``
    (:mod:`studies.ablation`, the first two confirmation seeds) for the rule's pick,
    all-or-nothing.

    Parameters
    ----------
    out_dir : str or pathlib.Path
        Folder of the tables.
    cells : pandas.DataFrame
        The rows of :func:`run_hypothesis` for every hypothesis and confirmation seed.
    jobs : int
        Processes for the profiles and the ablations.
    overwrite, presets : bool
    progress : callable, optional
        Called with a line of text as each stage starts.
    provenance : dict, optional
        :func:`code_commit` taken before the first run (default: taken now).

    Returns
    -------
    dict
        ``chosen`` (the rule's pick), the three tables and, with ``presets``, ``presets``,
        ``profiles`` and ``ablation``.
    """
    from sunlab.atomic import atomic_files

    from . import ablation, profiles

    protocol = load_protocol()
    files = _evidence_files(protocol, presets)
    cells = cells.sort_values(["hypothesis", "seed", "table", "column", "angle", "stat"])
    evidence = score_table(cells, protocol).sort_values(["hypothesis", "seed"])
    chosen = chosen_hypothesis(evidence, protocol)
    ints = intervals(cells, evidence)
    out = {"chosen": chosen, "cells": cells, "evidence": evidence, "intervals": ints}
    started = provenance or code_commit()
    if len(files) > 4:
        if progress:
            progress(f"presets: {chosen} at the prior medians")
        out["presets"] = profiles.fit_presets(protocol, chosen)
        tau = float(evidence.loc[evidence["hypothesis"] == chosen, "tau"].iloc[0])
        out["profiles"] = profiles.profile_likelihood(protocol, out["presets"], tau, jobs=jobs)
        if progress:
            progress(f"ablations of {chosen}")
        out["ablation"] = ablation.ablation(chosen, protocol["confirmation_seeds"][:2],
                                            evidence, cells, jobs=jobs)
    with atomic_files(out_dir, files, overwrite=overwrite, flag="--overwrite") as staging:
        for name, table in zip(files[:3], (cells, evidence, ints), strict=True):
            table.to_csv(Path(staging) / name, index=False)
        record = {**started, "protocol_version": protocol["version"],
                  "note": "code_commit: HEAD when the runs started (regenerate) or when "
                          "they were scored (write_evidence alone); dirty: tracked files "
                          "differed from it, so the code that ran is not exactly the commit"}
        (Path(staging) / files[3]).write_text(json.dumps(record, indent=2) + "\n",
                                             encoding="utf-8")
        if len(files) > 4:
            command = {"command": started["command"]} if "command" in started else {}
            (Path(staging) / "presets.json").write_text(
                json.dumps({**out["presets"], **command}, indent=2) + "\n", encoding="utf-8")
            out["profiles"].to_csv(Path(staging) / "profiles.csv", index=False)
            out["ablation"].to_csv(Path(staging) / "ablation.csv", index=False)
    return out


# ----------------------------------------------------------------------------- scoring
def scored_arrays(cells: pd.DataFrame, protocol: dict) -> dict:
    """What the score compares, as arrays.

    Parameters
    ----------
    cells : pandas.DataFrame
        The rows of :func:`run_hypothesis` for every hypothesis and seed.
    protocol : dict

    Returns
    -------
    dict
        ``paper`` (the paper's held-out logs, over ``quantities``, :func:`scored_quantities`),
        ``n_fit`` (the fit side's size) and ``by_h``: per hypothesis its ``seeds``, ``ss`` (the
        fit side's sum of squared log residuals, per seed) and ``held`` (the held-out log
        predictions, seeds x quantities).
    """
    q = scored_quantities(protocol)
    paper = _paper_cells()
    lp = {side: np.array([math.log(_quantity(paper, *x)) for x in q[side]]) for side in q}
    logs = {}  # (hypothesis, seed) -> side -> log predictions over its quantities
    for (h, seed), g in cells.groupby(["hypothesis", "seed"]):
        d = {(r.table, r.column, r.angle, r.stat): r.value for r in g.itertuples()}
        logs[(h, seed)] = {side: [math.log(max(_quantity(d, *x), 1e-9)) for x in q[side]]
                           for side in q}
    fit, held = (pd.DataFrame({k: v[side] for k, v in logs.items()}).T.rename_axis(
        ["hypothesis", "seed"]) for side in ("fit", "held_out"))
    by_h = {h: {"seeds": [int(s) for s in held.loc[h].index],
                "ss": np.sum((fit.loc[h].to_numpy() - lp["fit"]) ** 2, axis=1),
                "held": held.loc[h].to_numpy()} for h in held.index.unique("hypothesis")}
    return {"by_h": by_h, "paper": lp["held_out"], "quantities": q["held_out"],
            "n_fit": len(q["fit"])}


def tau2(ss: np.ndarray, k: int, n: int) -> float:
    """The protocol's tau^2: the mean fit-side sum of squares over (n - fitted parameters).

    Parameters
    ----------
    ss : numpy.ndarray
        The fit side's sums of squared log residuals, one per seed.
    k, n : int
        The fitted parameters and the fit side's quantities.

    Returns
    -------
    float
        tau^2, squared log units.
    """
    return float(np.mean(ss)) / (n - k)


def seed_scores(held: np.ndarray, paper: np.ndarray, tau2_: float) -> np.ndarray:
    """The score of each seed: the log density of the paper's logs under N(prediction,
    spread over the seeds^2 + tau^2).

    Parameters
    ----------
    held : numpy.ndarray
        Log predictions, seeds x quantities.
    paper : numpy.ndarray
        The paper's logs, one per quantity.
    tau2_ : float
        The model's discrepancy tau^2 (:func:`tau2`).

    Returns
    -------
    numpy.ndarray
        One score per seed, nats.
    """
    sd2 = held.std(axis=0, ddof=1) ** 2 if len(held) > 1 else 0.0
    return np.array([_log_density(paper - h, sd2 + tau2_) for h in held])


def score_table(cells: pd.DataFrame, protocol: dict) -> pd.DataFrame:
    """The evidence table: each hypothesis's held-out score on each seed.

    Parameters
    ----------
    cells : pandas.DataFrame
        The rows of :func:`run_hypothesis` for every hypothesis and seed.
    protocol : dict

    Returns
    -------
    pandas.DataFrame
        One row per hypothesis and seed: ``hypothesis``, ``seed``, ``parameters``, ``score``
        (held-out log predictive density, nats, higher is better), ``tau`` (the model's
        discrepancy, log units), ``held_out_rms_log``, ``held_out_within_1.25``, and the
        nuisance draw and fitted parameters.
    """
    a = scored_arrays(cells, protocol)
    extra_cols = [c for c in cells.columns if c not in
                  ("hypothesis", "seed", "table", "column", "angle", "stat", "value")]
    extras = cells.groupby(["hypothesis", "seed"])[extra_cols].first()
    rows = []
    for h, v in a["by_h"].items():
        t2 = tau2(v["ss"], _fitted_count(protocol, h), a["n_fit"])
        for seed, hh, ll in zip(v["seeds"], v["held"], seed_scores(v["held"], a["paper"], t2),
                                strict=True):
            r = a["paper"] - hh
            rows.append({"hypothesis": h, "seed": seed,
                         "parameters": int(protocol["hypotheses"][h]["parameters"]),
                         "score": ll, "tau": math.sqrt(t2),
                         "held_out_rms_log": float(np.sqrt(np.mean(r**2))),
                         "held_out_within_1.25": int(np.sum(np.abs(r) <= math.log(1.25))),
                         **extras.loc[(h, seed)].to_dict()})
    return pd.DataFrame(rows)


def _fitted_count(protocol: dict, name: str) -> int:
    """The fitted parameters of a hypothesis (tau's degrees of freedom are 12 minus these)."""
    gear = protocol["hypotheses"][name]["gear"]
    return int(protocol["score"]["fitted_parameters"]["with gear" if gear else "without gear"])


def chosen_hypothesis(evidence: pd.DataFrame, protocol: dict | None = None) -> str:
    """The hypothesis the protocol's one-standard-error rule picks from an evidence table.

    The best is the highest mean score over seeds; every hypothesis whose mean lies within
    one standard error (the best's, over its seeds) of it is eligible; the eligible one with
    the fewest parameters is chosen, a tie going to the higher mean.

    Examples
    --------
    >>> t = pd.DataFrame({"hypothesis": ["a", "a", "b", "b"], "seed": [0, 1, 0, 1],
    ...                   "parameters": [3, 3, 5, 5], "score": [1.0, 3.0, 1.9, 3.5]})
    >>> chosen_hypothesis(t)     # b is best (2.7 +- 0.8), a (2.0) lies within it: simpler
    'a'
    """
    g = evidence.groupby("hypothesis")["score"]
    se = (g.std(ddof=1) / np.sqrt(g.count())).fillna(0.0)
    params = evidence.groupby("hypothesis")["parameters"].first()
    return one_se_rule(g.mean().to_dict(), se.to_dict(), params.to_dict())[0]


def one_se_rule(mean: dict, se: dict, params: dict) -> tuple[str, list[str]]:
    """The one-standard-error rule on each hypothesis's mean score.

    Parameters
    ----------
    mean, se, params : dict
        Per hypothesis: the mean score over seeds, its standard error (nats) and its
        parameter count.

    Returns
    -------
    pick : str
        The eligible hypothesis with the fewest parameters (a tie to the higher mean).
    eligible : list of str
        Every hypothesis within one standard error of the best, sorted.
    """
    best = max(mean, key=mean.get)
    eligible = sorted(h for h in mean if mean[h] >= mean[best] - se[best])
    return str(min(eligible, key=lambda h: (params[h], -mean[h]))), eligible


def interval_role(protocol: dict, table: str, column: str) -> str:
    """A published column's role in the identification: ``"fit"``, ``"held-out"`` or
    ``"duplicate"``.

    ``fit``: the protocol's fit side (its cells pin the fitted parameters, so they lie inside
    their intervals nearly by construction); ``held-out``: the protocol's held-out columns;
    ``duplicate``: a published column the protocol drops because it repeats another (Table 5's
    ``1 hole``, Table 4's polynomial).

    Examples
    --------
    >>> p = load_protocol()
    >>> [interval_role(p, "table4", c) for c in ("polynomial", "cubic interp.")]
    ['fit', 'held-out']
    >>> interval_role(p, "table5", "1 hole")
    'duplicate'
    """
    for role, side in (("fit", "fit"), ("held-out", "held_out")):
        if column in protocol["cells"][side].get(table, ()):
            return role
    return "duplicate"


def with_roles(ints: pd.DataFrame, protocol: dict | None = None) -> pd.DataFrame:
    """The intervals table with each cell's ``role`` (:func:`interval_role`) as a column."""
    protocol = protocol or load_protocol()
    role = [interval_role(protocol, t, c) for t, c in zip(ints["table"], ints["column"],
                                                          strict=True)]
    return ints.drop(columns="role", errors="ignore").assign(role=role)


def intervals(cells: pd.DataFrame, evidence: pd.DataFrame, names: Iterable[str] | None = None,
              level: float = 0.90) -> pd.DataFrame:
    """Each published cell's predictive mean, interval and z under the given hypotheses.

    Returns
    -------
    pandas.DataFrame
        Columns ``hypothesis``, ``table``, ``column``, ``angle``, ``stat``, ``paper``,
        ``mean`` (exp of the mean log prediction), ``lo``, ``hi`` (the central ``level``
        interval, log-normal with sd = sqrt(seed spread^2 + tau^2)), ``z`` (the paper's log
        value in predictive sds from the mean), ``inside``.
    """
    from scipy.stats import norm

    zq = float(norm.ppf(0.5 + level / 2.0))
    paper = _paper_cells()
    tau = evidence.groupby("hypothesis")["tau"].first()
    names = list(names) if names is not None else sorted(tau.index)
    rows = []
    for h in names:
        g = cells[cells["hypothesis"] == h]
        for (t, c, a, s), v in g.groupby(["table", "column", "angle", "stat"])["value"]:
            lv = np.log(np.maximum(v.to_numpy(), 1e-9))
            m = float(lv.mean())
            sd = math.sqrt(float(lv.std(ddof=1)) ** 2 + float(tau[h]) ** 2)
            p = paper[(t, c, a, s)]
            z = (math.log(p) - m) / sd
            rows.append({"hypothesis": h, "table": t, "column": c, "angle": a, "stat": s,
                         "paper": p, "mean": math.exp(m), "lo": math.exp(m - zq * sd),
                         "hi": math.exp(m + zq * sd), "z": z, "inside": abs(z) <= zq})
    return with_roles(pd.DataFrame(rows))


# ----------------------------------------------------------------------------- shipped
def _data(name: str) -> pd.DataFrame:
    """A table the studies wrote: ``studies/results/NAME``, or ``sunlab/data/NAME``."""
    path = HERE / "results" / name
    path = path if path.exists() else LIBRARY_DATA / name
    if not path.exists():
        raise ConfigurationError(
            f"{name}: missing. Fix: run `python -m studies.identify --out DIR` and put the "
            "tables where docs/identification.md says.")
    return pd.read_csv(path)


def load_evidence(path=None) -> pd.DataFrame:
    """The shipped evidence table (``studies/results/evidence.csv``) or the one at ``path``.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        An ``evidence.csv`` written by :func:`studies.evidence.regenerate`.

    Returns
    -------
    pandas.DataFrame
        One row per hypothesis and seed: its draw, fit, parameter count and score.

    Examples
    --------
    >>> t = load_evidence()
    >>> {"hypothesis", "seed", "score"} <= set(t.columns)
    True
    """
    return pd.read_csv(path) if path is not None else _data("evidence.csv")


def load_intervals(path=None) -> pd.DataFrame:
    """The shipped predictive intervals (``sunlab/data/intervals.csv``) or those at ``path``.

    Parameters
    ----------
    path : str or pathlib.Path, optional
        An ``intervals.csv`` written by :func:`studies.evidence.regenerate`.

    Returns
    -------
    pandas.DataFrame
        As :func:`intervals`: one row per hypothesis and published cell.
    """
    return pd.read_csv(path) if path is not None else _data("intervals.csv")


def identified_hypothesis() -> str:
    """The hypothesis the protocol's rule picks from the shipped evidence (the presets' one).

    Returns
    -------
    str
        A key of the protocol's ``hypotheses`` (:func:`chosen_hypothesis`).

    Examples
    --------
    >>> identified_hypothesis() in load_protocol()["hypotheses"]
    True
    """
    return chosen_hypothesis(load_evidence(), load_protocol())


def recorded_draw(protocol: dict, evidence: pd.DataFrame, hypothesis: str,
                  seed: int) -> tuple[pd.Series, dict, dict]:
    """The evidence's row of one hypothesis and seed, its nuisance draw and fitted parameters.

    Parameters
    ----------
    protocol : dict
    evidence : pandas.DataFrame
        :func:`load_evidence`.
    hypothesis : str
    seed : int

    Returns
    -------
    record : pandas.Series
        The row.
    nuisances, fitted : dict
        As :func:`draw_nuisances` and :func:`fit_hypothesis` gave them for that seed.
    """
    record = evidence[(evidence["hypothesis"] == hypothesis)
                      & (evidence["seed"] == seed)].iloc[0]
    nuis = {k: float(record[k]) for k in protocol["priors"]}
    fitted = {k: float(record[k]) for k in [*protocol["cells"]["pinning"], "gear_period_deg"]
              if k in record and pd.notna(record[k]) and k not in nuis}
    return record, nuis, fitted


def _log_density(residual: np.ndarray, var: np.ndarray) -> float:
    """Sum of the normal log densities of log residuals with the given variances."""
    return float(np.sum(-0.5 * residual**2 / var - 0.5 * np.log(2 * math.pi * var)))
