"""The lab's own bench on the command line: ``sunlab import | evaluate | export``, and helpers.

From a folder of images to an on-board C table::

    sunlab import FOLDER --out cube.zarr --mask-distance-mm 5
    sunlab centroid cube.zarr --out train.nc        # or: sunlab centroid FOLDER --out ...
    sunlab calibrate train.nc --method polynomial --order 3 --out cal.json
    sunlab evaluate cal.json test.nc --out evaluation/ --paper
    sunlab export cal.json --format c --out onboard/

This module holds the parsers and runners of the new subcommands (registered in
:mod:`sunlab.cli.commands`), the reader of centroid tables given as CSV, the options shared by
``import`` and ``centroid`` for image folders, and :func:`read_calibration_json`, the reader
of ``sunlab info CAL.json`` (its text: :func:`sunlab.calibration.calibration_summary`). It
imports only the standard library at module level, so that ``sunlab --help`` and ``sunlab info
CAL.json`` start fast.

Examples
--------
>>> sorted(CALIBRATE_OPTIONS["order"])
['polynomial', 'trigonometric']
"""

from __future__ import annotations

import json
from pathlib import Path

from ..errors import SchemaError

__all__ = [
    "CALIBRATE_OPTIONS",
    "add_folder_options",
    "csv_line_of",
    "read_calibration_json",
    "centroids_from_csv",
    "is_image_folder",
    "open_centroid_table",
    "cube_from_folder",
]

#: Options of ``sunlab calibrate`` that apply only to some methods: option -> methods.
CALIBRATE_OPTIONS = {
    "order": ("polynomial", "trigonometric"),
    "validation": ("polynomial", "trigonometric", "neural", "linear", "cubic", "ideal",
                   "optimised"),
    "strategy": ("neural",),
    "hidden": ("neural",),
    "seed": ("neural",),
    "max_iter": ("neural",),
    "extrapolate": ("linear", "cubic"),
}

_STATS = ("mu", "sigma", "M", "sigma_M")
_PAPER_COLUMN = {"polynomial": "polynomial", "interpolation-linear": "linear interp.",
                 "interpolation-cubic": "cubic interp.", "neural": "NN strategy 4"}


# --------------------------------------------------------------------------------------------
# sunlab info CAL.json (standard library only; the text: sunlab.calibration.summary)
# --------------------------------------------------------------------------------------------
def read_calibration_json(path) -> dict | None:
    """The parsed document if ``path`` is a JSON file holding a calibration, else None."""
    path = Path(path)
    if not path.is_file():
        return None
    try:
        with open(path, "rb") as fh:
            head = fh.read(1).lstrip()
    except OSError as err:
        raise SchemaError(str(path), f"unreadable ({err.strerror or err})", "a readable file",
                          "check the file and its permissions") from err
    if head != b"{":  # an empty file is no JSON either: the cube readers describe it
        return None
    from .. import integrity  # standard library only

    doc = integrity.read_json(
        path, max_bytes=integrity.MAX_DOCUMENT_BYTES, what="a calibration/1 JSON document",
        fix="the file is corrupt, truncated or not a calibration; re-fit the calibration with "
            "`sunlab calibrate`")
    doc = integrity.verify_document(doc, path)
    if not isinstance(doc, dict) or "sunlab_schema" not in doc:
        raise SchemaError(
            f"{path}: sunlab_schema", "missing", "a calibration/1 JSON document",
            "this JSON file was not written by sunlab (sunlab calibrate / Calibration.save)",
        )
    if str(doc["sunlab_schema"]).partition("/")[0] != "calibration":
        raise SchemaError(f"{path}: sunlab_schema", doc["sunlab_schema"], "'calibration/1'",
                          "info reads frame cubes, centroid tables and calibration files")
    return doc


# --------------------------------------------------------------------------------------------
# Centroid tables as CSV
# --------------------------------------------------------------------------------------------
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
    import numpy as np

    from ..schema import STATUS, centroids_dataset

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
    import pandas as pd

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
    import numpy as np
    import pandas as pd

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
    import numpy as np
    import pandas as pd

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
    import numpy as np

    from ..schema import STATUS

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


