"""The course: the notebooks' exercises, and the student and teacher editions a teacher hands out.

An **exercise** is a pair of code cells in a numbered notebook (docs/course.md):

* a *solution cell* whose first line is ``# Exercise NN.k: title``, whose ``# Hint:`` comment
  lines say where to start, and whose answer sits between nbgrader's markers
  ``### BEGIN SOLUTION`` and ``### END SOLUTION``;
* within the next two code cells, a *check cell* whose first line is ``# Check NN.k``: it
  computes the reference in place (from physics or from the library) and asserts the answer
  with a tolerance and a message that tells a student what is wrong.

:func:`write_course` writes two editions of every notebook: the **teacher edition** (solutions
kept, nbgrader metadata added, so it is also an nbgrader source notebook) and the **student
edition** (each solution replaced by a stub that raises :class:`NotImplementedError` with the
hint; no marker left). By default both start with a cell that selects the small settings
(``SUNLAB_QUICK=1``), so that each notebook runs in a few minutes on a laptop.
:func:`grade_notebook` executes a student's notebook and reports each check (``pass``,
``wrong``, ``not answered``, ``error``), for a teacher who does not use nbgrader.

The notebooks are read with nbformat from the ``notebooks/`` folder of a sunlab checkout (the
package's parent folder); a sunlab installed from a wheel carries no notebooks, and then the
folder must be given (``notebooks=``, or ``sunlab course --notebooks DIR``).

Examples
--------
>>> src = "# Exercise 01.1: x\\n# Hint: two.\\n### BEGIN SOLUTION\\nx = 2\\n### END SOLUTION\\n"
>>> print(replace_solution(src, "x = None"))
# Exercise 01.1: x
# Hint: two.
x = None
<BLANKLINE>
>>> solution_hint(src)
'two.'
"""

from __future__ import annotations

import copy
import re
from pathlib import Path
from typing import NamedTuple

from .errors import ConfigurationError

__all__ = [
    "BEGIN_SOLUTION",
    "END_SOLUTION",
    "Exercise",
    "QUICK_CELL",
    "default_notebook_dir",
    "find_exercises",
    "grade_notebook",
    "replace_solution",
    "solution_hint",
    "student_notebook",
    "teacher_notebook",
    "write_course",
]

#: nbgrader's markers around the answer in a solution cell
BEGIN_SOLUTION = "### BEGIN SOLUTION"
END_SOLUTION = "### END SOLUTION"
_EXERCISE = re.compile(r"^# Exercise (\d\d\.\d+): *(.+)$")
_CHECK = re.compile(r"^# Check (\d\d\.\d+)\b")
_HINT = re.compile(r"^\s*# Hint: ?(.*)$")
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
    """

    notebook: str
    number: str
    title: str
    solution_cell: int
    check_cell: int
    hint: str


def _nbformat():
    try:
        import nbformat
    except ImportError:  # pragma: no cover - nbformat comes with Jupyter
        raise ConfigurationError(
            "nbformat: not installed; the course reads and writes notebooks with it. "
            "Fix: pip install nbformat (it comes with Jupyter)") from None
    return nbformat


def _read(nbf, path: Path):
    """A notebook read with nbformat; a file that is not one gives a clear error."""
    try:
        return nbf.read(path, as_version=4)
    except OSError:
        raise
    except Exception as err:  # NotJSONError, a schema ValidationError, a missing key ...
        raise ConfigurationError(
            f"{path}: not a Jupyter notebook ({type(err).__name__}: "
            f"{' '.join(str(err).split())[:200]}). Fix: give an .ipynb file saved by Jupyter"
        ) from None


def _nbclient():
    try:
        import nbclient
    except ImportError:  # pragma: no cover - nbclient comes with Jupyter
        raise ConfigurationError(
            "nbclient: not installed; grading executes the notebook with it. "
            "Fix: pip install nbclient ipykernel (they come with Jupyter)") from None
    return nbclient


def default_notebook_dir() -> Path:
    """The ``notebooks/`` folder of the sunlab checkout this package is imported from.

    Raises
    ------
    ConfigurationError
        When the package is not imported from a checkout (an installed wheel has no notebooks).
    """
    here = Path(__file__).resolve().parents[1] / "notebooks"
    if not any(here.glob("[0-9][0-9]-*.ipynb")):
        raise ConfigurationError(
            f"notebooks: no numbered notebook in {here}; sunlab installed as a package carries "
            "no notebooks. Fix: clone the sunlab repository and give its notebooks folder "
            "(sunlab course --notebooks PATH/TO/sunlab/notebooks)")
    return here


def solution_hint(source: str) -> str:
    """The hint of a solution cell: its ``# Hint:`` comment lines, joined ('' when none)."""
    lines, inside = [], False
    for line in source.splitlines():
        if line.strip() == BEGIN_SOLUTION:
            break
        m = _HINT.match(line)
        if m:
            inside = True
            lines.append(m.group(1).strip())
        elif inside and line.lstrip().startswith("#"):
            lines.append(line.lstrip()[1:].strip())
        else:
            inside = False
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
    """
    b, e, lines = _solution_span(source, where)
    indent = lines[b][: len(lines[b]) - len(lines[b].lstrip())]
    new = [indent + c if c else c for c in code.splitlines()]
    return "\n".join(lines[:b] + new + lines[e + 1:]) + "\n"


def find_exercises(nb, name: str = "notebook") -> list[Exercise]:
    """The exercises of a notebook, in order.

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
                            solution_hint(src)))
    return out


