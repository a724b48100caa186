"""The evaluation report of a calibration on a test table: what ``sunlab evaluate --out`` writes.

:func:`sunlab.stats.evaluate` computes the paper's global statistics (Table 4's column: mu,
sigma, M, sigma_M per angle, docs/paper.md sec. 5); :func:`write_report` writes them, with what
was evaluated, as ``evaluation.json``, the per-pose errors as ``errors.csv``, and Figs. 10
(error maps) and 11 (histograms of the local errors) as PNG files. A notebook and the command
line write the same files: the command only parses its arguments, calls these functions and
prints.

Examples
--------
>>> import tempfile
>>> import numpy as np
>>> from sunlab import calibration, sim
>>> a, b = np.meshgrid(np.arange(-4.0, 5.0), np.arange(-4.0, 5.0), indexing="ij")
>>> train = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=0.02, seed=1)
>>> test = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=0.02, seed=2)
>>> cal = calibration.fit(train, "polynomial", order=3)
>>> files = write_report(tempfile.mkdtemp(), cal, test)["files"]
>>> [f.name for f in files] == list(REPORT_FILES)
True
"""

from __future__ import annotations

import io as _io
import json
from pathlib import Path

import numpy as np
import pandas as pd

from . import atomic, stats
from .schema import STATUS, USABLE_STATUS

__all__ = ["write_report"]

#: The files of a report, in the order :func:`write_report` lists them: the statistics
#: (JSON), the per-pose errors (CSV), Fig. 10 (only when the test poses form a grid) and
#: Fig. 11.
REPORT_FILES = ("evaluation.json", "errors.csv", "fig10_error_maps.png", "fig11_histograms.png")

_DEFINITIONS = ("local error = mean over the shots of a pose of |estimated - commanded|; "
                "maximum error = max over the shots; mu, sigma = mean, sample std of the local "
                "errors over poses; M, sigma_M = the same of the maximum errors")


def evaluation_document(calibration, table, evaluation=None, *, paper: bool = False,
                        sources: dict | None = None, ddof: int = 1) -> dict:
    """The contents of ``evaluation.json``: the eight statistics and what was evaluated.

    Parameters
    ----------
    calibration : sunlab.calibration.Calibration
        The fitted (or loaded) calibration.
    table : xarray.Dataset
        The ``centroids/1`` test table (experiment III in the paper), commanded angles in deg.
    evaluation : tuple, optional
        ``(statistics, estimate, local)`` from ``sunlab.stats.evaluate(calibration, table,
        ddof=ddof, return_errors=True)`` when already computed (default: computed now).
    paper : bool
        Add the paper's Table 4 column of the calibration's method
        (:data:`sunlab.stats.PAPER_COLUMNS`), where it has one, under ``"paper"``.
    sources : dict, optional
        Where the calibration and the table came from, e.g. ``{"calibration": "cal.json",
        "test": "test.nc"}`` (file names); written as given.
    ddof : int
        Delta degrees of freedom of the standard deviations sigma and sigma_M (the paper's
        sample standard deviation: 1).

    Returns
    -------
    dict
        ``"alpha.mu"`` ... ``"beta.sigma_M"`` (deg; None where not finite), ``units``, the
        ``sources``, ``label``, ``kind``, ``n_poses``, ``n_shots``, ``n_ok_shots`` (usable
        shots of the table), ``n_out_of_domain`` (centroids outside the calibrated domain),
        ``ddof``, ``definitions`` and, with ``paper``, ``paper``.
    """
    frame, estimate, _ = evaluation or stats.evaluate(calibration, table, ddof=ddof,
                                                      return_errors=True)
    col = frame[calibration.label]
    doc = {f"{a}.{s}": (float(col[(a, s)]) if np.isfinite(col[(a, s)]) else None)
           for a in stats.ANGLES for s in stats.STATS}
    n_ok = int(np.isin(table["status"].values, [STATUS[k] for k in USABLE_STATUS]).sum())
    doc.update({
        "units": "deg", **{k: str(v) for k, v in (sources or {}).items()},
        "label": calibration.label, "kind": calibration.kind,
        "n_poses": int(table.sizes["pose"]), "n_shots": int(table.sizes["shot"]),
        "n_ok_shots": n_ok, "n_out_of_domain": int(estimate.attrs["n_out_of_domain"]),
        "ddof": int(ddof), "definitions": _DEFINITIONS,
    })
    want = stats.PAPER_COLUMNS.get(calibration.kind) if paper else None
    if want:
        column = stats.paper_table4()[want]
        doc["paper"] = {"column": want, **{f"{a}.{s}": float(column[(a, s)])
                                           for a in stats.ANGLES for s in stats.STATS}}
    return doc


def _png(fig) -> bytes:
    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, facecolor="white")
    return buf.getvalue()


