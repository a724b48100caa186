"""Grading students' notebooks against the teacher edition: a gradebook a teacher can trust.

:func:`sunlab.course.batch.grade_batch` (``sunlab course --grade``) checks every submission
first (a course notebook's name, handed in once), then grades them one by one, rewriting the
gradebook after each. :func:`grade_notebook` does not trust a submitted
notebook's check cells: it builds the notebook to run from the **teacher edition** of the course
notebook of the same name and takes only the student's answers from the submission (each
``# Exercise NN.k`` cell, or nbgrader's ``grade_id`` ``exNN-k``, and each written answer). A
check cell that was altered or deleted scores that exercise 0, and the message names the
tampering; an exercise handed in twice scores 0.

The notebook runs cell by cell in a fresh kernel in a scratch folder
(:class:`sunlab.course.kernel.NotebookRun`: a limit per cell, a budget per notebook, its process
group killed at the end). Right after each check cell that passes, the hidden check
(:mod:`sunlab.course.hidden`) runs **in this process**: the student's function is called in the
kernel on the fresh inputs and its outputs come back as data (:mod:`sunlab.course.wire`); the
references and the comparisons never exist in the kernel. Forbidden library calls are caught in
a fresh process (:mod:`sunlab.course.probe`). A time-out, a dead kernel or a kernel that stops
answering scores the exercises not yet checked 0 with a message saying which. Each exercise gets
its points (the check's ``(N points)``) or 0, and a message; answer cells that reach into the
interpreter are flagged. Written answers are listed with their points left blank for the teacher.

:func:`write_gradebook` writes ``gradebook.csv`` (columns ``student, notebook, exercise,
points, max_points, message``; the student is the name of the folder that holds the notebook)
and ``gradebook.json`` (the same rows, with each result and flags, the seed, the totals per
student and whether the batch is complete), both at once (:func:`sunlab.atomic.atomic_files`),
the CSV from the record the JSON holds.
"""

from __future__ import annotations

import copy
import json
import os
import re
from pathlib import Path

from .. import atomic
from ..errors import ConfigurationError
from . import hidden
from .editions import (
    _CHECK,
    _EXERCISE,
    _WRITTEN,
    WRITTEN_PROMPT,
    _read,
    default_notebook_dir,
    edition,
    find_exercises,
    find_written,
    strip_hidden,
)

__all__ = ["grade", "write_gradebook"]

#: the columns of gradebook.csv
COLUMNS = ("student", "notebook", "exercise", "points", "max_points", "message")
GRADEBOOK_FILES = ("gradebook.csv", "gradebook.json")


def _norm(source: str) -> str:
    return "\n".join(line.rstrip() for line in source.strip().splitlines())


def _source_for(path: Path, src: Path) -> Path:
    exact = src / path.name
    if exact.is_file():
        return exact
    same = sorted(src.glob(f"{path.name[:3]}*.ipynb")) if re.match(r"\d\d-", path.name) else []
    if len(same) == 1:
        return same[0]
    raise ConfigurationError(
        f"{path}: no course notebook of that name in {src}. Fix: keep the file name of the "
        "student edition (NN-title.ipynb), or give the course's folder with --notebooks")


def _submitted(nb):
    """The student's answer cells, check cells and written answers (``""``, ``"-check"``,
    ``"-written"``) by exercise number, each found by its first line or its nbgrader grade id,
    and the exercises whose answer cell is handed in more than once (number -> how many)."""
    found: dict = {"": {}, "-check": {}, "-written": {}}
    seen: dict = {}
    for cell in nb.cells:
        first = cell.source.split("\n", 1)[0]
        gid = str(cell.get("metadata", {}).get("nbgrader", {}).get("grade_id", ""))
        for pattern, kind in _KINDS.get(cell.cell_type, ()):
            m = pattern.match(first) or re.fullmatch(rf"ex(\d\d)-(\d+){kind}", gid)
            if m:
                number = m.group(1) if m.re is pattern else f"{m.group(1)}.{m.group(2)}"
                found[kind].setdefault(number, cell)
                seen[number] = seen.get(number, 0) + (kind == "")
    return *found.values(), {k: n for k, n in seen.items() if n > 1}


