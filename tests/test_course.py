"""The course (sunlab.course, ``sunlab course``, docs/course.md): exercises with checks that
pass on the answers and fail on wrong ones, and a student edition that holds no answer.

``test_teacher_edition_passes_and_each_check_catches_a_wrong_answer`` executes each notebook's
teacher edition once in quick mode, cell by cell in one kernel: every check must pass on the
answer; then the answer is swapped for a plausible wrong one (:data:`WRONG`), the check must
fail with an AssertionError, and the answer is run again before the notebook goes on.
"""

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from sunlab import course
from sunlab.errors import ConfigurationError

nbformat = pytest.importorskip("nbformat")

NOTEBOOK_DIR = Path(__file__).parents[1] / "notebooks"
CELL_TIMEOUT_S = 900

#: One plausible wrong answer per exercise; each replaces the marked answer of its cell.
WRONG = {
    # degrees given to np.cos
    "01.1": "def flux_ratio(alpha_deg, beta_deg):\n"
            "    return np.cos(alpha_deg) * np.cos(beta_deg)",
    # the derivative per radian, not per degree
    "01.2": "def px_per_degree(alpha_deg):\n"
            "    return F / p / np.cos(np.radians(alpha_deg)) ** 2",
    # an off-by-one window: rows r-3 .. r+1 instead of r-2 .. r+2
    "02.1": "def window_search(frame, size=5, need=18):\n"
            "    f = np.asarray(frame, dtype=float)\n"
            "    border = np.zeros(f.shape, bool)\n"
            "    border[:2], border[-2:], border[:, :2], border[:, -2:] = True, True, True, True\n"
            "    i_m = f[border].mean()\n"
            "    above = f > 3 * i_m\n"
            "    windows = np.lib.stride_tricks.sliding_window_view(np.pad(above, 2), (5, 5))\n"
            "    counts = np.roll(windows.sum(axis=(2, 3)), 1, axis=0)\n"
            "    ok = above & (counts >= need)\n"
            "    ok[[0, -1], :] = False\n"
            "    ok[:, [0, -1]] = False\n"
            "    row, col = np.argwhere(ok)[0]\n"
            "    return i_m, int(row), int(col)",
    # the Fisher information of a Gaussian of constant variance: mu^2 for mu
    "02.2": "def photon_crlb(n_e, b_e, radius, edge, s=8):\n"
            "    h = int(np.ceil(radius + edge + 3))\n"
            "    centres = np.arange(-h, h + 1)\n"
            "    grid = (centres[:, None] + (np.arange(s) + 0.5) / s - 0.5).ravel()\n"
            "    def share(x0, y0=0.2):\n"
            "        img = C.disk_profile(grid[None, :] - x0, grid[:, None] - y0, radius, edge)\n"
            "        return img.reshape(centres.size, s, centres.size, s).mean(axis=(1, 3))\n"
            "    norm = share(0.3).sum()\n"
            "    mu = n_e * share(0.3) / norm + b_e\n"
            "    dmu = n_e * (share(0.3 + 1e-3) - share(0.3 - 1e-3)) / (2e-3 * norm)\n"
            "    return 1.0 / np.sqrt(np.sum(dmu ** 2 / mu ** 2))",
    # cos of alpha in degrees
    "03.1": "def angles_from_centroid(x, y):\n"
            "    a = np.degrees(np.arctan((np.asarray(x) - X_CF) * P / F))\n"
            "    b = np.degrees(np.arctan((np.asarray(y) - Y_CF) * P * np.cos(a) / F))\n"
            "    return a, b",
    # a wrong sign
    "03.2": "def ideal_alpha_error(alpha_deg, delta_f_mm):\n"
            "    a = np.radians(alpha_deg)\n"
            "    return -np.degrees(delta_f_mm / F * np.sin(a) * np.cos(a))",
    # an off-by-one total degree: k in 0..n-1
    "04.1": "xm, ym = train.x.mean('shot').values, train.y.mean('shot').values\n"
            "def scaled(v, ref):\n"
            "    return 2 * (v - ref.min()) / (ref.max() - ref.min()) - 1\n"
            "def design(x, y, n):\n"
            "    u, v = scaled(x, xm), scaled(y, ym)\n"
            "    terms = [u ** (k - l) * v ** l for k in range(n) for l in range(k + 1)]\n"
            "    return np.stack(terms, -1)\n"
            "def validation_errors(n):\n"
            "    tr, va = [], []\n"
            "    for angle in ('alpha', 'beta'):\n"
            "        ref = train[angle].values\n"
            "        coef, *_ = np.linalg.lstsq(design(xm, ym, n), ref, rcond=None)\n"
            "        tr.append(np.abs(design(xm, ym, n) @ coef - train[angle].values).mean())\n"
            "        est = design(val.x.values, val.y.values, n) @ coef\n"
            "        va.append(np.abs(est - val[angle].values[:, None]).mean())\n"
            "    return sum(tr), sum(va)\n"
            "errs = {n: validation_errors(n) for n in range(1, 9)}\n"
            "chosen = min(errs, key=lambda n: errs[n][1])",
    # the population standard deviation (ddof=0)
    "04.2": "mine = {}\n"
            "for angle in ('alpha', 'beta'):\n"
            "    local_err, max_err = err[angle].mean('shot'), err[angle].max('shot')\n"
            "    mine[(angle, 'mu')] = float(local_err.mean())\n"
            "    mine[(angle, 'sigma')] = float(local_err.std())\n"
            "    mine[(angle, 'M')] = float(max_err.mean())\n"
            "    mine[(angle, 'sigma_M')] = float(max_err.std())",
    # the standard deviation of X instead of |X|
    "09.1": "ratio_uniform = (1 / 3) ** 0.5 / (1 / 2)\n"
            "ratio_normal = 1 / (2 / np.pi) ** 0.5",
    # a wrong sign: up minus down
    "09.2": "def backlash_from_errors(e, d):\n"
            "    e, d = np.asarray(e, dtype=float), np.asarray(d)\n"
            "    return 0.5 * (np.nanmean(e[d > 0]) - np.nanmean(e[d < 0]))",
}