def _stub(ex: Exercise) -> str:
    hint = f" Hint: {ex.hint}" if ex.hint else ""
    msg = f"Exercise {ex.number} ({ex.title}) is yours to answer: replace this line.{hint}"
    return f"# YOUR CODE HERE\nraise NotImplementedError({msg!r})"


def _edition(nb, name: str, *, student: bool, quick: bool):
    out = copy.deepcopy(nb)
    for cell in out.cells:
        if cell.cell_type == "code":
            cell.outputs, cell.execution_count = [], None
    for ex in find_exercises(nb, name):
        tag = f"ex{ex.number.replace('.', '-')}"
        sol, chk = out.cells[ex.solution_cell], out.cells[ex.check_cell]
        if student:
            sol.source = replace_solution(sol.source, _stub(ex), where=f"{name}, cell "
                                          f"{ex.solution_cell}").rstrip("\n")
        sol.metadata["nbgrader"] = {"grade": False, "solution": True, "locked": False,
                                    "grade_id": tag, "schema_version": 3}
        chk.metadata["nbgrader"] = {"grade": True, "solution": False, "locked": True,
                                    "points": 1, "grade_id": f"{tag}-check",
                                    "schema_version": 3}
        if student:  # Jupyter keeps a student from editing or deleting a check
            chk.metadata.update(editable=False, deletable=False)
            sol.metadata["deletable"] = False
    if quick:
        nbf = _nbformat()
        first = next((i for i, c in enumerate(out.cells) if c.cell_type == "code"),
                     len(out.cells))
        out.cells.insert(first, nbf.v4.new_code_cell(QUICK_CELL))
    return out


def teacher_notebook(nb, name: str = "notebook", *, quick: bool = True):
    """The teacher edition of a notebook: solutions kept, outputs cleared, nbgrader metadata
    on every solution and check cell; with ``quick``, a first code cell selecting the small
    settings."""
    return _edition(nb, name, student=False, quick=quick)


def student_notebook(nb, name: str = "notebook", *, quick: bool = True):
    """The student edition of a notebook: every marked answer replaced by a stub that raises
    :class:`NotImplementedError` with the exercise's hint; no solution marker left."""
    return _edition(nb, name, student=True, quick=quick)


