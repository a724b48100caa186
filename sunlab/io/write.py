"""Save frame cubes and centroid tables as Zarr v3 stores or NetCDF4 files.

Outputs are written to a hidden temporary sibling and renamed into place (:mod:`sunlab.atomic`):
an existing output is replaced only with ``overwrite=True`` and survives a write that fails.
Every Zarr chunk carries a CRC-32C checksum after the compressor, every NetCDF frame chunk an
HDF5 Fletcher-32 one; attributes go through :mod:`sunlab.io.codec`.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import xarray as xr

from .. import atomic, integrity
from ..errors import SchemaError
from ..schema import validate_centroids, validate_frames
from .chunks import _checked_dn
from .codec import _encode_attrs, _strings_as_objects

__all__ = ["save_frames", "save_centroids"]

#: Path suffixes saved as NetCDF4 (everything else is a Zarr store).
NETCDF_SUFFIXES = (".nc", ".nc4", ".netcdf", ".h5", ".hdf5")

_CHUNKING = ("frame", "pose")
#: NetCDF outputs up to this size (bytes in memory) are built in memory and written as plain
#: bytes: a write that fails there (a full disk) is an OSError like any other, where HDF5
#: writing to a file that stopped growing can leave its library in a state that crashes the
#: interpreter at exit. Larger ones (frame cubes; Zarr is the format for those) go straight
#: to the temporary file, where a full disk can still end in that crash after the error is
#: reported.
NETCDF_IN_MEMORY_MAX = 1 << 30


def _target(path, format: str | None, overwrite: bool, nbytes: int) -> tuple[Path, str]:
    """The output and its format; an existing output without ``overwrite``, a missing or
    read-only folder, a dataset of ``nbytes`` far past the free space refused early (before
    any frame is computed)."""
    path = Path(path)
    if format not in ("zarr", "netcdf", None):
        raise SchemaError("format", format, "'zarr', 'netcdf' or None (from the suffix)")
    fmt = format or ("netcdf" if path.suffix.lower() in NETCDF_SUFFIXES else "zarr")
    atomic.check_target(path, overwrite=overwrite, kind="zarr" if fmt == "zarr" else "file",
                        nbytes=nbytes)
    return path, fmt


def _prepare(ds: xr.Dataset) -> xr.Dataset:
    """A shallow copy with encodings cleared, attributes encoded and strings as objects."""
    ds = _strings_as_objects(ds.copy(deep=False))
    ds.encoding = {}
    for name, var in ds.variables.items():
        var.encoding = {}
        var.attrs = _encode_attrs(var.attrs, where=f"{name}.")
    ds.attrs = _encode_attrs({k: v for k, v in ds.attrs.items() if k != integrity.ATTR}, "")
    return ds


def _write(ds: xr.Dataset, path: Path, fmt: str, encoding: dict, progress: bool,
           overwrite: bool) -> None:
    """Write to a temporary sibling, then rename it into place (the old output survives).
    Every Zarr array gets a CRC-32C checksum after its compressor."""
    from zarr.codecs import Crc32cCodec, ZstdCodec

    from ..options import dask_progress

    with atomic.atomic_output(path, overwrite=overwrite,
                              kind="zarr" if fmt == "zarr" else "file") as tmp:
        # the metadata are written on zarr's own I/O thread: Ctrl-C waits until they are
        with atomic.signals_held():
            if fmt == "zarr":
                zarr_enc = {n: {**encoding.get(n, {}), "compressors": (*encoding.get(n, {}).get(
                    "compressors", (ZstdCodec(level=0),)), Crc32cCodec())} for n in ds.variables}
                job = ds.to_zarr(tmp, mode="w-", zarr_format=3, consolidated=False,
                                 write_empty_chunks=True, encoding=zarr_enc, compute=False)
            elif ds.nbytes <= NETCDF_IN_MEMORY_MAX:
                job = None
            else:
                job = ds.to_netcdf(tmp, engine="h5netcdf", encoding=encoding, compute=False)
        with dask_progress(progress, "write", minimum=1.0):
            if job is None:  # built in memory, then written as plain bytes
                with open(tmp, "wb") as fh:
                    fh.write(ds.to_netcdf(engine="h5netcdf", encoding=encoding))
                    fh.flush()
                    os.fsync(fh.fileno())
            else:
                _compute_then_settle(job)
        # the digest of what was written, checked by every read (sunlab.integrity)
        (integrity.seal_zarr if fmt == "zarr" else integrity.seal_netcdf)(tmp)


def _compute_then_settle(job) -> None:
    """Compute a delayed write; on the local threaded scheduler, return (or raise) only once
    every chunk write already started has finished.

    Dask's threaded scheduler raises the first task error at once while other threads may
    still be writing chunks; the temporary store removed on that error would then be
    recreated by a late write and left behind. A thread pool of our own is shut down (waiting)
    before the error reaches :func:`sunlab.atomic.atomic_output`. Another scheduler (a
    ``dask.distributed`` client, ``processes``) computes as configured.
    """
    import dask.threaded
    from dask.base import get_scheduler

    if get_scheduler(collections=[job]) is not dask.threaded.get:
        job.compute()
        return
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:  # exit waits
        job.compute(scheduler="threads", pool=pool)


def save_frames(
    cube: xr.Dataset,
    path,
    *,
    chunks: str = "frame",
    format: str | None = None,
    overwrite: bool = False,
    progress: bool = False,
    compression_level: int = 1,
) -> None:
    """Save a frame cube as a Zarr v3 store (default) or a NetCDF4 file (``.nc``).

    The cube is validated first (contract ``frames/1``). Lazy (Dask) cubes are computed chunk by
    chunk while writing, so a simulated experiment never has to fit in memory.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (:func:`sunlab.schema.frames_dataset`).
    path : str or path-like
        Target. A suffix in :data:`NETCDF_SUFFIXES` (``.nc``) selects NetCDF4; anything else is a
        Zarr directory store (``.zarr`` by habit).
    chunks : {"frame", "pose"}
        One frame (1, 1, y, x) or one pose (1, shot, y, x) per chunk. Per frame suits random
        access and incremental acquisition; per pose makes fewer, larger files.
    format : {"zarr", "netcdf"}, optional
        Overrides the choice made from the suffix.
    overwrite : bool
        Replace an existing store or file at ``path``; otherwise an existing path is an error.
    progress : bool
        Show a Dask progress bar while writing.
    compression_level : int
        Zarr: Blosc (byte shuffle + Zstandard) level; NetCDF: HDF5 shuffle + gzip level; 0 .. 9
        (0 stores the frames uncompressed in NetCDF).

    Raises
    ------
    SchemaError
        The cube breaks the contract.
    SunlabError
        ``path`` exists and ``overwrite`` is False, or its folder is missing or read-only
        (checked before any frame is computed).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
    >>> from sunlab.io import open_frames
    >>> cube = schema.frames_dataset(np.ones((1, 2, 3, 4), np.uint16), alpha=[0.0], beta=[0.0])
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.nc"
    >>> save_frames(cube, path)
    >>> with open_frames(path) as back:
    ...     print(back.frames.dtype, back.frames.data.chunksize)
    uint16 (1, 1, 3, 4)
    """
    path, fmt = _target(path, format, overwrite, cube.nbytes)
    validate_frames(cube)
    if chunks not in _CHUNKING:
        raise SchemaError("chunks", chunks, f"one of {_CHUNKING}", "per frame or per pose")
    ds = _prepare(cube)
    # metadata and ground truth in a few large chunks (<= ~32 MB), not one file per frame
    for name in [n for n, v in ds.variables.items() if n != "frames" and v.chunks is not None]:
        var = ds.variables[name]
        block = {d: -1 for d in var.dims}
        if "pose" in var.dims:
            per_pose = max(var.nbytes // max(var.sizes["pose"], 1), 1)
            block["pose"] = int(max(1, min(var.sizes["pose"], 32_000_000 // per_pose)))
        var = var.chunk(block)
        ds = ds.assign_coords({name: var}) if name in ds.coords else ds.assign({name: var})
    n_pose, n_shot, ny, nx = ds["frames"].shape
    block = (1, 1 if chunks == "frame" else max(n_shot, 1), max(ny, 1), max(nx, 1))
    ds["frames"] = ds["frames"].chunk(dict(zip(ds["frames"].dims, block, strict=True)))
    encoding = _frames_encoding(ds["frames"].dtype, block, fmt, int(compression_level))
    # Lazy frames (validate_frames checked in-memory ones): each chunk's DN range is checked
    # against the bit depth as it is written.
    ds["frames"] = ds["frames"].copy(data=_checked_dn(ds["frames"].data, cube.attrs["bit_depth"],
                                                      f"{path} (being written)"))
    _write(ds, path, fmt, encoding, progress, overwrite)


def _frames_encoding(dtype: np.dtype, block: tuple, fmt: str, level: int) -> dict:
    """Compression of the frames: Blosc (Zarr) or HDF5 shuffle + gzip and Fletcher-32 (NetCDF)."""
    if fmt == "zarr":
        from zarr.codecs import BloscCodec

        # Byte shuffle + Zstandard: on noisy 10-bit frames a better ratio than plain Zstandard
        # at about twice its speed.
        blosc = BloscCodec(cname="zstd", clevel=level, shuffle="shuffle", typesize=dtype.itemsize)
        return {"frames": {"compressors": (blosc,)}}
    return {"frames": {"chunksizes": block, "zlib": level > 0, "complevel": level,
                       "shuffle": level > 0, "fletcher32": True}}


def save_centroids(
    centroids: xr.Dataset,
    path,
    *,
    format: str | None = None,
    overwrite: bool = False,
) -> None:
    """Save a centroid table (contract ``centroids/1``) as Zarr (default) or NetCDF4 (``.nc``).

    Parameters
    ----------
    centroids : xarray.Dataset
        A centroid table (:func:`sunlab.schema.centroids_dataset`, or what
        :func:`sunlab.centroid.locate` returns), validated first.
    path : str or path-like
        Target. A suffix in :data:`NETCDF_SUFFIXES` (``.nc``) selects NetCDF4; anything else is
        a Zarr directory store.
    format : {"zarr", "netcdf"}, optional
        Overrides the choice made from the suffix.
    overwrite : bool
        Replace an existing store or file at ``path``; otherwise an existing path is an error.

    Raises
    ------
    SchemaError
        The table breaks the contract.
    SunlabError
        ``path`` exists and ``overwrite`` is False, or its folder is missing or read-only.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
    >>> from sunlab.io import open_centroids
    >>> cen = schema.centroids_dataset([[1.5, np.nan]], [[2.5, np.nan]])
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "centroids.zarr"
    >>> save_centroids(cen, path)
    >>> open_centroids(path).status.values.tolist()
    [[0, 1]]
    """
    path, fmt = _target(path, format, overwrite, centroids.nbytes)
    validate_centroids(centroids)
    ds = _prepare(centroids)
    _write(ds.chunk({d: -1 for d in ds.dims}), path, fmt, {}, progress=False,
           overwrite=overwrite)

