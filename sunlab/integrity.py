"""Checksums of what the artifacts sunlab writes mean, verified when sunlab reads them back.

The bytes of the data carry the checksums their formats write: Zarr's CRC-32C codec on every
chunk, HDF5's Fletcher-32 filter on every NetCDF frame chunk (:mod:`sunlab.io.write`). Neither
covers what the data mean: a one-character edit of a Zarr array's ``zarr.json`` (a shape, an
endianness) or a flipped bit in a NetCDF centroid table (whose small variables carry no chunk
checksum, nor do any attributes) still reads as a well-formed dataset. So every artifact also
carries a SHA-256 digest of what it means, written last and checked first:

* a Zarr store: every ``zarr.json`` of the store (the root group's attributes without the digest
  itself, each array's shape, data type, chunk grid and codecs), in the root attribute
  :data:`ATTR` (:func:`seal_zarr`, :func:`verify_zarr`);
* a NetCDF4 file: every variable's name, dimensions, shape, data type, attributes and values
  (all but the frames, whose chunks carry Fletcher-32), in the global attribute :data:`ATTR`
  (:func:`seal_netcdf`, :func:`verify_netcdf`);
* a JSON document (calibration): its canonical JSON text without the key :data:`ATTR`
  (:func:`seal_document`, :func:`verify_document`), kept under that key.

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


def _plain(obj):
    """A JSON-able form of attribute values (numpy scalars and arrays, bytes)."""
    if hasattr(obj, "tolist"):
        return obj.tolist()
    if isinstance(obj, bytes):
        return obj.decode("latin-1")
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


def _canonical(obj) -> bytes:
    """One byte string per value: sorted keys, no blanks, ASCII (NaN as NaN)."""
    return json.dumps(obj, sort_keys=True, separators=(",", ":"), ensure_ascii=True,
                      default=_plain).encode("ascii")


def _without(mapping: dict) -> dict:
    return {k: v for k, v in mapping.items() if k != ATTR}


def _check(stamp, found: str, source) -> None:
    """Compare ``found`` with the digest held in ``stamp`` (a dict or its JSON text; None:
    no digest, nothing to check)."""
    if stamp is None:
        return
    if isinstance(stamp, str | bytes):
        try:
            stamp = loads(stamp, source)
        except SunlabError:
            stamp = None
    if (not isinstance(stamp, dict) or stamp.get("algorithm") != "sha256"
            or not isinstance(stamp.get("digest"), str)):
        raise IntegrityError(
            f"{source}: unreadable {ATTR} attribute (expected sha256 and a digest). Fix: {_FIX}")
    if found != stamp["digest"]:
        raise IntegrityError(f"{source}: checksum mismatch ({ATTR} {stamp['digest'][:12]}..., "
                             f"content {found[:12]}...). Fix: {_FIX}")


def _stamp(digest: str) -> dict:
    return {"algorithm": "sha256", "digest": digest}


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
    return hashlib.sha256(_canonical(_without(doc))).hexdigest()


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
    return {**_without(doc), ATTR: _stamp(document_digest(doc))}


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
    _check(doc[ATTR], document_digest(doc), source)
    return _without(doc)


def check_depth(doc, source, fix: str = "give a document written by sunlab",
                what: str = "") -> None:
    """Refuse a parsed JSON document nested deeper than :data:`MAX_JSON_DEPTH` levels (before
    a recursive reader, such as a JSON Schema validator, meets it), or holding an integer no
    double can hold (more than 1023 bits: ``float()`` of it raises deep inside a reader),
    naming ``source``.

    Parameters
    ----------
    doc : object
        A parsed JSON document (dicts, lists, numbers, strings).
    source : str or path-like
        Where it was read from, for the messages.
    fix, what : str
        How to mend it, and what it should be (``", expected a sensor.json"``), for the message.

    Raises
    ------
    SunlabError
        Nested too deep, or an integer too large, naming ``source``.
    """
    stack = [(doc, "", 1)]
    while stack:
        obj, where, level = stack.pop()
        if isinstance(obj, dict | list) and level > MAX_JSON_DEPTH:
            raise SunlabError(f"{source}: JSON nested more than {MAX_JSON_DEPTH} levels deep"
                              f"{what}. Fix: {fix}")
        if isinstance(obj, dict):
            stack.extend((v, f"{where}.{k}" if where else str(k), level + 1)
                         for k, v in obj.items())
        elif isinstance(obj, list):
            stack.extend((v, f"{where}[{i}]", level + 1) for i, v in enumerate(obj))
        elif isinstance(obj, int) and not isinstance(obj, bool) and obj.bit_length() > 1023:
            raise SunlabError(
                f"{source}: {where or 'value'}: found an integer of {len(str(abs(obj)))} "
                f"digits, expected a number a double can hold (below 1.8e308). Fix: {fix}")


def read_json(path, *, max_bytes: int, what: str = "a JSON document", fix: str = ""):
    """Read a JSON file with a size limit and a nesting-depth limit (:func:`check_depth`).

    Parameters
    ----------
    path : path-like
        The file.
    max_bytes : int
        Largest file accepted, bytes (checked before it is read).
    what, fix : str
        What the file should be and how to mend it, for the messages.

    Returns
    -------
    object
        The parsed document (a dict for every file sunlab writes); a :class:`SunlabError`
        names the file if missing, a folder, too large, not UTF-8, not JSON, or too deep.
    """
    path = Path(path)
    fix = fix or f"give {what}"
    try:
        if path.exists() and not path.is_file():  # a folder, a FIFO, a device
            raise SunlabError(f"{path}: not a regular file, expected {what}. Fix: {fix}")
        with open(path, "rb") as fh:
            raw = fh.read(max_bytes + 1)  # a file that grows while read (a device) stops too
    except FileNotFoundError:
        raise SunlabError(f"{path}: no such file. Fix: check the path") from None
    except OSError as err:
        raise SunlabError(f"{path}: cannot be read ({err.strerror or err}). Fix: check the "
                          "file and its permissions") from None
    if len(raw) > max_bytes:
        raise SunlabError(f"{path}: more than the {max_bytes} bytes of {what}. Fix: {fix}")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise SunlabError(f"{path}: not UTF-8 text ({err.reason} at byte {err.start}), "
                          f"expected {what}. Fix: {fix}") from None
    return loads(text, path, what=what, fix=fix)


def loads(text, source, *, what: str = "a JSON document", fix: str = "", or_text: bool = False):
    """Parse JSON text: sunlab's one JSON reading path (files, a store's metadata and
    attributes, a command-line option's value), with the depth limit of :func:`check_depth`.

    Parameters
    ----------
    text, source : str
        The JSON text, and where it came from (a file, an option) for the messages.
    what, fix : str
        What it should be and how to mend it, for the messages.
    or_text : bool
        Return ``text`` itself when it is not JSON at all (an option's plain string value).

    Returns
    -------
    object
        The parsed document; a :class:`SunlabError` names ``source`` if the text is not JSON,
        nests deeper than :data:`MAX_JSON_DEPTH` levels or holds an integer no double holds.

    Examples
    --------
    >>> loads('{"a": [1, 2]}', "x")
    {'a': [1, 2]}
    >>> try:
    ...     loads("[" * 5000 + "]" * 5000, "--option roi")
    ... except SunlabError as err:
    ...     print(str(err)[:30])
    --option roi: JSON nested more
    """
    fix = fix or f"give {what}"
    try:
        doc = json.loads(text)
    except RecursionError:
        raise SunlabError(f"{source}: JSON nested more than {MAX_JSON_DEPTH} levels deep, "
                          f"expected {what}. Fix: {fix}") from None
    except ValueError as err:
        if or_text:
            return text
        raise SunlabError(f"{source}: invalid JSON ({err}), expected {what}. Fix: {fix}") from None
    check_depth(doc, source, fix, f", expected {what}")
    return doc


# -- Zarr stores --------------------------------------------------------------------------------
def _zarr_documents(root: Path) -> list[tuple[str, dict]]:
    """(relative name, parsed zarr.json) of the root group and its arrays, in name order."""
    docs = []
    for name in [""] + sorted(e.name for e in os.scandir(root) if e.is_dir(follow_symlinks=False)
                              and (Path(e.path) / "zarr.json").is_file()):
        meta = root / name / "zarr.json"
        try:
            text = meta.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise IntegrityError(f"{meta}: corrupt Zarr metadata ({type(err).__name__}: {err})."
                                 f" Fix: {_FIX}") from None
        docs.append((name, loads(text, f"{meta}: corrupt Zarr metadata", what="a zarr.json",
                                 fix=_FIX)))
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
            doc = {**doc, "attributes": _without(doc["attributes"])}
        h.update(name.encode("utf-8") + b"\0" + _canonical(doc) + b"\0")
    return h.hexdigest()


def _set_root_attr(path: Path, group, value) -> None:
    """Set (a dict) or remove (None) the digest in a store's root attributes, through ``group``
    when the caller holds it open (an open group writes its cached metadata back on its next
    change, undoing an edit of the file behind its back), else through the group opened here
    (Zarr replaces ``zarr.json`` atomically: a temporary file, then a rename)."""
    import zarr

    attrs = (zarr.open_group(path, mode="r+") if group is None else group).attrs
    if value is not None:
        attrs[ATTR] = value
    elif ATTR in attrs:
        del attrs[ATTR]


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
        The store's root group if the caller holds it open: the digest is written through it.

    Returns
    -------
    str
        The digest written (64 hexadecimal digits); ``""`` for a Zarr v2 store, left unsealed.
    """
    path = Path(path)
    if not (path / "zarr.json").is_file():
        return ""
    digest = zarr_digest(path)
    _set_root_attr(path, group, _stamp(digest))
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
    if group is not None or (Path(path) / "zarr.json").is_file():
        _set_root_attr(Path(path), group, None)


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
    attrs = _zarr_documents(path)[0][1].get("attributes")
    stamp = attrs.get(ATTR) if isinstance(attrs, dict) else None
    if stamp is not None:
        _check(stamp, zarr_digest(path), path)


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

    h = hashlib.sha256(_canonical({"sizes": {str(k): int(v) for k, v in ds.sizes.items()},
                                   "attrs": _without(ds.attrs)}))
    for name in sorted(map(str, ds.variables)):
        var = ds.variables[name]
        h.update(_canonical({"name": name, "dims": list(var.dims), "shape": list(var.shape),
                             "dtype": var.dtype.str, "attrs": dict(var.attrs)}))
        if name not in skip_data:
            values = np.asarray(var.values)
            h.update(_canonical([str(v) for v in values.ravel().tolist()])
                     if values.dtype.kind == "O" else np.ascontiguousarray(values).tobytes())
    return h.hexdigest()


def seal_netcdf(path) -> str:
    """Write the digest of a complete NetCDF4 file (:func:`netcdf_digest`) as its global
    attribute :data:`ATTR`.

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
    import xarray as xr

    with xr.open_dataset(path, engine="h5netcdf", chunks=None) as ds:
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
    if ds.attrs.get(ATTR) is not None:
        _check(ds.attrs[ATTR], netcdf_digest(ds), source)
