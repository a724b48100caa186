"""The files of ``sunlab reproduce --table learned`` (:mod:`sunlab.reproduce.learned`): its
settings, the command that writes them, the time it will take, its progress, the per-bench
records a stopped run resumes from, and the records' tables and figure.

A run writes, under its folder, ``benches/<bench>.json`` (the bench's settings, records, floor,
training history and seconds) after ``models/<bench>.json``, each atomically; a later run with
the same settings for that bench reads them back instead of recomputing it.

Examples
--------
>>> s = bench_settings("paper", {"I": [100, 2], "II": [49, 2], "III": [100, 2]}, seed=0,
...                    epochs=40, threads=2, device="cpu")
>>> s["seeds"], s["frames"]
({'I': 101, 'II': 102, 'III': 103}, 498)
"""

from __future__ import annotations

import json
import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from ..calibration import load
from ..errors import ConfigurationError
from .pipeline import write_files, write_json

#: Seconds of work per frame on 2 cores (render, detect, train, test and the classical fits,
#: spread over a bench's frames): the CPU seconds of sunlab's own runs at the quick plans
#: (docs/learned/README.md), for one-hole benches (the good-platform bench also runs the disk
#: fit) and the 100-hole benches (100 windows a frame, at most 12 epochs).
SECONDS_PER_FRAME = {"one-hole": 0.075, "good-platform": 0.11, "100-holes": 0.6}
#: How much more a frame costs when a bench's cubes exceed the memory kept
#: (:data:`sunlab.reproduce.learned.IN_MEMORY_BYTES`): they are rendered again for each pass
#: (detection, windows, test, disk fit). An estimate, not measured.
RERENDER = 2.0
#: A run longer than this prints its estimate before it starts, seconds.
ANNOUNCE_S = 60


def bench_settings(name: str, plans: dict, *, seed: int, epochs: int, threads: int,
                   device: str) -> dict:
    """What decides one bench's result: its plans (poses, shots per experiment), seeds, epochs,
    threads and device. A stored bench is reused only when these are equal."""
    from .learned import bench_seeds

    plans = {k: [int(n), int(s)] for k, (n, s) in plans.items()}
    return {"bench": name, "plans": plans, "seeds": bench_seeds(name, seed), "seed": int(seed),
            "epochs": int(epochs), "threads": int(threads), "device": str(device),
            "frames": sum(n * s for n, s in plans.values())}


def estimate_s(settings: dict) -> float:
    """Seconds one bench takes on 2 idle cores, by :data:`SECONDS_PER_FRAME` and
    :data:`RERENDER`."""
    from .learned import IN_MEMORY_BYTES, bench

    name = settings["bench"]
    b = bench(name)
    kind = ("100-holes" if b.n_holes > 1 else
            "good-platform" if name == "good-platform" else "one-hole")
    pixels = int(np.prod(b.detector.shape)) * settings["frames"]
    again = RERENDER if 2 * pixels > IN_MEMORY_BYTES else 1.0  # uint16 frames
    return SECONDS_PER_FRAME[kind] * settings["frames"] * again


def command(*, out, full: bool, quick: bool, seed: int, benches, threads: int, default_benches,
            step, shots, epochs: int, device: str) -> str:
    """The command line that runs these settings (``sunlab reproduce --table learned ...``), or
    the Python call where an option has no flag (``step``, ``shots``, ``epochs``, ``device``)."""
    if step is None and shots is None and epochs == 40 and device == "cpu":
        cmd = ["sunlab", "reproduce", "--table", "learned"]
        cmd += ["--full"] if full else ["--quick"] if quick else []
        if benches is not None and list(benches) != list(default_benches):
            cmd += ["--benches", *benches]
        cmd += [f"--seed {seed}"] if seed else []
        cmd += [f"--workers {threads}"] if threads != 2 else []
        return " ".join([*cmd, "--out", str(out)])
    kw = {"full": full, "quick": quick, "seed": seed, "benches": benches, "step": step,
          "shots": shots, "epochs": epochs, "threads": threads, "device": device,
          "out": None if out is None else str(out)}
    return "sunlab.reproduce.learned.reproduce_learned(" + ", ".join(
        f"{k}={v!r}" for k, v in kw.items()) + ")"


