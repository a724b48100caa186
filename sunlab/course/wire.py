"""Data between a student's kernel and the grader: the grader sends inputs, the kernel sends back
outputs as data, never as objects the grader would run.

The grader (:meth:`sunlab.course.kernel.NotebookRun.call`) asks the kernel to call one of the
notebook's functions on the hidden check's fresh inputs (pickled by the grader: the kernel trusts
the grader, never the other way). :func:`serve` runs in the kernel: it calls the function
(:func:`answer`) and displays its return value :func:`encode`-d as JSON (numbers, strings, lists,
dicts, numpy arrays saved without pickle, pandas series as dicts, xarray objects as their
``to_dict``, a sunlab calibration as its ``calibration/1`` document); anything else is refused.
:func:`reply` rebuilds the value in the grader from that JSON alone (a calibration through
:func:`sunlab.calibration.artifact.from_dict`, which checks the document as it checks a file): a
student's kernel can make its answer say anything, but it cannot make the grader run code.

Examples
--------
>>> import numpy as np
>>> back = decode(encode({("alpha", "mu"): 1.5, "x": np.arange(3.0)}))
>>> back[("alpha", "mu")], back["x"].tolist()
(1.5, [0.0, 1.0, 2.0])
"""

from __future__ import annotations

import base64
import io
import json
import pickle
from pathlib import PurePath
from unittest import mock

import numpy as np

__all__: list[str] = []

#: the MIME type of the kernel's answer in its ``display_data``
MIME = "text/x-sunlab-result"
#: the largest answer the grader reads, bytes
MAX_BYTES = 64 * 1024 * 1024


def _nd(a) -> dict:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(a), allow_pickle=False)
    return {"__nd__": base64.b64encode(buf.getvalue()).decode()}


def _enc(obj, depth):
    if depth > 20:
        raise ValueError("nested too deep")
    if obj is None or isinstance(obj, bool | int | float | str):
        return obj
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return _nd(obj) if obj.dtype.kind in "biufc" else [_enc(v, depth + 1)
                                                         for v in obj.tolist()]
    if isinstance(obj, PurePath):
        return str(obj)
    if isinstance(obj, tuple | list):
        items = [_enc(v, depth + 1) for v in obj]
        return {"__tuple__": items} if isinstance(obj, tuple) else items
    mod = type(obj).__module__.split(".")[0]
    if mod == "xarray":
        return {"__xr__": type(obj).__name__, "d": _enc(obj.to_dict(data="array"), depth + 1)}
    if mod == "sunlab" and hasattr(obj, "to_dict"):  # a calibration: its calibration/1 document
        return {"__calibration__": obj.to_dict()}
    if isinstance(obj, dict) or mod == "pandas" and hasattr(obj, "items") and hasattr(obj, "index"):
        return {"__dict__": [[_enc(k, depth + 1), _enc(v, depth + 1)] for k, v in obj.items()]}
    raise TypeError(f"a {type(obj).__name__} is not data: the grader reads numbers, arrays, "
                    "tables and sunlab calibrations")


def encode(obj) -> str:
    """``obj`` as JSON text of data only (see the module's text); run in the kernel.

    Parameters
    ----------
    obj : object
        A value a student's function returned.

    Returns
    -------
    str
        JSON text.
    """
    return json.dumps(_enc(obj, 0))


def _dec(obj):
    if isinstance(obj, list):
        return [_dec(v) for v in obj]
    if not isinstance(obj, dict):
        return obj
    if "__nd__" in obj:
        return np.load(io.BytesIO(base64.b64decode(obj["__nd__"])), allow_pickle=False)
    if "__tuple__" in obj:
        return tuple(_dec(v) for v in obj["__tuple__"])
    if "__dict__" in obj:
        out = {}
        for k, v in obj["__dict__"]:
            k = _dec(k)
            out[tuple(k) if isinstance(k, list) else k] = _dec(v)
        return out
    if "__xr__" in obj:
        import xarray as xr

        d = _dec(obj["d"])
        return (xr.DataArray if obj["__xr__"] == "DataArray" else xr.Dataset).from_dict(d)
    if "__calibration__" in obj:
        from ..calibration.artifact import from_dict

        return from_dict(obj["__calibration__"])
    return {k: _dec(v) for k, v in obj.items()}


