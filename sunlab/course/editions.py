"""The notebooks' exercises, and the student and teacher editions a teacher hands out.

An **exercise** is a pair of code cells in a numbered notebook (docs/teacher-notes.md):

* a *solution cell* whose first line is ``# Exercise NN.k: title``, whose ``# Hint:`` comment
  lines say where to start, and whose answer sits between nbgrader's markers
  ``### BEGIN SOLUTION`` and ``### END SOLUTION``;
* within the next two code cells, a *check cell* whose first line is ``# Check NN.k`` (with
  ``(N points)`` when it is worth more than one): it computes the reference in place (from
  physics or from the library) and asserts the answer with a tolerance and a message that tells
  a student what is wrong, then runs the exercise's hidden check between nbgrader's markers
  ``### BEGIN HIDDEN TESTS`` and ``### END HIDDEN TESTS`` (:mod:`sunlab.course.hidden`).

A **written answer** is a markdown cell whose first line is ``**Written answer NN.k** (N
points)``; the rest of the cell is the teacher's model answer.

:func:`write_course` writes the teacher and the student edition of every notebook
(:func:`edition`), all or nothing; :mod:`sunlab.course.grading` grades students' notebooks
against the teacher edition. The notebooks are read with nbformat from the ``notebooks/`` folder
of a sunlab checkout (the package's parent folder); a sunlab installed from a wheel carries no
notebooks, and then the folder must be given (``notebooks=``, or ``sunlab course --notebooks
DIR``). The package's docstring shows :func:`replace_solution` and :func:`solution_hint`.
"""

from __future__ import annotations

import copy
import importlib
import re
from pathlib import Path
from typing import NamedTuple

from .. import atomic
from ..errors import ConfigurationError

__all__ = ["write_course"]

#: nbgrader's markers around the answer in a solution cell
BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"
#: nbgrader's markers around the hidden part of a check cell
BEGIN_HIDDEN = "### BEGIN HIDDEN TESTS"
END_HIDDEN = "### END HIDDEN TESTS"
#: what a written answer's cell holds in the student edition (nbgrader's own prompt)
WRITTEN_PROMPT = "YOUR ANSWER HERE"
_EXERCISE = re.compile(r"^# Exercise (\d\d\.\d+): *(.+)$")
_CHECK = re.compile(r"^# Check (\d\d\.\d+)\b")
_POINTS = re.compile(r"\((\d+) points?\)")
_WRITTEN = re.compile(r"^\*\*Written answer (\d\d\.\d+)\*\*")
_HINT = re.compile(r"^\s*# Hint: ?(.*)$")
#: a hidden-test block, markers included (one left open runs to the end of the cell)
_HIDDEN_BLOCK = re.compile(
    rf"^[ \t]*{BEGIN_HIDDEN}[ \t]*\n(.*?)(?:^[ \t]*{END_HIDDEN}[ \t]*(?:\n|\Z)|\Z)", re.M | re.S)
#: how many code cells after a solution cell its check cell may come
CHECK_WITHIN = 2

#: the first code cell of each edition written with ``quick=True``
QUICK_CELL = """\
# Small settings for a class (written by `sunlab course`): this notebook runs in a few minutes.
# For the full settings, delete this cell and restart the kernel, or start Jupyter with
# SUNLAB_QUICK=0 in the environment.
import os

os.environ.setdefault("SUNLAB_QUICK", "1")"""


class Exercise(NamedTuple):
    """One exercise of a notebook.

    Attributes
    ----------
    notebook : str
        File name of the notebook.
    number : str
        ``"NN.k"``: the notebook's number and the exercise's rank in it.
    title : str
        What the exercise asks, from its first line.
    solution_cell, check_cell : int
        Indices of the solution cell and of its check cell in ``nb.cells``.
    hint : str
        The hint the student edition's stub raises.
    points : int
        What the check is worth (``(N points)`` on its first line; 1 when not said).
    """

    notebook: str
    number: str
    title: str
    solution_cell: int
    check_cell: int
    hint: str
    points: int = 1

    @property
    def grade_id(self) -> str:
        """nbgrader's id of the solution cell, ``exNN-k`` (the check's adds ``-check``)."""
        return f"ex{self.number.replace('.', '-')}"


class Written(NamedTuple):
    """A written answer (graded by hand): ``number``, ``cell`` (index), ``points``."""

    notebook: str
    number: str
    cell: int
    points: int

    @property
    def grade_id(self) -> str:
        """nbgrader's id of the cell, ``exNN-k-written``."""
        return f"ex{self.number.replace('.', '-')}-written"


