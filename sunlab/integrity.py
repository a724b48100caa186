"""Checksums of the artifacts sunlab writes, verified when sunlab reads them back.

Chunk checksums (CRC-32C in Zarr, Fletcher-32 in NetCDF frames) cover the bytes of the data, not
what the data mean: a one-character edit of a Zarr array's ``zarr.json`` (a shape, an
endianness) or a flipped bit in a NetCDF centroid table (whose small variables carry no chunk
checksum) still reads as a well-formed dataset. So every artifact also carries a SHA-256 digest
of what it means, written last and checked first:

* a Zarr store (frame cube, centroid table, acquisition run): the digest of every ``zarr.json``
  of the store (the root group's attributes without the digest itself, and each array's shape,
  data type, chunk grid and codecs), kept in the root attribute :data:`ATTR`
  (:func:`seal_zarr`, :func:`verify_zarr`). The chunks keep their own CRC-32C;
* a NetCDF4 file: the digest of every variable's name, dimensions, shape, data type, attributes
  and values (all but the frames, whose chunks carry Fletcher-32), kept in the global attribute
  :data:`ATTR` (:func:`netcdf_digest`, :func:`seal_netcdf`);
* a JSON document (calibration): the digest of its canonical JSON text without the key
  :data:`ATTR` (:func:`seal_document`, :func:`verify_document`), kept under that key.

A file without a digest (written by another tool or an older sunlab) is read as before; a file
whose digest does not match is refused with :class:`IntegrityError`, naming the file.
:func:`read_json` reads any JSON input with a size and a nesting-depth limit.

Examples
--------
>>> doc = seal_document({"kind": "polynomial", "parameters": {"order": 3}})
>>> verify_document(doc, "cal.json")["parameters"]
{'order': 3}
>>> doc["parameters"]["order"] = 4
>>> try:
...     verify_document(doc, "cal.json")
... except IntegrityError as err:
...     print(str(err)[:41])
cal.json: checksum mismatch (sunlab_integ
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .errors import SunlabError

__all__ = []

#: The attribute (or JSON key) that holds an artifact's digest.
ATTR = "sunlab_integrity"
#: Largest JSON document sunlab reads (bytes): a calibration is a few MB at most.
MAX_DOCUMENT_BYTES = 64 * 2**20
#: Deepest nesting of lists and objects :func:`read_json` accepts (sunlab's own documents
#: nest fewer than 8 levels).
MAX_JSON_DEPTH = 64

_FIX = ("restore this file from a backup or copy it again from its source (it was altered after "
        "sunlab wrote it: a disk or copy error, or an edit by hand), or re-create it with the "
        "sunlab command that wrote it")


class IntegrityError(SunlabError):
    """An artifact's content does not match the checksum sunlab wrote with it."""


def _mismatch(source, found: str, expected: str) -> IntegrityError:
    return IntegrityError(
        f"{source}: checksum mismatch ({ATTR} {expected[:12]}..., content {found[:12]}...). "
        f"Fix: {_FIX}"
    )


