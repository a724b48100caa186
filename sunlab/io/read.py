"""The two openers: :func:`open_frames` (a Zarr store, a NetCDF4 file, a folder of images with
its manifest, a TIFF stack) and :func:`open_centroids` (Zarr, NetCDF4, CSV).

A Zarr store or a NetCDF file opens lazily: every non-index variable is Dask-backed through a
reader that names the chunk when a read fails (:mod:`sunlab.io.chunks`), the metadata are checked
against their digest (:mod:`sunlab.integrity`) and attributes restored (:mod:`sunlab.io.codec`).
"""

from __future__ import annotations

from pathlib import Path

import xarray as xr

from .. import integrity
from ..errors import SchemaError, SunlabError
from ..schema import CENTROIDS_SCHEMA, FRAMES_SCHEMA, validate_centroids, validate_frames
from .chunks import _check_chunks, _checked_lazy
from .codec import _CODEC_ATTR, _decode_attrs, _strings_as_objects
from .csvtable import CSV_SUFFIXES, centroids_from_csv

__all__ = ["open_frames", "open_centroids"]

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_TIFF_SUFFIXES = (".tif", ".tiff")


def _fail_zarr(path: Path, exc: Exception):
    """Raise a SunlabError that says which file of a Zarr store is broken and what to do."""
    for meta in sorted(path.rglob("zarr.json")):
        try:
            integrity.loads(meta.read_text(encoding="utf-8"), meta)
        except (UnicodeDecodeError, SunlabError) as err:
            raise SunlabError(
                f"{meta}: corrupt Zarr metadata ({err}). Fix: restore this file from a backup or "
                "copy the store again from its source; a store written by sunlab.io can also be "
                "re-created with save_frames") from exc
    raise SunlabError(
        f"{path}: cannot be read as a Zarr store ({type(exc).__name__}: {exc}). Fix: check "
        "that the copy is complete, or re-create the store with sunlab.io.save_frames") from exc