def _books():
    return {p.name: nbformat.read(p, as_version=4)
            for p in sorted(NOTEBOOK_DIR.glob("[0-9][0-9]-*.ipynb"))}


BOOKS = _books()
EXERCISES = {name: course.find_exercises(nb, name) for name, nb in BOOKS.items()}
WITH_EXERCISES = [name for name, ex in EXERCISES.items() if ex]


# ------------------------------------------------------------------ the exercises as written

def test_at_least_8_exercises_in_at_least_5_notebooks():
    found = [ex for exs in EXERCISES.values() for ex in exs]
    assert len(found) >= 8 and len(WITH_EXERCISES) >= 5, [ex.number for ex in found]


@pytest.mark.parametrize("name", WITH_EXERCISES)
def test_each_answer_has_markers_hint_and_a_check_within_two_code_cells(name):
    nb = BOOKS[name]
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    for ex in EXERCISES[name]:
        src = nb.cells[ex.solution_cell].source
        assert course.BEGIN_SOLUTION in src and course.END_SOLUTION in src
        assert ex.hint, f"exercise {ex.number} has no '# Hint:' line"
        assert ex.number.startswith(name[:2]), f"exercise {ex.number} in {name}"
        gap = code.index(ex.check_cell) - code.index(ex.solution_cell)
        assert 1 <= gap <= 2, f"exercise {ex.number}: its check is {gap} code cells on"
        check = nb.cells[ex.check_cell].source
        assert "assert " in check and "Check" in check, f"check {ex.number} asserts nothing"


def test_every_exercise_has_a_wrong_answer_to_test_its_check():
    numbers = {ex.number for exs in EXERCISES.values() for ex in exs}
    assert numbers == set(WRONG)