def stored(out: Path | None, settings: dict) -> dict | None:
    """The bench's record under ``out`` when it was written with these settings, else None."""
    name = settings["bench"]
    if out is None or not (out / "models" / f"{name}.json").exists():
        return None
    try:
        doc = json.loads((out / "benches" / f"{name}.json").read_text())
    except (OSError, ValueError, RecursionError):  # missing, cut short or not ours: computed
        return None                                   # again, and the record replaced
    return doc if isinstance(doc, dict) and doc.get("settings") == settings else None


def store(out: Path, settings: dict, res: dict, seconds: float) -> None:
    """Write the bench's model, then its record (``benches/<bench>.json``), each atomically."""
    name = settings["bench"]
    for folder in ("models", "benches"):
        (out / folder).mkdir(parents=True, exist_ok=True)
    res["model"].save(out / "models" / f"{name}.json", overwrite=True)
    doc = {"settings": settings, "records": res["records"], "floor": res.get("floor"),
           "history": res["model"].history, "seconds": seconds}
    write_json(doc, out / "benches" / f"{name}.json")


def read_back(out: Path, doc: dict) -> dict:
    """A stored bench (:func:`stored`) as :func:`sunlab.reproduce.learned.reproduce_learned`
    uses it: ``records``, ``model`` (loaded, its training history restored), ``table`` and
    ``floor`` where the bench has one."""

    name = doc["settings"]["bench"]
    model = load(out / "models" / f"{name}.json")
    model.history = doc["history"]
    res = {"records": doc["records"], "model": model, "table": table_of(doc["records"])}
    if doc.get("floor") is not None:
        res["floor"] = doc["floor"]
    return res


class Progress:
    """Lines of a run's progress: a bar over the estimated seconds, elapsed and remaining
    minutes (the estimate scaled by how the finished work compared with its own)."""

    def __init__(self, estimates: dict, show: bool):
        self.estimates, self.show = dict(estimates), show
        self.start, self.done_est, self.done = time.perf_counter(), 0.0, []

    def announce(self, frames: int, reused: int = 0) -> None:
        """Print the work and its estimate (on 2 idle cores) when it exceeds
        :data:`ANNOUNCE_S`."""
        total, n = sum(self.estimates.values()), len(self.estimates)
        if self.show and total > ANNOUNCE_S:
            again = f" ({reused} read back from an earlier run)" if reused else ""
            print(f"learned: {n} bench{'es' * (n != 1)}{again}, {frames} frames to render "
                  f"and detect, training up to the epochs set: about {math.ceil(total / 60)} "
                  f"min on 2 idle cores (docs/learned/README.md)", flush=True)

    def _line(self, head: str, less_s: float = 0.0) -> None:
        """Print the bar with ``head``: the benches not done less ``less_s`` of work remain."""
        if not self.show:
            return
        rest_s = sum(v for k, v in self.estimates.items() if k not in self.done) - less_s
        elapsed = time.perf_counter() - self.start
        pace = elapsed / self.done_est if self.done_est > 0 and elapsed > 5 else 1.0
        total = sum(self.estimates.values()) or 1.0
        full = round(20 * min(1.0, max(0.0, 1 - rest_s / total)))
        print(f"[{'#' * full}{'-' * (20 - full)}] {head}: {elapsed / 60:.1f} min elapsed, about "
              f"{math.ceil(rest_s * pace / 60)} min left", flush=True)

    def stage(self, name: str, what: str, fraction: float) -> None:
        """A stage of bench ``name`` is done, and ``fraction`` of the bench with it."""
        self._line(f"{name}: {what}", fraction * self.estimates[name])

    def finished(self, name: str, reused: bool = False) -> None:
        """Bench ``name`` is done (``reused``: read back from an earlier run)."""
        self.done.append(name)
        self.done_est += 0.0 if reused else self.estimates[name]
        self._line(f"{len(self.done)}/{len(self.estimates)} benches ({name}"
                   f"{', read back from an earlier run' if reused else ''})")


def table_of(records):
    """The statistics table of one bench's records (rows angle and stat, columns methods)."""

    rows = [r for r in records if r["angle"] is not None and r["method"] != "CRLB floor"]
    df = pd.DataFrame(rows).pivot_table(index=["angle", "stat"], columns="method",
                                        values="value", sort=False, dropna=False)
    return df.reindex(columns=list(dict.fromkeys(r["method"] for r in rows)))


