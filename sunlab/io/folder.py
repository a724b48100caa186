"""A folder of images (or a TIFF stack) with its manifest CSV and ``sensor.json`` as a frame
cube, what :func:`sunlab.io.open_frames` returns for such a path; the shipped example.

The manifest names, per image, the commanded pose (``alpha``, ``beta``) and the shot label:
columns ``file`` (image name relative to the folder, inside it), ``alpha``, ``beta`` (deg),
``shot`` (integer label within the pose), optional ``page`` (the frame, 0-based, of a
multi-page TIFF). Poses are the unique (alpha, beta) pairs in manifest order; every pose has the
same shot labels, ordered by value (kept as ``shot_label`` when they are not 0 .. n - 1). Any
other column becomes a coordinate on (pose, shot) (``time`` parsed as a date-time). The bit
depth, when neither given nor in ``sensor.json``, is 8 for 8-bit images and otherwise the
smallest of 8, 10, 12, 14, 16 bits that holds the largest DN (every image read once).
Every check names the manifest line and column, or the image, and the fix.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pandas as pd
import xarray as xr

from ..errors import SchemaError, SunlabError
from ..schema import frames_dataset
from .calframes import with_calibration_frames
from .codec import _short
from .csvtable import _line, _numbers, _once, _poses, _require, read_csv_table
from .images import IMAGE_SUFFIXES, _image_header, _raw_dtype, _read_checked
from .sensor import find_sensor_json, read_sensor_json

__all__ = ["example_folder"]

_REQUIRED_COLUMNS = ("file", "alpha", "beta", "shot")
_RESERVED_COLUMNS = ("pose", "x", "y", "frames", "hole", "shot_label")
_SENSOR = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "bit_depth",
           "left_aligned", "mask", "experiment")


def _from_images(path: Path, manifest=None, *, lazy=True, dark=None, flat=None, bias=None,
                 **sensor) -> xr.Dataset:
    """The cube of a folder of images or of a TIFF stack (see :func:`sunlab.io.open_frames`)."""
    unknown = sorted(set(sensor) - set(_SENSOR))
    if unknown:
        raise TypeError(f"open_frames() got unexpected keyword(s) {unknown}")
    folder = path.parent if path.is_file() else path
    found = find_sensor_json(folder, manifest)
    doc = read_sensor_json(found) if found is not None else {}
    given = {k: sensor[k] if sensor.get(k) is not None else doc.get(k) for k in _SENSOR}
    bit_depth, left_aligned = given.pop("bit_depth"), bool(given.pop("left_aligned"))
    table, mname = _manifest_table(folder, manifest)
    if path.is_file():  # a TIFF stack: the manifest's rows that name it
        keep = (table["file"].fillna("").str.strip() == path.name).to_numpy()
        lines = [n for n, k in zip(table.attrs["lines"], keep, strict=True) if k]
        table = table[keep].reset_index(drop=True)
        table.attrs["lines"] = lines
    _check_columns(table, mname)
    alpha, beta, shot = (_numbers(table, c, f"manifest {mname}", "degrees" if c != "shot"
                                  else "integer") for c in ("alpha", "beta", "shot"))
    files, paths = _image_paths(folder, table, mname)
    # the page of each row of a TIFF stack (None without the column); no image listed twice
    pages = (_numbers(table, "page", f"manifest {mname}", "page").astype(np.int64)
             if "page" in table.columns else None)
    _once(table, list(files) if pages is None else list(zip(files, pages.tolist(), strict=True)),
          f"manifest {mname}", lambda i: f"file {files.iloc[i]!r}" + (
              "" if pages is None else f" page {pages[i]}"), "one image per (pose, shot)",
          "give each row its own image" + (" or page" if pages is not None else ""))
    poses, labels, order = _pose_grid(table, alpha, beta, shot.astype(np.int64), mname)
    shape, dtype = _common_header(table, paths, order, pages, mname)
    bit_depth = _checked_bit_depth(bit_depth, dtype, left_aligned)
    frames = _read_frames(paths, order, shape, dtype, (bit_depth, pages, left_aligned), lazy)
    if bit_depth is None:
        peak = int(frames.max()) if frames.size and dtype != np.uint8 else 0
        bit_depth = next(b for b in (8, 10, 12, 14, 16) if peak < 2**b)
    attrs = {"source": str(folder.resolve()), "left_aligned": left_aligned,
             **dict(doc.get("attrs") or {}), **({"sensor_json": str(found.resolve())} if found
                                                 else {})}
    kw = {k: given[k] for k in ("x_cf_px", "y_cf_px", "mask") if given[k] is not None}
    cube = frames_dataset(
        frames, alpha=[a for a, _ in poses], beta=[b for _, b in poses], bit_depth=bit_depth,
        pixel_pitch_mm=given["pixel_pitch_mm"], mask_distance_mm=given["mask_distance_mm"],
        experiment=given["experiment"] or folder.resolve().name, attrs=attrs,
        coords=_manifest_coords(table, files, order, labels, mname), **kw)
    return with_calibration_frames(cube, dark=dark, flat=flat, bias=bias)


def _manifest_table(folder: Path, manifest):
    if manifest is None:
        path = folder / "manifest.csv"
        if not path.exists():
            images = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
            if not images:
                raise SchemaError(
                    "folder", f"{folder} (no images, no manifest.csv)",
                    f"image files ({', '.join(IMAGE_SUFFIXES)}) and a manifest CSV",
                    "point to the folder that holds the frames, or acquire them first")
            raise SchemaError(
                "manifest", f"no manifest.csv in {folder} ({len(images)} images)",
                "a CSV with columns file, alpha, beta, shot (one row per image)",
                "write manifest.csv next to the images, or pass manifest=path")
    else:
        path = Path(manifest)
        if not path.is_absolute() and not path.exists():
            path = folder / path
        if not path.exists():
            raise SchemaError("manifest", str(manifest), "an existing CSV file",
                              f"give the manifest's path (absolute, or relative to {folder})")
    # every row checked against the header: comma decimals, duplicated columns, ESC in names
    return read_csv_table(path, "manifest"), path.name


def _check_columns(table, mname: str) -> None:
    """The manifest has rows, the required columns and no reserved or unstorable name."""
    _require(table, f"manifest {mname}", _REQUIRED_COLUMNS, "one row per image",
             "add them: file = the image's name, alpha, beta = commanded angles in degrees, "
             "shot = the frame's number within its pose (0, 1, ...)")
    for col in table.columns:
        # an extra column becomes a variable of the store: Zarr and NetCDF name nodes by path,
        # so '..', '../../x' or 'a/b' would name another place (or be refused deep in the writer)
        # and 'zarr.json' the store's own metadata file (a folder cannot replace it)
        if col not in _REQUIRED_COLUMNS and (len(col) > 100 or col.startswith((".", "__")) or
                                             col.lower() == "zarr.json" or
                                             col in _RESERVED_COLUMNS or
                                             not re.fullmatch(r"\w[\w .()\-]*", col, re.A)):
            raise SchemaError(
                f"manifest {mname} column {col!r}", "a name that cannot name a variable",
                "letters, digits, spaces and _ - . ( ) , not starting with '.' or '__', no "
                f"'/' or '\\', not zarr.json nor one of {_RESERVED_COLUMNS}, at most 100 "
                "characters", "rename the column (e.g. exposure_ms)")


def _image_paths(folder: Path, table, mname: str):
    """The ``file`` column (stripped) and the image paths: every one an existing file inside
    ``folder`` (a relative name; ``..`` that leaves the folder and absolute paths refused)."""
    files = table["file"].fillna("").astype(str).str.strip()
    root, paths = folder.resolve(), []
    for i, f in enumerate(files):
        field = f"manifest {mname} line {_line(table, i)} column 'file'"
        try:
            path = (folder / f).resolve()
        except (RuntimeError, OSError) as err:  # a symlink loop (RuntimeError before 3.13)
            raise SchemaError(field, f, f"an image file in {folder}", "the path cannot be "
                              f"resolved ({type(err).__name__}: {err}); replace the link by the "
                              "image itself") from err
        if not f or Path(f).is_absolute() or not path.is_relative_to(root):
            raise SchemaError(
                field, f, f"a file name relative to {folder}, inside it",
                "copy the image into the folder and give its name relative to the folder "
                "(absolute paths and '..' are refused, so a cube names only its own frames)")
        paths.append(path)
    missing = [i for i, p in enumerate(paths) if not _is_file(p)]
    if missing:
        raise SchemaError(f"manifest {mname} line {_line(table, missing[0])} column 'file'",
                          files.iloc[missing[0]], f"an image file in {folder}",
                          f"{len(missing)} listed file(s) do not exist; copy them into the "
                          "folder or remove their rows")
    return files, paths


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False for a path the system cannot follow (a symlink loop)."""
    try:
        return path.is_file()
    except OSError:
        return False


