"""The ``calibration/1`` artifact read back: check a document, rebuild its calibration.

:func:`load` reads a JSON file written by :meth:`sunlab.calibration.Calibration.save`,
:func:`validate_document` checks it against the contract, and :func:`from_dict` rebuilds the
fitted calibration through the registry (:func:`sunlab.calibration.registry.available_kinds`: the
built-in methods and every kind of the entry point group ``sunlab.calibrations``, the
multi-hole strategies among them), after the class has checked its own parameters: sizes
before any array is built, finite numbers, sane ranges.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from .. import integrity
from ..errors import SchemaError
from ..schema import validate_calibration
from ._checks import _bad
from .registry import ENTRY_POINT_GROUP, available_kinds, method_class

if TYPE_CHECKING:
    from .base import Calibration

__all__ = ["load"]

#: Largest calibration file :func:`load` reads (bytes); the biggest real one is a few MB.
MAX_FILE_BYTES = 64 * 2**20


def validate_document(doc) -> dict:
    """Check a ``calibration/1`` document; return it unchanged.

    Checks the schema tag and the JSON Schema of ``data_schema/`` with
    :func:`sunlab.schema.validate_calibration`, then that the kind is one sunlab can load.

    Parameters
    ----------
    doc : dict
        The parsed document.

    Returns
    -------
    dict
        ``doc`` itself, unchanged, once every check has passed.

    Raises
    ------
    SchemaError
        Naming the field, the value found, what is expected and the fix.

    Examples
    --------
    >>> try:
    ...     validate_document({"sunlab_schema": "calibration/0", "kind": "polynomial"})
    ... except SchemaError as err:
    ...     print(err.field)
    sunlab_schema
    """
    if not isinstance(doc, dict):
        raise SchemaError("calibration document", type(doc).__name__, "a JSON object",
                          "pass a file written by Calibration.save")
    validate_calibration(doc)
    kind = doc.get("kind")
    registry = available_kinds()
    if kind not in registry:
        fix = (f"a multi-hole strategy registers as an entry point of {ENTRY_POINT_GROUP!r}; "
               "reinstall sunlab (pip install -e .) so that it is found"
               if str(kind).startswith("multihole-")
               else "the file is corrupt, from a newer sunlab, or of a plug-in that is not "
               f"installed (entry point group {ENTRY_POINT_GROUP!r}); re-fit the calibration "
               "or install the plug-in")
        raise SchemaError("kind", kind, f"one of {sorted(registry)}", fix)
    return doc


def from_dict(doc: dict) -> Calibration:
    """Rebuild a fitted calibration from its ``calibration/1`` document.

    Parameters
    ----------
    doc : dict
        The document (:meth:`Calibration.to_dict`, or a parsed JSON file), of any kind of
        :func:`sunlab.calibration.registry.available_kinds`.

    Returns
    -------
    Calibration
        A fitted instance of the kind's class, with the document's ``training``, ``domain`` and
        ``residuals``; it predicts as the calibration that wrote the document did.

    Examples
    --------
    >>> from sunlab import sim
    >>> from sunlab.calibration import Polynomial
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> cal = from_dict(Polynomial(order=1).fit(cen).to_dict())
    >>> cal.kind
    'polynomial'
    """
    validate_document(doc)
    if not isinstance(doc["parameters"], dict):
        raise _bad("", type(doc["parameters"]).__name__, "an object")
    cls = method_class(doc["kind"], frames=True)
    cls._check_parameters(doc["parameters"])
    try:
        obj = cls._from_parameters(doc["parameters"])
    except SchemaError:
        raise
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as err:
        raise SchemaError(
            f"parameters (kind {doc['kind']!r})", f"{type(err).__name__}: {err}",
            f"the parameters a {cls.__name__} writes", "the file is corrupt; re-fit it",
        ) from err
    obj.training = dict(doc["training"] or {})
    obj.domain = doc["domain"]
    obj.residuals = doc["residuals"]
    return obj


def load(path) -> Calibration:
    """Load a calibration written by :meth:`Calibration.save`: any kind of the registry, a
    multi-hole strategy included.

    Sizes are checked before any array is built (the file itself at most
    :data:`MAX_FILE_BYTES`; an order or a layer width must match its coefficient lists), and
    non-finite numbers or degenerate scalings (a zero range) are refused, naming the field.

    Parameters
    ----------
    path : str or path-like
        The JSON file.

    Returns
    -------
    Calibration
        The fitted calibration (:func:`from_dict`), returned once the file's checksum
        (:meth:`Calibration.save` writes one; a file without it is read as is) matches.

    Raises
    ------
    SchemaError
        If the file is not valid JSON, not ``calibration/1``, or its parameters are corrupt.

    Examples
    --------
    >>> import tempfile, os
    >>> from sunlab import sim
    >>> from sunlab.calibration import Polynomial
    >>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    >>> path = os.path.join(tempfile.mkdtemp(), "cal.json")
    >>> load(Polynomial(order=1).fit(cen).save(path)).label
    'polynomial(1)'
    """
    path = Path(path)
    try:
        size = path.stat().st_size
        if not path.is_file():  # a folder; a FIFO or a device would block or never end
            raise IsADirectoryError(f"{path} is not a regular file")
        if size > MAX_FILE_BYTES:
            raise SchemaError(
                str(path), f"{size} bytes", f"a calibration JSON file of at most "
                f"{MAX_FILE_BYTES} bytes", "this is not a calibration written by sunlab (or it "
                "is corrupt); re-fit the calibration with `sunlab calibrate`")
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError as err:
        raise SchemaError("path", str(path), "an existing calibration JSON file",
                          "check the path, or fit one with `sunlab calibrate`") from err
    except UnicodeDecodeError as err:
        raise SchemaError(str(path), f"not UTF-8 text ({err})", "a calibration/1 JSON document",
                          "the file is corrupt or not a calibration; re-fit it") from err
    except OSError as err:
        raise SchemaError("path", f"{path} ({type(err).__name__}: {err.strerror or err})",
                          "a readable calibration JSON file",
                          "check the path and its permissions") from err
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError) as err:  # and integers of more than 4300 digits
        raise SchemaError(
            str(path), f"invalid JSON ({err})", "a calibration/1 JSON document",
            "the file is corrupt or truncated; re-fit the calibration with `sunlab calibrate`",
        ) from err
    # a depth limit; the fields; the checksum Calibration.save wrote
    integrity.check_depth(doc, path)
    try:
        cal = from_dict(doc)
    except SchemaError as err:  # the file named too, not only its field
        err.args = (f"{path}: {err}",)
        raise
    integrity.verify_document(doc, path)
    return cal
