"""A class graded in one run: every submission checked before any is graded, then each graded
in turn, the gradebook rewritten after each (``sunlab course --grade``).

:func:`check_submissions` refuses, with a row that says why, a file not named after a course
notebook and a notebook that a student handed in more than once (every copy); :func:`grade_batch`
grades the rest with :func:`sunlab.course.grading.grade_notebook`, whose kernel failures score a
notebook's open exercises 0; a failure of the grader itself on one notebook gives that notebook
a row ``grader error`` and the exit status :data:`GRADER_FAILED`, and the batch goes on.
"""

from __future__ import annotations

from pathlib import Path

from ..errors import ConfigurationError
from . import hidden
from .editions import _read, default_notebook_dir, find_exercises
from .grading import (
    DEFAULT_TIMEOUT,
    _one_line,
    _source_for,
    grade_notebook,
    result_rows,
    totals,
    write_gradebook,
)

__all__ = ["grade_batch"]


def check_submissions(paths, *, notebooks=None) -> tuple[list, list[dict]]:
    """Check every submission before any is graded: a file, named after a course notebook,
    handed in once per student.

    Parameters
    ----------
    paths : sequence of path-like
        The students' notebooks, ``STUDENT/NN-title.ipynb``.
    notebooks : path-like, optional
        The course's notebooks (default: the checkout's ``notebooks/``).

    Returns
    -------
    (list of Path, list of dict)
        The submissions to grade, and the rows of those refused (result ``refused``, with the
        reason).
    """
    src = Path(notebooks) if notebooks is not None else default_notebook_dir()
    keys, ok, refused = {}, [], []
    for p in map(Path, paths):
        head = {"student": p.resolve().parent.name, "notebook": p.name}
        try:
            course_nb = _source_for(p, src)
        except ConfigurationError as err:
            refused += result_rows(head, f"refused: {_one_line(err)}")
            continue
        keys.setdefault((head["student"], course_nb.name), []).append((p, head, course_nb))
    for (student, name), items in keys.items():
        if len(items) == 1:
            ok.append(items[0][0])
            continue
        exercises = find_exercises(_read(items[0][2]), name)
        where = ", ".join(str(p) for p, _, _ in items)
        for _p, head, _ in items:
            refused += result_rows(head, f"refused: {student} handed in {name} "
                                   f"{len(items)} times ({where}); none graded: hand in one",
                                   exercises)
    return ok, refused  # in the order of ``paths``: each key first seen at its only path


def report_rows(path, mine, report=print) -> None:
    """Print one notebook's rows (``sunlab course --grade``)."""
    for student, tot in totals(mine).items():
        passed = sum(r["result"] == "pass" for r in mine)
        checked = sum(r["points"] is not None for r in mine)
        report(f"{student}/{Path(path).name}: {tot['points']} of {tot['max_points']} "
               f"points ({passed} of {checked} checks pass"
               + (f"; {tot['written_max_points']} points of written answers to grade "
                  "by hand)" if tot["written_max_points"] else ")"))
    for r in mine:
        pts = "-" if r["points"] is None else r["points"]
        report(f"  {r['exercise']:<14} {pts}/{r['max_points']}  {r['result']:<12} "
               f"{r['message']}".rstrip())


#: ``sunlab course --grade``'s exit status when the grader itself failed on a notebook
GRADER_FAILED = 4


def grade_batch(paths, *, notebooks=None, seed: int | None = None, quick: bool = True,
                timeout: float = DEFAULT_TIMEOUT, budget: float | None = None,
                gradebook=None, overwrite: bool = False, report=print) -> tuple[list, int]:
    """Check every submission, then grade them one by one, the gradebook growing as it goes.

    A submission refused by :func:`check_submissions` gets its rows (``refused``) and the
    others are graded; a notebook whose kernel fails scores its open exercises 0
    (:func:`grade_notebook`); a notebook on which the grader itself fails gets rows ``grader
    error`` with the error, and the batch goes on. With ``gradebook``, the files are rewritten
    after each notebook (``complete`` false in the JSON until the last).

    Parameters
    ----------
    paths : sequence of path-like
        The students' notebooks, ``STUDENT/NN-title.ipynb``.
    notebooks : path-like, optional
        The course's notebooks (default: the checkout's ``notebooks/``).
    seed : int, optional
        Seed of the hidden checks' fresh inputs.
    quick : bool
        Run the notebooks on their small settings.
    timeout : float
        Limit per cell, s; past it the notebook's open exercises score 0.
    budget : float, optional
        Limit per notebook, s (default 10 ``timeout``).
    gradebook : path-like, optional
        Folder of ``gradebook.csv`` and ``gradebook.json``, rewritten after each notebook.
    overwrite : bool
        Replace a gradebook written before.
    report : callable
        Where each student's points and each exercise's line are printed.

    Returns
    -------
    (list of dict, int)
        The rows, and the exit status: 0 every check passes, 1 some do not (or a submission
        was refused), :data:`GRADER_FAILED` the grader failed on a notebook.
    """
    paths = list(paths)
    seed_value = hidden.DEFAULT_SEED if seed is None else int(seed)
    todo, rows = check_submissions(paths, notebooks=notebooks)
    for r in rows:
        report(f"{r['student']}/{r['notebook']}: {r['exercise']} {r['message']}")
    report(f"{len(todo)} of {len(paths)} submissions to grade")
    status = 1 if rows else 0
    written = False

    def save(complete):
        nonlocal written
        if gradebook is not None:
            write_gradebook(rows, gradebook, seed=seed_value, overwrite=overwrite or written,
                            complete=complete)
            written = True

    if rows:
        save(not todo)
    for k, path in enumerate(todo):
        try:
            mine = grade_notebook(path, notebooks=notebooks, seed=seed_value, quick=quick,
                                  timeout=timeout, budget=budget)
        except Exception as err:  # the grader's own failure: said, and the batch goes on
            status = GRADER_FAILED
            head = {"student": Path(path).resolve().parent.name, "notebook": Path(path).name}
            mine = result_rows(head, f"the grader failed on this notebook ({type(err).__name__}"
                               f": {_one_line(err)[:300]}): not graded; this is a fault of "
                               "sunlab, not of the student", result="grader error")
        rows += mine
        report_rows(path, mine, report)
        save(k == len(todo) - 1)
    if status != GRADER_FAILED and any(
            r["points"] is not None and r["points"] < r["max_points"] for r in rows):
        status = 1
    return rows, status