def _pose_grid(table, alpha, beta, shot, mname: str):
    """The poses (unique (alpha, beta) pairs in manifest order), the shot labels (sorted) and
    ``order``, the manifest row of each (pose, shot)."""
    poses, pose = _poses(alpha, beta)
    _once(table, list(zip(pose.tolist(), shot.tolist(), strict=True)), f"manifest {mname}",
          lambda i: f"alpha={alpha[i]:g}, beta={beta[i]:g}, shot={shot[i]}",
          "one row per (pose, shot)", "remove the duplicate row or give it the next shot number")
    labels = np.unique(shot)
    for p, (a, b) in enumerate(poses):
        have = set(shot[pose == p].tolist())
        if have != set(labels.tolist()):
            raise SchemaError(
                f"manifest {mname} pose alpha={a:g}, beta={b:g}", f"shots {sorted(have)}",
                f"the same shots as every other pose: {labels.tolist()}",
                f"add rows for shot(s) {sorted(set(labels.tolist()) - have)} of this pose, or "
                "drop the pose")
    order = np.full((len(poses), len(labels)), -1)
    order[pose, np.searchsorted(labels, shot)] = np.arange(len(pose))
    return poses, labels, order


def _common_header(table, paths, order, pages, mname: str):
    """Image headers: one frame size and one pixel type (uint8 or uint16) for the whole cube,
    and every ``page`` within its stack."""
    headers = {p: _image_header(p, stack=pages is not None) for p in dict.fromkeys(paths)}
    first = paths[int(order[0, 0])]
    shape, dtype, _ = headers[first]
    for i, path in enumerate(paths):
        shp, dt, n_pages = headers[path]
        _raw_dtype(path, dt)
        if shp != shape or dt != dtype:
            raise SchemaError(
                f"image {path.name} (manifest line {_line(table, i)})", f"shape {shp}, {dt}",
                f"shape {shape}, {dtype} like {first.name}", "every frame of a cube has the "
                "same size and pixel type; remove or re-export the odd image")
        if pages is not None and pages[i] >= n_pages:
            raise SchemaError(f"manifest {mname} line {_line(table, i)} column 'page'",
                              int(pages[i]), f"a page 0 .. {n_pages - 1} of {path.name} "
                              f"({n_pages} frames)", "correct the page number (pages count "
                              "from 0)")
    return shape, dtype


