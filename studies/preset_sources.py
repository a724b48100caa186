"""Where each preset value comes from (``sunlab/data/preset_sources.csv``, from the presets).

``python -m studies.preset_sources`` walks the dataclass fields of
:meth:`sunlab.sim.Bench.paper_single_hole` and :meth:`sunlab.sim.Bench.paper_multi_hole` (public
names only) and writes one row per numeric field: ``bench``, ``parameter`` (the dotted field path,
such as ``detector.gain_e_per_dn``; a tuple's items and each hole numbered), ``value``, ``source``
(``paper``, ``datasheet``, ``physics``, ``identified`` or ``assumed``) and ``reference``. The
source of each path is :data:`SOURCES`, the first pattern that matches; a field no pattern names
is ``assumed``, "no source recorded"; the table is ``studies/preset_sources.json``. A
one-at-a-time sensitivity of the assumed values (each at half and twice its value, scored on the
held-out cells) needs a surrogate run per value, and it has not been run.

Examples
--------
>>> t = preset_sources()
>>> sorted(set(t["source"])) <= ["assumed", "datasheet", "identified", "paper", "physics"]
True
>>> t.set_index(["bench", "parameter"]).loc[("paper_single_hole", "detector.read_noise_e"),
...                                         "source"]
'datasheet'
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import sys
from pathlib import Path

import pandas as pd

__all__ = ["SOURCES", "preset_sources"]

_FILE = Path(__file__).resolve().parent.parent / "sunlab" / "data" / "preset_sources.csv"
#: (pattern on the dotted path, source, reference): the first match names a field's source;
#: a data table, ``studies/preset_sources.json``.
SOURCES: tuple[tuple[str, str, str], ...] = tuple(
    (r["pattern"], r["source"], r["reference"])
    for r in json.loads((Path(__file__).with_suffix(".json")).read_text(encoding="utf-8")))


def _walk(obj, prefix: str = ""):
    """(dotted path, value) of every numeric leaf of a dataclass (tuples' items numbered)."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _walk(getattr(obj, f.name), f"{prefix}{f.name}.")
    elif isinstance(obj, tuple | list):
        for i, item in enumerate(obj):
            yield from _walk(item, f"{prefix}{i}.")
    elif isinstance(obj, int | float) and not isinstance(obj, bool):
        yield prefix.rstrip("."), obj


def _source(bench: str, path: str, value) -> tuple[str, str]:
    if bench == "paper_multi_hole" and path == "mask.delta_f_mm":
        return "assumed", "the 100-hole mask's height error: no source recorded (a choice)"
    if re.fullmatch(r"mask\.play_[xy]_mm", path) and value == 0:
        return "assumed", ("0: this mask's play is along the other axis (studies/protocol.json "
                           "common.mask_play_axes)")
    for pattern, source, reference in SOURCES:
        if re.fullmatch(pattern, path):
            return source, reference
    return "assumed", "no source recorded"


def preset_sources() -> pd.DataFrame:
    """Every numeric field of both presets with its source.

    Returns
    -------
    pandas.DataFrame
        Columns ``bench``, ``parameter``, ``value``, ``source``, ``reference``.
    """
    from sunlab.sim import Bench

    rows = []
    for bench in ("paper_single_hole", "paper_multi_hole"):
        for path, value in _walk(getattr(Bench, bench)()):
            source, reference = _source(bench, path, value)
            rows.append({"bench": bench, "parameter": path, "value": value, "source": source,
                         "reference": reference})
    return pd.DataFrame(rows)


def build_parser() -> argparse.ArgumentParser:
    """The arguments of ``python -m studies.preset_sources``."""
    p = argparse.ArgumentParser(prog="python -m studies.preset_sources")
    p.add_argument("--out", default=str(_FILE), metavar="CSV")
    return p


def main(argv=None) -> int:
    """Write ``sunlab/data/preset_sources.csv`` (or ``--out``) and print the count by source.

    Returns
    -------
    int
        0.
    """
    args = build_parser().parse_args(argv)
    t = preset_sources()
    t.to_csv(args.out, index=False)
    print(t.groupby(["bench", "source"]).size().to_string())
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