def test_no_other_cell_carries_solution_markers():
    for name, nb in BOOKS.items():
        marked = [i for i, c in enumerate(nb.cells) if course.BEGIN_SOLUTION in c.source]
        assert marked == [ex.solution_cell for ex in EXERCISES[name]], name


# ------------------------------------------------------------------ the library and the CLI

def test_replace_solution_keeps_the_rest_of_the_cell():
    src = ("# Exercise 01.1: t\n# Hint: h\ndef f():\n    ### BEGIN SOLUTION\n    return 1\n"
           "    ### END SOLUTION\nprint(f())\n")
    out = course.replace_solution(src, "raise NotImplementedError('h')")
    assert out == ("# Exercise 01.1: t\n# Hint: h\ndef f():\n    raise NotImplementedError('h')\n"
                   "print(f())\n")


def test_a_solution_without_its_check_is_refused():
    v4 = nbformat.v4
    answer = "# Exercise 07.1: t\n### BEGIN SOLUTION\nx = 1\n### END SOLUTION"
    cells = [v4.new_code_cell(answer), v4.new_code_cell("a = 1"), v4.new_code_cell("b = 1"),
             v4.new_code_cell("# Check 07.1\nassert x == 1")]
    with pytest.raises(ConfigurationError, match="no '# Check 07.1' cell within"):
        course.find_exercises(v4.new_notebook(cells=cells), "07-x.ipynb")
    del cells[1]
    assert [e.number for e in course.find_exercises(v4.new_notebook(cells=cells))] == ["07.1"]


def test_unbalanced_markers_are_refused():
    v4 = nbformat.v4
    cells = [v4.new_code_cell("# Exercise 07.1: t\n### BEGIN SOLUTION\nx = 1\n")]
    with pytest.raises(ConfigurationError, match="cell 0: found 1 .* and 0"):
        course.find_exercises(v4.new_notebook(cells=cells), "07-x.ipynb")


def _sunlab(*args, cwd=None):
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).parents[1])}
    return subprocess.run([sys.executable, "-m", "sunlab", *args], capture_output=True,
                          text=True, cwd=cwd, env=env)


def test_python_m_sunlab_course_writes_both_editions(tmp_path):
    res = _sunlab("course", "--out", str(tmp_path / "class"))
    assert res.returncode == 0, res.stderr
    n_ex = sum(map(len, EXERCISES.values()))
    assert f"{n_ex} exercises in {len(WITH_EXERCISES)} notebooks" in res.stdout
    for name in BOOKS:
        student = (tmp_path / "class" / "student" / name).read_text()
        student_nb = nbformat.reads(student, as_version=4)
        teacher = nbformat.read(tmp_path / "class" / "teacher" / name, as_version=4)
        assert "BEGIN SOLUTION" not in student and "END SOLUTION" not in student, name
        for ex in EXERCISES[name]:
            # the quick cell comes first: every index moves by one
            sol = teacher.cells[ex.solution_cell + 1]
            assert course.BEGIN_SOLUTION in sol.source
            assert sol.metadata["nbgrader"]["solution"] is True
            assert teacher.cells[ex.check_cell + 1].metadata["nbgrader"]["grade"] is True
            assert f"Exercise {ex.number}" in student and "raise NotImplementedError" in student
            locked = student_nb.cells[ex.check_cell + 1].metadata
            assert locked["editable"] is False and locked["nbgrader"]["locked"] is True
        first_code = next(c for c in teacher.cells if c.cell_type == "code")
        assert first_code.source == course.QUICK_CELL, name
    again = _sunlab("course", "--out", str(tmp_path / "class"))
    assert again.returncode == 1 and "--overwrite" in again.stderr, again.stderr


def test_course_without_notebooks_names_the_folder_and_the_fix(tmp_path):
    res = _sunlab("course", "--out", str(tmp_path / "c"), "--notebooks", str(tmp_path))
    assert res.returncode == 1
    assert str(tmp_path) in res.stderr and "Fix:" in res.stderr and "Traceback" not in res.stderr