#: how a cell of a submission is found: its first line, or nbgrader's grade id ``exNN-k`` + kind
_KINDS = {"code": ((_EXERCISE, ""), (_CHECK, "-check")), "markdown": ((_WRITTEN, "-written"),)}


def _error_of(cell):
    return next((o for o in cell.get("outputs", []) if o.get("output_type") == "error"), None)


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def _syntax_message(err) -> str:
    """A SyntaxError's message with its line, from the traceback nbclient recorded."""
    tb = _one_line(re.sub(r"\x1b\[[0-9;]*m", "", "\n".join(err.get("traceback", []))))
    line = re.search(r"line (\d+)", tb)
    where = f" (line {line.group(1)} of the cell)" if line else ""
    what = re.sub(r"\s*\(\S+\.py, line \d+\)$", "", _one_line(err["evalue"]))
    return f"SyntaxError in your answer{where}: {what}"


def _result(answer_err, check_err):
    """(result, message) of one exercise from the errors of its answer and check cells."""
    if answer_err is not None and answer_err["ename"] in ("SyntaxError", "IndentationError",
                                                          "TabError"):
        return "syntax error", _syntax_message(answer_err)
    if answer_err is not None and answer_err["ename"] == "NotImplementedError":
        return "not answered", _one_line(answer_err["evalue"])
    if check_err is None:
        return "pass", ""
    if check_err["ename"] == "AssertionError":
        return "wrong", _one_line(check_err["evalue"])
    if answer_err is not None:
        return "error", (f"your answer raised {answer_err['ename']}: "
                         f"{_one_line(answer_err['evalue'])}")
    if check_err["ename"] == "NameError":
        return "not answered", _one_line(check_err["evalue"])
    return "error", f"{check_err['ename']}: {_one_line(check_err['evalue'])}"


def result_rows(head, message, exercises=(), result="refused", written=()) -> list[dict]:
    """Rows of one result and message, with 0 points.

    Parameters
    ----------
    head : dict
        ``student`` and ``notebook``.
    message : str
        Each row's message.
    exercises : sequence of Exercise
        One row each; none: one row ``-`` (0 of 0 points).
    result : str
        Each row's result (``refused``, ``unreadable``, ``grader error``).
    written : sequence of Written
        One row each too, its points None (graded by hand).

    Returns
    -------
    list of dict
        Gradebook rows.
    """
    return [{**head, "exercise": e.number + (" (written)" if e in written else "") if e else "-",
             "points": None if e in written else 0, "max_points": e.points if e else 0,
             "result": result, "message": message, "flags": []}
            for e in [*exercises, *written] or [None]]


#: limit per cell, s (``sunlab course --grade --timeout``)
DEFAULT_TIMEOUT = 180.0
#: a notebook's budget, in limits per cell (every cell and every hidden check together)
BUDGET_CELLS = 10

_FAILED = {"time-out", "dead kernel", "crash"}


