"""The evidence of the identification: every (hypothesis, seed) run, scored and written.

:func:`regenerate` runs the protocol of ``sunlab/data/protocol.json`` on its confirmation seeds
(:func:`run_protocol`) and :func:`write_evidence` scores the predictions, applies the rule and
writes the shipped tables (``python -m studies.identify``); the science is in
:mod:`studies.identification`, the presets and profiles in :mod:`.profiles`, the
ablations in :mod:`.ablation`.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import pandas as pd

from .identification import chosen_hypothesis, intervals, load_protocol, run_hypothesis, score_table

__all__ = ["regenerate", "write_evidence"]


def run_protocol(protocol: dict, names=None, seeds=None, *, jobs: int = 1,
        progress: Callable | None = None) -> pd.DataFrame:
    """Every (hypothesis, seed) of the protocol: the long table of predicted cells.

    ``jobs`` > 1 runs them in that many processes (each builds its own surrogate maps).
    """
    names = list(names or protocol["hypotheses"])
    seeds = list(seeds if seeds is not None else protocol["confirmation_seeds"])
    tasks = [(h, s) for h in names for s in seeds]
    out = []
    if jobs <= 1:
        for h, s in tasks:
            if progress:
                progress(f"{h} seed {s}")
            out.append(run_hypothesis(protocol, h, s))
    else:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        with ProcessPoolExecutor(jobs) as pool:
            futs = {pool.submit(run_hypothesis, protocol, h, s): (h, s) for h, s in tasks}
            for f in as_completed(futs):
                if progress:
                    progress("{} seed {}".format(*futs[f]))
                out.append(f.result())
    return pd.concat(out, ignore_index=True)


def regenerate(out_dir, *, names=None, seeds=None, jobs: int = 2, overwrite: bool = False,
               presets: bool = True, progress: Callable | None = None) -> dict:
    """Run the whole protocol and write its evidence into ``out_dir`` (:func:`write_evidence`).

    Returns
    -------
    dict
        As :func:`write_evidence`.
    """
    from sunlab.atomic import check_folder

    protocol = load_protocol()
    check_folder(out_dir, _evidence_files(protocol, presets), overwrite=overwrite,
                 flag="--overwrite")
    cells = run_protocol(protocol, names, seeds, jobs=jobs, progress=progress)
    return write_evidence(out_dir, cells, jobs=jobs, overwrite=overwrite, presets=presets,
                          progress=progress)


def _evidence_files(protocol: dict, presets: bool) -> tuple[str, ...]:
    files = ("evidence_cells.csv", "evidence.csv", "intervals.csv")
    return files + (("presets.json", "profiles.csv", "ablation.csv")
                    if presets and "presets" in protocol else ())


def write_evidence(out_dir, cells: pd.DataFrame, *, jobs: int = 2, overwrite: bool = False,
                   presets: bool = True, progress: Callable | None = None) -> dict:
    """Score the predicted cells of every (hypothesis, seed) and write the evidence.

    Writes ``evidence_cells.csv`` (every predicted cell of every hypothesis and seed),
    ``evidence.csv`` (:func:`score_table`), ``intervals.csv`` (:func:`intervals` for every
    hypothesis) and, with ``presets`` and a protocol that names them, ``presets.json``,
    ``profiles.csv`` (:mod:`studies.profiles`) and ``ablation.csv``
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
    if len(files) > 3:
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
        if len(files) > 3:
            (Path(staging) / "presets.json").write_text(
                json.dumps(out["presets"], indent=2) + "\n", encoding="utf-8")
            out["profiles"].to_csv(Path(staging) / "profiles.csv", index=False)
            out["ablation"].to_csv(Path(staging) / "ablation.csv", index=False)
    return out


