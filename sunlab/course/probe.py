"""The library calls an exercise forbids, caught in a fresh process the student's code never
set up: ``python -m sunlab.course.probe`` (run by the grader, one per exercise).

The grader (:func:`recheck`) starts a new Python process and sends it, pickled on its standard
input, the notebook's imports and constants (from the teacher's cells), the student's answer
cells, the forbidden library functions and the first call the hidden check made in the kernel.
The process first turns every forbidden function into a tripwire (its code object replaced, so
that every name bound to it, ``from ... import`` aliases included, trips), and only then runs the
answer's statements (each on its own; those that need the notebook's other variables are
skipped) and the call. A tripwire ends the process at once with :data:`TRIPPED` (``os._exit``:
no ``try`` in the answer, no profiler switched off, can stop it). The output of the call must be
the output the kernel gave on the same inputs: an answer that behaves otherwise outside its
notebook (to dodge this check) fails as well.
"""

from __future__ import annotations

import ast
import os
import pickle
import subprocess
import sys
import tempfile

import numpy as np

from . import wire

__all__: list[str] = []

#: the exit status of a process whose answer called a forbidden function
TRIPPED = 77
_MARK = "SUNLAB-PROBE-OUTPUT "


def _simple(node) -> bool:
    """An import, or an assignment of a constant expression (numbers, names of constants)."""
    if isinstance(node, ast.Import | ast.ImportFrom):
        return True
    if isinstance(node, ast.Assign):
        return all(isinstance(n, ast.Constant | ast.BinOp | ast.UnaryOp | ast.Tuple | ast.Name
                              | ast.operator | ast.unaryop | ast.Load)
                   for n in ast.walk(node.value))
    return False


def setup_source(sources) -> str:
    """The imports and constant assignments of the teacher's cells, in order."""
    out = []
    for src in sources:
        try:
            tree = ast.parse(src)
        except SyntaxError:
            continue
        out += [ast.unparse(n) for n in tree.body if _simple(n)]
    return "\n".join(out)