def open_centroid_table(path, name: str = "table"):
    """A centroid table from NetCDF, Zarr or CSV (columns alpha, beta, x, y).

    A CSV table takes its sensor attributes (pixel pitch, mask distance, x_cf, y_cf) from a
    ``sensor.json`` in its folder, if there is one.
    """
    from .. import io

    if Path(path).suffix.lower() in (".csv", ".txt"):
        sensor = _sensor_json(Path(path).resolve().parent, None)
        keys = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px")
        return centroids_from_csv(path, attrs={k: sensor[k] for k in keys if k in sensor})
    ds = io.open_dataset(path)
    if ds.attrs.get("sunlab_schema") != "centroids/1":
        raise SchemaError(
            f"{name} {path}", f"a {ds.attrs.get('sunlab_schema')!r} dataset",
            "a centroid table (centroids/1, or a CSV with columns alpha, beta, x, y)",
            f"centroid the frames first: sunlab centroid {path} --out table.nc",
        )
    return ds


# --------------------------------------------------------------------------------------------
# Image folders (sunlab import, sunlab centroid FOLDER)
# --------------------------------------------------------------------------------------------
def is_image_folder(path) -> bool:
    """True for a folder of images (not a Zarr store)."""
    path = Path(path)
    if not path.is_dir() or (path / "zarr.json").exists() or (path / ".zgroup").exists():
        return False
    return (path / "manifest.csv").exists() or any(
        p.suffix.lower() in (".png", ".tif", ".tiff") for p in path.iterdir())


def add_folder_options(p) -> None:
    """The options of an image folder (``sunlab import``, ``sunlab centroid FOLDER``)."""
    g = p.add_argument_group("image folder (PNG/TIFF frames + manifest.csv)")
    g.add_argument("--manifest", default=None,
                   help="manifest CSV with columns file, alpha, beta, shot (default "
                        "FOLDER/manifest.csv)")
    g.add_argument("--pixel-pitch-mm", type=float, default=None,
                   help="pixel pitch, mm (default: sensor.json, else 0.007)")
    g.add_argument("--mask-distance-mm", type=float, default=None,
                   help="nominal mask-to-focal-plane distance F, mm (required unless the "
                        "manifest's folder holds sensor.json with mask_distance_mm)")
    g.add_argument("--bit-depth", type=int, default=None,
                   help="ADC bit depth (default: sensor.json, else from the images)")
    g.add_argument("--experiment", dest="folder_experiment", default=None,
                   help="experiment name stored in the cube (default: the folder name)")


_SENSOR_KEYS = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "bit_depth", "mask",
                "experiment")


def _sensor_json(folder: Path, manifest) -> dict:
    where = Path(manifest).resolve().parent if manifest else folder
    path = where / "sensor.json"
    if not path.exists() and manifest:
        path = folder / "sensor.json"
    if not path.exists():
        return {}
    from .. import integrity

    doc = integrity.read_json(path, max_bytes=2**20, what="a sensor.json object with keys "
                              f"among {list(_SENSOR_KEYS)}", fix="fix the JSON syntax")
    if not isinstance(doc, dict):
        raise SchemaError(str(path), type(doc).__name__, "a JSON object", "fix the file")
    unknown = sorted(set(doc) - set(_SENSOR_KEYS) - {"comment", "attrs"})
    if unknown:
        raise SchemaError(f"{path.name} keys {unknown}", "unknown",
                          f"keys among {list(_SENSOR_KEYS)}", "remove or rename them")
    return doc