def _plain(obj):
    """A JSON-able form of attribute values (numpy scalars and arrays, bytes)."""
    import numpy as np

    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, bytes):
        return obj.decode("latin-1")
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _canonical(obj) -> bytes:
    """One byte string per value: sorted keys, no blanks, ASCII (NaN as NaN)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      default=_plain).encode("ascii")


def _stamp(digest: str) -> dict:
    return {"algorithm": "sha256", "digest": digest}


def _stamped(value, source) -> str | None:
    """The digest held in ``value`` (a dict, or its JSON text), or None when absent."""
    if value is None:
        return None
    if isinstance(value, str | bytes):
        try:
            value = json.loads(value)
        except ValueError:
            value = None
    if (not isinstance(value, dict) or value.get("algorithm") != "sha256"
            or not isinstance(value.get("digest"), str)):
        raise IntegrityError(
            f"{source}: unreadable {ATTR} attribute (expected sha256 and a digest). Fix: {_FIX}")
    return value["digest"]


# -- JSON documents -----------------------------------------------------------------------------
def document_digest(doc: dict) -> str:
    """SHA-256 (hex) of a JSON document's canonical text, without its :data:`ATTR` key.

    Parameters
    ----------
    doc : dict
        A JSON-able document (numpy scalars and arrays allowed).

    Returns
    -------
    str
        64 hexadecimal digits: SHA-256 of the document as JSON with sorted keys, no blanks,
        ASCII.
    """
    body = {k: v for k, v in doc.items() if k != ATTR}
    return hashlib.sha256(_canonical(body)).hexdigest()


def seal_document(doc: dict) -> dict:
    """A copy of ``doc`` with its digest under :data:`ATTR` (see :func:`verify_document`).

    Parameters
    ----------
    doc : dict
        A JSON-able document; a digest already under :data:`ATTR` is replaced.

    Returns
    -------
    dict
        A new dict: ``doc``'s keys and ``ATTR: {"algorithm": "sha256", "digest": ...}``.
    """
    return {**{k: v for k, v in doc.items() if k != ATTR}, ATTR: _stamp(document_digest(doc))}


def verify_document(doc, source) -> dict:
    """Check the digest of a document read from ``source``; return it without :data:`ATTR`.

    A document without the key is returned as it is (not written by this sunlab).

    Parameters
    ----------
    doc : dict
        A parsed JSON document.
    source : str or path-like
        Where it was read from, for the messages.

    Returns
    -------
    dict
        A copy of ``doc`` without :data:`ATTR` (``doc`` itself when it has no digest).

    Raises
    ------
    SunlabError
        The document nests deeper than :data:`MAX_JSON_DEPTH` levels.
    IntegrityError
        The digest does not match the content, naming ``source``.
    """
    check_depth(doc, source)
    if not isinstance(doc, dict) or ATTR not in doc:
        return doc
    expected = _stamped(doc[ATTR], source)
    found = document_digest(doc)
    if found != expected:
        raise _mismatch(source, found, expected)
    return {k: v for k, v in doc.items() if k != ATTR}


def check_depth(doc, source) -> None:
    """Refuse a parsed JSON document nested deeper than :data:`MAX_JSON_DEPTH` levels (before
    a recursive reader, such as a JSON Schema validator, meets it), naming ``source``.

    Also refuses an integer no double can hold (more than 1023 bits).

    Parameters
    ----------
    doc : object
        A parsed JSON document (dicts, lists, numbers, strings).
    source : str or path-like
        Where it was read from, for the messages.

    Raises
    ------
    SunlabError
        Nested too deep, or an integer too large, naming ``source``.
    """
    if _depth(doc) > MAX_JSON_DEPTH:
        raise SunlabError(f"{source}: JSON nested more than {MAX_JSON_DEPTH} levels deep. Fix: "
                          "give a document written by sunlab")
    _check_integers(doc, source, "give a document written by sunlab")


def _check_integers(doc, source, fix: str) -> None:
    """Refuse an integer no double can hold (JSON allows 4,300 digits): every number sunlab
    reads is a double in the end, and ``float()`` of such an integer raises OverflowError
    deep inside a reader."""
    stack = [(doc, "")]
    while stack:
        obj, where = stack.pop()
        if isinstance(obj, dict):
            stack.extend((v, f"{where}.{k}" if where else str(k)) for k, v in obj.items())
        elif isinstance(obj, list):
            stack.extend((v, f"{where}[{i}]") for i, v in enumerate(obj))
        elif isinstance(obj, int) and not isinstance(obj, bool) and obj.bit_length() > 1023:
            raise SunlabError(
                f"{source}: {where or 'value'}: found an integer of {len(str(abs(obj)))} "
                "digits, expected a number a double can hold (below 1.8e308). Fix: " + fix)


def _depth(doc) -> int:
    """Nesting depth of lists and objects, without recursion."""
    deepest, stack = 0, [(doc, 1)]
    while stack:
        obj, level = stack.pop()
        if isinstance(obj, dict | list):
            deepest = max(deepest, level)
            if deepest > MAX_JSON_DEPTH:
                return deepest
            stack.extend((v, level + 1) for v in (obj.values() if isinstance(obj, dict)
                                                  else obj))
    return deepest


def read_json(path, *, max_bytes: int, what: str = "a JSON document", fix: str = ""):
    """Read a JSON file with a size limit and a nesting-depth limit (:data:`MAX_JSON_DEPTH`).

    Parameters
    ----------
    path : path-like
        The file.
    max_bytes : int
        Largest file accepted, bytes (checked before it is read).
    what : str
        What the file should be, for the message.
    fix : str
        How to mend a bad file, for the message.

    Returns
    -------
    object
        The parsed document (a dict for every file sunlab writes).

    Raises
    ------
    SunlabError
        Naming the file: missing, a folder, too large, not UTF-8, not JSON, or nested too deep.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "deep.json"
    >>> _ = path.write_text("[" * 10000 + "]" * 10000)
    >>> try:
    ...     read_json(path, max_bytes=2**20)
    ... except SunlabError as err:
    ...     print("nested" in str(err))
    True
    """
    path = Path(path)
    fix = fix or f"give {what}"
    try:
        if path.exists() and not path.is_file():  # a folder, a FIFO, a device
            raise SunlabError(f"{path}: not a regular file, expected {what}. Fix: {fix}")
        size = path.stat().st_size
        if size > max_bytes:
            raise SunlabError(f"{path}: {size} bytes, more than the {max_bytes} bytes of "
                              f"{what}. Fix: {fix}")
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)
    except FileNotFoundError:
        raise SunlabError(f"{path}: no such file. Fix: check the path") from None
    except OSError as err:
        raise SunlabError(f"{path}: cannot be read ({err.strerror or err}). Fix: check the "
                          "file and its permissions") from None
    if len(raw) > max_bytes:  # grew while being read (a device or a pipe)
        raise SunlabError(f"{path}: more than the {max_bytes} bytes of {what}. Fix: {fix}")
    try:
        doc = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError as err:
        raise SunlabError(f"{path}: not UTF-8 text ({err.reason} at byte {err.start}), "
                          f"expected {what}. Fix: {fix}") from None
    except RecursionError:
        raise SunlabError(f"{path}: JSON nested more than {MAX_JSON_DEPTH} levels deep, "
                          f"expected {what}. Fix: {fix}") from None
    except ValueError as err:
        raise SunlabError(f"{path}: invalid JSON ({err}), expected {what}. Fix: {fix}") from None
    if _depth(doc) > MAX_JSON_DEPTH:
        raise SunlabError(f"{path}: JSON nested more than {MAX_JSON_DEPTH} levels deep, "
                          f"expected {what}. Fix: {fix}")
    _check_integers(doc, path, fix)
    return doc


# -- Zarr stores --------------------------------------------------------------------------------
def _zarr_documents(root: Path) -> list[tuple[str, dict]]:
    """(relative name, parsed zarr.json) of the root group and its arrays, in name order."""
    docs = []
    names = [""] + sorted(e.name for e in os.scandir(root) if e.is_dir(follow_symlinks=False)
                          and (Path(e.path) / "zarr.json").is_file())
    for name in names:
        meta = root / name / "zarr.json" if name else root / "zarr.json"
        try:
            docs.append((name, json.loads(meta.read_text(encoding="utf-8"))))
        except (OSError, UnicodeDecodeError, ValueError) as err:
            raise IntegrityError(
                f"{meta}: corrupt Zarr metadata ({type(err).__name__}: {err}). Fix: {_FIX}"
            ) from None
    return docs


def zarr_digest(path) -> str:
    """SHA-256 (hex) of a Zarr v3 store's metadata: every ``zarr.json`` of the root group and
    its arrays, the root's :data:`ATTR` attribute left out.

    Parameters
    ----------
    path : str or path-like
        The store's root folder.

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    h = hashlib.sha256()
    for name, doc in _zarr_documents(Path(path)):
        if not name and isinstance(doc.get("attributes"), dict):
            doc = {**doc, "attributes": {k: v for k, v in doc["attributes"].items()
                                         if k != ATTR}}
        h.update(name.encode("utf-8") + b"\0" + _canonical(doc) + b"\0")
    return h.hexdigest()


