"""Grading students' notebooks against the teacher edition: a gradebook a teacher can trust.

:func:`grade` does not trust a submitted notebook's check cells. For each notebook it builds the
notebook to run from the **teacher edition** of the course notebook of the same name, and takes
only the student's answers from the submission: the code of each exercise cell (``# Exercise
NN.k``, or nbgrader's ``grade_id`` ``exNN-k``) and the text of each written answer. Every
other cell, each check cell included, is the teacher's, with its hidden-test block
(:mod:`sunlab.course.hidden`), which runs the answer on fresh inputs drawn from the grader's
seed. A submission whose check cell was altered (replaced by a ``print``, edited) or deleted
scores that exercise 0, whatever the restored check says, and the message names the tampering.

The notebook runs top to bottom in a fresh kernel in the submission's folder, going on past
errors. Each exercise then gets its points (the check's ``(N points)``) or 0, and a message:
the check's own message (visible or hidden) when the answer is wrong, ``not answered`` when the
stub still raises, ``SyntaxError in your answer`` with the line, or the error. Written answers
are listed with their points left blank for the teacher.

:func:`write_gradebook` writes ``gradebook.csv`` (columns ``student, notebook, exercise,
points, max_points, message``; the student is the name of the folder that holds the notebook)
and ``gradebook.json`` (the same rows, with each result, the seed and the totals per student),
both at once (:func:`sunlab.atomic.atomic_files`).
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
    _jupyter,
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


def _grade_id(cell) -> str:
    return str(cell.get("metadata", {}).get("nbgrader", {}).get("grade_id", ""))


def _first(cell) -> str:
    return cell.source.split("\n", 1)[0]


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
    """The student's answer cells, check cells and written answers, by exercise number."""
    answers, checks, texts = {}, {}, {}
    for cell in nb.cells:
        gid = _grade_id(cell)
        if cell.cell_type == "code":
            m = _EXERCISE.match(_first(cell))
            c = _CHECK.match(_first(cell))
            g = re.fullmatch(r"ex(\d\d)-(\d+)(-check)?", gid)
            if g and not g.group(3) or m:
                answers.setdefault(m.group(1) if m else f"{g.group(1)}.{g.group(2)}", cell)
            if g and g.group(3) or c:
                checks.setdefault(c.group(1) if c else f"{g.group(1)}.{g.group(2)}", cell)
        elif cell.cell_type == "markdown":
            w = _WRITTEN.match(_first(cell))
            g = re.fullmatch(r"ex(\d\d)-(\d+)-written", gid)
            if w or g:
                texts.setdefault(w.group(1) if w else f"{g.group(1)}.{g.group(2)}", cell)
    return answers, checks, texts


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


def _rows_for_unreadable(head, message, exercises, written):
    return [{**head, "exercise": e.number + (" (written)" if e in written else ""),
             "points": None if e in written else 0, "max_points": e.points,
             "result": "unreadable", "message": message} for e in [*exercises, *written]]