def _points(source: str) -> int:
    """What a check or written answer is worth: ``(N points)`` on its first line, or 1."""
    m = _POINTS.search(source.split("\n", 1)[0])
    return int(m.group(1)) if m else 1


def _jupyter(name: str):
    """nbformat or nbclient, which read, write and run the course's notebooks."""
    try:
        return importlib.import_module(name)
    except ImportError:  # pragma: no cover - they come with Jupyter
        raise ConfigurationError(
            f"{name}: not installed; the course reads, writes and runs notebooks with it. "
            "Fix: pip install nbformat nbclient ipykernel (they come with Jupyter)") from None


def _read(path: Path):
    """A notebook read with nbformat; a file that is not one gives a clear error."""
    try:
        return _jupyter("nbformat").read(path, as_version=4)
    except OSError:
        raise
    except Exception as err:  # NotJSONError, a schema ValidationError, a missing key ...
        raise ConfigurationError(
            f"{path}: not a Jupyter notebook ({type(err).__name__}: "
            f"{' '.join(str(err).split())[:200]}). Fix: give an .ipynb file saved by Jupyter"
        ) from None


def default_notebook_dir() -> Path:
    """The ``notebooks/`` folder of the sunlab checkout this package is imported from.

    Returns
    -------
    pathlib.Path
        The folder beside the ``sunlab`` package, holding ``NN-*.ipynb`` notebooks.

    Raises
    ------
    ConfigurationError
        When the package is not imported from a checkout (an installed wheel has no notebooks).
    """
    here = Path(__file__).resolve().parents[2] / "notebooks"
    if not any(here.glob("[0-9][0-9]-*.ipynb")):
        raise ConfigurationError(
            f"notebooks: no numbered notebook in {here}; sunlab installed as a package carries "
            "no notebooks. Fix: clone the sunlab repository and give its notebooks folder "
            "(sunlab course --notebooks PATH/TO/sunlab/notebooks)")
    return here


def solution_hint(source: str) -> str:
    """The hint of a solution cell: its ``# Hint:`` comment lines, joined.

    Parameters
    ----------
    source : str
        A solution cell's source.

    Returns
    -------
    str
        The text of the ``# Hint:`` line and of the comment lines that follow it, before
        ``### BEGIN SOLUTION``, joined by spaces; ``''`` when the cell has no hint.
    """
    lines, inside = [], False
    for line in source.splitlines():
        if line.strip() == BEGIN_SOLUTION:
            break
        m = _HINT.match(line)
        inside = bool(m) or inside and line.lstrip().startswith("#")
        if inside:
            lines.append((m.group(1) if m else line.lstrip()[1:]).strip())
    return " ".join(x for x in lines if x)


def _solution_span(source: str, where: str) -> tuple[int, int, list[str]]:
    lines = source.splitlines()
    begins = [i for i, s in enumerate(lines) if s.strip() == BEGIN_SOLUTION]
    ends = [i for i, s in enumerate(lines) if s.strip() == END_SOLUTION]
    if len(begins) != 1 or len(ends) != 1 or ends[0] < begins[0]:
        raise ConfigurationError(
            f"{where}: found {len(begins)} {BEGIN_SOLUTION!r} and {len(ends)} {END_SOLUTION!r} "
            "lines, expected one of each, BEGIN first. Fix: mark the answer of the cell once")
    return begins[0], ends[0], lines


def replace_solution(source: str, code: str, *, where: str = "cell") -> str:
    """The solution cell ``source`` with its marked answer (markers included) replaced by
    ``code``, indented like the BEGIN marker.

    Parameters
    ----------
    source : str
        A solution cell's source, with one ``### BEGIN SOLUTION`` ... ``### END SOLUTION``.
    code : str
        What takes the answer's place (a stub, or a wrong answer in the tests).
    where : str
        The cell's name for the error message.

    Returns
    -------
    str
        The new source, ending with a newline.

    Raises
    ------
    ConfigurationError
        The cell does not hold exactly one BEGIN and one END marker, BEGIN first.
    """
    b, e, lines = _solution_span(source, where)
    indent = lines[b][: len(lines[b]) - len(lines[b].lstrip())]
    new = [indent + c if c else c for c in code.splitlines()]
    return "\n".join(lines[:b] + new + lines[e + 1:]) + "\n"