def _write_root(path: Path, doc: dict) -> None:
    """Replace the root zarr.json atomically (temporary sibling, fsync, rename)."""
    meta = path / "zarr.json"
    tmp = path / f".zarr.json.tmp-{os.getpid()}"
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(doc, fh, indent=2)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, meta)


def seal_zarr(path, group=None) -> str:
    """Write the digest of a Zarr v3 store's metadata into its root attributes; return it.

    Call it when the store is complete: any later change of its metadata (attributes
    included) makes :func:`verify_zarr` refuse it until it is sealed again. A Zarr v2 store
    (no ``zarr.json``) is left as it is.

    Parameters
    ----------
    path : path-like
        The store.
    group : zarr.Group, optional
        The store's root group if the caller holds it open: the digest is then written through
        it (an open group writes its whole cached metadata back on its next change, which
        would undo an edit of the file behind its back).

    Returns
    -------
    str
        The digest written (64 hexadecimal digits); ``""`` for a Zarr v2 store, left unsealed.
    """
    path = Path(path)
    if not (path / "zarr.json").is_file():
        return ""
    digest = zarr_digest(path)
    if group is not None:
        group.attrs[ATTR] = _stamp(digest)
        return digest
    doc = json.loads((path / "zarr.json").read_text(encoding="utf-8"))
    doc.setdefault("attributes", {})[ATTR] = _stamp(digest)
    _write_root(path, doc)
    return digest