def cube_from_folder(folder, args):
    """A lazy frame cube from an image folder and the folder options of ``args``."""
    from .. import io
    from ..errors import ConfigurationError

    folder = Path(folder)
    manifest = getattr(args, "manifest", None)
    sensor = _sensor_json(folder, manifest)
    kw = {k: sensor[k] for k in ("x_cf_px", "y_cf_px", "mask") if k in sensor}
    kw["attrs"] = dict(sensor.get("attrs") or {})
    pitch = args.pixel_pitch_mm if args.pixel_pitch_mm is not None else sensor.get(
        "pixel_pitch_mm", 0.007)
    distance = (args.mask_distance_mm if args.mask_distance_mm is not None
                else sensor.get("mask_distance_mm"))
    if distance is None:
        raise ConfigurationError(
            "--mask-distance-mm: not given, and no sensor.json with mask_distance_mm next to the "
            f"manifest in {folder}. Fix: pass --mask-distance-mm F (the nominal "
            "mask-to-focal-plane distance, mm), or write sensor.json with it"
        )
    bit_depth = args.bit_depth if args.bit_depth is not None else sensor.get("bit_depth")
    experiment = (getattr(args, "folder_experiment", None) or sensor.get("experiment")
                  or folder.resolve().name)
    return io.from_image_folder(folder, manifest, bit_depth=bit_depth, pixel_pitch_mm=pitch,
                                mask_distance_mm=distance, experiment=experiment, **kw)


# --------------------------------------------------------------------------------------------
# sunlab import
# --------------------------------------------------------------------------------------------
def _add_import(sub) -> None:
    p = sub.add_parser(
        "import", help="import a folder of PNG/TIFF frames + manifest.csv into a frame cube",
        description="Read FOLDER/manifest.csv (columns file, alpha, beta, shot; one row per "
        "image) and the PNG or TIFF frames it lists into a frame cube (contract frames/1). "
        "Sensor constants come from the options, else FOLDER/sensor.json.",
    )
    p.add_argument("folder", help="folder of images with manifest.csv (and sensor.json)")
    p.add_argument("--out", required=True, help="output cube (.zarr store or .nc file)")
    add_folder_options(p)
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.set_defaults(func=_run_import)


def _run_import(args) -> int:
    from .. import atomic, io

    kind = "file" if Path(args.out).suffix.lower() in io.NETCDF_SUFFIXES else "zarr"
    atomic.check_target(args.out, overwrite=args.overwrite, kind=kind, flag="--overwrite")
    cube = cube_from_folder(args.folder, args)
    io.save_frames(cube, args.out, overwrite=args.overwrite, progress=not args.no_progress)
    print(f"{args.out}: {cube.sizes['pose']} poses x {cube.sizes['shot']} shots of "
          f"{cube.sizes['y']} x {cube.sizes['x']} px ({cube.attrs['bit_depth']}-bit), "
          f"F = {cube.attrs['mask_distance_mm']} mm, pitch {cube.attrs['pixel_pitch_mm']} mm")
    return 0


# --------------------------------------------------------------------------------------------
# sunlab evaluate
# --------------------------------------------------------------------------------------------
def _add_evaluate(sub) -> None:
    p = sub.add_parser(
        "evaluate", help="apply a saved calibration to a test centroid table: the paper's "
                         "statistics, per-pose errors, Figs. 10-11",
        description="Estimate the angles of every centroid of TEST with the calibration CAL, "
        "and compare with the commanded angles: local error (mean over shots) and maximum error "
        "per pose, then mu, sigma (of the local errors), M, sigma_M (of the maximum errors) per "
        "angle, as in the paper's Table 4 (docs/paper.md sec. 5).",
    )
    p.add_argument("calibration", help="calibration file (.json, from sunlab calibrate)")
    p.add_argument("test", help="test centroid table (.nc, .zarr, or .csv with columns alpha, "
                               "beta, x, y[, shot])")
    p.add_argument("--out", default=None, metavar="DIR",
                   help="write DIR/evaluation.json, DIR/errors.csv, DIR/fig10_error_maps.png, "
                        "DIR/fig11_histograms.png")
    p.add_argument("--paper", action="store_true", help="print the paper's Table 4 beside")
    p.add_argument("--overwrite", action="store_true", help="replace existing outputs in DIR")
    p.set_defaults(func=_run_evaluate)


def _figure_bytes(fig) -> bytes:
    import io as _io

    buf = _io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, facecolor="white")
    return buf.getvalue()