def find_exercises(nb, name: str = "notebook") -> list[Exercise]:
    """The exercises of a notebook, in order.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        A course notebook (nbformat version 4).
    name : str
        The notebook's file name, kept in each :class:`Exercise` and named in errors.

    Returns
    -------
    list of Exercise
        One per solution cell (a code cell with the solution markers), with its check cell,
        hint and points.

    Raises
    ------
    ConfigurationError
        A solution cell without its ``# Exercise NN.k:`` line, without markers, or without a
        ``# Check NN.k`` cell within the next :data:`CHECK_WITHIN` code cells.
    """
    out = []
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    for rank, i in enumerate(code):
        src = nb.cells[i].source
        if BEGIN_SOLUTION not in src and END_SOLUTION not in src:
            continue
        where = f"{name}, cell {i}"
        _solution_span(src, where)
        m = _EXERCISE.match(src.splitlines()[0])
        if not m:
            raise ConfigurationError(
                f"{where}: a solution cell must start with '# Exercise NN.k: title'. Fix: add "
                "that line")
        checks = [j for j in code[rank + 1: rank + 1 + CHECK_WITHIN]
                  if _CHECK.match(nb.cells[j].source) and
                  _CHECK.match(nb.cells[j].source).group(1) == m.group(1)]
        if not checks:
            raise ConfigurationError(
                f"{where}: exercise {m.group(1)} has no '# Check {m.group(1)}' cell within the "
                f"next {CHECK_WITHIN} code cells. Fix: add the check cell after the answer")
        out.append(Exercise(name, m.group(1), m.group(2).strip(), i, checks[0],
                            solution_hint(src), _points(nb.cells[checks[0]].source)))
    return out


def find_written(nb, name: str = "notebook") -> list[Written]:
    """The written answers of a notebook: markdown cells whose first line is
    ``**Written answer NN.k** (N points)``.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        A course notebook (nbformat version 4).
    name : str
        The notebook's file name, kept in each :class:`Written`.

    Returns
    -------
    list of Written
        One per written answer, in order, with its cell index and points (1 when not said).
    """
    return [Written(name, m.group(1), i, _points(c.source)) for i, c in enumerate(nb.cells)
            if c.cell_type == "markdown" and (m := _WRITTEN.match(c.source))]


def strip_hidden(source: str) -> str:
    """A check cell's source without its hidden-test block (markers included).

    Parameters
    ----------
    source : str
        A check cell's source.

    Returns
    -------
    str
        The source without the lines from ``### BEGIN HIDDEN TESTS`` to ``### END HIDDEN
        TESTS``, trailing newlines removed.

    Examples
    --------
    >>> print(strip_hidden("assert x\\n### BEGIN HIDDEN TESTS\\ncheck()\\n### END HIDDEN TESTS\\n"))
    assert x
    """
    return _HIDDEN_BLOCK.sub("", source).rstrip("\n")


def edition(nb, name: str = "notebook", *, student: bool, quick: bool = True):
    """The student or the teacher edition of a notebook (a copy; outputs cleared, nbgrader
    metadata on every solution, check and written-answer cell).

    The **teacher edition** keeps the solutions, hidden tests and model answers: it is also an
    nbgrader source notebook. The **student edition** has every marked answer replaced by a
    stub that raises :class:`NotImplementedError` with the exercise's hint, every hidden-test
    block and model answer left out (no solution marker left), and its check cells locked.

    Parameters
    ----------
    nb : nbformat.NotebookNode
        A course notebook (left unchanged).
    name : str
        Its file name, for the stubs' and the errors' messages.
    student : bool
        Write the student edition (True) or the teacher's (False).
    quick : bool
        Insert :data:`QUICK_CELL` before the first code cell (``SUNLAB_QUICK=1``).

    Returns
    -------
    nbformat.NotebookNode
        The edition.
    """
    out = copy.deepcopy(nb)
    for cell in out.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    meta = {"schema_version": 3}
    for ex in find_exercises(nb, name):
        sol, chk = out.cells[ex.solution_cell], out.cells[ex.check_cell]
        if student:  # Jupyter keeps a student from editing or deleting a check
            hint = f" Hint: {ex.hint}" if ex.hint else ""
            msg = f"Exercise {ex.number} ({ex.title}) is yours to answer: replace this line.{hint}"
            stub = f"# YOUR CODE HERE\nraise NotImplementedError({msg!r})"
            sol.source = replace_solution(sol.source, stub, where=f"{name}, cell "
                                          f"{ex.solution_cell}").rstrip("\n")
            chk.source = strip_hidden(chk.source)
            chk.metadata.update(editable=False, deletable=False)
            sol.metadata["deletable"] = False
        sol.metadata["nbgrader"] = {"grade": False, "solution": True, "locked": False,
                                    "grade_id": ex.grade_id, **meta}
        chk.metadata["nbgrader"] = {"grade": True, "solution": False, "locked": True,
                                    "points": ex.points, "grade_id": f"{ex.grade_id}-check", **meta}
    for w in find_written(nb, name):
        cell = out.cells[w.cell]
        if student:  # the model answer stays with the teacher
            cell.source = cell.source.split("\n", 1)[0] + "\n\n" + WRITTEN_PROMPT
            cell.metadata["deletable"] = False
        cell.metadata["nbgrader"] = {"grade": True, "solution": True, "locked": False,
                                     "points": w.points, "grade_id": w.grade_id, **meta}
    if quick:
        first = next((i for i, c in enumerate(out.cells) if c.cell_type == "code"),
                     len(out.cells))
        out.cells.insert(first, _jupyter("nbformat").v4.new_code_cell(QUICK_CELL))
    return out


