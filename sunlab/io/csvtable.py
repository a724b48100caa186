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
from ..plans import MAX_ANGLE_DEG
from ..schema import STATUS, centroids_dataset

__all__: list[str] = []

#: File suffixes read as CSV centroid tables.
CSV_SUFFIXES = (".csv", ".txt")

#: Largest CSV table read (bytes): a million shots is about 40 MB.
MAX_CSV_BYTES = 512 * 2**20

#: Largest page number of a TIFF stack in a manifest (a stack of 2**31 frames is no stack).
_MAX_PAGE = 2**31 - 1

#: The numeric columns of manifests and centroid tables, one rule each: what a value must be,
#: and its test on the parsed floats ``v`` (NaN: no number) and ``empty`` (an empty field).
_RULES = {
    "degrees": (f"a commanded angle within (-{MAX_ANGLE_DEG:g}, {MAX_ANGLE_DEG:g}) deg, a finite "
                "number of degrees (the sun in front of the mask; the paper's platform spans a "
                "few tens of degrees)", lambda v, empty: np.abs(v) < MAX_ANGLE_DEG),
    "pixels": ("a number of pixels, or empty (no spot)", lambda v, empty: ~np.isnan(v) | empty),
    "label": ("a finite number", lambda v, empty: np.isfinite(v)),
    "integer": ("an integer (frames of a pose numbered 0, 1, 2, ...)",
                lambda v, empty: np.isfinite(v) & (v == np.round(v))),
    "page": (f"an integer page 0 .. {_MAX_PAGE} of the TIFF stack named in 'file'",
             lambda v, empty: (v >= 0) & (v <= _MAX_PAGE) & (v == np.round(v))),
}


def _uncommented(text: str) -> str:
    """A line up to its first ``#`` outside double quotes (the rest is a comment)."""
    quoted = False
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif ch == "#" and not quoted:
            return text[:i]
    return text


def _read_text(path: Path, name: str) -> str:
    """The file's text (UTF-8, a BOM dropped), at most :data:`MAX_CSV_BYTES`."""
    try:
        if path.stat().st_size > MAX_CSV_BYTES:
            raise SchemaError(name, f"{path.stat().st_size} bytes",
                              f"a table of at most {MAX_CSV_BYTES} bytes", "split the table")
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError as err:
        raise SchemaError("path", str(path), "an existing CSV file", "check the path") from err
    except IsADirectoryError as err:
        raise SchemaError("path", f"{path} (a folder)", "a CSV file", "give the file") from err
    except UnicodeDecodeError as err:
        raise SchemaError(name, f"not UTF-8 text ({err.reason} at byte {err.start})",
                          "a UTF-8 CSV file", "save the table as UTF-8 CSV") from err


def _checked_header(header: list, name: str, head_line: int) -> list:
    """The header's column names, trailing empty ones dropped; a semicolon-separated table, an
    empty, duplicated or unprintable name refused naming the line."""
    while header and not header[-1]:  # trailing commas on the header
        header = header[:-1]
    if len(header) == 1 and ";" in header[0]:
        raise SchemaError(f"{name} line {head_line}", "fields separated by ';'",
                          "comma-separated values with '.' decimals",
                          "save the table as CSV with ',' between fields and '.' as the "
                          "decimal mark")
    seen: dict = {}
    for k, col in enumerate(header):
        if not col:
            raise SchemaError(f"{name} line {head_line}", f"no name for column {k + 1}",
                              "a name for every column", "name the column or remove it")
        if not col.isprintable():
            raise SchemaError(f"{name} line {head_line} column {k + 1}",
                              col.encode("unicode_escape").decode("ascii"),
                              "a column name of printable characters",
                              "rename the column (control characters such as ESC are refused)")
        if col in seen:
            raise SchemaError(f"{name} line {head_line}", f"column {col!r} twice (columns "
                              f"{seen[col] + 1} and {k + 1})", "each column name once",
                              "rename or remove one of them")
        seen[col] = k
    return header


