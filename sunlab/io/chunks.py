"""Checked chunks: every chunk read from (or written to) a store names itself when it fails.

A frame chunk whose DN reach ``2**bit_depth``, a chunk that fails its checksum or cannot be
decoded, and a Zarr chunk file that is missing each raise an error that names the store, the
variable, the chunk index and (for Zarr) its file, with the fix.
"""

from __future__ import annotations

import contextlib
import itertools
from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import SchemaError, SunlabError

__all__: list[str] = []


def _chunk_label(dims, index) -> str:
    return ", ".join(f"{d} {i}" for d, i in zip(dims, index, strict=True))


def _chunk_file(arr, path: Path, index) -> str:
    """The file of chunk ``index`` of a Zarr array (``path/c/1/0/0/0``)."""
    return str(path / arr.metadata.chunk_key_encoding.encode_chunk_key(tuple(index)))


def _check_dn_block(block, bits, where, dims, block_info=None):
    if block.size and int(block.max()) >= 2**bits:
        loc = (block_info or {}).get(0, {}).get("chunk-location") or ()
        raise SchemaError(
            f"{where} frames chunk ({_chunk_label(dims, loc) if loc else '?'})",
            f"DN up to {int(block.max())}", f"< 2**{bits} = {2**bits} DN for "
            f"attrs['bit_depth'] = {bits}", "set the true ADC bit depth (frames_dataset("
            "bit_depth=...)); if the camera left-aligns its data in the 16-bit word, divide the "
            "frames by 2**(16 - bit_depth) first")
    return block


def _checked_dn(data, bits, where: str):
    """A Dask array (``data`` itself if not Dask) whose chunks fail if DN >= 2**bits."""
    if not hasattr(data, "map_blocks") or data.dtype.kind != "u" or \
            int(bits) >= 8 * data.dtype.itemsize:
        return data
    return data.map_blocks(_check_dn_block, int(bits), where, ("pose", "shot", "y", "x"),
                           dtype=data.dtype, meta=np.empty((0,) * data.ndim, data.dtype))


class _ChunkReader:
    """Array-like over one lazily opened variable that names its chunk when a read fails.

    Dask reads the stored chunks through it, one ``__getitem__`` per chunk; a checksum mismatch,
    or a decompression error becomes a :class:`SunlabError` naming the store, the variable, the
    chunk index and its file (DN above the bit depth: :func:`_checked_dn`, on the frames).
    """

    def __init__(self, var: xr.Variable, path: Path, name: str, fmt: str, chunks):
        self.var, self.path, self.name, self.fmt, self.chunks = var, path, name, fmt, chunks
        self.shape, self.ndim = var.shape, var.ndim
        self.dtype = var.dtype if var.dtype.kind in "OSUT" else var.dtype.newbyteorder("=")

    def __getitem__(self, key):
        key = key if isinstance(key, tuple) else (key,)
        index = tuple((k.start or 0 if isinstance(k, slice) else int(k)) // max(size, 1)
                      for k, size in zip(key, self.chunks, strict=False))
        try:
            block = np.asarray(self.var[key].values, dtype=self.dtype)
        except Exception as exc:  # noqa: BLE001 - any decoder failure is reported with the chunk
            raise self._error(index, exc) from exc
        return block

    def _error(self, index, exc: Exception) -> SunlabError:
        where = f"{self.path} (HDF5 variable {self.name!r})"
        if self.fmt == "zarr":
            try:
                import zarr

                arr = zarr.open_array(str(self.path / self.name), mode="r")
                where = _chunk_file(arr, self.path / self.name, index)
            except Exception:  # noqa: BLE001 - the file name is a courtesy; the index is enough
                where = f"{self.path / self.name} chunk {index}"
        text = str(exc)
        what = ("fails its checksum (the data were changed after writing)"
                if "checksum" in text.lower() or "fletcher" in text.lower()
                else f"cannot be decoded ({type(exc).__name__}: {text})")
        return SunlabError(
            f"{where}: chunk ({_chunk_label(self.var.dims, index)}) of variable {self.name!r} "
            f"in {self.path} {what}. Fix: the store is damaged (disk error, interrupted or "
            "edited copy): copy it again from its source or re-create it; sunlab will not read "
            "corrupt data")


def _stored_chunks(var: xr.Variable) -> tuple[int, ...]:
    """The chunks on disk (xarray's backends say them; a contiguous variable is one chunk)."""
    pref = var.encoding.get("preferred_chunks") or {}
    return tuple(int(pref.get(d, n)) for d, n in zip(var.dims, var.shape, strict=True))


def _checked_lazy(ds: xr.Dataset, path: Path, fmt: str) -> xr.Dataset:
    """Dask-back every non-index variable of a lazily opened dataset through a _ChunkReader."""
    import dask.array as da
    from dask.base import tokenize

    stamp = path.stat().st_mtime_ns
    bits = ds.attrs.get("bit_depth")
    bits = int(bits) if isinstance(bits, int | np.integer) and not isinstance(bits, bool) \
        else None
    new = {}
    for name, var in ds.variables.items():
        if name in ds.indexes or var.ndim == 0:
            continue
        chunks = _stored_chunks(var)
        # the backend's lazily indexed array
        reader = _ChunkReader(xr.Variable(var.dims, var._data), path, str(name), fmt, chunks)
        data = da.from_array(reader, chunks=chunks, asarray=False, fancy=False,
                             name=f"sunlab-open-{name}-{tokenize(str(path), stamp, name, chunks)}",
                             meta=np.empty((0,) * var.ndim, reader.dtype))
        checked = name == "frames" and bits is not None and var.dims == ("pose", "shot", "y", "x")
        new[name] = var.copy(deep=False, data=_checked_dn(data, bits, str(path)) if checked
                             else data)
    coords = {n: v for n, v in new.items() if n in ds.coords}
    return ds.assign_coords(coords).assign({n: v for n, v in new.items() if n not in coords})


def _chunk_report(path: Path) -> dict[str, tuple[int, int, list[str]]]:
    """Arrays of a Zarr store with missing chunk files: name -> (missing, total, examples)."""
    import zarr

    report = {}
    for name, arr in zarr.open_group(str(path), mode="r").arrays():
        n_missing = arr.nchunks - arr.nchunks_initialized
        if n_missing > 0:
            examples = []
            with contextlib.suppress(AttributeError):  # zarr v2 metadata: no example paths
                files = (_chunk_file(arr, path / name, i) for i in np.ndindex(*arr.cdata_shape))
                examples = list(itertools.islice((f for f in files if not Path(f).exists()), 3))
            report[name] = (n_missing, arr.nchunks, examples)
    return report


def _check_chunks(ds: xr.Dataset, path: Path) -> None:
    """Every chunk of a sunlab Zarr store exists (missing chunks would read as silent zeros)."""
    for name, (n_missing, total, examples) in _chunk_report(path).items():
        raise SchemaError(
            f"{name} chunks", f"{n_missing} of {total} chunk files missing"
            + (f", e.g. {', '.join(examples)}" if examples else ""),
            "every chunk of the store on disk",
            "the store is incomplete (an interrupted copy, write or acquisition, or deleted "
            "files): copy it again from its source, re-create it, or finish the acquisition; "
            "to read it anyway, with missing frames as 0 DN, pass check_chunks=False")
