"""The student edition states no answer that its checks grade (issue 48), one test per
exercise: no line of the teacher's answer (its code, not its def line, docstring or comments)
appears anywhere else in the student edition of its notebook, text or code.
"""

import re
import sys
from pathlib import Path

import pytest

from sunlab.course import editions

sys.path.insert(0, str(Path(__file__).parents[1]))
from test_course import BOOKS, EXERCISES  # noqa: E402

#: exercises whose hand-out still shows the answer (issue 48 asks for the text to be reworded)
NOT_YET = {"08.2": "notebook 08's section 3 runs the capstone's fit call with its model choice"}


def _answer_lines(source):
    body = source.split(editions.BEGIN_SOLUTION, 1)[1].split(editions.END_SOLUTION, 1)[0]
    out = []
    for line in body.splitlines():
        code = line.split("#", 1)[0].strip()
        if (len(code) < 20 or code.startswith(("def ", "return (", '"""', "'''"))
                or code.startswith("return") and len(code) < 30):
            continue
        out.append(code)
    return out


def _norm(text):
    return re.sub(r"\s+", "", text)


@pytest.mark.parametrize("number", [e.number for exs in EXERCISES.values() for e in exs])
def test_the_student_edition_does_not_state_the_answer(number):
    if number in NOT_YET:
        pytest.xfail(NOT_YET[number])
    ex = next(e for exs in EXERCISES.values() for e in exs if e.number == number)
    nb = editions.edition(BOOKS[ex.notebook], ex.notebook, student=True)
    text = _norm("\n".join(c.source for c in nb.cells))
    lines = _answer_lines(BOOKS[ex.notebook].cells[ex.solution_cell].source)
    shown = [line for line in lines if _norm(line) in text]
    assert not shown, f"exercise {number}: the student edition shows {shown[0]!r}"