def grade_notebook(path, *, notebooks=None, seed: int | None = None, quick: bool = True,
                   timeout: float = DEFAULT_TIMEOUT, budget: float | None = None) -> list[dict]:
    """Grade one student's notebook against the teacher edition (see the module's text).

    Parameters
    ----------
    path : str or path-like
        A notebook of the student edition, with the student's answers; the folder that holds it
        names the student.
    notebooks : str or path-like, optional
        The course's notebooks (the teacher's source); default the checkout's.
    seed : int, optional
        Draws the hidden checks' fresh inputs; default :data:`sunlab.course.hidden.DEFAULT_SEED`.
    quick : bool
        Run with the small settings (``SUNLAB_QUICK=1``), as the editions do by default.
    timeout : float
        Limit per cell (and per hidden check's call), s.
    budget : float, optional
        Limit for the whole notebook, s; default :data:`BUDGET_CELLS` times ``timeout``.

    Returns
    -------
    list of dict
        One row per exercise and per written answer, in order: ``student``, ``notebook``,
        ``exercise``, ``points`` (None for a written answer: graded by hand), ``max_points``,
        ``result`` (``pass``, ``wrong``, ``not answered``, ``syntax error``, ``error``,
        ``tampered``, ``handed in twice``, ``time-out``, ``dead kernel``, ``crash``,
        ``written``, ``unreadable``), ``message`` and ``flags`` (what the answer reaches into).
    """
    from . import probe

    path = Path(path)
    src = Path(notebooks) if notebooks is not None else default_notebook_dir()
    source_path = _source_for(path, src)
    # the teacher edition, as it runs: its exercises' cell indices count the quick cell
    teacher = edition(_read(source_path), source_path.name, student=False, quick=quick)
    exercises = find_exercises(teacher, source_path.name)
    written = find_written(teacher, source_path.name)
    if not exercises and not written:
        raise ConfigurationError(
            f"{path}: the course notebook {source_path.name} has no exercise to grade. Fix: "
            "give the notebooks that carry exercises")
    head = {"student": path.resolve().parent.name, "notebook": path.name}
    try:
        submitted = _read(path)
    except (ConfigurationError, OSError) as err:
        return result_rows(head, _one_line(err), exercises, "unreadable", written)
    answers, checks, texts, twice = _submitted(submitted)
    graded, tampered, outside = _graded(teacher, exercises, answers, checks, twice)
    seed_value = hidden.DEFAULT_SEED if seed is None else int(seed)
    budget = BUDGET_CELLS * float(timeout) if budget is None else float(budget)
    env = {**os.environ, hidden.SEED_VARIABLE: str(seed_value)}
    verdicts, calls, failure = _run(graded, exercises, outside, env, timeout, budget,
                                    seed_value)
    _recheck(graded, exercises, calls, verdicts, timeout)
    rows = []
    for ex in exercises:
        result, message = _outcome(graded, ex, exercises, failure, verdicts)
        points = ex.points if result == "pass" else 0
        if ex.number in twice:
            result, message, points = "handed in twice", (
                f"exercise {ex.number} is handed in {twice[ex.number]} times (one answer cell "
                "each): scored 0; keep one cell per exercise"), 0
        elif ex.number in tampered and result not in _FAILED:
            points = 0
            ran = "it passes" if result == "pass" else f"{result}: {message}" if message else result
            result, message = "tampered", (
                f"{tampered[ex.number]}: scored 0 (the teacher's check, restored and run, says "
                f"{ran})")
        got = probe.flags(answers[ex.number].source) if ex.number in answers else []
        if got:
            message = (message + " " if message else "") + (
                f"[flagged for the teacher: the answer reaches into {', '.join(got)}]")
        rows.append({**head, "exercise": ex.number, "points": points, "max_points": ex.points,
                     "result": result, "message": message, "flags": got})
    rows += [_written_row(head, w, texts.get(w.number)) for w in written]
    return rows


def _run(graded, exercises, outside, env, timeout, budget, seed_value):
    """Run the graded notebook cell by cell, each standard hidden check here right after its
    check cell when that passed; return the hidden checks' verdicts, their calls with
    forbidden functions, and the kernel's failure ``(kind, message, cell index, number of the
    hidden check or None)`` or None."""
    from . import kernel

    verdicts, calls, where, hid = {}, {}, 0, None
    by_check = {ex.check_cell: ex for ex in exercises}
    try:
        with kernel.NotebookRun(graded, env=env, timeout=timeout, budget=budget) as run:
            for i, cell in enumerate(graded.cells):
                if cell.cell_type != "code":
                    continue
                where, hid = i, None
                run.execute(cell, i)
                ex = by_check.get(i)
                # a check cell that failed has decided: its hidden check would not count
                if ex is not None and ex.number in outside and _error_of(cell) is None:
                    hid = ex.number
                    run.calls = calls[ex.number] = []
                    verdicts[ex.number] = _hidden_verdict(ex.number, run, seed_value)
    except kernel.KernelFailure as err:
        return verdicts, calls, (err.kind, err.message, where, hid)
    return verdicts, calls, None


