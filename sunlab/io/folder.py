"""Build a frame cube from a folder of image files and a manifest CSV; the shipped example.

The manifest names, per image, the commanded pose (``alpha``, ``beta``) and the shot label;
every check names the manifest line and column, or the image, and the fix.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import SchemaError, SunlabError
from ..schema import frames_dataset
from .codec import _short
from .csvtable import read_csv_table
from .images import IMAGE_SUFFIXES, _image_header, _read_checked

__all__ = ["from_image_folder", "example_folder"]

_REQUIRED_COLUMNS = ("file", "alpha", "beta", "shot")
_RESERVED_COLUMNS = ("pose", "x", "y", "frames", "hole", "shot_label")


def _manifest_table(folder: Path, manifest):
    import pandas as pd

    if isinstance(manifest, pd.DataFrame):
        return manifest.copy(), "manifest"
    if manifest is None:
        path = folder / "manifest.csv"
        if not path.exists():
            images = [p for p in folder.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES]
            if not images:
                raise SchemaError(
                    "folder", f"{folder} (no images, no manifest.csv)",
                    f"image files ({', '.join(IMAGE_SUFFIXES)}) and a manifest CSV",
                    "point to the folder that holds the frames, or acquire them first",
                )
            raise SchemaError(
                "manifest", f"no manifest.csv in {folder} ({len(images)} images)",
                "a CSV with columns file, alpha, beta, shot (one row per image)",
                "write manifest.csv next to the images, or pass manifest=path",
            )
    else:
        path = Path(manifest)
        if not path.is_absolute() and not path.exists():
            path = folder / path
        if not path.exists():
            raise SchemaError(
                "manifest", str(manifest), "an existing CSV file",
                f"give the manifest's path (absolute, or relative to {folder})",
            )
    # every row checked against the header: comma decimals, duplicated columns, ESC in names
    table = read_csv_table(path, "manifest")
    return table, path.name


def _line(i: int) -> int:
    """CSV line number of table row i (line 1 is the header)."""
    return int(i) + 2


def from_image_folder(
    folder,
    manifest=None,
    *,
    bit_depth: int | None = None,
    left_aligned: bool = False,
    lazy: bool = True,
    **frames_kwargs,
) -> xr.Dataset:
    """Build a frame cube from a folder of PNG or TIFF frames and a manifest CSV.

    Parameters
    ----------
    folder : str or path-like
        Folder holding the images (8-bit, or 16-bit for deeper ADCs; single channel).
    manifest : str, path-like or pandas.DataFrame, optional
        The manifest, one row per image; default ``folder/manifest.csv`` (a relative path is
        relative to ``folder``). Required columns: ``file`` (image name relative to
        ``folder``), ``alpha``, ``beta`` (commanded platform angles, deg), ``shot`` (integer
        label within the pose, e.g. 0 .. 7). Optional ``page``: the frame (0-based) of a
        multi-page TIFF (a stack per pose, shots as pages). One row per image (file, page);
        files inside ``folder`` only.
        Poses are the unique (alpha, beta) pairs in manifest order; every pose must have the same
        set of shot labels, ordered by value. Any other column becomes a coordinate on
        (pose, shot) (``time`` parsed as a date-time). Lines starting with ``#`` are comments.
    bit_depth : int, optional
        ADC bit depth. Default: 8 for 8-bit images; for 16-bit images the smallest of 8, 10,
        12, 14, 16 bits that holds the largest DN in the folder (this reads every image once;
        give it for dark or dim frames, whose maximum says little about the ADC).
    left_aligned : bool
        DN in the top bits of the 16-bit word (12-bit machine-vision cameras): shifted right
        by ``16 - bit_depth`` on read (:func:`~sunlab.io.read_image`). Needs ``bit_depth``.
    lazy : bool
        Read each image only when its frame is computed (``dask.delayed`` per image, one chunk
        per frame); headers are still checked at once. False reads everything now.
    **frames_kwargs
        Passed to :func:`sunlab.schema.frames_dataset` (``pixel_pitch_mm``, ``attrs``, ...).

    Returns
    -------
    xarray.Dataset
        A frame cube (contract ``frames/1``) with a ``file`` coordinate on (pose, shot), and
        ``shot_label`` on shot when the labels are not 0 .. n_shot - 1.

    Raises
    ------
    SchemaError
        Naming the manifest line and column, or the image, and the fix.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib, tifffile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> rows = ["file,alpha,beta,shot"]
    >>> for k, (a, b, s) in enumerate([(0, 0, 0), (0, 0, 1), (5, -2, 0), (5, -2, 1)]):
    ...     tifffile.imwrite(folder / f"f{k}.tif", np.full((4, 6), 100 * k, np.uint16))
    ...     rows.append(f"f{k}.tif,{a},{b},{s}")
    >>> _ = (folder / "manifest.csv").write_text("\\n".join(rows))
    >>> cube = from_image_folder(folder, bit_depth=10)
    >>> dict(cube.sizes), cube.alpha.values.tolist(), int(cube.frames[1, 0, 0, 0])
    ({'pose': 2, 'shot': 2, 'y': 4, 'x': 6}, [0.0, 5.0], 200)
    """
    folder = _existing_folder(folder)
    table, mname = _manifest_table(folder, manifest)
    _check_columns(table, mname)
    alpha, beta, shot = _pose_columns(table, mname)
    files, paths = _image_paths(folder, table, mname)
    pages = _page_column(table, files, mname)
    poses, labels, order = _pose_grid(alpha, beta, shot, mname)
    shape, dtype = _common_header(paths, order, pages, mname)
    bit_depth = _checked_bit_depth(bit_depth, dtype, left_aligned)
    frames = _read_frames(paths, order, shape, dtype, (bit_depth, pages, left_aligned), lazy)
    bit_depth = _detected_bit_depth(frames, dtype) if bit_depth is None else bit_depth
    coords = {**_manifest_coords(table, files, order, labels, mname),
              **dict(frames_kwargs.pop("coords", None) or {})}
    attrs = {"source": str(folder.resolve()), "left_aligned": bool(left_aligned),
             **dict(frames_kwargs.pop("attrs", None) or {})}
    return frames_dataset(frames, alpha=[a for a, _ in poses], beta=[b for _, b in poses],
                          bit_depth=bit_depth, coords=coords, attrs=attrs, **frames_kwargs)


def _existing_folder(folder) -> Path:
    folder = Path(folder)
    if not folder.is_dir():
        raise SchemaError(
            "folder", str(folder), "an existing folder of images",
            "check the path (it is relative to the current directory unless absolute)",
        )
    return folder


def _check_columns(table, mname: str) -> None:
    """The manifest has rows, the required columns and no reserved column name."""
    if len(table) == 0:
        raise SchemaError(
            f"manifest {mname}", "no rows", "one row per image", "add the rows for the images"
        )
    for col in _REQUIRED_COLUMNS:
        if col not in table.columns:
            raise SchemaError(
                f"manifest {mname} column {col!r}", f"missing (columns: {list(table.columns)})",
                "columns file, alpha, beta, shot",
                f"add a {col!r} column"
                + {
                    "file": " with the image file name of each row",
                    "alpha": " with the commanded outer-axis angle in degrees",
                    "beta": " with the commanded inner-axis angle in degrees",
                    "shot": " numbering the frames of each pose 0, 1, ...",
                }[col],
            )
    for col in table.columns:
        if col in _RESERVED_COLUMNS:
            raise SchemaError(
                f"manifest {mname} column {col!r}", "a reserved name",
                f"extra columns named other than {_RESERVED_COLUMNS}", "rename the column",
            )
        if col not in _REQUIRED_COLUMNS and not _storable_name(col):
            # an extra column becomes a variable of the store: Zarr and NetCDF name nodes by
            # path, so '..', '../../x' or 'a/b' would name another place (or be refused deep
            # inside the writer)
            raise SchemaError(
                f"manifest {mname} column {col!r}", "a name that cannot name a variable",
                "letters, digits, spaces and _ - . ( ) , not starting with '.' or '__', no "
                "'/' or '\\', at most 100 characters",
                "rename the column (e.g. exposure_ms)",
            )


def _storable_name(name: str) -> bool:
    """Whether a manifest column can name a variable of a Zarr store and a NetCDF file."""
    import re

    return (0 < len(name) <= 100 and not name.startswith((".", "__"))
            and re.fullmatch(r"[A-Za-z0-9_][A-Za-z0-9_ .()\-]*", name) is not None)


def _pose_columns(table, mname: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The ``alpha``, ``beta`` (finite degrees) and ``shot`` (integer label) columns."""
    import pandas as pd

    numeric = {}
    for col in ("alpha", "beta", "shot"):
        values = pd.to_numeric(table[col], errors="coerce")
        bad = np.flatnonzero(~np.isfinite(values.to_numpy(dtype=float)))
        if bad.size:
            i = bad[0]
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column {col!r}", table[col].iloc[i],
                "a finite number" + (" of degrees" if col != "shot" else ""),
                f"correct the value ({bad.size} bad row(s), first on line {_line(i)})",
            )
        numeric[col] = values.to_numpy(dtype=float)
    from ..plans import MAX_ANGLE_DEG

    for col in ("alpha", "beta"):
        bad = np.flatnonzero(np.abs(numeric[col]) >= MAX_ANGLE_DEG)
        if bad.size:
            i = bad[0]
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column {col!r}", table[col].iloc[i],
                f"a commanded angle within (-{MAX_ANGLE_DEG:g}, {MAX_ANGLE_DEG:g}) deg (the sun "
                "in front of the mask)", f"correct the value ({bad.size} such row(s))",
            )
    if np.any(numeric["shot"] != np.round(numeric["shot"])):
        i = int(np.flatnonzero(numeric["shot"] != np.round(numeric["shot"]))[0])
        raise SchemaError(
            f"manifest {mname} line {_line(i)} column 'shot'", table["shot"].iloc[i],
            "an integer shot label", "number the frames of each pose 0, 1, 2, ...",
        )
    return numeric["alpha"], numeric["beta"], numeric["shot"].astype(np.int64)


