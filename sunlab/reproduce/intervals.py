"""The identified bench's 90 % predictive intervals beside a reproduced table.

:func:`identified` reads the hypothesis the presets carry and each published cell's interval and
role (fit, held-out, duplicate) from ``sunlab/data/`` (``presets.json``, ``intervals.csv``;
written by ``python -m studies.identify``, docs/identification.md); :func:`interval_coverage`
counts the cells inside, the held-out cells apart from the whole table, and
:func:`coverage_lines` prints them under Tables 4 and 5.
"""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pandas as pd

from .. import stats
from ..errors import ConfigurationError
from .pipeline import cells

__all__: list[str] = []


def identified(table: str) -> dict:
    """The identified bench's hypothesis and each published cell's 90 % predictive interval.

    Read from ``sunlab/data/presets.json`` (its ``hypothesis``) and ``sunlab/data/intervals.csv``
    (written by ``python -m studies.identify``; docs/identification.md): the spread over the
    confirmation seeds and the model's discrepancy, not a function of any one run's seed.

    Parameters
    ----------
    table : {"table4", "table5"}

    Returns
    -------
    dict
        ``hypothesis``, ``interval90``: ``{column: {"angle.stat": [lo, hi]}}`` (deg), keyed
        as ``table4.json``'s ``ours`` rows (Table 5's columns carry its JSON's `` [sunlab]``),
        and ``interval_role``, with the same keys: each cell's role in the identification,
        ``"fit"`` (its column pinned the fit: inside nearly by construction), ``"held-out"``
        or ``"duplicate"`` (Table 5's ``1 hole``, a repeat of Table 4's polynomial).

    Examples
    --------
    >>> iv = identified("table4")
    >>> lo, hi = iv["interval90"]["polynomial"]["alpha.mu"]
    >>> iv["hypothesis"], bool(0 < lo < hi), iv["interval_role"]["cubic interp."]["alpha.mu"]
    ('F5', True, 'held-out')
    """
    name = json.loads((resources.files("sunlab") / "data" / "presets.json")
                      .read_text("utf-8"))["hypothesis"]
    with resources.as_file(resources.files("sunlab") / "data" / "intervals.csv") as path:
        ints = pd.read_csv(path)
    if "role" not in ints.columns:
        raise ConfigurationError(
            f"{path}: no 'role' column. Fix: rewrite it with `python -m studies.identify` "
            "(studies.evidence.intervals gives each cell its role).")
    ints = ints[ints["hypothesis"] == name]
    out: dict = {}
    role: dict = {}
    for r in ints[ints["table"] == table].itertuples():
        key = r.column if table == "table4" else f"{r.column} [sunlab]"
        out.setdefault(key, {})[f"{r.angle}.{r.stat}"] = [float(r.lo), float(r.hi)]
        role.setdefault(key, {})[f"{r.angle}.{r.stat}"] = str(r.role)
    return {"hypothesis": name, "interval90": out, "interval_role": role}


def interval_coverage(interval90: dict, interval_role: dict, values: dict) -> dict:
    """How many of ``values``' cells lie inside their 90 % interval, by role.

    Parameters
    ----------
    interval90, interval_role : dict
        As :func:`identified` gives them.
    values : dict
        ``{column: {"angle.stat": value}}`` (deg), keyed as ``interval90``; cells missing
        or not finite are left out.

    Returns
    -------
    dict
        ``"held-out"``, ``"fit"``, ``"duplicate"`` and ``"all"`` (the whole table), each
        ``{"inside": int, "cells": int, "median_half_width": float}``: the half-width as a
        fraction of the value, (hi - lo) / 2 / value, its median over the cells.

    Examples
    --------
    >>> iv = {"a": {"x": [1.0, 3.0], "y": [1.0, 2.0]}}
    >>> cov = interval_coverage(iv, {"a": {"x": "held-out", "y": "fit"}},
    ...                         {"a": {"x": 2.0, "y": 4.0}})
    >>> cov["held-out"], cov["all"]["inside"]
    ({'inside': 1, 'cells': 1, 'median_half_width': 0.5}, 1)
    """
    rows = [(interval_role[c][k], lo <= values[c][k] <= hi, (hi - lo) / 2.0 / values[c][k])
            for c, cells in interval90.items() for k, (lo, hi) in cells.items()
            if values.get(c, {}).get(k) is not None and np.isfinite(values[c][k])
            and values[c][k] > 0]
    out = {}
    for role in ("held-out", "fit", "duplicate", "all"):
        sel = [r for r in rows if role in ("all", r[0])]
        out[role] = {"inside": int(sum(r[1] for r in sel)), "cells": len(sel),
                     "median_half_width": float(np.median([r[2] for r in sel])) if sel
                     else float("nan")}
    return out


def coverage_lines(interval90: dict, interval_role: dict, paper: dict, ours: dict) -> list[str]:
    """The printed lines of a table's interval coverage: the paper's cells and this run's,
    the held-out cells beside the whole table (:func:`interval_coverage`)."""
    if not interval90:
        return []
    lines = ["", "Inside our 90 % interval: the held-out cells (never fitted) beside the whole "
             "table (its fit-side\nand duplicate cells are inside nearly by construction)"]
    for label, values in (("paper", paper), ("ours (this run)", ours)):
        cov = interval_coverage(interval90, interval_role, values)
        if cov["all"]["cells"]:
            lines.append(f"  {label:<16s}" + "; ".join(
                f"{role} {cov[role]['inside']} of {cov[role]['cells']}, median half-width "
                f"{cov[role]['median_half_width']:.3f} of the value"
                for role in ("held-out", "all")))
    return lines


def stat_lines(title: str, head: str, width: int, paper, ours, interval90: dict,
               interval_role: dict) -> list[str]:
    """The printed lines of Table 4 or 5: per column the paper's eight statistics, ours and our
    90 % interval, then the interval coverage (:func:`coverage_lines`).

    Parameters
    ----------
    title : str
        The first line.
    head, width : str, int
        The label column's heading and its width, characters.
    paper, ours : pandas.DataFrame
        The paper's statistics and ours, index ``(angle, stat)``, a column per method (deg);
        every column of ``ours`` is printed, the paper's line above it where it has one.
    interval90, interval_role : dict
        As :func:`identified` gives them, keyed by ``ours``' columns (empty: no intervals).

    Returns
    -------
    list of str
        Values to 4 decimals, intervals as ``.0071-.0118`` (deg).
    """

    def line(label, values, tag):
        return f"{label:<{width}s}" + "".join(
            f"{v:>12s}" if isinstance(v, str) else f"{v:12.4f}" for v in values) + f"   {tag}"

    keys = [(a, st) for a in stats.ANGLES for st in stats.STATS]
    lines = [title, "paper = the 2005 preprint; ours = sunlab virtual bench (simulated frames); "
             "our 90 % interval = the identified bench's predictive interval "
             "(docs/identification.md)", "",
             f"{head:<{width}s}" + "".join(f"{a[0] + ' ' + st:>12s}" for a, st in keys)]
    for c in ours.columns:
        if c in paper.columns:
            lines.append(line(c, [paper.loc[k, c] for k in keys], "paper"))
        lines.append(line("" if c in paper.columns else c, [ours.loc[k, c] for k in keys], "ours"))
        if interval90.get(c):
            lines.append(line("", [f"{lo:.4f}-{hi:.4f}".replace("0.", ".") for lo, hi in (
                interval90[c][f"{a}.{st}"] for a, st in keys)], "our 90 % interval"))
    return lines + coverage_lines(interval90, interval_role, cells(paper), cells(ours))