def _recheck(graded, exercises, calls, verdicts, timeout) -> None:
    """The forbidden-call check of each exercise in a fresh process (:mod:`.probe`); a failure
    becomes the exercise's verdict."""
    from . import probe

    answer_cells = {e.solution_cell for e in exercises}
    check_cells = {e.check_cell for e in exercises}
    for ex in exercises:
        if not calls.get(ex.number):
            continue
        setup = probe.setup_source([
            c.source for j, c in enumerate(graded.cells) if c.cell_type == "code"
            and j < ex.solution_cell and j not in answer_cells and j not in check_cells])
        mine = [graded.cells[e.solution_cell].source for e in exercises
                if e.solution_cell <= ex.solution_cell]
        for call in calls[ex.number]:
            why = probe.recheck(call, setup, mine, timeout=timeout)
            if why and verdicts.get(ex.number) is None:
                verdicts[ex.number] = f"hidden check {ex.number}: {why}"


def _outcome(graded, ex, exercises, failure, verdicts):
    """(result, message) of one exercise: the kernel's failure before its verdict, its cells'
    errors, or its hidden check's verdict."""
    check_at = ex.check_cell
    if failure is not None and failure[2] <= check_at:  # a failure before its verdict
        return failure[0], (f"{failure[1]} while running "
                            f"{_cell_name(*failure[2:], exercises)}; exercise {ex.number} "
                            "was not checked: scored 0")
    result, message = _result(_error_of(graded.cells[ex.solution_cell]),
                              _error_of(graded.cells[check_at]))
    if result == "pass" and verdicts.get(ex.number):
        return "wrong", verdicts[ex.number]
    return result, message


def _cell_name(where, hid, exercises) -> str:
    if hid is not None:
        return f"the hidden check of exercise {hid}"
    for ex in exercises:
        if where == ex.solution_cell:
            return f"the answer of exercise {ex.number}"
        if where == ex.check_cell:
            return f"the check of exercise {ex.number}"
    return f"cell {where}"


def _hidden_verdict(number, ns, seed_value):
    """The hidden check run here, on the kernel's outputs: None (passes) or its message."""
    from .kernel import KernelFailure

    try:
        hidden.check(number, ns, seed_value)
    except AssertionError as err:
        return _one_line(err)
    except KernelFailure:
        raise
    except Exception as err:  # an output the check cannot read
        return (f"hidden check {number}: your answer's output could not be checked "
                f"({type(err).__name__}: {_one_line(err)[:200]})")
    return None


def _graded(teacher, exercises, answers, checks, twice=()):
    """The teacher edition with the student's answers in it (none for an exercise handed in
    ``twice``), the exercises whose check cell was altered or deleted (number -> what
    happened), and those whose standard hidden-test block was taken out of the check cell (the
    grader runs it in its own process)."""
    graded = copy.deepcopy(teacher)
    tampered, outside = {}, set()
    for ex in exercises:
        mine = answers.get(ex.number) if ex.number not in twice else None
        graded.cells[ex.solution_cell].source = (
            mine.source if mine is not None else
            f"raise NotImplementedError('the cell of exercise {ex.number} is missing from the "
            "submission')")
        check = checks.get(ex.number)
        expected = strip_hidden(teacher.cells[ex.check_cell].source)
        if check is None:
            tampered[ex.number] = "check cell deleted"
        elif _norm(check.source) != _norm(expected):
            tampered[ex.number] = "check cell altered"
        if hidden.call_of(graded.cells[ex.check_cell].source) == ex.number:
            graded.cells[ex.check_cell].source = expected
            outside.add(ex.number)
    return graded, tampered, outside