def _checked_bit_depth(bit_depth, dtype: np.dtype, left_aligned=False) -> int | None:
    """The given bit depth as an int that fits the pixel type (None stays None, unless the
    frames are left-aligned: their shift needs it)."""
    if bit_depth is None and left_aligned:
        raise SchemaError("bit_depth", None, "the ADC's bit depth for left-aligned frames",
                          "give bit_depth (sensor.json \"bit_depth\", or --bit-depth) with "
                          "left_aligned")
    if bit_depth is not None and (int(bit_depth) != bit_depth
                                  or not 1 <= bit_depth <= 8 * dtype.itemsize):
        raise SchemaError("bit_depth", bit_depth, f"an integer 1 .. {8 * dtype.itemsize} for "
                          f"{dtype} images", "give the ADC bit depth (Ibis4: 10)")
    return None if bit_depth is None else int(bit_depth)


def _read_frames(paths, order, shape, dtype, how, lazy: bool):
    """The (pose, shot, y, x) frames: one ``dask.delayed`` read per image, or all read now;
    ``how`` is (bit_depth, pages or None, left_aligned)."""
    bit_depth, pages, left_aligned = how

    def args(row):
        page = None if pages is None else int(pages[row])
        return paths[row], shape, dtype, bit_depth, page, left_aligned

    if not lazy:
        return np.stack([np.stack([_read_checked(*args(r)) for r in rows]) for rows in order])
    import dask
    import dask.array as da

    read = dask.delayed(_read_checked, pure=True)
    return da.stack([da.stack([da.from_delayed(read(*args(r)), shape, dtype) for r in rows])
                     for rows in order])