def _figures(calibration, local, title: str) -> tuple[dict, list[str]]:
    """Figs. 10 and 11 as PNG bytes by file name, and why one was not drawn."""
    from . import plots

    figures, notes = {}, []
    try:
        fig10 = plots.error_maps(local, title=f"{calibration.label}: errors on {title}")
    except (ValueError, KeyError) as err:  # poses that do not form a grid: no map
        notes.append(f"no Fig. 10 (error maps): the test poses do not form a grid ({err})")
    else:
        figures[REPORT_FILES[2]] = _png(fig10)
    fig11 = plots.accuracy.new_figure(figsize=(9, 3.4), layout="constrained")
    for ax, a in zip(fig11.subplots(1, 2), stats.ANGLES, strict=True):
        plots.error_histogram(local, angle=a, title=f"local error of {a}", ax=ax)
    figures[REPORT_FILES[3]] = _png(fig11)
    return figures, notes


def write_report(out, calibration, table, evaluation=None, *, paper: bool = False,
                 sources: dict | None = None, ddof: int = 1, overwrite: bool = False,
                 flag: str = "overwrite=True") -> dict:
    """Write the evaluation report of ``calibration`` on ``table`` into the folder ``out``.

    The files are :data:`REPORT_FILES`: ``evaluation.json`` (:func:`evaluation_document`),
    ``errors.csv`` (per pose: ``pose``, ``alpha_cmd``, ``beta_cmd``, ``alpha_local_error``,
    ``alpha_max_error``, ``beta_local_error``, ``beta_max_error`` in deg, ``n_shots``,
    ``in_domain``), ``fig10_error_maps.png`` (Fig. 10, when the test poses form a grid) and
    ``fig11_histograms.png`` (Fig. 11). They are written together or not at all
    (:func:`sunlab.atomic.atomic_files`).

    Parameters
    ----------
    out : str or path-like
        The output folder (created if missing).
    calibration : sunlab.calibration.Calibration
        The fitted (or loaded) calibration.
    table : xarray.Dataset
        The ``centroids/1`` test table, commanded angles (deg) as coordinates.
    evaluation : tuple, optional
        ``(statistics, estimate, local)`` of ``sunlab.stats.evaluate(calibration, table,
        ddof=ddof, return_errors=True)`` when already computed (default: computed now).
    paper : bool
        Put the paper's Table 4 column beside the statistics (:func:`evaluation_document`).
    sources : dict, optional
        Where the calibration and the table came from (file names), for the JSON and the
        title of Fig. 10 (``sources["test"]``'s file name).
    ddof : int
        Delta degrees of freedom of sigma and sigma_M.
    overwrite : bool
        Replace files of :data:`REPORT_FILES` that exist in ``out``.
    flag : str
        How the caller asks to overwrite, for the message when a file exists.

    Returns
    -------
    dict
        ``"files"``: the paths written (list of pathlib.Path, in the order of
        :data:`REPORT_FILES`); ``"notes"``: what was not drawn and why (list of str);
        ``"evaluation"``: the JSON document (dict).

    Raises
    ------
    sunlab.errors.SunlabError
        A file exists and ``overwrite`` is False, or ``out`` cannot be made.
    """
    out = atomic.check_folder(out, REPORT_FILES, overwrite=overwrite, flag=flag)
    evaluation = evaluation or stats.evaluate(calibration, table, ddof=ddof, return_errors=True)
    doc = evaluation_document(calibration, table, evaluation, paper=paper, sources=sources,
                              ddof=ddof)
    _, estimate, local = evaluation
    title = Path(str((sources or {}).get("test", "the test table"))).name
    figures, notes = _figures(calibration, local, title)
    errors = pd.DataFrame({  # per pose: the commanded angles, errors, shots, in the domain
        "pose": table["pose"].values,
        "alpha_cmd": table["alpha"].values, "beta_cmd": table["beta"].values,
        **{f"{a}_{v}": local[v].sel(angle=a).values for a in stats.ANGLES
           for v in ("local_error", "max_error")},
        "n_shots": local["n_shots"].sel(angle="alpha").values,
        "in_domain": estimate["in_domain"].all("shot").values})
    texts = {REPORT_FILES[0]: json.dumps(doc, indent=1) + "\n",
             REPORT_FILES[1]: errors.to_csv(index=False, float_format="%.8g")}
    with atomic.atomic_files(out, REPORT_FILES, overwrite=overwrite, flag=flag) as tmp:
        for name, text in texts.items():
            (tmp / name).write_text(text, encoding="utf-8")
        for name, data in figures.items():
            (tmp / name).write_bytes(data)
    files = [out / name for name in REPORT_FILES if name in texts or name in figures]
    return {"files": files, "notes": notes, "evaluation": doc}