def _written_row(head, w, cell) -> dict:
    """A written answer's row: points left to the teacher, the length of the answer said."""
    body = cell.source.split("\n", 1)[1].strip() if cell is not None and "\n" in cell.source \
        else ""
    words = 0 if body in ("", WRITTEN_PROMPT) else len(body.split())
    return {**head, "exercise": f"{w.number} (written)", "points": None,
            "max_points": w.points, "result": "written",
            "message": (f"graded by hand: {words} words written; the model answer is in the "
                        "teacher edition") if words else "not answered"}


def grade(paths, *, notebooks=None, seed: int | None = None, quick: bool = True,
          timeout: float = DEFAULT_TIMEOUT, budget: float | None = None) -> list[dict]:
    """Grade several students' notebooks (:func:`sunlab.course.batch.grade_batch` without a
    gradebook or report).

    Parameters
    ----------
    paths : iterable of str or path-like
        The submitted notebooks, each in a folder named after its student.
    notebooks, seed, quick, timeout, budget
        As :func:`grade_notebook`'s.

    Returns
    -------
    list of dict
        The rows of every notebook, in the order of ``paths`` (a submission refused by the
        checks before grading has rows with the result ``refused``).
    """
    from .batch import grade_batch

    return grade_batch(paths, notebooks=notebooks, seed=seed, quick=quick, timeout=timeout,
                       budget=budget, report=lambda *a: None)[0]


def totals(rows) -> dict:
    """Per student: ``points`` and ``max_points`` of the checked exercises, and
    ``written_max_points`` (graded by hand).

    Parameters
    ----------
    rows : iterable of dict
        Gradebook rows (:func:`grade`).

    Returns
    -------
    dict of str to dict
        Student -> ``{"points", "max_points", "written_max_points"}`` (int).
    """
    out: dict = {}
    for r in rows:
        t = out.setdefault(r["student"], dict.fromkeys(("points", "max_points",
                                                         "written_max_points"), 0))
        hand = r["points"] is None
        t["written_max_points" if hand else "max_points"] += r["max_points"]
        t["points"] += r["points"] or 0
    return out


def csv_text(rows) -> str:
    """The gradebook's CSV (:data:`COLUMNS`; a written answer's points are empty).

    Parameters
    ----------
    rows : iterable of dict
        Gradebook rows (:func:`grade`); keys beyond :data:`COLUMNS` are left out.

    Returns
    -------
    str
        The CSV text: a header line, then one line per row, ``\\n`` line ends.
    """
    import pandas as pd

    return pd.DataFrame(list(rows), columns=list(COLUMNS), dtype=object).to_csv(
        index=False, lineterminator="\n")


def write_gradebook(rows, folder, *, seed: int, overwrite: bool = False,
                    complete: bool = True) -> list[Path]:
    """Write ``gradebook.csv`` and ``gradebook.json`` into ``folder``, both or neither.

    Parameters
    ----------
    rows : list of dict
        :func:`grade`'s rows.
    folder : str or path-like
        Created when missing.
    seed : int
        The hidden checks' seed, recorded in the JSON.
    overwrite : bool
        Replace a gradebook written before.
    complete : bool
        Whether every submission is graded (recorded in the JSON; False while a batch grows).

    Returns
    -------
    list of Path
        The two files.
    """
    folder = Path(folder)
    doc = {"schema": "sunlab-gradebook/1", "seed": int(seed), "complete": bool(complete),
           "columns": list(COLUMNS), "rows": list(rows), "totals": totals(rows)}
    text = json.dumps(doc, indent=1) + "\n"
    record = json.loads(text)  # the CSV is written from the very record the JSON holds
    with atomic.atomic_files(folder, GRADEBOOK_FILES, overwrite=overwrite,
                             flag="--overwrite") as tmp:
        (tmp / "gradebook.csv").write_text(csv_text(record["rows"]), encoding="utf-8")
        (tmp / "gradebook.json").write_text(text, encoding="utf-8")
    return [folder / name for name in GRADEBOOK_FILES]