def read_csv_table(path, what: str = "table"):
    """A CSV file as a table of text, each field stripped, every row checked against the header.

    Foreign tables fail loudly instead of being read with shifted columns: a row with more
    fields than the header (comma decimals, ``512,5``, or a text holding a comma) names its
    line; a header with a duplicated or empty column name, or a column name holding control
    characters, is refused. Trailing commas (empty fields after the last column, on the header
    or on any row) are accepted and dropped. Lines starting with ``#`` and blank lines are
    skipped; ``#`` outside quotes starts a comment.

    Parameters
    ----------
    path : str or path-like
        The CSV file (UTF-8).
    what : str
        What the file is, for the messages (``"manifest"``, ``"table"``, ``"plan"``).

    Returns
    -------
    pandas.DataFrame
        One column of text per header column (empty fields: NaN); ``attrs["lines"]`` holds the
        file's line number (1-based) of each row.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.csv"
    >>> _ = path.write_text("alpha,beta,x,y,\\n# a comment\\n0,0,512.5,300,\\n")
    >>> t = read_csv_table(path)
    >>> list(t.columns), t["x"].tolist(), t.attrs["lines"]
    (['alpha', 'beta', 'x', 'y'], ['512.5'], [3])
    >>> _ = path.write_text("alpha,beta,x,y\\n0,0,512,5,300,25\\n")
    >>> try:
    ...     read_csv_table(path)
    ... except SchemaError as err:
    ...     print(err.field, "|", err.found)
    table t.csv line 2 | 6 fields
    """
    import csv

    path = Path(path)
    name = f"{what} {path.name}" if what else path.name
    records = [(n, [f.strip() for f in next(csv.reader([body]))])
               for n, raw in enumerate(_read_text(path, name).splitlines(), 1)
               if (body := _uncommented(raw)).strip()]
    if not records:
        raise SchemaError(name, "an empty file", "a header line and one row per line",
                          "write the header and the rows")
    header = _checked_header(records[0][1], name, records[0][0])
    n = len(header)
    for number, fields in records[1:]:
        if any(fields[n:]):
            raise SchemaError(
                f"{name} line {number}", f"{len(fields)} fields",
                f"the header's {n} ({', '.join(header)})",
                "write decimals with '.', not ',' (512.5, not 512,5), quote a text that holds a "
                "comma, or remove the extra fields")
    table = pd.DataFrame([[f or None for f in fields[:n]] + [None] * (n - len(fields))
                          for _, fields in records[1:]], columns=header, dtype=object)
    table.attrs["lines"] = [number for number, _ in records[1:]]
    return table


def centroids_from_csv(path, *, attrs: dict | None = None):
    """A CSV table of another tool as a ``centroids/1`` table on (pose, shot): what
    :func:`sunlab.io.open_centroids` returns for a ``.csv`` path (the columns are described
    there; ``status`` holds names or codes of :data:`sunlab.schema.STATUS`, default ``ok`` where
    x and y are finite). ``attrs``: attributes of the table (the sensor's)."""
    path = Path(path)
    table = _read_csv_table(path)
    num = {c: _numbers(table, c, path.name, "pixels" if c in "xy" else "degrees")
           for c in ("alpha", "beta", "x", "y")}
    poses, pose = _poses(num["alpha"], num["beta"])
    shot = _shot_numbers(table, pose, path.name)
    shape = (len(poses), int(shot.max()) + 1)
    x, y = np.full(shape, np.nan), np.full(shape, np.nan)
    status = np.full(shape, STATUS["no_spot"], dtype=np.int8)
    x[pose, shot], y[pose, shot] = num["x"], num["y"]
    status[pose, shot] = _status_codes(table, num, path.name)
    return centroids_dataset(
        x, y, status=status, alpha=[a for a, _ in poses], beta=[b for _, b in poses],
        method=str((attrs or {}).get("method", "")),
        attrs={"source": str(path.resolve()), "experiment": path.stem, **dict(attrs or {})})


def csv_line_of(path, shot: dict) -> int | None:
    """The line number (1-based) of the CSV row holding ``shot`` (its ``alpha``, ``beta``,
    ``x``, ``y``), or None: how an excluded shot is named (:mod:`sunlab.screening`).

    Parameters
    ----------
    path : str or path-like
        The CSV centroid table.
    shot : dict
        ``alpha``, ``beta`` (deg) and ``x``, ``y`` (px) of the shot, compared for exact
        equality with the numbers of each row.

    Returns
    -------
    int or None
        The 1-based line of the file (comment and blank lines counted) of the first matching
        row; None when no row matches.
    """
    table = _read_csv_table(Path(path))
    hit = np.logical_and.reduce([_numbers(table, k, "", "pixels" if k in "xy" else "degrees")
                                 == shot[k] for k in ("alpha", "beta", "x", "y")])
    return _line(table, np.flatnonzero(hit)[0]) if hit.any() else None