def _image_paths(folder: Path, table, mname: str):
    """The ``file`` column (stripped) and the image paths: every one an existing file inside
    ``folder`` (a relative name; ``..`` that leaves the folder and absolute paths refused)."""
    files = table["file"].fillna("").astype(str).str.strip()
    root = folder.resolve()
    paths = []
    for i, f in enumerate(files):
        try:
            path = (folder / f).resolve()
        except (RuntimeError, OSError) as err:  # a symlink loop (RuntimeError before 3.13)
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column 'file'", f,
                f"an image file in {folder}",
                f"the path cannot be resolved ({type(err).__name__}: {err}); replace the link "
                "by the image itself",
            ) from err
        if not f or Path(f).is_absolute() or not path.is_relative_to(root):
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column 'file'", f,
                f"a file name relative to {folder}, inside it",
                "copy the image into the folder and give its name relative to the folder "
                "(absolute paths and '..' are refused, so a cube names only its own frames)",
            )
        paths.append(path)
    missing = [i for i, p in enumerate(paths) if not _is_file(p)]
    if missing:
        i = missing[0]
        raise SchemaError(
            f"manifest {mname} line {_line(i)} column 'file'", files.iloc[i],
            f"an image file in {folder}",
            f"{len(missing)} listed file(s) do not exist; copy them into the folder or remove "
            "their rows",
        )
    return files, paths