def unseal_zarr(path, group=None) -> None:
    """Remove a store's digest before it is changed in place (an acquisition run resumed);
    ``group`` as in :func:`seal_zarr`.

    Parameters
    ----------
    path : str or path-like
        The store's root folder.
    group : zarr.Group, optional
        The store's root group, if the caller holds it open.
    """
    path = Path(path)
    if group is not None:
        if ATTR in group.attrs:
            del group.attrs[ATTR]
        return
    meta = path / "zarr.json"
    if not meta.is_file():
        return
    doc = json.loads(meta.read_text(encoding="utf-8"))
    if ATTR in doc.get("attributes", {}):
        del doc["attributes"][ATTR]
        _write_root(path, doc)


def verify_zarr(path) -> None:
    """Check a Zarr store's metadata against the digest in its root attributes.

    A store without a digest (another tool, an acquisition in progress) passes.

    Parameters
    ----------
    path : str or path-like
        The store's root folder.

    Raises
    ------
    IntegrityError
        The metadata (a shape, a data type, a codec, an attribute) differ from what was
        sealed, naming the store.
    """
    path = Path(path)
    if not (path / "zarr.json").is_file():
        return
    docs = _zarr_documents(path)
    attrs = docs[0][1].get("attributes")
    expected = _stamped(attrs.get(ATTR) if isinstance(attrs, dict) else None, path)
    if expected is None:
        return
    found = zarr_digest(path)
    if found != expected:
        raise _mismatch(path, found, expected)


# -- NetCDF files -------------------------------------------------------------------------------
def netcdf_digest(ds, skip_data=("frames",)) -> str:
    """SHA-256 (hex) of a dataset as opened from NetCDF: every variable's name, dimensions,
    shape, data type, attributes and values (except the values of ``skip_data``, whose chunks
    carry their own checksum), and the global attributes but :data:`ATTR`.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset as opened from the file (names, dims, dtypes and attributes as stored).
    skip_data : tuple of str
        Variables whose values are left out (their dims, shape, dtype and attributes count).

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    import numpy as np

    h = hashlib.sha256()
    h.update(_canonical({"sizes": {str(k): int(v) for k, v in ds.sizes.items()},
                         "attrs": {k: v for k, v in ds.attrs.items() if k != ATTR}}))
    for name in sorted(map(str, ds.variables)):
        var = ds.variables[name]
        h.update(_canonical({"name": name, "dims": list(var.dims), "shape": list(var.shape),
                             "dtype": var.dtype.str, "attrs": dict(var.attrs)}))
        if name in skip_data:
            continue
        values = np.asarray(var.values)
        if values.dtype.kind == "O":
            h.update(_canonical([str(v) for v in values.ravel().tolist()]))
        else:
            h.update(np.ascontiguousarray(values).tobytes())
    return h.hexdigest()


def _open_netcdf(path):
    import xarray as xr

    return xr.open_dataset(path, engine="h5netcdf", chunks=None)


def seal_netcdf(path) -> str:
    """Write the digest of a NetCDF4 file (:func:`netcdf_digest`) as its global attribute.

    Parameters
    ----------
    path : str or path-like
        A complete NetCDF4 file, opened for writing once its digest is computed.

    Returns
    -------
    str
        The digest written (64 hexadecimal digits).
    """
    import h5netcdf

    with _open_netcdf(path) as ds:
        digest = netcdf_digest(ds)
    with h5netcdf.File(path, "r+") as fh:
        fh.attrs[ATTR] = json.dumps(_stamp(digest))
    return digest


def verify_netcdf(ds, source) -> None:
    """Check a dataset opened from the NetCDF file ``source`` against its digest attribute.

    A dataset without the attribute (another tool, an older sunlab) passes.

    Parameters
    ----------
    ds : xarray.Dataset
        The dataset opened from the file.
    source : str or path-like
        The file, for the message.

    Raises
    ------
    IntegrityError
        A value, a shape or an attribute differs from what was written, naming the file.
    """
    expected = _stamped(ds.attrs.get(ATTR), source)
    if expected is None:
        return
    found = netcdf_digest(ds)
    if found != expected:
        raise _mismatch(source, found, expected)
