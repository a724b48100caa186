"""The exercises and the two editions of a notebook (sunlab.course.editions), on a small
notebook built here: the student's has stubs and no hidden tests or model answers, the
teacher's keeps them, both carry nbgrader's metadata."""

import nbformat
import pytest

from sunlab.course import editions as E
from sunlab.errors import ConfigurationError

SOLUTION = """# Exercise 03.1: the spot's shift
# Hint: use eq. (1),
#   and mind the units.
import numpy as np
### BEGIN SOLUTION
def shift(a):
    return 12.5 * a
### END SOLUTION
print(shift(1.0))"""
CHECK = """# Check 03.1 (2 points)
assert abs(shift(1.0) - 12.5) < 1e-9, "one degree moves the spot 12.5 px"
### BEGIN HIDDEN TESTS
from sunlab.course import hidden
hidden.check("03.1", globals())
### END HIDDEN TESTS"""


def _notebook():
    v4 = nbformat.v4
    return v4.new_notebook(cells=[
        v4.new_markdown_cell("# 03"), v4.new_code_cell("x = 1"), v4.new_code_cell(SOLUTION),
        v4.new_code_cell(CHECK),
        v4.new_markdown_cell("**Written answer 03.2** (3 points)\nThe model answer."),
    ])


def test_exercises_and_written_answers_are_found_with_their_points():
    nb = _notebook()
    [ex] = E.find_exercises(nb, "03.ipynb")
    assert (ex.number, ex.title, ex.solution_cell, ex.check_cell, ex.points) == (
        "03.1", "the spot's shift", 2, 3, 2)
    assert ex.hint == "use eq. (1), and mind the units." and ex.grade_id == "ex03-1"
    [w] = E.find_written(nb, "03.ipynb")
    assert (w.number, w.cell, w.points, w.grade_id) == ("03.2", 4, 3, "ex03-2-written")


def test_student_edition_hides_the_answers_and_locks_the_checks():
    nb = E.edition(_notebook(), "03.ipynb", student=True, quick=False)
    sol, chk, written = nb.cells[2].source, nb.cells[3], nb.cells[4]
    assert E.BEGIN_SOLUTION not in sol and "12.5 * a" not in sol
    assert "raise NotImplementedError" in sol and "use eq. (1)" in sol
    assert sol.startswith("# Exercise 03.1") and sol.endswith("print(shift(1.0))")
    assert E.BEGIN_HIDDEN not in chk.source and "hidden.check" not in chk.source
    assert chk.metadata["editable"] is False and chk.metadata["deletable"] is False
    assert chk.metadata["nbgrader"]["points"] == 2
    assert written.source.endswith(E.WRITTEN_PROMPT) and "model answer" not in written.source


def test_teacher_edition_keeps_everything_and_adds_the_quick_cell():
    nb = E.edition(_notebook(), "03.ipynb", student=False, quick=True)
    assert nb.cells[1].source == E.QUICK_CELL  # before the first code cell
    assert nb.cells[3].source == SOLUTION and nb.cells[4].source == CHECK
    assert nb.cells[3].metadata["nbgrader"]["grade_id"] == "ex03-1"
    assert nb.cells[4].metadata["nbgrader"]["grade_id"] == "ex03-1-check"


def test_replace_solution_keeps_the_markers_indent():
    src = "def f():\n    ### BEGIN SOLUTION\n    return 1\n    ### END SOLUTION\n"
    assert E.replace_solution(src, "return 2\nx = 3") == "def f():\n    return 2\n    x = 3\n"
    with pytest.raises(ConfigurationError, match="expected one of each"):
        E.replace_solution("### BEGIN SOLUTION\n", "pass", where="03, cell 2")


def test_a_solution_without_its_check_is_refused():
    nb = _notebook()
    nb.cells[3].source = "# Check 03.9\npass"
    with pytest.raises(ConfigurationError, match="exercise 03.1 has no '# Check 03.1' cell"):
        E.find_exercises(nb, "03.ipynb")
    assert E.strip_hidden(CHECK).endswith("one degree moves the spot 12.5 px\"")