def write_course(out, *, notebooks=None, quick: bool = True, overwrite: bool = False) -> dict:
    """Write the student and teacher editions of the course's notebooks, all or nothing.

    Every target is checked before anything is written: without ``overwrite``, a notebook of
    either edition already in ``out`` (a student's work, perhaps) stops the run with nothing
    written. Both editions are written into a temporary folder (:func:`sunlab.atomic.atomic_files`)
    and moved into place together (SIGINT, SIGTERM and SIGHUP held back); an interrupt before
    that (Ctrl-C; SIGTERM or SIGHUP under ``sunlab course``, whose signal handling raises them)
    removes the temporary folder and leaves ``out`` as it was, and a later run clears what a
    killed writer left (:func:`sunlab.atomic.remove_stale`).

    Parameters
    ----------
    out : str or path-like
        Folder that receives ``student/`` and ``teacher/`` (created when missing).
    notebooks : str or path-like, optional
        Folder of numbered notebooks (``NN-title.ipynb``); by default the checkout's
        (:func:`default_notebook_dir`).
    quick : bool
        Begin each notebook with a cell that selects the small settings (``SUNLAB_QUICK=1``).
    overwrite : bool
        Replace notebooks that a previous run wrote.

    Returns
    -------
    dict
        ``student`` and ``teacher`` (lists of the paths written), ``exercises`` (every
        :class:`Exercise`, in the order of study) and ``written`` (every :class:`Written`).

    Raises
    ------
    ConfigurationError
        No numbered notebook in ``notebooks``, or a malformed exercise (names the cell).
    sunlab.atomic.OutputExistsError
        A notebook of an edition exists and ``overwrite`` is False (nothing written).
    """
    nbf = _jupyter("nbformat")
    src = Path(notebooks) if notebooks is not None else default_notebook_dir()
    paths = sorted(src.glob("[0-9][0-9]-*.ipynb"))
    if not paths:
        raise ConfigurationError(
            f"notebooks: no numbered notebook (NN-title.ipynb) in {src}. Fix: give the "
            "notebooks folder of a sunlab checkout")
    out = atomic.check_folder(out, (), flag="--overwrite")  # a folder, or one that can be made
    if not overwrite:
        taken = [out / e / p.name for e in ("teacher", "student") for p in paths
                 if (out / e / p.name).exists()]
        if taken:
            raise atomic.OutputExistsError(
                f"{taken[0]}: exists ({len(taken)} notebook(s) of the editions are already in "
                f"{out}); nothing was written. Fix: pass --overwrite to replace them, or "
                "choose a new folder")
    books = {p.name: _read(p) for p in paths}
    exercises = [ex for name, nb in books.items() for ex in find_exercises(nb, name)]
    written_answers = [w for name, nb in books.items() for w in find_written(nb, name)]
    with atomic.atomic_files(out, overwrite=overwrite, flag="--overwrite") as staging:
        for kind in ("teacher", "student"):
            (staging / kind).mkdir(parents=True)
            for name, nb in books.items():
                (staging / kind / name).write_text(nbf.writes(edition(
                    nb, name, student=kind == "student", quick=quick)) + "\n", encoding="utf-8")
    return {kind: [out / kind / name for name in books] for kind in ("student", "teacher")} | {
        "exercises": exercises, "written": written_answers}