def _is_file(path: Path) -> bool:
    """``path.is_file()``, False for a path the system cannot follow (a symlink loop)."""
    try:
        return path.is_file()
    except OSError:
        return False


#: Largest page number of a TIFF stack in a manifest (a stack of 2**31 frames is no stack).
_MAX_PAGE = 2**31 - 1


def _page_column(table, files, mname: str):
    """The ``page`` of each row (None without the column): a non-negative integer, and no
    image (file, page) listed twice."""
    import pandas as pd

    if "page" not in table.columns:
        pages = None
        keys = list(files)
    else:
        values = pd.to_numeric(table["page"], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(values) | (values < 0) | (values > _MAX_PAGE)
                             | (values != np.round(values)))
        if bad.size:
            i = int(bad[0])
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column 'page'", table["page"].iloc[i],
                f"an integer page 0, 1, ... (at most {_MAX_PAGE}) of the TIFF stack named in "
                "'file'",
                f"correct the value ({bad.size} bad row(s))",
            )
        pages = values.astype(np.int64)
        keys = list(zip(files, pages.tolist(), strict=True))
    first: dict = {}
    for i, key in enumerate(keys):
        if key in first:
            what = f"file {key[0]!r} page {key[1]}" if pages is not None else f"file {key!r}"
            raise SchemaError(
                f"manifest {mname} line {_line(i)}", f"{what} again (first on line "
                f"{_line(first[key])})", "one image per (pose, shot)",
                "give each row its own image" + (" or page" if pages is not None else ""),
            )
        first[key] = i
    return pages