def test_grade_tells_a_pass_a_wrong_answer_and_an_unanswered_exercise(tmp_path):
    """``sunlab course --grade``: a student's notebook executed, each check reported."""
    v4 = nbformat.v4

    def exercise(n, answer, check):
        return [v4.new_code_cell(f"# Exercise 07.{n}: t\n# Hint: h\n{answer}"),
                v4.new_code_cell(f"# Check 07.{n}\n{check}")]

    stub = "raise NotImplementedError('Exercise 07.3: yours')"
    cells = (exercise(1, "x = 2", "assert x == 2, 'x is two'")
             + exercise(2, "y = 3", "assert y == 2, 'y is two: count again'")
             + exercise(3, stub, "assert z == 2, 'z is two'"))
    path = tmp_path / "07-student.ipynb"
    nbformat.write(v4.new_notebook(cells=cells), path)
    res = _sunlab("course", "--grade", str(path))
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert lines[0] == f"{path}: 1 of 3 checks pass"
    assert re.match(r"\s+07\.1\s+pass$", lines[1]), lines
    assert re.match(r"\s+07\.2\s+wrong\s+y is two: count again$", lines[2]), lines
    assert re.match(r"\s+07\.3\s+not answered\s+Exercise 07.3: yours$", lines[3]), lines


def test_grading_a_file_that_is_not_a_notebook_says_so(tmp_path):
    bad = tmp_path / "03-answers.ipynb"
    bad.write_text("my answers: 42")
    res = _sunlab("course", "--grade", str(bad))
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert f"{bad}: not a Jupyter notebook" in res.stderr and "Fix:" in res.stderr


# ------------------------------------------------------------------ executed editions

def _client(nb):
    nbclient = pytest.importorskip("nbclient")
    return nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                   resources={"metadata": {"path": str(NOTEBOOK_DIR)}})


def test_student_edition_stops_at_the_first_exercise():
    nbclient = pytest.importorskip("nbclient")
    name = "03-geometric-models.ipynb"  # the quickest to reach its first exercise
    nb = course.student_notebook(BOOKS[name], name)
    first = EXERCISES[name][0].solution_cell + 1  # after the quick cell
    with pytest.raises(nbclient.exceptions.CellExecutionError) as info:
        _client(nb).execute()
    assert info.value.ename == "NotImplementedError"
    assert f"Exercise {EXERCISES[name][0].number}" in info.value.evalue
    ran = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.execution_count]
    assert ran and ran[-1] == first, (ran, first)


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_EXERCISES)
def test_teacher_edition_passes_and_each_check_catches_a_wrong_answer(name):
    nbclient = pytest.importorskip("nbclient")
    nb = course.teacher_notebook(BOOKS[name], name)
    exercises = {ex.check_cell + 1: ex for ex in EXERCISES[name]}
    client = _client(nb)
    caught = []
    with client.setup_kernel():
        for i, cell in enumerate(nb.cells):
            if cell.cell_type != "code":
                continue
            client.execute_cell(cell, i)  # raises if a check fails on the answer
            ex = exercises.get(i)
            if ex is None:
                continue
            answer = nb.cells[ex.solution_cell + 1]
            wrong = nbformat.v4.new_code_cell(
                course.replace_solution(answer.source, WRONG[ex.number]))
            client.execute_cell(wrong, i)
            with pytest.raises(nbclient.exceptions.CellExecutionError) as info:
                client.execute_cell(nbformat.v4.new_code_cell(cell.source), i)
            assert info.value.ename == "AssertionError", (ex.number, info.value.ename)
            assert re.search(r"\w", info.value.evalue), f"check {ex.number}: no message"
            caught.append(ex.number)
            client.execute_cell(nbformat.v4.new_code_cell(answer.source), i)  # the answer back
    assert caught == [ex.number for ex in EXERCISES[name]]
