"""Frames and tables on the command line: ``sunlab import`` (a folder of images into a cube),
``sunlab centroid`` (a cube or a folder into a centroid table), ``sunlab info`` (what a cube,
table or calibration holds), and the opening of centroid tables the other verbs share.

Only the standard library is imported at module level, so that ``sunlab --help`` and
``sunlab info CAL.json`` start fast.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigurationError, SchemaError
from ._args import WORKERS, check_out, printable, verb

__all__: list[str] = []


def _add(sub) -> None:
    """Add ``import``, ``centroid`` and ``info``."""
    p = verb(sub, "import", run_import, "import a folder of PNG/TIFF frames and its manifest.csv "
             "(file, alpha, beta, shot) into a frame cube; dark, bias and flat masters stored "
             "with it", progress=True, overwrite="an existing output")
    p.add_argument("folder", help="folder of images with manifest.csv (and sensor.json)")
    p.add_argument("--out", required=True, help="output cube (.zarr store or .nc file)")
    _add_folder_options(p)

    p = verb(sub, "centroid", run_centroid, "centroid every frame of a cube into a centroid "
             "table", progress=True, overwrite="an existing output")
    p.add_argument("cube", help="a frame cube (.zarr, .nc), or an image folder (as import)")
    p.add_argument("--method", choices=["threshold", "projection", "tight", "fit"],
                   help="default: projection for one spot per frame, tight for 100 holes")
    p.add_argument("--out", required=True, help="output centroid table (.nc or .zarr)")
    p.add_argument("--background", choices=["ring", "plane"],
                   help="tight window: a constant background around each spot, or a plane")
    p.add_argument("--scheduler", default="threads",
                   choices=["threads", "processes", "synchronous", "cluster"],
                   help="local Dask scheduler (docs/scaling.md)")
    p.add_argument("--address", help="dask.distributed scheduler address")
    p.add_argument("--workers", type=WORKERS, help="local threads or processes")
    _add_folder_options(p)

    p = verb(sub, "info", run_info, "summarise a frame cube, centroid table or calibration")
    p.add_argument("path", help="a .zarr store, a .nc file, or a calibration .json")


def run_import(args) -> int:
    """``sunlab import``: :func:`sunlab.io.open_frames` saved as a cube."""
    from .. import io

    check_out(args.out, args.overwrite)
    cube = _cube_from_folder(args.folder, args)
    io.save_frames(cube, args.out, overwrite=args.overwrite, progress=not args.no_progress)
    said = {k: cube.attrs.get(k, "not given") for k in ("mask_distance_mm", "pixel_pitch_mm")}
    frames = cube.attrs.get("calibration_frames") or {}
    masters = ", ".join(f"master {k} of {v['n_frames']}" for k, v in frames.items())
    print(f"{args.out}: {cube.sizes['pose']} poses x {cube.sizes['shot']} shots of "
          f"{cube.sizes['y']} x {cube.sizes['x']} px ({cube.attrs['bit_depth']}-bit"
          f"{', left-aligned' if cube.attrs.get('left_aligned') else ''}), "
          f"F = {said['mask_distance_mm']} mm, pitch {said['pixel_pitch_mm']} mm"
          + (f"; {masters}" if masters else ""))
    flat = frames.get("flat") or {}
    if flat.get("clipped_pixels"):
        row, col = flat["first_clipped"]
        print(f"warning: {flat['clipped_pixels']} pixel(s) of the flats at full scale (first at "
              f"row {row}, column {col}): their response is unknown, so they read as saturated "
              "(a spot on one is flagged, or repaired when isolated). Fix: expose the flats "
              "shorter")
    return 0


def run_centroid(args) -> int:
    """``sunlab centroid``: :func:`sunlab.centroid.locate` saved as a table."""
    from .. import centroid, io
    check_out(args.out, args.overwrite)
    cube = _cube_from_folder(args.cube, args)  # a store refuses the folder options
    method = args.method or centroid.default_method(cube, args.background)
    extra = {}
    if args.background is not None:
        if method != "tight" or centroid.cube.is_multi_hole(cube):
            raise ConfigurationError(
                f"--background: applies to the single-spot tight window, not --method "
                f"{method}. Fix: pass --method tight, or drop --background")
        extra["background"] = args.background
    cen = centroid.locate(cube, method, scheduler=args.scheduler, address=args.address,
                          num_workers=args.workers, progress=not args.no_progress, **extra)
    io.save_centroids(cen, args.out, overwrite=args.overwrite)
    ok = int((cen.status.values == 0).sum())
    print(f"{args.out}: {cen.status.size} centroids ({ok} ok) by method {method!r}")
    return 0


def run_info(args) -> int:
    """``sunlab info``: a calibration's summary (standard library only), else a cube's or a
    table's (:func:`sunlab.io.summary`; an incomplete store, an acquisition in progress, is
    described with its missing chunks). Text from the file is shown escaped, never run."""
    doc = _calibration_json(args.path)
    if doc is not None:
        from ..calibration.summary import calibration_summary

        print(printable(calibration_summary(doc), keep="\n"))
        return 0
    from .. import io

    print(printable(io.summary(args.path), keep="\n"))
    return 0


def _calibration_json(path) -> dict | None:
    """The ``calibration/1`` document in ``path`` (its checksum verified), or None when
    ``path`` is no file or does not start with ``{`` (a cube or a table: the other readers);
    a corrupt, huge or foreign JSON document is a :class:`SchemaError`."""
    path = Path(path)
    if not path.is_file():
        return None
    with open(path, "rb") as fh:  # an unreadable file: an OSError naming it
        head = fh.read(1)
    if head != b"{":  # an empty file is no JSON either: the cube readers describe it
        return None
    from .. import integrity  # standard library only

    doc = integrity.verify_document(integrity.read_json(
        path, max_bytes=integrity.MAX_DOCUMENT_BYTES, what="a calibration/1 JSON document",
        fix="the file is corrupt, truncated or not a calibration; re-fit the calibration with "
            "`sunlab calibrate`"), path)
    found = doc.get("sunlab_schema", "missing") if isinstance(doc, dict) else "missing"
    if str(found).partition("/")[0] != "calibration":
        raise SchemaError(f"{path}: sunlab_schema", found, "a calibration/1 JSON document",
                          "this JSON file was not written by sunlab (sunlab calibrate / "
                          "Calibration.save); info reads frame cubes, centroid tables and "
                          "calibration files")
    return doc


def open_centroid_table(path, name: str):
    """:func:`sunlab.io.open_centroids` (NetCDF, Zarr, or CSV with its ``sensor.json``); an
    error about the whole file names the argument (``train``, ``validation``, ``test``)."""
    from .. import io

    try:
        return io.open_centroids(path)
    except SchemaError as err:
        if err.field != str(path):
            raise
        raise SchemaError(f"{name} {path}", err.found, err.expected, err.fix) from err


def _add_folder_options(p) -> None:
    """The options of an image folder (``import``, ``centroid FOLDER``); each defaults to the
    folder's ``sensor.json`` (:func:`sunlab.io.open_frames`)."""
    g = p.add_argument_group("image folder (PNG/TIFF frames + manifest.csv)")
    g.add_argument("--manifest", help="columns file, alpha, beta, shot (FOLDER/manifest.csv)")
    g.add_argument("--pixel-pitch-mm", type=float, help="pixel pitch, mm (never guessed)")
    g.add_argument("--mask-distance-mm", type=float, help="mask-to-focal-plane distance F, mm")
    g.add_argument("--bit-depth", type=int, help="ADC bits, 8-16 (default: from the images)")
    g.add_argument("--left-aligned", action="store_true", default=None,
                   help="DN in the top bits of the 16-bit word (shifted down on read)")
    g.add_argument("--experiment", dest="folder_experiment", help="default: the folder name")
    g.add_argument("--dark", help="dark frames (folder or TIFF stack): median subtracted")
    g.add_argument("--flat", help="flat frames: median of the dark-subtracted, normalised, "
                   "divides")
    g.add_argument("--bias", help="bias frames: subtracted when no dark is given")


def _cube_from_folder(folder, args):
    """A lazy cube of an image folder (or a store) with the folder options of ``args``
    (:func:`sunlab.io.open_frames`)."""
    from .. import io

    return io.open_frames(
        folder, args.manifest, dark=args.dark, flat=args.flat, bias=args.bias,
        pixel_pitch_mm=args.pixel_pitch_mm, mask_distance_mm=args.mask_distance_mm,
        bit_depth=args.bit_depth, left_aligned=args.left_aligned,
        experiment=args.folder_experiment)
