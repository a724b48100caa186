"""Centroid tables written by other tools: CSV with the columns ``alpha, beta, x, y[, shot]``.

One row per shot; :func:`centroids_from_csv` turns it into a ``centroids/1`` table on
(pose, shot), which :func:`sunlab.io.open_centroids` returns for a ``.csv`` path. A value that
is not a number, a missing column or a repeated (pose, shot) raises a
:class:`sunlab.SchemaError` naming the file, the line and the column.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from ..errors import SchemaError
from ..schema import STATUS, centroids_dataset

__all__ = ["CSV_SUFFIXES", "centroids_from_csv", "csv_line_of"]

#: File suffixes read as CSV centroid tables.
CSV_SUFFIXES = (".csv", ".txt")


def centroids_from_csv(path, *, attrs: dict | None = None):
    """Read a centroid table written by another tool: CSV with columns alpha, beta, x, y.

    One row per shot: ``alpha``, ``beta`` (commanded angles, deg), ``x``, ``y`` (centroid, px,
    x = column, y = row, centre of the first pixel = 0; empty or NaN where no spot). Optional
    columns: ``shot`` (label within the pose; default the order of the rows of a pose) and
    ``status`` (a code or name of :data:`sunlab.schema.STATUS`; default ``ok`` where x and y are
    finite). Poses are the distinct (alpha, beta) pairs in file order; poses with fewer shots
    are padded with NaN (status ``no_spot``). Lines starting with ``#`` are comments.

    Parameters
    ----------
    path : str or path-like
        The CSV file.
    attrs : dict, optional
        Attributes of the table (sensor: ``mask_distance_mm``, ``pixel_pitch_mm``, ...).

    Returns
    -------
    xarray.Dataset
        A ``centroids/1`` table on (pose, shot).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "c.csv"
    >>> _ = path.write_text("alpha,beta,x,y\\n0,0,10.5,20.25\\n0,0,10.7,20.0\\n1,0,30.0,20.0\\n")
    >>> cen = centroids_from_csv(path)
    >>> dict(cen.sizes), cen.status.values.tolist()
    ({'pose': 2, 'shot': 2}, [[0, 0], [0, 1]])
    """
    path = Path(path)
    table = _read_csv_table(path)
    num = _numeric_columns(table, path.name)
    pairs = list(zip(num["alpha"].tolist(), num["beta"].tolist(), strict=True))
    pose_of: dict = {}
    for pair in pairs:
        pose_of.setdefault(pair, len(pose_of))
    pose = np.array([pose_of[p] for p in pairs])
    shot = _shot_numbers(table, pose, path.name)
    n_pose, n_shot = len(pose_of), int(shot.max()) + 1
    x = np.full((n_pose, n_shot), np.nan)
    y = np.full((n_pose, n_shot), np.nan)
    status = np.full((n_pose, n_shot), STATUS["no_spot"], dtype=np.int8)
    x[pose, shot], y[pose, shot] = num["x"], num["y"]
    status[pose, shot] = _status_codes(table, num, path.name)
    return centroids_dataset(
        x, y, status=status, alpha=[a for a, _ in pose_of], beta=[b for _, b in pose_of],
        method=str((attrs or {}).get("method", "")),
        attrs={"source": str(path.resolve()), "experiment": path.stem, **dict(attrs or {})},
    )


def csv_line_of(path, shot: dict) -> int | None:
    """The line number (1-based) of the CSV row holding ``shot`` (its ``alpha``, ``beta``,
    ``x``, ``y``), or None: how an excluded shot is named (:mod:`sunlab.screening`)."""
    import numpy as np

    table = _read_csv_table(Path(path))
    num = _numeric_columns(table, Path(path).name)
    hit = np.ones(len(table), dtype=bool)
    for key in ("alpha", "beta", "x", "y"):
        hit &= num[key] == shot[key]
    if not hit.any():
        return None
    # the data lines: what pandas reads (blank lines and '#' comments skipped), after the header
    with open(path, encoding="utf-8", errors="replace") as fh:
        lines = [n for n, text in enumerate(fh, 1) if text.split("#", 1)[0].strip()]
    row = int(np.flatnonzero(hit)[0]) + 1
    return lines[row] if row < len(lines) else None


def _read_csv_table(path: Path):
    """The CSV as a DataFrame, with the columns alpha, beta, x, y and at least one row."""
    try:
        table = pd.read_csv(path, comment="#", skipinitialspace=True)
    except FileNotFoundError as err:
        raise SchemaError("path", str(path), "an existing CSV file", "check the path") from err
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as err:
        raise SchemaError(str(path), f"unreadable CSV ({err})",
                          "a header line alpha,beta,x,y and one row per shot",
                          "fix the CSV syntax") from err
    table.columns = [str(c).strip() for c in table.columns]
    missing = [c for c in ("alpha", "beta", "x", "y") if c not in table.columns]
    if missing:
        raise SchemaError(
            f"{path.name} columns {missing}", f"missing (columns: {list(table.columns)})",
            "columns alpha, beta (deg), x, y (px); shot and status optional",
            "rename the columns (x = centroid column, y = centroid row, in pixels)",
        )
    if len(table) == 0:
        raise SchemaError(path.name, "no rows", "one row per shot", "add the rows")
    return table


def _numeric_columns(table, name: str) -> dict:
    """alpha, beta, x, y as float arrays; a value that is not a number names its line (x, y
    may be empty: no spot)."""
    num = {}
    for col in ("alpha", "beta", "x", "y"):
        v = pd.to_numeric(table[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(np.isnan(v) & table[col].notna().to_numpy()
                             if col in ("x", "y") else ~np.isfinite(v))
        if bad.size:
            raise SchemaError(
                f"{name} line {int(bad[0]) + 2} column {col!r}", table[col].iloc[bad[0]],
                "a number" + (" of degrees" if col in ("alpha", "beta") else " of pixels"),
                f"correct the value ({bad.size} bad row(s))",
            )
        num[col] = v
    return num


def _shot_numbers(table, pose, name: str):
    """Each row's shot within its pose: the rank of its ``shot`` label, or its order."""
    if "shot" not in table.columns:
        return pd.Series(pose).groupby(pose).cumcount().to_numpy()
    labels = pd.to_numeric(table["shot"], errors="coerce").to_numpy(dtype=float)
    if not np.all(np.isfinite(labels)):
        i = int(np.flatnonzero(~np.isfinite(labels))[0])
        raise SchemaError(f"{name} line {i + 2} column 'shot'", table["shot"].iloc[i],
                          "an integer shot label", "number the shots 0, 1, 2, ...")
    order = pd.DataFrame({"p": pose, "s": labels}).groupby("p")["s"].rank(method="first")
    dup = pd.DataFrame({"p": pose, "s": labels}).duplicated()
    if dup.any():
        i = int(np.flatnonzero(dup.to_numpy())[0])
        raise SchemaError(f"{name} line {i + 2}", "the same pose and shot again",
                          "one row per (alpha, beta, shot)", "remove the duplicate row")
    return order.to_numpy(dtype=int) - 1


def _status_codes(table, num: dict, name: str):
    """Each row's status code: the ``status`` column (name or code), or ``ok`` where x and y
    are finite and ``no_spot`` elsewhere."""
    if "status" not in table.columns:
        return np.where(np.isfinite(num["x"]) & np.isfinite(num["y"]),
                        STATUS["ok"], STATUS["no_spot"])
    codes = []
    for i, v in enumerate(table["status"].tolist()):
        code = STATUS.get(str(v).strip()) if not isinstance(v, int | float) else int(v)
        if code not in STATUS.values():
            raise SchemaError(f"{name} line {i + 2} column 'status'", v,
                              f"a status name or code of {STATUS}", "correct the value")
        codes.append(code)
    return codes