def write(result: dict, out: Path) -> list[str]:
    """``learned.json`` (the command, the settings and the records), ``learned_settings.json``
    (the settings with the floors and the training histories), ``learned.png`` and
    ``models/<bench>.json`` (written as each bench finished); the paths. The first three are
    written together or not at all (:func:`sunlab.atomic.atomic_files`)."""
    doc = {**result["settings"], "floors": result["floors"], "histories": result["histories"]}
    record = {k: result[k] for k in ("command", "settings", "records")}
    return [str(out / "models" / f"{n}.json") for n in result["models"]] + write_files(out, {
        "learned.json": lambda path: write_json(record, path),
        "learned_settings.json": lambda path: write_json(doc, path),
        "learned.png": learned_figure(result["records"])})


def records_of(doc) -> list[dict]:
    """The records of ``learned.json``: its ``records`` (a list of records passes through).

    Examples
    --------
    >>> records_of({"command": "sunlab reproduce --table learned --out r", "records": []})
    []
    """
    return doc["records"] if isinstance(doc, dict) else list(doc)


def records_table(records, stat: str = "mu"):
    """The records of one statistic as a table: rows (bench, angle), columns the methods.

    Parameters
    ----------
    records : sequence of dict, or dict
        ``learned.json`` (its ``records``), or the records: each with ``bench``,
        ``method``, ``angle`` (None for a statistic of no angle), ``stat`` and ``value``.
    stat : str
        The statistic kept (e.g. ``"mu"``, deg).

    Returns
    -------
    pandas.DataFrame
        Values indexed by (bench, angle), or by bench alone where no record has an angle;
        benches and methods in the order first met.

    Examples
    --------
    >>> recs = [{"bench": "paper", "method": "learned", "angle": "alpha", "stat": "mu",
    ...          "value": 0.01}, {"bench": "paper", "method": "polynomial", "angle": "alpha",
    ...          "stat": "mu", "value": 0.012}]
    >>> records_table(recs).loc[("paper", "alpha")].tolist()
    [0.01, 0.012]
    """

    df = pd.DataFrame([r for r in records_of(records) if r["stat"] == stat])
    if df.empty:
        raise ConfigurationError(f"stat: found {stat!r}, not among the records' stats")
    order = list(dict.fromkeys(df["bench"]))
    cols = list(dict.fromkeys(df["method"]))
    if df["angle"].isna().all():
        table = df.pivot(index="bench", columns="method", values="value")
        return table.reindex(index=order, columns=cols)
    table = df.pivot_table(index=["bench", "angle"], columns="method", values="value",
                           sort=False)
    return table.reindex(columns=cols)


def learned_figure(records):
    """mu of alpha and beta per bench, every method side by side (log scale, deg); the CRLB
    floor where computed as a black tick.

    Parameters
    ----------
    records : list of dict
        The records of :func:`reproduce_learned` (``learned.json``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    import matplotlib.pyplot as plt

    mu = records_table(records, "mu")
    methods = [m for m in mu.columns if m != "CRLB floor"]
    benches = list(dict.fromkeys(mu.index.get_level_values(0)))
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.2), layout="constrained", sharey=True)
    width = 0.8 / len(methods)
    xs = np.arange(len(benches))
    for ax, angle in zip(axes, ("alpha", "beta"), strict=True):
        for k, m in enumerate(methods):
            vals = [mu[m].get((b, angle), np.nan) for b in benches]
            ax.bar(xs - 0.4 + (k + 0.5) * width, vals, width, label=m)
        if "CRLB floor" in mu.columns:
            floor = [mu["CRLB floor"].get((b, angle), np.nan) for b in benches]
            ax.scatter(xs, floor, marker="_", s=600, color="k", zorder=3, label="CRLB floor")
        ax.set_yscale("log")
        ax.set_xticks(xs, benches, rotation=30, ha="right")
        ax.set_title(f"{angle}: mu on experiment III (unseen seeds)")
        ax.grid(axis="y", which="both", alpha=0.3)
    axes[0].set_ylabel("mu, deg")
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1), frameon=False)
    return fig