def evaluate(cal, test) -> dict:
    """Statistics of a calibration on a test table: estimate, local errors, Table-4 column."""
    from .. import stats

    est = cal.predict(test)
    local = stats.local_errors(est)
    table = stats.global_stats({cal.label: local})
    return {"estimate": est, "local": local, "table": table}


def _run_evaluate(args) -> int:
    import numpy as np
    import pandas as pd

    from .. import atomic, calibration, stats

    out = None if args.out is None else Path(args.out)
    names = ("evaluation.json", "errors.csv", "fig10_error_maps.png", "fig11_histograms.png")
    if out is not None:  # checked now, made only once every file is written
        atomic.check_folder(out, names, overwrite=args.overwrite, flag="--overwrite")
    cal = calibration.load(args.calibration)
    test = open_centroid_table(args.test, "test")
    res = evaluate(cal, test)
    est, local, table = res["estimate"], res["local"], res["table"]
    col = table[cal.label]
    n_out = int(est.attrs["n_out_of_domain"])
    from ..schema import STATUS, USABLE_STATUS

    n_ok = int(np.isin(test["status"].values, [STATUS[k] for k in USABLE_STATUS]).sum())
    print(f"{cal.label} on {args.test}: {test.sizes['pose']} poses x {test.sizes['shot']} shots "
          f"({n_ok} ok); global statistics (deg), as the paper's Table 4:")
    shown = table.rename(columns={cal.label: f"{cal.label} (sunlab)"})
    if args.paper:
        paper = stats.paper_table4()
        want = _PAPER_COLUMN.get(cal.kind)
        keep = [want] if want in paper.columns else list(paper.columns)
        shown = pd.concat([shown, paper[keep].add_suffix(" (paper)")], axis=1)
    print(shown.to_string(float_format=lambda v: f"{v:.5f}"))
    if n_out:
        print(f"warning: {n_out} centroid(s) outside the calibrated domain (extrapolated"
              f"{' or NaN' if cal.kind.startswith('interpolation') else ''}); see in_domain in "
              "errors.csv")
    if out is None:
        return 0
    doc = _evaluation_doc(args, cal, test, col, n_ok, n_out)
    rows = pd.DataFrame({
        "pose": test["pose"].values,
        "alpha_cmd": test["alpha"].values, "beta_cmd": test["beta"].values,
        **{f"{a}_{v}": local[v].sel(angle=a).values for a in ("alpha", "beta")
           for v in ("local_error", "max_error")},
        "n_shots": local["n_shots"].sel(angle="alpha").values,
        "in_domain": est["in_domain"].all("shot").values,
    })
    # every file or none (sunlab.atomic.atomic_files)
    with atomic.atomic_files(out, names, overwrite=args.overwrite, flag="--overwrite") as tmp:
        (tmp / names[0]).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
        (tmp / names[1]).write_text(rows.to_csv(index=False, float_format="%.8g"),
                                    encoding="utf-8")
        written = [names[0], names[1]] + _write_evaluation_figures(args, cal, local, tmp,
                                                                   names[2:])
    print(f"wrote {', '.join(str(out / n) for n in written)}")
    return 0


def _evaluation_doc(args, cal, test, col, n_ok: int, n_out: int) -> dict:
    """``evaluation.json``: the eight statistics, what was evaluated, and the paper's column."""
    import numpy as np

    from .. import stats

    doc = {f"{a}.{s}": (None if not np.isfinite(col[(a, s)]) else float(col[(a, s)]))
           for a in ("alpha", "beta") for s in _STATS}
    doc.update({
        "units": "deg", "calibration": str(args.calibration), "label": cal.label,
        "kind": cal.kind, "test": str(args.test), "n_poses": int(test.sizes["pose"]),
        "n_shots": int(test.sizes["shot"]), "n_ok_shots": n_ok, "n_out_of_domain": n_out,
        "ddof": 1,
        "definitions": "local error = mean over the shots of a pose of |estimated - commanded|; "
                       "maximum error = max over the shots; mu, sigma = mean, sample std of "
                       "the local errors over poses; M, sigma_M = the same of the maximum errors",
    })
    want = _PAPER_COLUMN.get(cal.kind) if args.paper else None
    if want:
        paper = stats.paper_table4()[want]
        doc["paper"] = {"column": want, **{f"{a}.{s}": float(paper[(a, s)])
                                           for a in ("alpha", "beta") for s in _STATS}}
    return doc