def grade_notebook(path, *, notebooks=None, seed: int | None = None, quick: bool = True,
                   timeout: float = 900.0) -> list[dict]:
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
        Limit per cell, s.

    Returns
    -------
    list of dict
        One row per exercise and per written answer, in order: ``student``, ``notebook``,
        ``exercise``, ``points`` (None for a written answer: graded by hand), ``max_points``,
        ``result`` (``pass``, ``wrong``, ``not answered``, ``syntax error``, ``error``,
        ``tampered``, ``written``, ``unreadable``) and ``message``.
    """
    nbf = _jupyter("nbformat")
    path = Path(path)
    src = Path(notebooks) if notebooks is not None else default_notebook_dir()
    source_path = _source_for(path, src)
    source = _read(nbf, source_path)
    exercises = find_exercises(source, source_path.name)
    written = find_written(source, source_path.name)
    if not exercises and not written:
        raise ConfigurationError(
            f"{path}: the course notebook {source_path.name} has no exercise to grade. Fix: "
            "give the notebooks that carry exercises")
    head = {"student": path.resolve().parent.name, "notebook": path.name}
    try:
        submitted = _read(nbf, path)
    except (ConfigurationError, OSError) as err:
        return _rows_for_unreadable(head, _one_line(err), exercises, written)
    answers, checks, texts = _submitted(submitted)
    graded, tampered = _graded(source, source_path.name, exercises, answers, checks, quick)
    seed_value = hidden.DEFAULT_SEED if seed is None else int(seed)
    _jupyter("nbclient").NotebookClient(
        graded, timeout=timeout, kernel_name="python3", allow_errors=True,
        resources={"metadata": {"path": str(path.parent)}}).execute(
        env={**os.environ, hidden.SEED_VARIABLE: str(seed_value)})  # the kernel's environment
    shift = 1 if quick else 0
    rows = []
    for ex in exercises:
        result, message = _result(_error_of(graded.cells[ex.solution_cell + shift]),
                                  _error_of(graded.cells[ex.check_cell + shift]))
        points = ex.points if result == "pass" else 0
        if ex.number in tampered:
            points = 0
            ran = "it passes" if result == "pass" else f"{result}: {message}" if message else result
            result, message = "tampered", (
                f"{tampered[ex.number]}: scored 0 (the teacher's check, restored and run, says "
                f"{ran})")
        rows.append({**head, "exercise": ex.number, "points": points, "max_points": ex.points,
                     "result": result, "message": message})
    rows += [_written_row(head, w, texts.get(w.number)) for w in written]
    return rows


def _graded(source, name, exercises, answers, checks, quick):
    """The teacher edition with the student's answers in it, and the exercises whose check
    cell was altered or deleted (number -> what happened)."""
    teacher = edition(source, name, student=False, quick=quick)
    shift = 1 if quick else 0
    graded = copy.deepcopy(teacher)
    tampered = {}
    for ex in exercises:
        mine = answers.get(ex.number)
        graded.cells[ex.solution_cell + shift].source = (
            mine.source if mine is not None else
            f"raise NotImplementedError('the cell of exercise {ex.number} is missing from the "
            "submission')")
        check = checks.get(ex.number)
        expected = strip_hidden(teacher.cells[ex.check_cell + shift].source)
        if check is None:
            tampered[ex.number] = "check cell deleted"
        elif _norm(check.source) != _norm(expected):
            tampered[ex.number] = "check cell altered"
    return graded, tampered


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
          timeout: float = 900.0) -> list[dict]:
    """Grade several students' notebooks (``grade_notebook`` for each).

    Parameters
    ----------
    paths : iterable of str or path-like
        The submitted notebooks, each in a folder named after its student.
    notebooks : str or path-like, optional
        The course's notebooks (the teacher's source); default the checkout's.
    seed : int, optional
        Draws the hidden checks' fresh inputs; default :data:`sunlab.course.hidden.DEFAULT_SEED`.
    quick : bool
        Run with the small settings (``SUNLAB_QUICK=1``).
    timeout : float
        Limit per cell, s.

    Returns
    -------
    list of dict
        The rows of ``grade_notebook`` of every notebook, in the order of ``paths``.
    """
    return [r for path in paths for r in grade_notebook(path, notebooks=notebooks, seed=seed,
                                                         quick=quick, timeout=timeout)]


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


def write_gradebook(rows, folder, *, seed: int, overwrite: bool = False) -> list[Path]:
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

    Returns
    -------
    list of Path
        The two files.
    """
    folder = Path(folder)
    doc = {"schema": "sunlab-gradebook/1", "seed": int(seed), "columns": list(COLUMNS),
           "rows": rows, "totals": totals(rows)}
    with atomic.atomic_files(folder, GRADEBOOK_FILES, overwrite=overwrite,
                             flag="--overwrite") as tmp:
        (tmp / "gradebook.csv").write_text(csv_text(rows), encoding="utf-8")
        (tmp / "gradebook.json").write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return [folder / name for name in GRADEBOOK_FILES]
