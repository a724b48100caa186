"""Three simulated students of the course, for the grading tests and the teacher's demo.

:func:`write_submissions` writes ``ROOT/right/NN.ipynb``, ``ROOT/wrong/NN.ipynb`` and
``ROOT/tampered/NN.ipynb`` from the student edition of course notebooks:

* **right**: every exercise answered with the teacher's answer, every written answer written;
* **wrong**: every exercise answered with the plausible wrong answer of ``WRONG`` (_answers.py),
  except the second exercise of each notebook, which holds a SyntaxError;
* **tampered**: the wrong answers, the first check cell replaced by a ``print`` that claims a
  pass, every other check cell deleted.

Run as a script, it writes them and prints the command that grades them::

    python tests/_students.py /tmp/class 03-geometric-models.ipynb 09-platform-fault.ipynb
"""

import sys
from pathlib import Path

import nbformat

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # run as a script from anywhere
    sys.path.insert(0, str(REPO))

from sunlab import course  # noqa: E402

NOTEBOOK_DIR = REPO / "notebooks"


def _wrong():
    sys.path.insert(0, str(Path(__file__).parent))
    from _answers import WRONG

    return WRONG


def write_submissions(root, names, *, notebooks=NOTEBOOK_DIR) -> dict:
    """Write the three students' copies of the notebooks ``names``; return their paths."""
    wrong = _wrong()
    root = Path(root)
    out = {"right": [], "wrong": [], "tampered": []}
    for name in names:
        source = nbformat.read(Path(notebooks) / name, as_version=4)
        exercises = course.editions.find_exercises(source, name)
        written = course.editions.find_written(source, name)
        for student in out:
            nb = course.editions.edition(source, name, student=True)
            for k, ex in enumerate(exercises):
                cell = nb.cells[ex.solution_cell + 1]  # after the quick cell
                answer = source.cells[ex.solution_cell].source
                if student == "right":
                    cell.source = answer
                elif student == "wrong" and k == 1:
                    cell.source = course.editions.replace_solution(answer, "def broken(:\n    pass")
                else:
                    cell.source = course.editions.replace_solution(answer, wrong[ex.number])
            for w in written:
                if student == "right":
                    cell = nb.cells[w.cell + 1]
                    cell.source = cell.source.replace(
                        course.editions.WRITTEN_PROMPT,
                        "My answer, in my own words, about this question.")
            if student == "tampered":
                checks = [ex.check_cell + 1 for ex in exercises]
                nb.cells[checks[0]].source = f'print("Check {exercises[0].number} passed")'
                for i in sorted(checks[1:], reverse=True):
                    del nb.cells[i]
            folder = root / student
            folder.mkdir(parents=True, exist_ok=True)
            nbformat.write(nb, folder / name)
            out[student].append(folder / name)
    return out


if __name__ == "__main__":
    made = write_submissions(sys.argv[1], sys.argv[2:] or ["03-geometric-models.ipynb"])
    paths = " ".join(str(p) for ps in made.values() for p in ps)
    print(f"sunlab course --grade {paths} --gradebook {sys.argv[1]}/gradebook")