def _sniff(path: Path) -> str:
    """``"netcdf"`` for a NetCDF4/HDF5 file (by its signature); otherwise a SunlabError."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8)
    except OSError as err:
        raise SunlabError(f"{path}: cannot be read ({err.strerror or err}). Fix: check the file "
                          "and its permissions") from err
    if head == _HDF5_SIGNATURE:
        return "netcdf"
    if head[:3] == b"CDF":
        raise SunlabError(f"{path}: a NetCDF3 (classic) file; sunlab reads NetCDF4/HDF5. Fix: "
                          "convert it with `nccopy -k nc4 in.nc out.nc`")
    raise SunlabError(
        f"{path}: neither a Zarr store (a directory) nor a NetCDF4/HDF5 file (first bytes "
        f"{head!r}). Fix: the file may be truncated or of another type; copy it again from its "
        "source")


def _existing(path) -> Path:
    path = Path(path)
    if not path.exists():
        raise SunlabError(f"{path}: no such file or directory. Fix: give the path of a .zarr "
                          "store or a .nc file written by sunlab.io (or sunlab simulate)")
    if not (path.is_dir() or path.is_file()):  # a FIFO or a device would block or never end
        raise SunlabError(f"{path}: not a regular file or folder. Fix: give the path of a .zarr "
                          "store or a .nc file written by sunlab.io")
    return path


def _is_zarr(path: Path) -> bool:
    return (path / "zarr.json").exists() or (path / ".zgroup").exists()


def _open_raw(path, format: str | None = None) -> xr.Dataset:
    """Open a store or file lazily, decode sunlab attributes; no validation."""
    path = _existing(path)
    format = format or ("zarr" if path.is_dir() else _sniff(path))
    if format == "zarr":
        if not (path.is_dir() and _is_zarr(path)):
            raise SunlabError(f"{path}: not a Zarr store (no zarr.json in it). Fix: give the "
                              "store's top directory, or copy the store again if its metadata "
                              "is missing")
        integrity.verify_zarr(path)  # metadata (shapes, data types, codecs) as written
        try:
            ds = xr.open_zarr(path, consolidated=False, chunks=None)
        except Exception as exc:  # noqa: BLE001 - turned into a message naming the file
            _fail_zarr(path, exc)
    else:
        ds = None
        try:
            ds = xr.open_dataset(path, engine="h5netcdf", chunks=None)
            integrity.verify_netcdf(ds, path)  # every value but the frames' (Fletcher-32)
        except Exception as exc:  # noqa: BLE001 - turned into a message naming the file
            if ds is not None:
                ds.close()
            if isinstance(exc, SunlabError):
                raise
            raise SunlabError(
                f"{path}: cannot be read as NetCDF4/HDF5 ({type(exc).__name__}: {exc}). Fix: "
                "the file is probably truncated or corrupt (an interrupted copy or write); copy "
                "it again from its source or re-create it with sunlab.io.save_frames") from exc
    ds.attrs.pop(integrity.ATTR, None)
    try:
        ds = _strings_as_objects(ds)
        for var in ds.variables.values():
            var.attrs = _decode_attrs(var.attrs)
        ds.attrs = _decode_attrs(ds.attrs)
    except (ValueError, TypeError, KeyError, RecursionError) as exc:  # deep JSON too
        ds.close()
        raise SunlabError(
            f"{path}: unreadable attribute {_CODEC_ATTR!r} ({exc}). Fix: the metadata was edited "
            "by hand or by another tool; remove that attribute or re-create the store") from exc
    ds = _checked_lazy(ds, path, format)
    ds.encoding.update(sunlab_format=format, source=str(path))
    return ds


def _finish(ds: xr.Dataset, validate, check_chunks: bool) -> xr.Dataset:
    try:
        validate(ds)
        if check_chunks and ds.encoding.get("sunlab_format") == "zarr":
            _check_chunks(ds, Path(ds.encoding["source"]))
    except BaseException:
        ds.close()
        raise
    return ds


def _is_image_source(path: Path) -> bool:
    """A TIFF stack, or a folder that is no Zarr store (nor the remains of one)."""
    if path.is_file():
        return path.suffix.lower() in _TIFF_SUFFIXES
    return path.is_dir() and not _is_zarr(path) and not any(path.glob("*/zarr.json"))


def open_frames(path, manifest=None, *, format: str | None = None, check_chunks: bool = True,
                lazy: bool = True, dark=None, flat=None, bias=None, **sensor) -> xr.Dataset:
    """Open a frame cube from any source sunlab reads, lazily, validated (``frames/1``).

    The one opener of frames: a Zarr store or a NetCDF4 file written by
    :func:`~sunlab.io.save_frames`, a folder of PNG or TIFF images with its ``manifest.csv``
    (and ``sensor.json``), or a multi-page TIFF stack with the manifest beside it. The same run
    gives the same cube from each (:mod:`sunlab.io.folder` says how a folder becomes a cube).

    Parameters
    ----------
    path : str or path-like
        A Zarr store (a folder holding ``zarr.json``), a NetCDF4 file, a folder of images or a
        TIFF stack (``.tif``, ``.tiff``: the rows of the manifest beside it that name it).
    manifest : str or path-like, optional
        Images only: another manifest (default ``manifest.csv`` in the folder); its folder's
        ``sensor.json`` is read first.
    format : {"zarr", "netcdf"}, optional
        Stores only. Default: a directory is Zarr, a file is NetCDF4 (checked by its signature).
    check_chunks : bool
        Zarr only: check that every chunk file exists. A missing chunk would otherwise read as
        frames of 0 DN without any warning. Turn off to read an incomplete store on purpose.
    lazy : bool
        Images only: read each image when its frame is computed (headers are checked at once).
    dark, flat, bias : str, path-like or array_like, optional
        Images only: calibration frames whose masters are stored with the cube
        (:func:`~sunlab.io.with_calibration_frames`).
    **sensor
        Images only: sensor constants that override ``sensor.json``: ``pixel_pitch_mm``,
        ``mask_distance_mm``, ``x_cf_px``, ``y_cf_px``, ``bit_depth``, ``left_aligned``,
        ``mask``, ``experiment`` (None = not given). The pitch and the mask distance are never
        guessed: absent, they stay absent, and only the methods that need them ask.

    Returns
    -------
    xarray.Dataset
        The cube; close it (or use ``with``) to release a NetCDF file.

    Raises
    ------
    SunlabError
        The path is missing, truncated or corrupt (the message names the file and the fix).
    SchemaError
        The dataset breaks the contract ``frames/1``, Zarr chunks are missing, or a manifest
        line, a column or an image is wrong (named, with the fix).

    Examples
    --------
    >>> from sunlab import io
    >>> cube = io.open_frames(io.example_folder("train"))
    >>> cube.attrs["bit_depth"], cube.attrs["mask_distance_mm"], dict(cube.sizes)["pose"]
    (10, 17.0, 25)
    """
    path = _existing(path)
    if format is None and _is_image_source(path):
        from .folder import _from_images

        return _from_images(path, manifest, lazy=lazy, dark=dark, flat=flat, bias=bias,
                            **sensor)
    given = [k for k, v in {"manifest": manifest, "dark": dark, "flat": flat, "bias": bias,
                            **sensor}.items() if v is not None]
    if given:
        raise SunlabError(f"{path}: {', '.join(given)} apply to a folder of images or a TIFF "
                          "stack only. Fix: leave them out (a store carries its own)")
    return _finish(_open_raw(path, format), validate_frames, check_chunks)


def _sensor_attrs(path) -> dict | None:
    """The sensor attributes of a CSV table (pitch, mask distance, design centre) from the
    ``sensor.json`` in its folder, or None."""
    from .sensor import find_sensor_json, read_sensor_json

    if (found := find_sensor_json(Path(path).resolve().parent)) is None:
        return None
    doc = read_sensor_json(found)
    return {**{k: doc[k] for k in ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px")
               if k in doc}, "sensor_json": str(found)}


def open_centroids(path, *, format: str | None = None, lazy: bool = False,
                   check_chunks: bool = True, attrs: dict | None = None) -> xr.Dataset:
    """Open and validate a centroid table: Zarr, NetCDF4 or CSV; loaded unless ``lazy``.

    The one opener of centroid tables.

    Parameters
    ----------
    path : str or path-like
        A Zarr store or NetCDF4 file written by :func:`~sunlab.io.save_centroids`, or a CSV
        file (suffix ``.csv`` or ``.txt``) of another tool with the columns
        ``alpha, beta, x, y[, shot, status]`` (commanded angles in deg, centroid in px, one row
        per shot; poses are the distinct (alpha, beta) pairs in file order, poses with fewer
        shots padded with NaN and status ``no_spot``; ``#`` starts a comment).
    format : {"zarr", "netcdf", "csv"}, optional
        Default: from the path (a directory is Zarr, a ``.csv``/``.txt`` file CSV, any other
        file NetCDF4, checked by its signature).
    lazy : bool
        Zarr and NetCDF: keep the variables Dask-backed instead of loading them.
    check_chunks : bool
        Zarr only: check that every chunk file exists.
    attrs : dict, optional
        CSV only: attributes of the table, e.g. the sensor's ``pixel_pitch_mm``,
        ``mask_distance_mm``, ``x_cf_px``, ``y_cf_px`` (a geometric model needs them).
        Default: those of a ``sensor.json`` beside the CSV file (``io.sensor.read_sensor_json``),
        if there is one, recorded in ``attrs['sensor_json']``; ``sunlab calibrate`` and
        ``sunlab evaluate`` read a CSV table the same way.

    Returns
    -------
    xarray.Dataset
        A ``centroids/1`` table on (pose, shot) or (pose, shot, hole).

    Raises
    ------
    SunlabError
        The path is missing, truncated or corrupt.
    SchemaError
        The file is not a centroid table (a frame cube: centroid it first), or a CSV value or
        column is wrong (the message names the line and the column).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "c.csv"
    >>> _ = path.write_text("alpha,beta,x,y\\n0,0,10.5,20.25\\n0,0,10.7,20.0\\n1,0,30.0,20.0\\n")
    >>> cen = open_centroids(path)
    >>> dict(cen.sizes), cen.status.values.tolist()
    ({'pose': 2, 'shot': 2}, [[0, 0], [0, 1]])
    """
    if format == "csv" or (format is None and Path(path).suffix.lower() in CSV_SUFFIXES):
        return centroids_from_csv(path, attrs=_sensor_attrs(path) if attrs is None else attrs)
    if attrs is not None:
        raise SunlabError(f"{path}: attrs= applies to CSV tables only. Fix: leave attrs out (a "
                          "Zarr or NetCDF table carries its own attributes)")
    ds = _open_raw(path, format)
    if ds.attrs.get("sunlab_schema") == FRAMES_SCHEMA:
        ds.close()
        raise SchemaError(
            f"{path}", "a frame cube (frames/1)", "a centroid table (centroids/1)",
            f"centroid the frames first: sunlab.centroid.locate(cube) or `sunlab centroid {path} "
            "--out table.nc`")
    ds = _finish(ds, validate_centroids, check_chunks)
    if lazy:
        return ds
    loaded = ds.load()
    ds.close()
    return loaded


def _open_any(path) -> xr.Dataset:
    """A frame cube (lazy) or a centroid table (lazy), whichever the file's contract names;
    missing Zarr chunks allowed."""
    ds = _open_raw(path)
    centroids = ds.attrs.get("sunlab_schema") == CENTROIDS_SCHEMA
    return _finish(ds, validate_centroids if centroids else validate_frames, False)