def _pose_grid(alpha, beta, shot, mname: str):
    """Poses and shots of the manifest rows.

    Poses are the unique (alpha, beta) pairs in manifest order, shots the labels sorted by
    value. Returns the poses (an ordered dict of pairs), the shot labels and ``order``, the
    manifest row of each (pose, shot).
    """
    pairs = list(zip(alpha.tolist(), beta.tolist(), strict=True))
    pose_of_pair: dict = {}
    for pair in pairs:
        pose_of_pair.setdefault(pair, len(pose_of_pair))
    pose = np.array([pose_of_pair[p] for p in pairs])
    seen: dict = {}
    for i, key in enumerate(zip(pose.tolist(), shot.tolist(), strict=True)):
        if key in seen:
            raise SchemaError(
                f"manifest {mname} line {_line(i)}",
                f"alpha={alpha[i]:g}, beta={beta[i]:g}, shot={shot[i]} again (first on line "
                f"{_line(seen[key])})",
                "one row per (pose, shot)",
                "remove the duplicate row or give it the next shot number",
            )
        seen[key] = i
    labels = np.unique(shot)
    n_pose, n_shot = len(pose_of_pair), len(labels)
    for p, (a, b) in enumerate(pose_of_pair):
        have = set(shot[pose == p].tolist())
        if have != set(labels.tolist()):
            lacking = sorted(set(labels.tolist()) - have)
            raise SchemaError(
                f"manifest {mname} pose alpha={a:g}, beta={b:g}", f"shots {sorted(have)}",
                f"the same shots as every other pose: {labels.tolist()}",
                f"add rows for shot(s) {lacking} of this pose, or drop the pose",
            )
    shot_index = np.searchsorted(labels, shot)
    order = np.full((n_pose, n_shot), -1)
    order[pose, shot_index] = np.arange(len(pairs))
    return pose_of_pair, labels, order


def _common_header(paths, order, pages, mname: str) -> tuple[tuple[int, ...], np.dtype]:
    """Image headers: one frame size and one pixel type (uint8 or uint16) for the whole cube,
    and every ``page`` within its stack."""
    headers = {}
    for p in dict.fromkeys(paths):
        headers[p] = _image_header(p, stack=pages is not None)
    shape, dtype, _ = headers[paths[int(order[0, 0])]]
    for i, path in enumerate(paths):
        shp, dt, n_pages = headers[path]
        if dt not in (np.dtype(np.uint8), np.dtype(np.uint16)):
            raise SchemaError(
                f"image {path.name}", f"pixel type {dt}", "uint8 or uint16 digital numbers",
                "export raw DN as 8- or 16-bit unsigned integers; float or 32-bit images are "
                "not raw frames",
            )
        if shp != shape or dt != dtype:
            raise SchemaError(
                f"image {path.name} (manifest line {_line(i)})", f"shape {shp}, {dt}",
                f"shape {shape}, {dtype} like {paths[int(order[0, 0])].name}",
                "every frame of a cube has the same size and pixel type; remove or re-export "
                "the odd image",
            )
        if pages is not None and pages[i] >= n_pages:
            raise SchemaError(
                f"manifest {mname} line {_line(i)} column 'page'", int(pages[i]),
                f"a page 0 .. {n_pages - 1} of {path.name} ({n_pages} frames)",
                "correct the page number (pages count from 0)",
            )
    return shape, dtype


