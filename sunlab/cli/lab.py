"""The lab's own bench on the command line: ``sunlab import | evaluate | export``, and helpers.

From a folder of images to an on-board C table::

    sunlab import FOLDER --out cube.zarr --dark DARK --flat FLAT   # sensor.json beside
    sunlab centroid cube.zarr --out train.nc        # or: sunlab centroid FOLDER --out ...
    sunlab calibrate train.nc --method polynomial --order 3 --out cal.json
    sunlab evaluate cal.json test.nc --out evaluation/ --paper
    sunlab export cal.json --format c --out onboard/

This module holds the parsers and runners of the new subcommands (registered in
:mod:`sunlab.cli.commands`), the opening of centroid tables (:func:`sunlab.io.open_centroids`
with a CSV table's ``sensor.json``), the options shared by
``import`` and ``centroid`` for image folders, and :func:`read_calibration_json`, the reader
of ``sunlab info CAL.json`` (its text: :func:`sunlab.calibration.calibration_summary`). It
imports only the standard library at module level, so that ``sunlab --help`` and ``sunlab info
CAL.json`` start fast.

Examples
--------
>>> import tempfile
>>> is_image_folder(tempfile.mkdtemp())
False
"""

from __future__ import annotations

from pathlib import Path

from ..errors import SchemaError

__all__ = []

# --------------------------------------------------------------------------------------------
# sunlab info CAL.json (standard library only; the text: sunlab.calibration.summary)
# --------------------------------------------------------------------------------------------
def read_calibration_json(path) -> dict | None:
    """The parsed document if ``path`` is a JSON file holding a calibration, else None.

    Parameters
    ----------
    path : str or path-like
        The file ``sunlab info`` was given.

    Returns
    -------
    dict or None
        The ``calibration/1`` document, its checksum verified
        (:func:`sunlab.integrity.verify_document`); None when ``path`` is no file or does not
        start with ``{`` (a cube or a table, for the other readers).

    Raises
    ------
    SchemaError
        An unreadable file, or a JSON document that is corrupt, too large or no calibration.
    """
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
def open_centroid_table(path, name: str = "table"):
    """A centroid table from NetCDF, Zarr or CSV (columns alpha, beta, x, y).

    :func:`sunlab.io.open_centroids` (which reads a CSV table's ``sensor.json``); an error
    about the file as a whole names the argument.

    Parameters
    ----------
    path : str or path-like
        The table file or store.
    name : str
        The argument it was given as (``train``, ``validation``, ``test``), for the message.

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1``: ``x``, ``y`` px on (pose, shot[, hole]) with the commanded
        ``alpha``, ``beta`` (deg).

    Raises
    ------
    SchemaError
        The file cannot be read as a centroid table (the field ``NAME PATH`` when it is the
        whole file).
    """
    from .. import io

    try:
        return io.open_centroids(path)  # a CSV table's sensor.json is read by the library
    except SchemaError as err:
        if err.field != str(path):
            raise
        raise SchemaError(f"{name} {path}", err.found, err.expected, err.fix) from err


# --------------------------------------------------------------------------------------------
# Image folders (sunlab import, sunlab centroid FOLDER)
# --------------------------------------------------------------------------------------------
def is_image_folder(path) -> bool:
    """Whether ``path`` is a folder of images (not a Zarr store).

    Parameters
    ----------
    path : str or path-like
        The path given on the command line.

    Returns
    -------
    bool
        True for a directory without Zarr metadata that holds ``manifest.csv`` or a PNG or
        TIFF file.
    """
    path = Path(path)
    if not path.is_dir() or (path / "zarr.json").exists() or (path / ".zgroup").exists():
        return False
    return (path / "manifest.csv").exists() or any(
        p.suffix.lower() in (".png", ".tif", ".tiff") for p in path.iterdir())


def add_folder_options(p) -> None:
    """Add the options of an image folder (``sunlab import``, ``sunlab centroid FOLDER``).

    Parameters
    ----------
    p : argparse.ArgumentParser
        The subcommand's parser; gains the group ``--manifest``, ``--pixel-pitch-mm``,
        ``--mask-distance-mm``, ``--bit-depth``, ``--left-aligned``, ``--experiment``,
        ``--dark``, ``--flat``, ``--bias`` (read by :func:`cube_from_folder`).
    """
    g = p.add_argument_group("image folder (PNG/TIFF frames + manifest.csv)")
    g.add_argument("--manifest", default=None,
                   help="manifest CSV with columns file, alpha, beta, shot (default "
                        "FOLDER/manifest.csv)")
    g.add_argument("--pixel-pitch-mm", type=float, default=None,
                   help="pixel pitch, mm (default: sensor.json; never guessed: the geometric "
                        "models ask for it)")
    g.add_argument("--mask-distance-mm", type=float, default=None,
                   help="nominal mask-to-focal-plane distance F, mm (default: sensor.json; "
                        "only the geometric models need it)")
    g.add_argument("--bit-depth", type=int, default=None,
                   help="ADC bit depth, 8-16; sets the saturation level (default: sensor.json, "
                        "else from the images)")
    g.add_argument("--left-aligned", action="store_true", default=None,
                   help="the camera writes its DN in the top bits of the 16-bit word (e.g. 12-bit "
                        "data x 16); shifted down on read (default: sensor.json)")
    g.add_argument("--experiment", dest="folder_experiment", default=None,
                   help="experiment name stored in the cube (default: the folder name)")
    g.add_argument("--dark", default=None, metavar="DARK",
                   help="dark frames (a folder of images or a TIFF stack): their median is "
                        "subtracted from every frame before centroiding")
    g.add_argument("--flat", default=None, metavar="FLAT",
                   help="flat frames (folder or stack): the median of the dark-subtracted flats, "
                        "normalised to 1, divides every frame")
    g.add_argument("--bias", default=None, metavar="BIAS",
                   help="bias frames (folder or stack): subtracted when no dark is given")


