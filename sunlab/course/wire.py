"""Data between a student's kernel and the grader: the grader sends inputs, the kernel sends back
outputs as data, never as objects the grader would run.

The grader (:mod:`sunlab.course.kernel`) asks the kernel to call one of the notebook's functions
on the hidden check's fresh inputs (pickled by the grader: the kernel trusts the grader, never
the other way). :func:`serve` runs in the kernel: it calls the function and displays its return
value :func:`encode`-d as JSON (numbers, strings, lists, dicts, numpy arrays saved without
pickle, pandas series as dicts, xarray objects as their ``to_dict``); anything else stays in the
kernel as a *handle* the grader may call methods of, again as data. :func:`decode` rebuilds the
value in the grader from that JSON alone: a student's kernel can make its answer say anything,
but it cannot make the grader run code.

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
#: objects the kernel keeps for the grader's later calls (handles)
_HANDLES: dict = {}


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
    if isinstance(obj, dict) or mod == "pandas" and hasattr(obj, "items") and hasattr(obj, "index"):
        return {"__dict__": [[_enc(k, depth + 1), _enc(v, depth + 1)] for k, v in obj.items()]}
    key = len(_HANDLES)
    _HANDLES[key] = obj
    names = [n for n in dir(obj) if not n.startswith("_")]
    return {"__handle__": key, "type": type(obj).__name__, "names": names}


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


class Handle:
    """An object that stayed in the kernel: its attributes are fetched, its methods called there
    (:meth:`sunlab.course.kernel.NotebookRun.remote`), the results again as data."""

    def __init__(self, run, key: int, type_name: str, names):
        self._run, self._key, self._type, self._names = run, key, type_name, set(names)

    def __getattr__(self, name):
        if name.startswith("_") or name not in self._names:
            raise AttributeError(name)
        return self._run.remote("attr", self._key, name)

    def __call__(self, *args, **kwargs):
        return self._run.remote("call", self._key, None, args, kwargs)

    def __repr__(self):
        return f"<{self._type} in the student's kernel>"


def _dec(obj, run):
    if isinstance(obj, list):
        return [_dec(v, run) for v in obj]
    if not isinstance(obj, dict):
        return obj
    if "__nd__" in obj:
        return np.load(io.BytesIO(base64.b64decode(obj["__nd__"])), allow_pickle=False)
    if "__tuple__" in obj:
        return tuple(_dec(v, run) for v in obj["__tuple__"])
    if "__dict__" in obj:
        out = {}
        for k, v in obj["__dict__"]:
            k = _dec(k, run)
            out[tuple(k) if isinstance(k, list) else k] = _dec(v, run)
        return out
    if "__xr__" in obj:
        import xarray as xr

        d = _dec(obj["d"], run)
        return (xr.DataArray if obj["__xr__"] == "DataArray" else xr.Dataset).from_dict(d)
    if "__handle__" in obj:
        if run is None:
            raise ValueError("an object that is not data")
        return Handle(run, int(obj["__handle__"]), str(obj.get("type", "object")),
                      obj.get("names", []))
    return {k: _dec(v, run) for k, v in obj.items()}


def decode(text: str, run=None):
    """The value of :func:`encode`'s JSON, rebuilt from data only; run in the grader.

    Parameters
    ----------
    text : str
        JSON text from the kernel.
    run : sunlab.course.kernel.NotebookRun, optional
        The kernel that keeps the handles; without it a handle is refused.

    Returns
    -------
    object
    """
    if len(text) > MAX_BYTES:
        raise ValueError(f"an answer of {len(text)} bytes (at most {MAX_BYTES})")
    return _dec(json.loads(text), run)


def request(what, target, name=None, args=(), kwargs=None, bind=None) -> str:
    """The grader's request to the kernel (:func:`answer`), as text."""
    return base64.b64encode(pickle.dumps(
        (what, target, name, tuple(args), dict(kwargs or {}), dict(bind or {})))).decode()


def answer(ns: dict, text: str) -> str:
    """In the kernel: carry out the grader's request and return its result as JSON text.

    Parameters
    ----------
    ns : dict
        The notebook's globals.
    text : str
        :func:`request`'s text: ``what`` is ``"call"`` (``target`` a name of ``ns`` or a
        handle) or ``"attr"`` (a handle's attribute); ``bind`` rebinds names of ``ns`` for the
        call, and ``ns`` is put back as it was after it.

    Returns
    -------
    str
        JSON of ``{"ok": value}``, ``{"missing": true}`` or ``{"raised": name, "message": ...}``.
    """
    what, target, name, args, kwargs, bind = pickle.loads(base64.b64decode(text))
    try:
        with mock.patch.dict(ns, bind):  # the notebook's globals as they were, after the call
            obj = ns.get(target) if isinstance(target, str) else _HANDLES[target]
            if what == "attr":
                out = {"ok": getattr(obj, name)}
            else:
                out = {"missing": True} if obj is None else {"ok": obj(*args, **kwargs)}
    except BaseException as err:  # the answer's own error, reported as data
        out = {"raised": type(err).__name__, "message": str(err)[:500]}
    try:
        return json.dumps({k: (_enc(v, 0) if k == "ok" else v) for k, v in out.items()})
    except Exception as err:
        return json.dumps({"raised": "TypeError", "message": f"an answer that is not data: {err}"})


def serve(ns: dict, text: str) -> None:
    """In the kernel: :func:`answer`, displayed (the grader reads it from the cell's output).

    Parameters
    ----------
    ns : dict
        The notebook's namespace.
    text : str
        The grader's request, as :func:`answer` reads it.
    """
    from IPython.display import display

    display({MIME: answer(ns, text)}, raw=True)


class Missing:
    """What :func:`reply` returns for a name the notebook does not define."""


MISSING = Missing()


class AnswerRaised(Exception):
    """The student's function raised ``ename`` in its kernel."""

    def __init__(self, ename: str, message: str):
        super().__init__(f"{ename}: {message}")
        self.ename, self.message = ename, message


def reply(text: str, run=None):
    """In the grader: the value of :func:`answer`'s text (:data:`MISSING` for an undefined
    name); raises :class:`AnswerRaised` when the student's function raised or the text is not
    data."""
    try:
        env = decode(text, run)  # the envelope's own keys are plain JSON
        if env.get("missing"):
            return MISSING
        raised = ("raised" in env and (str(env["raised"]), str(env.get("message", ""))))
        out = None if raised else env["ok"]
    except Exception as err:
        raise AnswerRaised("ValueError", f"an output that is not data ({err})") from None
    if raised:
        raise AnswerRaised(*raised)
    return out