def write_course(out, *, notebooks=None, quick: bool = True, overwrite: bool = False) -> dict:
    """Write the student and teacher editions of the course's notebooks.

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
        ``student`` and ``teacher`` (lists of the paths written) and ``exercises`` (every
        :class:`Exercise`, in the order of study).

    Raises
    ------
    ConfigurationError
        No numbered notebook in ``notebooks``, or a malformed exercise (names the cell).
    sunlab.atomic.OutputExistsError
        A notebook of an edition exists and ``overwrite`` is False.
    """
    from . import atomic

    nbf = _nbformat()
    src = Path(notebooks) if notebooks is not None else default_notebook_dir()
    paths = sorted(src.glob("[0-9][0-9]-*.ipynb"))
    if not paths:
        raise ConfigurationError(
            f"notebooks: no numbered notebook (NN-title.ipynb) in {src}. Fix: give the "
            "notebooks folder of a sunlab checkout")
    out = Path(out)
    books = {p.name: _read(nbf, p) for p in paths}
    exercises = [ex for name, nb in books.items() for ex in find_exercises(nb, name)]
    written = {"student": [], "teacher": [], "exercises": exercises}
    for edition, make in (("teacher", teacher_notebook), ("student", student_notebook)):
        folder = out / edition
        folder.mkdir(parents=True, exist_ok=True)
        for name, nb in books.items():
            text = nbf.writes(make(nb, name, quick=quick)) + "\n"
            written[edition].append(atomic.write_text(folder / name, text, overwrite=overwrite,
                                                      flag="--overwrite"))
    return written


def _error_of(cell):
    return next((o for o in cell.get("outputs", []) if o.get("output_type") == "error"), None)


def grade_notebook(path, *, timeout: float = 900.0) -> list[dict]:
    """Execute a student's notebook top to bottom and grade every check cell.

    The notebook runs in a fresh kernel in its own folder, going on past errors (an
    unanswered exercise must not hide the others); each ``# Check NN.k`` cell then says
    how its exercise went.

    Parameters
    ----------
    path : str or path-like
        A notebook of the student edition, with the student's answers.
    timeout : float
        Limit per cell, s.

    Returns
    -------
    list of dict
        One per check cell, in order: ``exercise`` (``"NN.k"``), ``result`` (``"pass"``,
        ``"wrong"``: the check's assertion failed, ``"not answered"``: the stub still raises
        or a name the exercise defines is missing, ``"error"``: anything else) and ``message``
        (the check's message or the error, '' on a pass).

    Raises
    ------
    ConfigurationError
        The notebook holds no check cell.
    """
    nbf, nbclient = _nbformat(), _nbclient()
    path = Path(path)
    nb = _read(nbf, path)
    cells = [(i, c) for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    checks = [(i, _CHECK.match(c.source).group(1)) for i, c in cells if _CHECK.match(c.source)]
    if not checks:
        raise ConfigurationError(
            f"{path}: no '# Check NN.k' cell. Fix: give a notebook of the course (sunlab "
            "course --out DIR writes them)")
    first = {i: c.source.split("\n", 1)[0] for i, c in cells}
    answers = {_EXERCISE.match(first[i]).group(1): c for i, c in cells
               if _EXERCISE.match(first[i])}
    nbclient.NotebookClient(nb, timeout=timeout, kernel_name="python3", allow_errors=True,
                            resources={"metadata": {"path": str(path.parent)}}).execute()
    rows = []
    for i, number in checks:
        err, stub = _error_of(nb.cells[i]), _error_of(answers.get(number, {}))
        if err is None:
            result, message = "pass", ""
        elif stub is not None and stub["ename"] == "NotImplementedError":
            result, message = "not answered", stub["evalue"]
        elif err["ename"] == "AssertionError":
            result, message = "wrong", err["evalue"]
        elif err["ename"] == "NameError":
            result, message = "not answered", err["evalue"]
        else:
            result, message = "error", f"{err['ename']}: {err['evalue']}"
        rows.append({"exercise": number, "result": result, "message": message})
    return rows