def _checked_bit_depth(bit_depth, dtype: np.dtype, left_aligned=False) -> int | None:
    """The given bit depth as an int that fits the pixel type (None stays None, unless the
    frames are left-aligned: their shift needs it)."""
    if bit_depth is None and left_aligned:
        raise SchemaError(
            "bit_depth", None, "the ADC's bit depth for left-aligned frames",
            "give bit_depth (sensor.json \"bit_depth\", or --bit-depth) with left_aligned",
        )
    if bit_depth is None:
        return None
    if int(bit_depth) != bit_depth or not 1 <= bit_depth <= 8 * dtype.itemsize:
        raise SchemaError(
            "bit_depth", bit_depth, f"an integer 1 .. {8 * dtype.itemsize} for {dtype} images",
            "give the ADC bit depth (Ibis4: 10)",
        )
    return int(bit_depth)


def _read_frames(paths, order, shape, dtype, how, lazy: bool):
    """The (pose, shot, y, x) frames: one ``dask.delayed`` read per image, or all read now;
    ``how`` is (bit_depth, pages or None, left_aligned)."""
    bit_depth, pages, left_aligned = how
    n_pose, n_shot = order.shape

    def args(p, s):
        row = order[p, s]
        page = None if pages is None else int(pages[row])
        return paths[row], shape, dtype, bit_depth, page, left_aligned

    if lazy:
        import dask
        import dask.array as da

        read = dask.delayed(_read_checked, pure=True)
        return da.stack([
            da.stack([da.from_delayed(read(*args(p, s)), shape, dtype) for s in range(n_shot)])
            for p in range(n_pose)
        ])
    frames = np.empty((n_pose, n_shot, *shape), dtype)
    for p in range(n_pose):
        for s in range(n_shot):
            frames[p, s] = _read_checked(*args(p, s))
    return frames


def _detected_bit_depth(frames, dtype: np.dtype) -> int:
    """8 for 8-bit images, else the smallest of 8, 10, 12, 14, 16 bits that holds the peak DN."""
    if dtype == np.uint8:
        return 8
    peak = int(frames.max()) if frames.size else 0
    return next(b for b in (8, 10, 12, 14, 16) if peak < 2**b)


def _manifest_coords(table, files, order, labels, mname: str) -> dict:
    """Coordinates from the manifest: ``file``, ``shot_label`` and every extra column."""
    import pandas as pd

    n_shot = order.shape[1]
    coords = {
        "file": (("pose", "shot"), files.to_numpy(dtype=object)[order]),
    }
    if not np.array_equal(labels, np.arange(n_shot)):
        coords["shot_label"] = ("shot", labels)
    for col in table.columns:
        if col in _REQUIRED_COLUMNS:
            continue
        raw = table[col]
        if col == "time":
            try:
                values = pd.to_datetime(raw).to_numpy(dtype="datetime64[ns]")
            except (ValueError, TypeError) as exc:
                raise SchemaError(
                    f"manifest {mname} column 'time'", _short(raw.tolist()),
                    "ISO 8601 date-times, e.g. 2005-06-01T12:00:00.125",
                    f"write the times in ISO 8601 or rename the column ({exc})",
                ) from exc
        else:
            num = pd.to_numeric(raw, errors="coerce")
            if num.notna().sum() == raw.notna().sum():
                values = num.to_numpy()
            else:
                values = raw.fillna("").astype(str).to_numpy(dtype=object)
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
    >>> folder = example_folder("train")
    >>> sorted(p.name for p in folder.glob("*.json")), (folder / "manifest.csv").exists()
    (['sensor.json'], True)
    >>> cube = from_image_folder(folder, mask_distance_mm=17.0, bit_depth=10)
    >>> dict(cube.sizes)["pose"], cube.frames.dtype
    (25, dtype('uint16'))
    """
    names = ("train", "test")
    if name not in names:
        raise SchemaError("name", name, f"one of {names}", "pass 'train' or 'test'")
    from importlib import resources

    folder = Path(str(resources.files("sunlab") / "data" / "example" / name))
    if not (folder / "manifest.csv").is_file():
        raise SunlabError(
            f"example_folder: {folder} has no manifest.csv. Fix: reinstall sunlab (the package "
            "data is missing), or regenerate it with sunlab/data/make_example.py"
        )
    return folder