def _read_csv_table(path: Path):
    """The CSV as a DataFrame, with the columns alpha, beta, x, y and at least one row."""
    table = read_csv_table(path, "")
    _require(table, path.name, ("alpha", "beta", "x", "y"), "one row per shot", "add or rename "
             "them (alpha, beta: commanded angles, deg; x = centroid column, y = centroid row, "
             "px; shot and status optional)")
    return table


def _require(table, name: str, columns, rows: str, fix: str) -> None:
    """The table has the ``columns`` and at least one row."""
    missing = [c for c in columns if c not in table.columns]
    if missing:
        raise SchemaError(f"{name} columns {missing}", f"missing (columns: "
                          f"{list(table.columns)})", f"columns {', '.join(columns)}", fix)
    if len(table) == 0:
        raise SchemaError(name, "no rows", rows, "add the rows")


def _line(table, i) -> int:
    """The file's line number of row ``i`` (:func:`read_csv_table`)."""
    return int(table.attrs["lines"][int(i)])


def _numbers(table, col: str, name: str, rule: str):
    """A column as floats, each value checked against its rule of :data:`_RULES`; the first bad
    one names its line (a commanded angle a pinhole sensor cannot see, |angle| >= 90 deg, is
    refused, as one typo would bend a whole calibration)."""
    expected, ok = _RULES[rule]
    v = pd.to_numeric(table[col], errors="coerce").to_numpy(dtype=float)
    bad = np.flatnonzero(~ok(v, table[col].isna().to_numpy()))
    if bad.size:
        raise SchemaError(f"{name} line {_line(table, bad[0])} column {col!r}",
                          table[col].iloc[bad[0]], expected,
                          f"correct the value, or remove the row ({bad.size} such row(s))")
    return v


def _poses(alpha, beta):
    """The distinct (alpha, beta) pairs in order of appearance, and each row's pose."""
    pairs = list(zip(alpha.tolist(), beta.tolist(), strict=True))
    poses = dict.fromkeys(pairs)
    index = {p: i for i, p in enumerate(poses)}
    return list(poses), np.array([index[p] for p in pairs], dtype=int)


def _shot_numbers(table, pose, name: str):
    """Each row's shot within its pose: the rank of its ``shot`` label, or its order."""
    if "shot" not in table.columns:
        return pd.Series(pose).groupby(pose).cumcount().to_numpy()
    labels = _numbers(table, "shot", name, "label")
    _once(table, list(zip(pose.tolist(), labels.tolist(), strict=True)), name,
          lambda i: f"alpha={table['alpha'].iloc[i]}, beta={table['beta'].iloc[i]}, shot="
          f"{table['shot'].iloc[i]}", "one row per (alpha, beta, shot)", "remove the duplicate row")
    frame = pd.DataFrame({"p": pose, "s": labels})
    return frame.groupby("p")["s"].rank(method="first").to_numpy(dtype=int) - 1


def _once(table, keys: list, name: str, what, expected: str, fix: str) -> None:
    """Each row's key (a file, a page, a pose and shot) once: a repeat names its line, the
    first line, and ``what(row)`` was repeated."""
    first: dict = {}
    for i, key in enumerate(keys):
        if key in first:
            raise SchemaError(f"{name} line {_line(table, i)}", f"{what(i)} again (first on "
                              f"line {_line(table, first[key])})", expected, fix)
        first[key] = i


def _status_codes(table, num: dict, name: str):
    """Each row's status code: the ``status`` column (name or code), or ``ok`` where x and y
    are finite and ``no_spot`` elsewhere."""
    if "status" not in table.columns:
        return np.where(np.isfinite(num["x"]) & np.isfinite(num["y"]), STATUS["ok"],
                        STATUS["no_spot"])
    codes = table["status"].astype(str).str.strip().map(
        lambda text: int(text) if text.isdigit() else STATUS.get(text, -1))
    bad = np.flatnonzero(~codes.isin(list(STATUS.values())).to_numpy())
    if bad.size:
        raise SchemaError(f"{name} line {_line(table, bad[0])} column 'status'",
                          table["status"].iloc[bad[0]], f"a status name or code of {STATUS}",
                          "correct the value")
    return codes.to_numpy(dtype=np.int8)