def decode(text: str):
    """The value of :func:`encode`'s JSON, rebuilt from data only; run in the grader.

    Parameters
    ----------
    text : str
        JSON text from the kernel.

    Returns
    -------
    object
    """
    if len(text) > MAX_BYTES:
        raise ValueError(f"an answer of {len(text)} bytes (at most {MAX_BYTES})")
    return _dec(json.loads(text))


def answer(ns: dict, name: str, args=(), kwargs=None, bind=None) -> str:
    """In the kernel: ``ns[name](*args, **kwargs)`` with the names ``bind`` of ``ns`` rebound
    for the call (``ns`` is put back as it was after it), as JSON text for :func:`reply`.

    Parameters
    ----------
    ns : dict
        The notebook's globals.
    name : str
        The function to call.
    args, kwargs, bind : tuple, dict, dict
        Its arguments, and the notebook's names rebound for the call.

    Returns
    -------
    str
        JSON of ``{"ok": value}``, ``{"missing": true}`` or ``{"raised": name, "message": ...}``.
    """
    try:
        with mock.patch.dict(ns, bind or {}):  # the notebook's globals as they were, after
            fn = ns.get(name)
            out = {"missing": True} if fn is None else {"ok": _enc(fn(*args, **(kwargs or {})),
                                                                   0)}
    except BaseException as err:  # the answer's own error (or output not data), as data
        out = {"raised": type(err).__name__, "message": str(err)[:500]}
    return json.dumps(out)


def request(name: str, args=(), kwargs=None, bind=None) -> str:
    """In the grader: the code of a cell that makes the kernel :func:`serve` the call
    ``name(*args, **kwargs)`` with the notebook's names ``bind`` rebound.

    Parameters
    ----------
    name : str
        The notebook's function.
    args, kwargs, bind : tuple, dict, dict
        Its arguments, and the notebook's names rebound for the call.

    Returns
    -------
    str
        One line of Python: :func:`serve` on the pickled request (base64).
    """
    text = base64.b64encode(pickle.dumps((name, tuple(args), dict(kwargs or {}),
                                          dict(bind or {})))).decode()
    return f"__import__('sunlab.course.wire', fromlist=['serve']).serve(globals(), {text!r})"


def serve(ns: dict, text: str) -> None:
    """In the kernel: :func:`answer` to the grader's pickled ``(name, args, kwargs, bind)``,
    displayed (the grader reads it from the cell's output).

    Parameters
    ----------
    ns : dict
        The notebook's namespace.
    text : str
        The grader's request, base64 of the pickled tuple (:func:`request`).
    """
    from IPython.display import display

    display({MIME: answer(ns, *pickle.loads(base64.b64decode(text)))}, raw=True)


def reply(text: str, name: str):
    """In the grader: the value of :func:`answer`'s text about the function ``name``.

    Parameters
    ----------
    text : str
        :func:`answer`'s JSON text.
    name : str
        The function called, named in the messages.

    Returns
    -------
    object
        The function's output, rebuilt from data.

    Raises
    ------
    AssertionError
        The function is not defined, raised, or gave an output that is not data (the message
        says which, for the student).
    """
    try:
        env = decode(text)  # the envelope's own keys are plain JSON
        missing, raised, out = env.get("missing"), env.get("raised"), env.get("ok")
    except Exception as err:
        raise AssertionError(f"your `{name}` gave an output that is not data ({err})") from None
    if missing:
        raise AssertionError(f"`{name}` is not defined: the exercise asks you to define it")
    if raised is not None:
        raise AssertionError(f"your `{name}` raised {raised}: {env.get('message', '')}")
    return out
