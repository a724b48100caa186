"""The student edition states no answer that its checks grade (issue 48), one test per
exercise: no line of the teacher's answer (its code, not its def line, docstring or comments)
appears anywhere else in the student edition of its notebook, text or code.
"""

import re
import sys
from pathlib import Path

import pytest

from sunlab import calibration, centroid, io, stats
from sunlab.course import capstone, editions, hidden

sys.path.insert(0, str(Path(__file__).parents[1]))
from test_course import BOOKS, EXERCISES  # noqa: E402


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
    ex = next(e for exs in EXERCISES.values() for e in exs if e.number == number)
    nb = editions.edition(BOOKS[ex.notebook], ex.notebook, student=True)
    text = _norm("\n".join(c.source for c in nb.cells))
    lines = _answer_lines(BOOKS[ex.notebook].cells[ex.solution_cell].source)
    shown = [line for line in lines if _norm(line) in text]
    assert not shown, f"exercise {number}: the student edition shows {shown[0]!r}"


def test_the_fit_notebook_08_demonstrates_misses_the_capstone_goal(tmp_path):
    """Section 3's demonstration (a fit on the shipped 5 x 5 example) is not 08.2's answer: each
    fit call in a code cell of the student edition, run on the training run of the student's own
    capstone recording, misses the goal that check 08.2 grades on its test run."""
    name = "08-calibrate-your-own-sensor.ipynb"
    nb = editions.edition(BOOKS[name], name, student=True)
    calls = [call for c in nb.cells if c.cell_type == "code"
             for call in re.findall(r"calibration\.fit\([^()]*\)", c.source)]
    assert calls, "notebook 08 demonstrates no calibration.fit call"
    rec = capstone.write_recording(tmp_path / "rec", capstone.STUDENT_SEED)
    cen = {run: centroid.locate(io.open_frames(rec.folder / run, dark=rec.folder / "dark",
                                               flat=rec.folder / "flat"),
                                "projection", progress=False) for run in ("train", "test")}
    for call in calls:
        cal = eval(call, {"calibration": calibration, "train": cen["train"]})  # noqa: S307
        t = stats.evaluate(cal, cen["test"]).iloc[:, 0]
        assert any(t[(a, "mu")] >= hidden.CAPSTONE_MU_DEG or t[(a, "M")] >= hidden.CAPSTONE_M_DEG
                   for a in ("alpha", "beta")), f"{call} reaches the capstone's goal: 08.2's answer"
