"""Open frame cubes and centroid tables lazily, checked chunk by chunk, and validate them.

A directory is read as a Zarr store, a file as NetCDF4/HDF5 (checked by its signature). Every
non-index variable is Dask-backed through a reader that names the chunk when a read fails
(:mod:`sunlab.io.chunks`); attributes are restored by :mod:`sunlab.io.codec`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from .. import integrity
from ..errors import SchemaError, SunlabError
from ..schema import CENTROIDS_SCHEMA, FRAMES_SCHEMA, validate_centroids, validate_frames
from .chunks import _check_chunks, _checked_lazy
from .codec import _CODEC_ATTR, _decode_attrs
from .csvtable import CSV_SUFFIXES, centroids_from_csv

__all__ = ["open_frames", "open_centroids", "open_dataset"]

_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"


def _fail_zarr(path: Path, exc: Exception):
    """Raise a SunlabError that says which file of a Zarr store is broken and what to do."""
    for meta in sorted(path.rglob("zarr.json")):
        try:
            json.loads(meta.read_text(encoding="utf-8"))
        except (UnicodeDecodeError, ValueError) as err:
            raise SunlabError(
                f"{meta}: corrupt Zarr metadata ({err}). Fix: restore this file from a backup or "
                "copy the store again from its source; a store written by sunlab.io can also be "
                "re-created with save_frames"
            ) from exc
    raise SunlabError(
        f"{path}: cannot be read as a Zarr store ({type(exc).__name__}: {exc}). Fix: check "
        "that the copy is complete, or re-create the store with sunlab.io.save_frames"
    ) from exc


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
        raise SunlabError(
            f"{path}: a NetCDF3 (classic) file; sunlab reads NetCDF4/HDF5. Fix: convert it with "
            "`nccopy -k nc4 in.nc out.nc`"
        )
    raise SunlabError(
        f"{path}: neither a Zarr store (a directory) nor a NetCDF4/HDF5 file (first bytes "
        f"{head!r}). Fix: the file may be truncated or of another type; copy it again from its "
        "source"
    )


def _open_raw(path, format: str | None = None) -> xr.Dataset:
    """Open a store or file lazily, decode sunlab attributes; no validation."""
    path = Path(path)
    if not path.exists():
        raise SunlabError(
            f"{path}: no such file or directory. Fix: give the path of a .zarr store or a .nc "
            "file written by sunlab.io (or sunlab simulate)"
        )
    if not (path.is_dir() or path.is_file()):  # a FIFO or a device would block or never end
        raise SunlabError(
            f"{path}: not a regular file or folder. Fix: give the path of a .zarr store or a .nc "
            "file written by sunlab.io"
        )
    if format is None:
        format = "zarr" if path.is_dir() else _sniff(path)
    if format == "zarr":
        if not path.is_dir() or not (
            (path / "zarr.json").exists() or (path / ".zgroup").exists()
        ):
            raise SunlabError(
                f"{path}: not a Zarr store (no zarr.json in it). Fix: give the store's top "
                "directory, or copy the store again if its metadata is missing"
            )
        integrity.verify_zarr(path)  # metadata (shapes, data types, codecs) as written
        try:
            ds = xr.open_zarr(path, consolidated=False, chunks=None)
        except Exception as exc:  # noqa: BLE001 - turned into a message naming the file
            _fail_zarr(path, exc)
    else:
        try:
            ds = xr.open_dataset(path, engine="h5netcdf", chunks=None)
        except Exception as exc:  # noqa: BLE001 - turned into a message naming the file
            raise SunlabError(
                f"{path}: cannot be read as NetCDF4/HDF5 ({type(exc).__name__}: {exc}). Fix: "
                "the file is probably truncated or corrupt (an interrupted copy or write); copy "
                "it again from its source or re-create it with sunlab.io.save_frames"
            ) from exc
        try:
            integrity.verify_netcdf(ds, path)  # every value but the frames' (Fletcher-32)
        except SunlabError:
            ds.close()
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged variable: name the file
            ds.close()
            raise SunlabError(
                f"{path}: a variable cannot be read ({type(exc).__name__}: {exc}). Fix: the "
                "file is corrupt; copy it again from its source or re-create it"
            ) from exc
    ds.attrs.pop(integrity.ATTR, None)
    try:
        for name in list(ds.variables):
            var = ds.variables[name]
            if var.dtype.kind in "UT":
                new = (var.dims, np.asarray(var.values).astype(object), var.attrs)
                ds = ds.assign_coords({name: new}) if name in ds.coords else ds.assign({name: new})
        for var in ds.variables.values():
            var.attrs = _decode_attrs(var.attrs)
        ds.attrs = _decode_attrs(ds.attrs)
    except (ValueError, TypeError, KeyError, RecursionError) as exc:  # deep JSON too
        ds.close()
        raise SunlabError(
            f"{path}: unreadable attribute {_CODEC_ATTR!r} ({exc}). Fix: the metadata was edited "
            "by hand or by another tool; remove that attribute or re-create the store"
        ) from exc
    ds = _checked_lazy(ds, path, format)
    ds.encoding["sunlab_format"] = format
    ds.encoding["source"] = str(path)
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


def open_frames(path, *, format: str | None = None, check_chunks: bool = True) -> xr.Dataset:
    """Open a frame cube lazily (Dask arrays, one chunk per stored chunk) and validate it.

    Parameters
    ----------
    path : str or path-like
        A Zarr store or a NetCDF4 file written by :func:`~sunlab.io.save_frames`.
    format : {"zarr", "netcdf"}, optional
        Default: a directory is Zarr, a file is NetCDF4 (checked by its signature).
    check_chunks : bool
        Zarr only: check that every chunk file exists. A missing chunk would otherwise read as
        frames of 0 DN without any warning. Turn off to read an incomplete store on purpose.

    Returns
    -------
    xarray.Dataset
        The cube; close it (or use ``with``) to release a NetCDF file.

    Raises
    ------
    SunlabError
        The path is missing, truncated or corrupt (the message names the file and the fix).
    SchemaError
        The dataset breaks the contract ``frames/1``, or Zarr chunks are missing.

    Examples
    --------
    See :func:`~sunlab.io.save_frames`.
    """
    return _finish(_open_raw(path, format), validate_frames, check_chunks)


#: The sensor constants a CSV centroid table takes from the ``sensor.json`` beside it.
CSV_SENSOR_KEYS = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px")


def _sensor_attrs(path) -> dict | None:
    """The sensor attributes of a CSV table from the ``sensor.json`` in its folder, or None."""
    from .sensor import read_sensor_json

    sensor_json = Path(path).resolve().parent / "sensor.json"
    if not sensor_json.is_file():
        return None
    sensor = read_sensor_json(sensor_json)
    return {**{k: sensor[k] for k in CSV_SENSOR_KEYS if k in sensor},
            "sensor_json": str(sensor_json)}


def open_centroids(
    path, *, format: str | None = None, lazy: bool = False, check_chunks: bool = True,
    attrs: dict | None = None,
) -> xr.Dataset:
    """Open and validate a centroid table: Zarr, NetCDF4 or CSV; loaded unless ``lazy``.

    Parameters
    ----------
    path : str or path-like
        A Zarr store or NetCDF4 file written by :func:`~sunlab.io.save_centroids`, or a CSV
        file (suffix ``.csv`` or ``.txt``) with the columns ``alpha, beta, x, y[, shot]``
        (commanded angles in deg, centroid in px; :func:`~sunlab.io.centroids_from_csv`).
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
        Default: those of a ``sensor.json`` beside the CSV file (:func:`read_sensor_json`),
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
    >>> _ = path.write_text("alpha,beta,x,y\\n0,0,10.5,20.25\\n1,0,30.0,20.0\\n")
    >>> dict(open_centroids(path).sizes)
    {'pose': 2, 'shot': 1}
    """
    if format == "csv" or (format is None and Path(path).suffix.lower() in CSV_SUFFIXES):
        return centroids_from_csv(path, attrs=_sensor_attrs(path) if attrs is None else attrs)
    if attrs is not None:
        raise SunlabError(
            f"{path}: attrs= applies to CSV tables only. Fix: leave attrs out (a Zarr or NetCDF "
            "table carries its own attributes)")
    ds = _open_raw(path, format)
    found = ds.attrs.get("sunlab_schema")
    if found == FRAMES_SCHEMA:
        ds.close()
        raise SchemaError(
            f"{path}", "a frame cube (frames/1)", "a centroid table (centroids/1)",
            f"centroid the frames first: sunlab.centroid.locate(cube) or `sunlab centroid {path} "
            "--out table.nc`")
    ds = _finish(ds, validate_centroids, check_chunks)
    if not lazy:
        loaded = ds.load()
        ds.close()
        return loaded
    return ds


def open_dataset(path, *, format: str | None = None, check_chunks: bool = True) -> xr.Dataset:
    """Open a frame cube or a centroid table, whichever ``attrs['sunlab_schema']`` names.

    Frame cubes open lazily (see :func:`open_frames`), centroid tables are loaded.

    Parameters
    ----------
    path : str or path-like
        A Zarr store or a NetCDF4 file written by :mod:`sunlab.io`.
    format : {"zarr", "netcdf"}, optional
        Default: a directory is Zarr, a file is NetCDF4 (checked by its signature).
    check_chunks : bool
        Zarr only: check that every chunk file exists (see :func:`open_frames`).

    Returns
    -------
    xarray.Dataset
        A validated ``frames/1`` cube (lazy; close it to release a NetCDF file) or a
        ``centroids/1`` table (in memory, the file closed).

    Raises
    ------
    SunlabError
        The path is missing, truncated or corrupt (the message names the file and the fix).
    SchemaError
        ``attrs['sunlab_schema']`` names neither contract, or the dataset breaks its contract.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
    >>> from sunlab.io import save_centroids
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "c.zarr"
    >>> save_centroids(schema.centroids_dataset([[1.0]], [[2.0]]), path)
    >>> open_dataset(path).attrs["sunlab_schema"]
    'centroids/1'
    """
    ds = _open_raw(path, format)
    found = ds.attrs.get("sunlab_schema")
    if found == FRAMES_SCHEMA:
        return _finish(ds, validate_frames, check_chunks)
    if found == CENTROIDS_SCHEMA:
        ds = _finish(ds, validate_centroids, check_chunks)
        loaded = ds.load()
        ds.close()
        return loaded
    ds.close()
    family = str(found).partition("/")[0]
    if family in ("frames", "centroids"):
        fix = (
            f"this sunlab reads {FRAMES_SCHEMA!r} and {CENTROIDS_SCHEMA!r}: open the file with "
            "the sunlab version that wrote it and save it again, or upgrade sunlab"
        )
    else:
        fix = (
            "the file was not written by sunlab.io; build a dataset with sunlab.schema "
            "(frames_dataset, centroids_dataset) and save it with sunlab.io"
        )
    raise SchemaError(
        "attrs['sunlab_schema']", found, f"{FRAMES_SCHEMA!r} or {CENTROIDS_SCHEMA!r}", fix
    )