def _manifest_coords(table, files, order, labels, mname: str) -> dict:
    """Coordinates from the manifest: ``file``, ``shot_label`` and every extra column."""
    coords = {"file": (("pose", "shot"), files.to_numpy(dtype=object)[order])}
    if not np.array_equal(labels, np.arange(order.shape[1])):
        coords["shot_label"] = ("shot", labels)
    for col in [c for c in table.columns if c not in _REQUIRED_COLUMNS]:
        raw = table[col]
        if col == "time":
            try:
                values = pd.to_datetime(raw).to_numpy(dtype="datetime64[ns]")
            except (ValueError, TypeError) as exc:
                raise SchemaError(
                    f"manifest {mname} column 'time'", _short(raw.tolist()),
                    "ISO 8601 date-times, e.g. 2005-06-01T12:00:00.125",
                    f"write the times in ISO 8601 or rename the column ({exc})") from exc
        else:
            num = pd.to_numeric(raw, errors="coerce")
            values = (num.to_numpy() if num.notna().sum() == raw.notna().sum()
                      else raw.fillna("").astype(str).to_numpy(dtype=object))
        coords[col] = (("pose", "shot"), values[order])
    return coords


def example_folder(name: str = "train") -> Path:
    """A small recording shipped with sunlab: a folder of 16-bit PNG frames, as a lab's own.

    ``"train"``: a 5 x 5 grid of poses (alpha -10..-6 deg, beta 5..9 deg, 1-degree steps),
    ``"test"``: the 4 x 4 grid between them; 2 shots per pose, frames of the virtual bench's
    one-hole sensor cropped to the region the spot crosses. Each folder holds ``manifest.csv``
    (file, alpha, beta, shot) and ``sensor.json`` (pixel pitch, mask distance, design centre,
    bit depth), so ``sunlab import FOLDER --out cube.zarr`` needs no other option.

    Parameters
    ----------
    name : {"train", "test"}
        Which recording.

    Returns
    -------
    pathlib.Path
        The folder inside the installed package (read it, do not write to it).

    Examples
    --------
    >>> from sunlab import io
    >>> folder = example_folder("train")
    >>> sorted(p.name for p in folder.glob("*.json")), (folder / "manifest.csv").exists()
    (['sensor.json'], True)
    >>> cube = io.open_frames(folder)
    >>> dict(cube.sizes)["pose"], cube.frames.dtype
    (25, dtype('uint16'))
    """
    if name not in ("train", "test"):
        raise SchemaError("name", name, "one of ('train', 'test')", "pass 'train' or 'test'")
    from importlib import resources

    folder = Path(str(resources.files("sunlab") / "data" / "example" / name))
    if not (folder / "manifest.csv").is_file():
        raise SunlabError(
            f"example_folder: {folder} has no manifest.csv. Fix: reinstall sunlab (the package "
            "data is missing), or regenerate it with sunlab/data/make_example.py")
    return folder
