"""The ``calibration/1`` artifact read back: check a document, rebuild its calibration.

:func:`load` reads a JSON file written by :meth:`sunlab.calibration.Calibration.save`,
:func:`validate_document` checks it against the contract, and :func:`from_dict` rebuilds the
fitted calibration through the registry (:func:`sunlab.calibration.registry.available_kinds`: the
built-in methods and every kind of the entry point group ``sunlab.calibrations``, the
multi-hole strategies among them), after the class has checked its own parameters
(:func:`check_parameters` on the class's table of rules): sizes before any array is built,
finite numbers, sane ranges.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from .. import integrity
from ..errors import SchemaError
from ..schema import validate_calibration
from .registry import ENTRY_POINT_GROUP, available_kinds, method_class

if TYPE_CHECKING:
    from .base import Calibration

__all__ = ["load"]

#: Largest calibration file :func:`load` reads (bytes); the biggest real one is a few MB.
MAX_FILE_BYTES = 64 * 2**20
#: Rules of :func:`check_parameters`: a count (an integer >= 0), the first element of a rule
#: of positive numbers (``(POSITIVE, 2)``: two), a range of centroids ``[lo, hi]`` (px, hi > lo).
COUNT, POSITIVE, SPAN = range(2**63), "+", "span"
_REFIT = "the file is corrupt or edited by hand; re-fit the calibration with `sunlab calibrate`"


def _bad(field: str, found, expected: str, fix: str = _REFIT) -> SchemaError:
    return SchemaError(f"parameters.{field}", found, expected, fix)


def _numbers(v, field: str, shape: tuple, positive: bool) -> None:
    """Nested lists of finite numbers of ``shape`` (``()``: one number), checked without
    building an array; a JSON integer of 400 digits is no double (``float()`` overflows)."""
    if not shape:
        try:
            ok = not isinstance(v, bool) and math.isfinite(float(v)) and (v > 0 or not positive)
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise _bad(field, v, "a finite positive number" if positive else "a finite number")
    elif not isinstance(v, list) or len(v) != shape[0]:
        raise _bad(field, f"{len(v)} values" if isinstance(v, list) else type(v).__name__,
                   f"{shape[0]} values")
    else:
        for i, x in enumerate(v):
            _numbers(x, f"{field}[{i}]", shape[1:], positive)


def check_parameters(p: dict, rules: dict, prefix: str = "") -> None:
    """Check a document's parameters ``p`` against a class's table of ``rules`` (field ->
    rule), before any array is built; raise a :class:`~sunlab.errors.SchemaError` naming the
    first field at fault (``parameters.FIELD``) and the fix.

    Parameters
    ----------
    p : dict
        The parameters (or an object within them).
    rules : dict
        Per field: a dict (an object of exactly these fields: a layer more is refused, not left
        unused), a tuple of sizes (nested lists of finite numbers of that shape, ``()`` one
        number; positive ones after :data:`POSITIVE`), a ``range`` (an integer in it,
        :data:`COUNT`: any >= 0), ``bool`` (true or false), :data:`SPAN`, or None (not checked).
    prefix : str
        The path of ``p`` in the parameters (``"networks.alpha."``).

    Examples
    --------
    >>> check_parameters({"order": 3, "period": 0}, {"order": COUNT, "period": (POSITIVE,)})
    Traceback (most recent call last):
    ...
    sunlab.errors.SchemaError: parameters.period: found 0, expected a finite positive number. \
Fix: the file is corrupt or edited by hand; re-fit the calibration with `sunlab calibrate`
    """
    for key, rule in rules.items():
        field, v = prefix + key, p.get(key)
        if isinstance(rule, dict):
            if not isinstance(v, dict):
                raise _bad(field, type(v).__name__, f"an object of {sorted(rule)}")
            if extra := sorted(set(v) - set(rule)):
                raise _bad(f"{field}.{extra[0]}", "a field more", f"only {sorted(rule)}")
            check_parameters(v, rule, field + ".")
        elif isinstance(rule, range) and (isinstance(v, bool) or not isinstance(v, int)
                                          or v not in rule):
            raise _bad(field, v, f"an integer >= {rule.start}" if rule.stop > 2**62
                       else f"an integer from {rule.start} to {rule.stop - 1}")
        elif rule is bool and not isinstance(v, bool):
            raise _bad(field, v, "true or false")
        elif rule == SPAN:
            _numbers(v, field, (2,), False)
            if not v[1] > v[0]:
                raise _bad(field, v, "[lo, hi] with hi > lo (a range of centroids, px)",
                           "a zero or negative range divides by zero in predict; re-fit the "
                           "calibration on poses that move the spot along both axes")
        elif isinstance(rule, tuple):
            positive = rule[:1] == (POSITIVE,)
            _numbers(v, field, rule[positive:], positive)


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