def _write_evaluation_figures(args, cal, local, out: Path, names) -> list[str]:
    """Fig. 10 (error maps, when the test poses form a grid) and Fig. 11 (histograms)."""
    from .. import plots

    written = []
    try:
        fig10 = plots.error_maps(local, title=f"{cal.label}: errors on {Path(args.test).name}")
    except (ValueError, KeyError) as err:  # poses that do not form a grid: no map
        print(f"no Fig. 10 (error maps): the test poses do not form a grid ({err})")
    else:
        (out / names[0]).write_bytes(_figure_bytes(fig10))
        written.append(names[0])
    fig11 = plots.new_figure(figsize=(9, 3.4), layout="constrained")
    for ax, a in zip(fig11.subplots(1, 2), ("alpha", "beta"), strict=True):
        h = plots.error_histogram(local, angle=a, title=f"local error of {a}")
        _copy_histogram(h.axes[0], ax)
    (out / names[1]).write_bytes(_figure_bytes(fig11))
    return written + [names[1]]


def _copy_histogram(src, ax) -> None:
    """Redraw a one-axes histogram figure (bars + normal curve) into ``ax``."""
    for patch in src.patches:
        x, w, h = patch.get_x(), patch.get_width(), patch.get_height()
        ax.bar(x, h, width=w, align="edge", color=patch.get_facecolor(),
               edgecolor=patch.get_edgecolor())
    for line in src.lines:
        ax.plot(*line.get_data(), color=line.get_color(), label=line.get_label())
    ax.set_ylim(src.get_ylim())  # the source's headroom keeps the legend clear of the bars
    ax.set_title(src.get_title())
    ax.set_xlabel(src.get_xlabel())
    ax.set_ylabel(src.get_ylabel())
    if any(not str(line.get_label()).startswith("_") for line in src.lines):
        ax.legend(fontsize="small")


# --------------------------------------------------------------------------------------------
# sunlab export
# --------------------------------------------------------------------------------------------
def _add_export(sub) -> None:
    p = sub.add_parser(
        "export", help="export a calibration for on-board use (C99 header + source, or JSON)",
        description="Write DIR/sunlab_calibration.h and DIR/sunlab_calibration.c: self-contained "
        "C99 (no allocation, only <math.h>) with sunlab_calibration_eval (double) and "
        "sunlab_calibration_evalf (float), returning 0 inside the calibrated domain and non-zero "
        "outside. Polynomial, linear interpolation, neural networks and the geometric models "
        "are exported; cubic interpolation and trigonometric calibrations are refused.",
    )
    p.add_argument("calibration", help="calibration file (.json, from sunlab calibrate)")
    p.add_argument("--format", default="c", choices=["c", "json"],
                   help="c (header + source, default) or json (the interchange artifact)")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--check", action="store_true",
                   help="compile with the system C compiler and compare with Python on 1,000 "
                        "points of the domain")
    p.add_argument("--overwrite", action="store_true", help="replace existing files in DIR")
    p.set_defaults(func=_run_export)


def _run_export(args) -> int:
    from .. import calibration, export

    cal = calibration.load(args.calibration)
    files = export.export(cal, args.out, format=args.format, overwrite=args.overwrite)
    print(f"{cal.label}: wrote {', '.join(map(str, files))}")
    if args.check and args.format == "c":
        report = export.check_c(cal, args.out)
        print(f"compiled with {report['compiler']}; max |C - Python| on {report['n']} points: "
              f"double {report['max_error_double']:.2e} deg, float "
              f"{report['max_error_float']:.2e} deg; domain flags agree: "
              f"{report['flags_agree']}")
    return 0