def cube_from_folder(folder, args):
    """A lazy frame cube from an image folder and the folder options of ``args``.

    Parameters
    ----------
    folder : str or path-like
        Folder of PNG/TIFF frames with ``manifest.csv`` (and ``sensor.json``).
    args : argparse.Namespace
        The parsed command line with the options of :func:`add_folder_options`.

    Returns
    -------
    xarray.Dataset
        Contract ``frames/1`` on (pose, shot, y, x), DN, read lazily, with the masters of
        the dark, flat and bias frames stored for centroiding (:func:`sunlab.io.open_frames`).
    """
    from .. import io

    return io.open_frames(
        folder, getattr(args, "manifest", None), dark=getattr(args, "dark", None),
        flat=getattr(args, "flat", None), bias=getattr(args, "bias", None),
        pixel_pitch_mm=args.pixel_pitch_mm, mask_distance_mm=args.mask_distance_mm,
        bit_depth=args.bit_depth, left_aligned=getattr(args, "left_aligned", None),
        experiment=getattr(args, "folder_experiment", None),
    )


# --------------------------------------------------------------------------------------------
# sunlab import
# --------------------------------------------------------------------------------------------
def _add_import(sub) -> None:
    p = sub.add_parser(
        "import", help="import a folder of PNG/TIFF frames + manifest.csv into a frame cube",
        description="Read FOLDER/manifest.csv (columns file, alpha, beta, shot; one row per "
        "image) and the PNG or TIFF frames it lists into a frame cube (contract frames/1). "
        "Sensor constants come from the options, else FOLDER/sensor.json; dark, bias and flat "
        "frames (--dark, --bias, --flat) are combined into masters stored with the cube and "
        "applied before centroiding.",
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
    said = {k: cube.attrs.get(k, "not given") for k in ("mask_distance_mm", "pixel_pitch_mm")}
    masters = ", ".join(f"master {k} of {v['n_frames']}"
                        for k, v in (cube.attrs.get("calibration_frames") or {}).items())
    print(f"{args.out}: {cube.sizes['pose']} poses x {cube.sizes['shot']} shots of "
          f"{cube.sizes['y']} x {cube.sizes['x']} px ({cube.attrs['bit_depth']}-bit"
          f"{', left-aligned' if cube.attrs.get('left_aligned') else ''}), "
          f"F = {said['mask_distance_mm']} mm, pitch {said['pixel_pitch_mm']} mm"
          + (f"; {masters}" if masters else ""))
    flat = (cube.attrs.get("calibration_frames") or {}).get("flat") or {}
    if flat.get("clipped_pixels"):
        row, col = flat["first_clipped"]
        print(f"warning: {flat['clipped_pixels']} pixel(s) of the flats at full scale (first at "
              f"row {row}, column {col}): their response is unknown, so they read as saturated "
              "(a spot on one is flagged, or repaired when isolated). Fix: expose the flats "
              "shorter")
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


def _run_evaluate(args) -> int:
    """``sunlab evaluate``: :func:`sunlab.stats.evaluate` printed as the paper's Table 4, and
    with ``--out`` the files of :func:`sunlab.report.write_report`."""
    import pandas as pd

    from .. import atomic, calibration, report, stats

    if args.out is not None:  # checked now, before any work; made once every file is written
        atomic.check_folder(args.out, report.REPORT_FILES, overwrite=args.overwrite,
                            flag="--overwrite")
    cal = calibration.load(args.calibration)
    test = open_centroid_table(args.test, "test")
    evaluation = stats.evaluate(cal, test, return_errors=True)
    sources = {"calibration": args.calibration, "test": args.test}
    doc = report.evaluation_document(cal, test, evaluation, paper=args.paper, sources=sources)
    table = evaluation[0]
    print(f"{cal.label} on {args.test}: {doc['n_poses']} poses x {doc['n_shots']} shots "
          f"({doc['n_ok_shots']} ok); global statistics (deg), as the paper's Table 4:")
    shown = table.rename(columns={cal.label: f"{cal.label} (sunlab)"})
    if args.paper:
        paper = stats.paper_table4()
        want = stats.PAPER_COLUMNS.get(cal.kind)
        keep = [want] if want in paper.columns else list(paper.columns)
        shown = pd.concat([shown, paper[keep].add_suffix(" (paper)")], axis=1)
    print(shown.to_string(float_format=lambda v: f"{v:.5f}"))
    from ..calibration.plausibility import implausible

    col = table[cal.label]
    for finding in implausible(cal, test_mu={a: col[(a, "mu")] for a in ("alpha", "beta")}):
        print(f"warning: implausible: {finding}")
    if doc["n_out_of_domain"]:
        print(f"warning: {doc['n_out_of_domain']} centroid(s) outside the calibrated domain "
              f"(extrapolated{' or NaN' if cal.kind.startswith('interpolation') else ''}); see "
              "in_domain in errors.csv")
    if args.out is None:
        return 0
    written = report.write_report(args.out, cal, test, evaluation, paper=args.paper,
                                  sources=sources, overwrite=args.overwrite, flag="--overwrite")
    for note in written["notes"]:
        print(note)
    print(f"wrote {', '.join(map(str, written['files']))}")
    return 0


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
