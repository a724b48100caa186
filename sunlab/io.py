"""Open and save frame cubes and centroid tables; import a folder of images with a manifest.

Two on-disk formats hold the same datasets (contracts ``frames/1`` and ``centroids/1`` of
``data_schema/``):

* **Zarr v3** (the default; any path not ending in ``.nc``): a directory store, frames chunked one
  frame (or one pose) per chunk, Blosc-compressed (byte shuffle + Zstandard), every chunk
  written, opened lazily as Dask arrays.
* **NetCDF4/HDF5** (``.nc``): one file written with the ``h5netcdf`` engine, frames chunked and
  compressed the same way; uint16 DN survive as uint16.

Nothing lost, nothing silent: every chunk carries a checksum (Zarr: a CRC-32C codec after the
compressor; NetCDF: the HDF5 Fletcher-32 filter on the frames), so a damaged chunk fails to read
with a :class:`sunlab.SunlabError` that names the store, the variable and the chunk; stores
written before checksums still open. Outputs are written to a hidden temporary sibling and
renamed into place (:mod:`sunlab.atomic`): an existing output is replaced only with
``overwrite=True`` and survives a write that fails. Frames read from disk are checked against
the store's ``bit_depth`` chunk by chunk.

Round trips are exact: dtypes, coordinates and attributes come back as they were saved. Attribute
values that NetCDF or Zarr cannot hold natively (booleans, None, lists, dicts, numpy arrays in Zarr)
are stored as JSON text or flat arrays and listed, per dataset or variable, in the attribute
``sunlab_attr_codec``, which the readers use to restore them; other readers see plain text.
Numpy scalar attributes come back as the Python ``int``, ``float`` or ``bool`` of the same value.

Examples
--------
>>> import numpy as np, tempfile, pathlib
>>> from sunlab import io, schema
>>> cube = schema.frames_dataset(np.arange(2 * 3 * 4 * 5, dtype=np.uint16).reshape(2, 3, 4, 5),
...                              alpha=[0.0, 1.0], beta=[0.0, 0.0])
>>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.zarr"
>>> io.save_frames(cube, path)
>>> back = io.open_frames(path)
>>> back.frames.data.chunksize, back.frames.dtype
((1, 1, 4, 5), dtype('uint16'))
>>> bool((back.frames == cube.frames).all())
True
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Mapping
from pathlib import Path

import numpy as np
import xarray as xr

from . import atomic
from .errors import SchemaError, SunlabError
from .schema import (
    CENTROIDS_SCHEMA,
    FRAMES_SCHEMA,
    STATUS,
    frames_dataset,
    validate_centroids,
    validate_frames,
)

__all__ = [
    "IMAGE_SUFFIXES",
    "NETCDF_SUFFIXES",
    "save_frames",
    "open_frames",
    "save_centroids",
    "open_centroids",
    "open_dataset",
    "from_image_folder",
    "example_folder",
    "read_image",
    "summary",
]

#: File suffixes read by :func:`from_image_folder` and :func:`read_image`.
IMAGE_SUFFIXES = (".png", ".tif", ".tiff")
#: Path suffixes saved as NetCDF4 (everything else is a Zarr store).
NETCDF_SUFFIXES = (".nc", ".nc4", ".netcdf", ".h5", ".hdf5")

_CODEC_ATTR = "sunlab_attr_codec"
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_PNG_MODES = {"L": np.uint8, "I;16": np.uint16, "I;16L": np.uint16, "I;16B": np.uint16}
_REQUIRED_COLUMNS = ("file", "alpha", "beta", "shot")
_RESERVED_COLUMNS = ("pose", "x", "y", "frames", "hole", "shot_label")
_CHUNKING = ("frame", "pose")


# --------------------------------------------------------------------------------------------
# Attribute codec: exact round trips through NetCDF and Zarr attributes
# --------------------------------------------------------------------------------------------
def _encode_attrs(attrs: Mapping, where: str) -> dict:
    """Attributes ready for NetCDF and Zarr, plus the codec entry that restores them."""
    out: dict = {}
    codec: dict = {}
    for key, value in attrs.items():
        if key == _CODEC_ATTR:
            continue
        if isinstance(value, np.generic):
            value = value.item()
        big_int = isinstance(value, int) and not -(2**63) <= value < 2**63
        if (
            isinstance(value, bool)
            or value is None
            or isinstance(value, list | tuple | dict)
            or big_int
        ):
            try:
                out[key] = json.dumps(value, allow_nan=False, default=_json_default)
            except (TypeError, ValueError) as exc:
                raise SchemaError(
                    f"{where}attrs[{key!r}]", _short(value), "a JSON-serialisable value",
                    f"convert it to numbers, strings, lists or dicts before saving ({exc})",
                ) from exc
            codec[key] = "tuple" if isinstance(value, tuple) else "json"
        elif isinstance(value, str | int | float):
            out[key] = value
        elif isinstance(value, np.ndarray) and value.dtype.kind in "iuf" and value.size > 0:
            out[key] = value.ravel()
            codec[key] = {"ndarray": value.dtype.str, "shape": list(value.shape)}
        elif isinstance(value, np.ndarray) and value.dtype.kind in "iufb":
            out[key] = json.dumps(value.tolist())
            codec[key] = {"ndarray": value.dtype.str, "shape": list(value.shape)}
        else:
            raise SchemaError(
                f"{where}attrs[{key!r}]", f"a value of type {type(value).__name__}",
                "str, int, float, bool, None, list, tuple, dict or a numeric numpy array",
                "convert the attribute to one of these types before saving",
            )
    if codec:
        out[_CODEC_ATTR] = json.dumps(codec)
    return out


def _json_default(obj):
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _decode_attrs(attrs: Mapping) -> dict:
    """Inverse of :func:`_encode_attrs`."""
    codec = json.loads(attrs.get(_CODEC_ATTR, "{}"))
    out = {}
    for key, value in attrs.items():
        if key == _CODEC_ATTR:
            continue
        rule = codec.get(key)
        if rule is None:
            if isinstance(value, np.generic):
                value = value.item()
        elif rule in ("json", "tuple"):
            value = json.loads(value)
            if rule == "tuple":
                value = tuple(value)
        else:
            if isinstance(value, str):
                value = json.loads(value)
            value = np.asarray(value, dtype=np.dtype(rule["ndarray"])).reshape(rule["shape"])
        out[key] = value
    return out


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 4] + " ..."


# --------------------------------------------------------------------------------------------
# Writing
# --------------------------------------------------------------------------------------------
def _format_of(path: Path, format: str | None) -> str:
    if format is None:
        return "netcdf" if path.suffix.lower() in NETCDF_SUFFIXES else "zarr"
    if format not in ("zarr", "netcdf"):
        raise SchemaError("format", format, "'zarr', 'netcdf' or None (from the suffix)")
    return format


def _prepare(ds: xr.Dataset, fmt: str) -> xr.Dataset:
    """A shallow copy with encodings cleared, attributes encoded and strings as objects."""
    ds = ds.copy(deep=False)
    ds.encoding = {}
    for name in list(ds.variables):
        var = ds.variables[name]
        kind = var.dtype.kind
        if kind in "UT":
            # Zarr v3 has no stable fixed-width unicode type: write variable-length strings.
            values = np.asarray(var.values).astype(object)
            new = (var.dims, values, var.attrs)
            ds = ds.assign_coords({name: new}) if name in ds.coords else ds.assign({name: new})
    for name, var in ds.variables.items():
        var.encoding = {}
        var.attrs = _encode_attrs(var.attrs, where=f"{name}.")
    ds.attrs = _encode_attrs(ds.attrs, where="")
    return ds


def _check_target(path: Path, fmt: str, overwrite: bool) -> None:
    """Refuse an existing output without ``overwrite``, a missing or read-only folder: early."""
    atomic.check_target(path, overwrite=overwrite, kind="zarr" if fmt == "zarr" else "file")


def _zarr_checksum_encoding(ds: xr.Dataset, encoding: dict) -> dict:
    """Encoding that gives every array of a Zarr store a CRC-32C checksum after compression."""
    from zarr.codecs import Crc32cCodec, ZstdCodec

    out = {}
    for name in ds.variables:
        enc = dict(encoding.get(name, {}))
        compressors = tuple(enc.get("compressors", (ZstdCodec(level=0),)))
        enc["compressors"] = (*compressors, Crc32cCodec())
        out[name] = enc
    return out


@contextlib.contextmanager
def _maybe_progress(progress: bool):
    from .options import show_progress

    if show_progress(progress):
        from dask.diagnostics import ProgressBar

        with ProgressBar():
            yield
    else:
        yield


def _write(ds: xr.Dataset, path: Path, fmt: str, encoding: dict, progress: bool,
           overwrite: bool) -> None:
    """Write to a temporary sibling, then rename it into place (the old output survives)."""
    with atomic.atomic_output(path, overwrite=overwrite,
                               kind="zarr" if fmt == "zarr" else "file") as tmp:
        if fmt == "zarr":
            job = ds.to_zarr(
                tmp, mode="w-", zarr_format=3, consolidated=False, write_empty_chunks=True,
                encoding=_zarr_checksum_encoding(ds, encoding), compute=False,
            )
        else:
            job = ds.to_netcdf(tmp, engine="h5netcdf", encoding=encoding, compute=False)
        with _maybe_progress(progress):
            job.compute()


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

    Notes
    -----
    The store is written to a hidden sibling (``.NAME.tmp-XXXXXXXX``) and renamed into place
    only when complete; with ``overwrite=True`` the old output is moved aside, the new one moved
    in, and only then the old one deleted, so a failed write leaves the old output intact.
    Every Zarr chunk carries a CRC-32C checksum, every NetCDF frame chunk a Fletcher-32 one.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
    >>> cube = schema.frames_dataset(np.ones((1, 2, 3, 4), np.uint16), alpha=[0.0], beta=[0.0])
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "cube.nc"
    >>> save_frames(cube, path)
    >>> with open_frames(path) as back:
    ...     print(back.frames.dtype, back.frames.data.chunksize)
    uint16 (1, 1, 3, 4)
    """
    path = Path(path)
    fmt = _format_of(path, format)
    _check_target(path, fmt, overwrite)
    validate_frames(cube)
    if chunks not in _CHUNKING:
        raise SchemaError("chunks", chunks, f"one of {_CHUNKING}", "per frame or per pose")
    ds = _prepare(cube, fmt)
    for name in [n for n, v in ds.variables.items() if n != "frames" and v.chunks is not None]:
        # Metadata and ground truth: a few large chunks (<= ~32 MB), not one file per frame.
        var = ds.variables[name]
        per_pose = max(var.nbytes // max(var.sizes.get("pose", 1), 1), 1)
        block = {d: -1 for d in var.dims}
        if "pose" in var.dims:
            block["pose"] = int(max(1, min(var.sizes["pose"], 32_000_000 // per_pose)))
        var = var.chunk(block)
        ds = ds.assign_coords({name: var}) if name in ds.coords else ds.assign({name: var})
    n_pose, n_shot, ny, nx = ds["frames"].shape
    block = (1, 1 if chunks == "frame" else max(n_shot, 1), max(ny, 1), max(nx, 1))
    ds["frames"] = ds["frames"].chunk(dict(zip(ds["frames"].dims, block, strict=True)))
    level = int(compression_level)
    if fmt == "zarr":
        from zarr.codecs import BloscCodec

        # Byte shuffle + Zstandard: on noisy 10-bit frames a better ratio than plain Zstandard
        # at about twice its speed.
        codec = BloscCodec(cname="zstd", clevel=level, shuffle="shuffle",
                           typesize=ds["frames"].dtype.itemsize)
        encoding = {"frames": {"compressors": (codec,)}}
    else:
        encoding = {
            "frames": {
                "chunksizes": block, "zlib": level > 0, "complevel": level, "shuffle": level > 0,
                "fletcher32": True,
            }
        }
    # Lazy frames (validate_frames checked in-memory ones): each chunk's DN range is checked
    # against the bit depth as it is written.
    ds["frames"] = ds["frames"].copy(data=_checked_dn(ds["frames"].data, cube.attrs["bit_depth"],
                                                      f"{path} (being written)"))
    _write(ds, path, fmt, encoding, progress, overwrite)


def save_centroids(
    centroids: xr.Dataset,
    path,
    *,
    format: str | None = None,
    overwrite: bool = False,
) -> None:
    """Save a centroid table (contract ``centroids/1``) as Zarr (default) or NetCDF4 (``.nc``).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
    >>> cen = schema.centroids_dataset([[1.5, np.nan]], [[2.5, np.nan]])
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "centroids.zarr"
    >>> save_centroids(cen, path)
    >>> open_centroids(path).status.values.tolist()
    [[0, 1]]
    """
    path = Path(path)
    fmt = _format_of(path, format)
    _check_target(path, fmt, overwrite)
    validate_centroids(centroids)
    ds = _prepare(centroids, fmt)
    ds = ds.chunk({d: -1 for d in ds.dims})
    _write(ds, path, fmt, {}, progress=False, overwrite=overwrite)


# --------------------------------------------------------------------------------------------
# Checked reading: every chunk read from disk names itself when it fails
# --------------------------------------------------------------------------------------------
def _chunk_label(dims, index) -> str:
    return ", ".join(f"{d} {i}" for d, i in zip(dims, index, strict=True))


def _dn_error(where: str, label: str, peak: int, bits: int) -> SchemaError:
    return SchemaError(
        f"{where} frames chunk ({label})", f"DN up to {peak}",
        f"< 2**{bits} = {2**bits} DN for attrs['bit_depth'] = {bits}",
        "set the true ADC bit depth (frames_dataset(bit_depth=...)); if the camera left-aligns "
        "its data in the 16-bit word, divide the frames by 2**(16 - bit_depth) first",
    )


def _check_dn_block(block, bits, where, dims, block_info=None):
    if block.size and int(block.max()) >= 2**bits:
        loc = (block_info or {}).get(0, {}).get("chunk-location") or ()
        raise _dn_error(where, _chunk_label(dims, loc) if loc else "?", int(block.max()), bits)
    return block


def _checked_dn(data, bits, where: str):
    """A Dask array (``data`` itself if not Dask) whose chunks fail if DN >= 2**bits."""
    if not hasattr(data, "map_blocks") or data.dtype.kind != "u":
        return data
    bits = int(bits)
    if bits >= 8 * data.dtype.itemsize:
        return data
    return data.map_blocks(_check_dn_block, bits, where, ("pose", "shot", "y", "x"),
                           dtype=data.dtype, meta=np.empty((0,) * data.ndim, data.dtype))


class _ChunkReader:
    """Array-like over one lazily opened variable that names its chunk when a read fails.

    Dask reads the stored chunks through it, one ``__getitem__`` per chunk; a checksum mismatch,
    a decompression error or DN above the bit depth becomes a :class:`SunlabError` naming the
    store, the variable, the chunk index and its file.
    """

    def __init__(self, var: xr.Variable, path: Path, name: str, fmt: str, chunks, bits):
        self.var = var
        self.path, self.name, self.fmt, self.chunks, self.bits = path, name, fmt, chunks, bits
        self.shape, self.ndim = var.shape, var.ndim
        self.dtype = var.dtype if var.dtype.kind in "OSUT" else var.dtype.newbyteorder("=")

    def __getitem__(self, key):
        try:
            block = np.asarray(self.var[key].values, dtype=self.dtype)
        except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the chunk
            raise self._error(key, exc) from exc
        if self.bits is not None and block.size and int(block.max()) >= 2**self.bits:
            raise _dn_error(str(self.path), self._label(key), int(block.max()), self.bits)
        return block

    def _index(self, key) -> tuple[int, ...]:
        key = key if isinstance(key, tuple) else (key,)
        out = []
        for k, size in zip(key, self.chunks, strict=False):
            start = k.start or 0 if isinstance(k, slice) else int(k)
            out.append(start // max(size, 1))
        return tuple(out)

    def _label(self, key) -> str:
        return _chunk_label(self.var.dims, self._index(key))

    def _chunk_file(self, index) -> str:
        if self.fmt != "zarr":
            return f"{self.path} (HDF5 variable {self.name!r})"
        try:
            import zarr

            arr = zarr.open_array(str(self.path / self.name), mode="r")
            return str(self.path / self.name / arr.metadata.chunk_key_encoding.encode_chunk_key(
                index))
        except Exception:  # noqa: BLE001 - the file name is a courtesy; the index is enough
            return f"{self.path / self.name} chunk {index}"

    def _error(self, key, exc: Exception) -> SunlabError:
        index = self._index(key)
        text = str(exc)
        checksum = "checksum" in text.lower() or "fletcher" in text.lower()
        what = "fails its checksum (the data were changed after writing)" if checksum else \
            f"cannot be decoded ({type(exc).__name__}: {text})"
        return SunlabError(
            f"{self._chunk_file(index)}: chunk ({_chunk_label(self.var.dims, index)}) of "
            f"variable {self.name!r} in {self.path} {what}. Fix: the store is damaged (disk "
            "error, interrupted or edited copy): copy it again from its source or re-create it; "
            "sunlab will not read corrupt data"
        )


def _stored_chunks(var: xr.Variable) -> tuple[int, ...]:
    enc = var.encoding
    preferred = enc.get("preferred_chunks")
    if preferred:
        return tuple(int(preferred.get(d, n)) for d, n in zip(var.dims, var.shape, strict=True))
    chunks = enc.get("chunks") or enc.get("chunksizes")
    if chunks and len(chunks) == var.ndim:
        return tuple(int(c) for c in chunks)
    return tuple(int(n) for n in var.shape)


def _checked_lazy(ds: xr.Dataset, path: Path, fmt: str) -> xr.Dataset:
    """Dask-back every non-index variable of a lazily opened dataset through a _ChunkReader."""
    import dask.array as da
    from dask.base import tokenize

    try:
        stamp = path.stat().st_mtime_ns
    except OSError:  # pragma: no cover - the store was just opened
        stamp = 0
    bits = ds.attrs.get("bit_depth")
    bits = int(bits) if isinstance(bits, int | np.integer) and not isinstance(bits, bool) \
        else None
    new = {}
    for name, var in ds.variables.items():
        if name in ds.indexes or var.ndim == 0:
            continue
        chunks = _stored_chunks(var)
        lazy = xr.Variable(var.dims, var._data)  # the backend's lazily indexed array
        check = bits if name == "frames" and var.dtype.kind == "u" else None
        reader = _ChunkReader(lazy, path, str(name), fmt, chunks, check)
        data = da.from_array(
            reader, chunks=chunks, asarray=False, fancy=False,
            name=f"sunlab-open-{name}-{tokenize(str(path), stamp, name, chunks)}",
            meta=np.empty((0,) * var.ndim, reader.dtype),
        )
        new[name] = var.copy(deep=False, data=data)
    coords = {n: v for n, v in new.items() if n in ds.coords}
    ds = ds.assign_coords(coords).assign({n: v for n, v in new.items() if n not in coords})
    return ds


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
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


def _open_raw(path, format: str | None = None) -> xr.Dataset:
    """Open a store or file lazily, decode sunlab attributes; no validation."""
    path = Path(path)
    if not path.exists():
        raise SunlabError(
            f"{path}: no such file or directory. Fix: give the path of a .zarr store or a .nc "
            "file written by sunlab.io (or sunlab simulate)"
        )
    if format is None:
        if path.is_dir():
            format = "zarr"
        else:
            with open(path, "rb") as fh:
                head = fh.read(8)
            if head == _HDF5_SIGNATURE:
                format = "netcdf"
            elif head[:3] == b"CDF":
                raise SunlabError(
                    f"{path}: a NetCDF3 (classic) file; sunlab reads NetCDF4/HDF5. Fix: convert "
                    "it with `nccopy -k nc4 in.nc out.nc`"
                )
            else:
                raise SunlabError(
                    f"{path}: neither a Zarr store (a directory) nor a NetCDF4/HDF5 file "
                    f"(first bytes {head!r}). Fix: the file may be truncated or of another type; "
                    "copy it again from its source"
                )
    if format == "zarr":
        if not path.is_dir() or not (
            (path / "zarr.json").exists() or (path / ".zgroup").exists()
        ):
            raise SunlabError(
                f"{path}: not a Zarr store (no zarr.json in it). Fix: give the store's top "
                "directory, or copy the store again if its metadata is missing"
            )
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
        for name in list(ds.variables):
            var = ds.variables[name]
            if var.dtype.kind in "UT":
                new = (var.dims, np.asarray(var.values).astype(object), var.attrs)
                ds = ds.assign_coords({name: new}) if name in ds.coords else ds.assign({name: new})
        for var in ds.variables.values():
            var.attrs = _decode_attrs(var.attrs)
        ds.attrs = _decode_attrs(ds.attrs)
    except (ValueError, TypeError, KeyError) as exc:
        ds.close()
        raise SunlabError(
            f"{path}: unreadable attribute {_CODEC_ATTR!r} ({exc}). Fix: the metadata was edited "
            "by hand or by another tool; remove that attribute or re-create the store"
        ) from exc
    ds = _checked_lazy(ds, path, format)
    ds.encoding["sunlab_format"] = format
    ds.encoding["source"] = str(path)
    return ds


def _chunk_report(path: Path) -> dict[str, tuple[int, int, list[str]]]:
    """Arrays of a Zarr store with missing chunk files: name -> (missing, total, examples)."""
    import zarr

    report = {}
    group = zarr.open_group(str(path), mode="r")
    for name, arr in group.arrays():
        n_missing = arr.nchunks - arr.nchunks_initialized
        if n_missing <= 0:
            continue
        examples = []
        try:
            encode = arr.metadata.chunk_key_encoding.encode_chunk_key
            for index in np.ndindex(*arr.cdata_shape):
                key = encode(index)
                if not (path / name / key).exists():
                    examples.append(str(path / name / key))
                    if len(examples) == 3:
                        break
        except AttributeError:  # zarr v2 metadata: no example paths
            pass
        report[name] = (n_missing, arr.nchunks, examples)
    return report


def _check_chunks(ds: xr.Dataset, path: Path) -> None:
    """Every chunk of a sunlab Zarr store exists (missing chunks would read as silent zeros)."""
    for name, (n_missing, total, examples) in _chunk_report(path).items():
        raise SchemaError(
            f"{name} chunks",
            f"{n_missing} of {total} chunk files missing"
            + (f", e.g. {', '.join(examples)}" if examples else ""),
            "every chunk of the store on disk",
            "the store is incomplete (an interrupted copy, write or acquisition, or deleted "
            "files): copy it again from its source, re-create it, or finish the acquisition; "
            "to read it anyway, with missing frames as 0 DN, pass check_chunks=False",
        )


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
        A Zarr store or a NetCDF4 file written by :func:`save_frames`.
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
    See :func:`save_frames`.
    """
    return _finish(_open_raw(path, format), validate_frames, check_chunks)


def open_centroids(
    path, *, format: str | None = None, lazy: bool = False, check_chunks: bool = True
) -> xr.Dataset:
    """Open and validate a centroid table; loaded into memory unless ``lazy``.

    Examples
    --------
    See :func:`save_centroids`.
    """
    ds = _finish(_open_raw(path, format), validate_centroids, check_chunks)
    if not lazy:
        loaded = ds.load()
        ds.close()
        return loaded
    return ds


def open_dataset(path, *, format: str | None = None, check_chunks: bool = True) -> xr.Dataset:
    """Open a frame cube or a centroid table, whichever ``attrs['sunlab_schema']`` names.

    Frame cubes open lazily (see :func:`open_frames`), centroid tables are loaded.

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib
    >>> from sunlab import schema
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


# --------------------------------------------------------------------------------------------
# Images and manifests
# --------------------------------------------------------------------------------------------
def _image_header(path: Path) -> tuple[tuple[int, ...], np.dtype]:
    """Shape and dtype of an image, from its header only."""
    suffix = path.suffix.lower()
    expected = "a single-channel 8- or 16-bit unsigned PNG or TIFF image"
    fix = "export raw frames as 8- or 16-bit grayscale PNG or TIFF (16-bit for a 10-bit ADC)"
    try:
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                mode, (width, height) = im.mode, im.size
            if mode not in _PNG_MODES:
                raise SchemaError(f"image {path.name}", f"PNG mode {mode!r}", expected, fix)
            return (height, width), np.dtype(_PNG_MODES[mode])
        if suffix in (".tif", ".tiff"):
            import tifffile

            with tifffile.TiffFile(path) as tif:
                series = tif.series[0]
                shape, dtype, n_pages = tuple(series.shape), np.dtype(series.dtype), len(tif.pages)
            if n_pages > 1 or len(shape) != 2:
                raise SchemaError(
                    f"image {path.name}", f"a TIFF of shape {shape} ({n_pages} pages)",
                    "one 2-d frame per file", "save one frame per file",
                )
            return shape, dtype
    except SchemaError:
        raise
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(
            f"image {path.name}", f"unreadable ({type(exc).__name__}: {exc})", expected,
            "the file is corrupt or of another type; export it again",
        ) from exc
    raise SchemaError(
        f"image {path.name}", f"suffix {path.suffix!r}", f"one of {IMAGE_SUFFIXES}", fix
    )


def read_image(path, *, bit_depth: int | None = None) -> np.ndarray:
    """Read one frame from a PNG (Pillow) or TIFF (tifffile) file as a 2-d uint8/uint16 array.

    Parameters
    ----------
    path : str or path-like
        Image file; 16-bit PNGs (Pillow mode ``I;16``) and 16-bit TIFFs give uint16.
    bit_depth : int, optional
        When given, every DN must be below ``2**bit_depth``.

    Returns
    -------
    numpy.ndarray, shape (y, x)
        The frame in DN, indexed ``frame[y, x]`` (y = row, x = column).

    Examples
    --------
    >>> import numpy as np, tempfile, pathlib, tifffile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "f.tif"
    >>> tifffile.imwrite(path, np.full((2, 3), 1023, np.uint16))
    >>> read_image(path, bit_depth=10).max()
    np.uint16(1023)
    """
    path = Path(path)
    _, dtype = _image_header(path)
    if dtype not in (np.dtype(np.uint8), np.dtype(np.uint16)):
        raise SchemaError(
            f"image {path.name}", f"pixel type {dtype}", "uint8 or uint16 digital numbers",
            "export raw DN as 8- or 16-bit unsigned integers; float or 32-bit images are not "
            "raw frames",
        )
    try:
        if path.suffix.lower() == ".png":
            from PIL import Image

            with Image.open(path) as im:
                frame = np.asarray(im)
        else:
            import tifffile

            frame = tifffile.imread(path)
    except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the file
        raise SchemaError(
            f"image {path}", f"unreadable pixel data ({type(exc).__name__}: {exc})",
            "a complete single-channel PNG or TIFF image",
            "the file is truncated or corrupt (an interrupted copy or write); copy or export "
            "it again",
        ) from exc
    frame = np.ascontiguousarray(frame, dtype=dtype.newbyteorder("="))
    if bit_depth is not None and frame.size and int(frame.max()) >= 2**bit_depth:
        shift = 16 - bit_depth if dtype.itemsize == 2 else 8 - bit_depth
        raise SchemaError(
            f"image {path.name}", f"maximum {int(frame.max())} DN",
            f"< 2**{bit_depth} = {2**bit_depth} DN for bit_depth={bit_depth}",
            "give the true bit_depth (or None to detect it); if the camera left-aligns its data "
            f"in the word (values in steps of {2**max(shift, 0)}), divide by that step first",
        )
    return frame


def _read_checked(path: Path, shape, dtype, bit_depth):
    frame = read_image(path, bit_depth=bit_depth)
    if frame.shape != shape or frame.dtype != dtype:
        raise SchemaError(
            f"image {path.name}", f"shape {frame.shape}, {frame.dtype}", f"shape {shape}, {dtype}",
            "every frame of a cube has the same size and pixel type",
        )
    return frame


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
    try:
        table = pd.read_csv(path, dtype={"file": str}, skipinitialspace=True, comment="#")
    except pd.errors.EmptyDataError as exc:
        raise SchemaError(
            f"manifest {path.name}", "an empty file",
            "a header line file,alpha,beta,shot and one row per image",
            "write the manifest rows",
        ) from exc
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise SchemaError(
            f"manifest {path.name}", f"unparsable CSV ({exc})", "comma-separated values",
            "fix the CSV syntax (same number of fields on every line)",
        ) from exc
    table.columns = [str(c).strip() for c in table.columns]
    return table, path.name


def _line(i: int) -> int:
    """CSV line number of table row i (line 1 is the header)."""
    return int(i) + 2


def from_image_folder(
    folder,
    manifest=None,
    *,
    bit_depth: int | None = None,
    lazy: bool = True,
    **frames_kwargs,
) -> xr.Dataset:
    """Build a frame cube from a folder of PNG or TIFF frames and a manifest CSV.

    Parameters
    ----------
    folder : str or path-like
        Folder holding the images (8-bit, or 16-bit for deeper ADCs; single channel).
    manifest : str, path-like or pandas.DataFrame, optional
        The manifest, one row per image; default ``folder/manifest.csv``. A relative path is
        looked up relative to ``folder``. Required columns:

        ``file``
            image file name, relative to ``folder``;
        ``alpha``, ``beta``
            commanded platform angles, degrees;
        ``shot``
            integer shot label within the pose (e.g. 0 .. 7).

        Poses are the unique (alpha, beta) pairs in manifest order; every pose must have the same
        set of shot labels, ordered by value. Any other column becomes a coordinate on
        (pose, shot) (``time`` is parsed as a date-time; numeric columns stay numeric, others
        are text). Lines starting with ``#`` are comments.
    bit_depth : int, optional
        ADC bit depth. Default: 8 for 8-bit images; for 16-bit images the smallest of 8, 10,
        12, 14, 16 bits that holds the largest DN in the folder (this reads every image once;
        give it for dark or dim frames, whose maximum says little about the ADC).
    lazy : bool
        Read each image only when its frame is computed (``dask.delayed`` per image, one chunk
        per frame); headers are still checked at once. False reads everything now.
    **frames_kwargs
        Passed to :func:`sunlab.schema.frames_dataset` (``pixel_pitch_mm``,
        ``mask_distance_mm``, ``x_cf_px``, ``y_cf_px``, ``mask``, ``experiment``, ``attrs``).

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
    import pandas as pd

    folder = Path(folder)
    if not folder.is_dir():
        raise SchemaError(
            "folder", str(folder), "an existing folder of images",
            "check the path (it is relative to the current directory unless absolute)",
        )
    table, mname = _manifest_table(folder, manifest)
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
    if np.any(numeric["shot"] != np.round(numeric["shot"])):
        i = int(np.flatnonzero(numeric["shot"] != np.round(numeric["shot"]))[0])
        raise SchemaError(
            f"manifest {mname} line {_line(i)} column 'shot'", table["shot"].iloc[i],
            "an integer shot label", "number the frames of each pose 0, 1, 2, ...",
        )
    alpha, beta, shot = numeric["alpha"], numeric["beta"], numeric["shot"].astype(np.int64)

    files = table["file"].astype(str).str.strip()
    paths = [folder / f for f in files]
    missing = [i for i, p in enumerate(paths) if not p.is_file()]
    if missing:
        i = missing[0]
        raise SchemaError(
            f"manifest {mname} line {_line(i)} column 'file'", files.iloc[i],
            f"an image file in {folder}",
            f"{len(missing)} listed file(s) do not exist; copy them into the folder or remove "
            "their rows",
        )

    # Poses: unique (alpha, beta) in manifest order; shots: labels sorted by value.
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
    order[pose, shot_index] = np.arange(len(table))

    # Image headers: one size and one pixel type for the whole cube.
    headers = [_image_header(p) for p in paths]
    shape, dtype = headers[int(order[0, 0])]
    for i, (shp, dt) in enumerate(headers):
        if dt not in (np.dtype(np.uint8), np.dtype(np.uint16)):
            raise SchemaError(
                f"image {paths[i].name}", f"pixel type {dt}", "uint8 or uint16 digital numbers",
                "export raw DN as 8- or 16-bit unsigned integers; float or 32-bit images are "
                "not raw frames",
            )
        if shp != shape or dt != dtype:
            raise SchemaError(
                f"image {paths[i].name} (manifest line {_line(i)})", f"shape {shp}, {dt}",
                f"shape {shape}, {dtype} like {paths[int(order[0, 0])].name}",
                "every frame of a cube has the same size and pixel type; remove or re-export "
                "the odd image",
            )
    if bit_depth is not None:
        if int(bit_depth) != bit_depth or not 1 <= bit_depth <= 8 * dtype.itemsize:
            raise SchemaError(
                "bit_depth", bit_depth, f"an integer 1 .. {8 * dtype.itemsize} for {dtype} images",
                "give the ADC bit depth (Ibis4: 10)",
            )
        bit_depth = int(bit_depth)

    if lazy:
        import dask
        import dask.array as da

        read = dask.delayed(_read_checked, pure=True)
        frames = da.stack(
            [
                da.stack(
                    [
                        da.from_delayed(
                            read(paths[order[p, s]], shape, dtype, bit_depth), shape, dtype
                        )
                        for s in range(n_shot)
                    ]
                )
                for p in range(n_pose)
            ]
        )
    else:
        frames = np.empty((n_pose, n_shot, *shape), dtype)
        for p in range(n_pose):
            for s in range(n_shot):
                frames[p, s] = _read_checked(paths[order[p, s]], shape, dtype, bit_depth)
    if bit_depth is None:
        if dtype == np.uint8:
            bit_depth = 8
        else:
            peak = int(frames.max()) if frames.size else 0
            bit_depth = next(b for b in (8, 10, 12, 14, 16) if peak < 2**b)

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
    user_coords = dict(frames_kwargs.pop("coords", None) or {})
    attrs = {"source": str(folder.resolve()), **dict(frames_kwargs.pop("attrs", None) or {})}
    return frames_dataset(
        frames,
        alpha=[a for a, _ in pose_of_pair],
        beta=[b for _, b in pose_of_pair],
        bit_depth=bit_depth,
        coords={**coords, **user_coords},
        attrs=attrs,
        **frames_kwargs,
    )


def example_folder(name: str = "train") -> Path:
    """A small recording shipped with sunlab: a folder of 16-bit PNG frames, as a lab's own.

    ``"train"``: a 5 x 5 grid of poses (alpha -10..-6 deg, beta 5..9 deg, 1-degree steps),
    ``"test"``: the 4 x 4 grid between them; 2 shots per pose, frames of the virtual bench's
    one-hole sensor cropped to the region the spot crosses. Each folder holds ``manifest.csv``
    (file, alpha, beta, shot) and ``sensor.json`` (pixel pitch, mask distance, design centre,
    bit depth), so ``sunlab import FOLDER --out cube.zarr`` needs no other option.

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


# --------------------------------------------------------------------------------------------
# Summary
# --------------------------------------------------------------------------------------------
def _nbytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} TB"  # pragma: no cover


def _range(values, unit: str) -> str:
    values = np.asarray(values, dtype=float)
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return "no finite values"
    n_unique = np.unique(finite).size
    return f"{finite.min():g} .. {finite.max():g} {unit} ({n_unique} distinct)"


def _coord_lines(ds: xr.Dataset, skip) -> list[str]:
    lines = []
    for name in ds.coords:
        if name in skip:
            continue
        var = ds.coords[name]
        lines.append(f"  {name}: dims {tuple(map(str, var.dims))}, {var.dtype}")
    return lines


def summary(ds: xr.Dataset) -> str:
    """A human-readable summary of a frame cube or a centroid table.

    Frame cubes: contract, dims, pose grid ranges, shots, dtype and bit depth, chunking, size,
    sensor attributes and extra coordinates. Centroid tables: dims, method, status counts and
    the centroid ranges. A Zarr store opened with ``check_chunks=False`` that lacks chunk files
    (an acquisition in progress, an interrupted copy) gets an ``INCOMPLETE`` line per array.
    Only coordinates are read; the frames stay lazy.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> cen = schema.centroids_dataset([[1.0, np.nan], [3.0, 4.0]], [[2.0, np.nan], [5.0, 6.0]])
    >>> print(summary(cen).splitlines()[0])
    sunlab centroid table (centroids/1)
    >>> "no_spot 1 (25.0 %)" in summary(cen)
    True
    """
    contract = ds.attrs.get("sunlab_schema")
    source = ds.encoding.get("source")
    dims = ", ".join(f"{k}={v}" for k, v in ds.sizes.items())
    storage = []
    if ds.encoding.get("sunlab_format") == "zarr" and source:
        for name, (n_missing, total, examples) in _chunk_report(Path(source)).items():
            storage.append(
                f"  INCOMPLETE: {name}: {n_missing} of {total} chunk files missing (they read "
                f"as 0 or NaN){', e.g. ' + examples[0] if examples else ''}"
            )
    if contract == FRAMES_SCHEMA:
        frames = ds["frames"]
        lines = [f"sunlab frame cube ({contract})"]
        if source:
            lines.append(f"  source: {source}")
        lines.extend(storage)
        lines.append(f"  dims: {dims}")
        chunks = getattr(frames.data, "chunksize", None)
        lines.append(
            f"  frames: {frames.dtype} DN, {ds.attrs.get('bit_depth')}-bit ADC, "
            f"{_nbytes(frames.nbytes)}"
            + (f", chunks {tuple(int(c) for c in chunks)} (lazy)" if chunks else " (in memory)")
        )
        n_pose = ds.sizes["pose"]
        lines.append(f"  poses: {n_pose}, shots per pose: {ds.sizes['shot']}")
        if n_pose:
            lines.append(f"  alpha: {_range(ds['alpha'].values, 'deg')}")
            lines.append(f"  beta:  {_range(ds['beta'].values, 'deg')}")
        a = ds.attrs
        lines.append(
            f"  sensor: pixel pitch {a.get('pixel_pitch_mm')} mm, mask distance F "
            f"{a.get('mask_distance_mm')} mm, x_cf {a.get('x_cf_px')} px, "
            f"y_cf {a.get('y_cf_px')} px"
        )
        lines.append(f"  mask: {a.get('mask')!r}, experiment: {a.get('experiment')!r}")
        extra = _coord_lines(ds, skip=("pose", "shot", "alpha", "beta"))
        if extra:
            lines.append("  coordinates:")
            lines.extend("  " + line for line in extra)
        others = [n for n in ds.data_vars if n != "frames"]
        if others:
            lines.append(f"  other variables: {', '.join(map(str, others))}")
        return "\n".join(lines)
    if contract == CENTROIDS_SCHEMA:
        lines = [f"sunlab centroid table ({contract})"]
        if source:
            lines.append(f"  source: {source}")
        lines.extend(storage)
        lines.append(f"  dims: {dims}")
        lines.append(f"  method: {ds.attrs.get('method') or '(not recorded)'}")
        status = np.asarray(ds["status"].values).ravel()
        total = status.size
        counts = [
            f"{name} {int(np.sum(status == code))} ({100 * np.mean(status == code):.1f} %)"
            for name, code in STATUS.items()
            if np.any(status == code)
        ]
        lines.append(f"  status ({total} spots): " + (", ".join(counts) or "none"))
        lines.append(f"  x: {_range(ds['x'].values, 'px')}")
        lines.append(f"  y: {_range(ds['y'].values, 'px')}")
        if "alpha" in ds.coords and ds.sizes["pose"]:
            lines.append(f"  alpha: {_range(ds['alpha'].values, 'deg')}")
            lines.append(f"  beta:  {_range(ds['beta'].values, 'deg')}")
        others = [
            n for n in ds.data_vars
            if n not in ("x", "y", "flux", "status", "x0", "x1", "y0", "y1")
        ]
        if others:
            lines.append(f"  other variables: {', '.join(map(str, others))}")
        return "\n".join(lines)
    raise SchemaError(
        "attrs['sunlab_schema']", contract, f"{FRAMES_SCHEMA!r} or {CENTROIDS_SCHEMA!r}",
        "open the file with sunlab.io.open_dataset",
    )