def _same(a, b) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list | tuple) and isinstance(b, list | tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    try:
        x, y = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        return a == b
    return x.shape == y.shape and bool(np.allclose(x, y, rtol=1e-9, atol=1e-12, equal_nan=True))


def recheck(call: dict, setup: str, answers: list[str], *, timeout: float) -> str | None:
    """Re-run one answer's call in a fresh process with its forbidden functions as tripwires.

    Parameters
    ----------
    call : dict
        An entry of ``calls`` of :class:`sunlab.course.kernel.NotebookRun`.
    setup : str
        The notebook's imports and constants (:func:`setup_source`).
    answers : list of str
        The student's answer cells, up to this exercise's.
    timeout : float
        Limit, s.

    Returns
    -------
    str or None
        Why the answer fails (a forbidden call, another output, no output), or None.
    """
    name = call["name"]
    request = {"setup": setup, "answers": answers, "forbidden": call["forbidden"],
               "call": (name, call["args"], call["kwargs"], call["bind"])}
    with tempfile.TemporaryDirectory(prefix="sunlab-probe-") as tmp:
        try:
            res = subprocess.run([sys.executable, "-m", "sunlab.course.probe"],
                                 input=pickle.dumps(request), capture_output=True, cwd=tmp,
                                 timeout=timeout, start_new_session=True,
                                 env={**os.environ, "HOME": tmp})
        except subprocess.TimeoutExpired:
            return (f"your `{name}`, run again apart from the notebook to check its library "
                    f"calls, ran past {timeout:g} s")
    if res.returncode == TRIPPED:
        hit = res.stderr.decode(errors="replace").rsplit("SUNLAB-FORBIDDEN ", 1)[-1].strip()
        return (f"your `{name}` calls {hit or 'a library function'}, the library's version of "
                "what this exercise asks you to write: write it yourself (numpy is enough)")
    lines = [x for x in res.stdout.decode(errors="replace").splitlines()
             if x.startswith(_MARK)]
    try:
        out = wire.decode(lines[-1][len(_MARK):]) if lines and res.returncode == 0 else None
    except Exception:
        out = None
    if out is None or not _same(out, call["output"]):
        return (f"your `{name}`, run again apart from the notebook on the same inputs (to check "
                "that it does not call the library function the exercise asks you to write), "
                "gave another answer or none: make it depend on its inputs and the notebook's "
                "imports only")
    return None


def _tripwire(fn, spec: str):
    """A function that ends the process with :data:`TRIPPED`, put in ``fn``'s code where it
    has plain code (so every alias trips); return it and whether ``fn`` itself was rewired."""
    src = (f"def _t(*a, **k):\n import os\n os.write(2, b'SUNLAB-FORBIDDEN {spec}\\n')\n"
           f" os._exit({TRIPPED})\n")
    space: dict = {}
    exec(compile(src, "<tripwire>", "exec"), space)
    target = getattr(fn, "__func__", fn)
    plain = getattr(target, "__code__", None) is not None and not target.__code__.co_freevars
    if plain:
        target.__code__ = space["_t"].__code__
    return space["_t"], plain


#: what an answer cell may not reach into without a flag (names and attributes in its code)
_REACH = {"sys": "sys", "inspect": "frames (inspect)", "builtins": "builtins",
          "__builtins__": "builtins", "_getframe": "frames", "f_back": "frames",
          "f_locals": "frames", "f_globals": "frames", "tb_frame": "frames",
          "gi_frame": "frames", "setprofile": "the profiler", "settrace": "the profiler",
          "monitoring": "the profiler", "gc": "the garbage collector (gc)",
          "ctypes": "ctypes", "importlib": "importlib", "__code__": "code objects",
          "__closure__": "closures", "__globals__": "function globals",
          "_exit": "os._exit", "subprocess": "subprocess", "signal": "signal",
          "hidden": "the course package", "course": "the course package",
          "__import__": "builtins", "exec": "exec/eval", "eval": "exec/eval",
          "compile": "exec/eval", "open": "files", "read_text": "files",
          "read_bytes": "files", "nbformat": "notebooks (nbformat)",
          "globals": "the notebook's globals", "setsid": "a process of its own",
          "fork": "a process of its own", "Popen": "subprocess"}


def flags(source: str) -> list[str]:
    """What an answer cell reaches into: the interpreter, the course package, numpy's
    attributes (assigned), files and processes; flagged in the gradebook for the teacher.

    Parameters
    ----------
    source : str
        An answer cell's code.

    Returns
    -------
    list of str
        What it reaches into, each said once, in order of appearance (empty for a SyntaxError).

    Examples
    --------
    >>> flags("import sys\\nnp.abs = abs")
    ['sys', 'attributes of numpy']
    """
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return []
    found = []
    for node in ast.walk(tree):
        names = []
        if isinstance(node, ast.Name):
            names = [node.id]
        elif isinstance(node, ast.Attribute):
            names = [node.attr]
        elif isinstance(node, ast.Import | ast.ImportFrom):
            names = [a.name.split(".")[0] for a in node.names] + (
                (node.module or "").split(".") if isinstance(node, ast.ImportFrom) else [])
            names += [a.name.split(".")[-1] for a in node.names]
        found += [_REACH[n] for n in names if n in _REACH]
        targets = node.targets if isinstance(node, ast.Assign) else (
            [node.target] if isinstance(node, ast.AugAssign | ast.AnnAssign) else [])
        if any(isinstance(t, ast.Attribute) and isinstance(t.value, ast.Name)
               and t.value.id in ("np", "numpy") for t in targets):
            found.append("attributes of numpy")
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and \
                node.func.id in ("setattr", "delattr"):
            found.append("setattr")
        if isinstance(node, ast.Constant) and ".ipynb" in str(node.value):
            found.append("notebooks (nbformat)")
    return list(dict.fromkeys(found))


def _main() -> None:
    """The fresh process: tripwires first, then the answer, then the call."""
    import importlib

    req = pickle.loads(sys.stdin.buffer.read())
    for spec in req["forbidden"]:
        mod, qual = spec.split(":", 1)
        owner, obj = None, importlib.import_module(mod)
        for part in qual.split("."):
            owner, obj = obj, getattr(obj, part)
        wire_fn, plain = _tripwire(obj, spec.replace(":", "."))
        if not plain:
            setattr(owner, qual.split(".")[-1], wire_fn)
    ns: dict = {"__name__": "__main__"}
    for src in [req["setup"], *req["answers"]]:
        try:
            body = ast.parse(src).body
        except SyntaxError:
            continue
        for node in body:
            try:
                exec(compile(ast.Module([node], []), "<answer>", "exec"), ns)
            except BaseException:  # needs the notebook's other variables: left out
                continue
    name, args, kwargs, bind = req["call"]
    ns.update(bind)
    out = ns[name](*args, **kwargs)
    sys.stdout.write("\n" + _MARK + wire.encode(out) + "\n")
    sys.stdout.flush()


if __name__ == "__main__":
    _main()
