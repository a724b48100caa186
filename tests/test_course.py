"""The course (sunlab.course, ``sunlab course``, docs/course.md, docs/teacher-notes.md):
exercises whose checks pass on the answers and fail on wrong ones, hidden checks that fail on
constants and library shortcuts, a student edition that states no answer, grading that restores
the teacher's checks and writes a gradebook, and editions written all or nothing.

``test_teacher_edition_passes_and_each_check_catches_a_wrong_answer`` executes each notebook's
teacher edition once in quick mode, cell by cell in one kernel: every check (its hidden part
included) must pass on the answer; then the answer is swapped for a plausible wrong one
(:data:`WRONG`), the check must fail with an AssertionError, and the answer is run again before
the notebook goes on (tests/_answers.py). That execution is conftest.py's ``executed_notebook``,
shared with the reader-facing test of tests/test_notebooks.py: each notebook runs once.
"""

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from _answers import WRONG

from sunlab import course
from sunlab.course import hidden
from sunlab.errors import ConfigurationError

nbformat = pytest.importorskip("nbformat")

REPO = Path(__file__).parents[1]
NOTEBOOK_DIR = REPO / "notebooks"
CELL_TIMEOUT_S = 900

#: Answers that call the library function the exercise asks the student to write.
SHORTCUTS = {
    "01.1": ("def flux_ratio(alpha_deg, beta_deg):\n"
             "    return geometry.sun_vector(alpha_deg, beta_deg)[2]", "sun_vector"),
    "02.1": ("def window_search(frame, size=5, need=18):\n"
             "    i_m = C.border_mean(frame, 2)\n"
             "    return (i_m, *C.first_hit(frame, 3 * i_m, test_size=5, test_count=18))",
             "border_mean"),
    "02.3": ("def photon_crlb(n_e, b_e, radius, edge):\n"
             "    return C.crlb(n_e, b_e, 0.0, gain=1.0, radius=radius, edge=edge,\n"
             "                  quantisation=False).sigma_x", "crlb"),
    "03.1": ("def angles_from_centroid(x, y):\n"
             "    return geometry.ideal_angles(x, y, F, P, X_CF, Y_CF)", "ideal_angles"),
    "04.1": ("def validation_errors(train, val, n):\n"
             "    _, s = Polynomial.select_order(train, val, orders=[n])\n"
             "    return 0.0, float(s['alpha_mean_abs'][n] + s['beta_mean_abs'][n])",
             "select_order"),
    "05.1": ("def rectangle_areas(table):\n"
             "    return stats.rectangles(table)['area']", "rectangles"),
    "09.2": ("def backlash_from_errors(e, d):\n"
             "    return pf.approach_split(e, d)['backlash_deg']", "approach_split"),
}

#: Answers with the numbers of one bench (or one table) written in: fresh inputs must fail them.
CONSTANTS = {
    # the visible check asserts only on the backlash bench, whose backlash is 0.017 deg
    "09.2": "def backlash_from_errors(e, d):\n    return 0.017",
    # the bound that notebook 05 quotes, returned whatever the offset
    "09.1": "def abs_ratio_uniform(c, w):\n    return 0.5773502691896258",
    # notebook 01's F and p written into the answer
    "01.2": "def px_per_degree(alpha_deg):\n"
            "    return 5.0 / 0.007 / np.cos(np.radians(alpha_deg)) ** 2 * np.pi / 180",
    # notebook 03's bench written into the answer
    "03.1": "def angles_from_centroid(x, y):\n"
            "    a = np.arctan((np.asarray(x) - 640.0) * 0.007 / 5.0)\n"
            "    b = np.arctan((np.asarray(y) - 512.0) * 0.007 * np.cos(a) / 5.0)\n"
            "    return np.degrees(a), np.degrees(b)",
    # the areas of the paper's Table 4, looked up
    "05.1": "def rectangle_areas(table):\n"
            "    return dict(stats.rectangles(stats.paper_table4())['area'])",
}

#: Phrases that would state an exercise's answer (the student edition and syllabus hold none).
ANSWER_PHRASES = [
    r"cos\(alpha\) cos\(beta\)", r"sec\^2", r"1 / cos\^2", r"\(c\^2 \+ w\^2\) / \(?2 ?w",
    r"c\^2 \+ w\^2 ?/ ?3", r"sin\(alpha\) cos\(alpha\)", r"sin\(2 alpha\)",
    r"tan\(alpha\) = \(x - x_cf\)", r"tan\(beta\) = \(y - y_cf\)", r"tan\(alpha_read\)",
    r"std\(ddof=1\)", r"6 sigma_M", r"c\^2 \+ s\^2 / n", r"half the gap",
    r"M - 3 sigma_M", r"M \+ 3 sigma_M", r"UNIMODAL_BOUND\) < 1e-9",
]


def _books():
    return {p.name: nbformat.read(p, as_version=4)
            for p in sorted(NOTEBOOK_DIR.glob("[0-9][0-9]-*.ipynb"))}


BOOKS = _books()
EXERCISES = {name: course.editions.find_exercises(nb, name) for name, nb in BOOKS.items()}
WRITTEN = {name: course.editions.find_written(nb, name) for name, nb in BOOKS.items()}
WITH_EXERCISES = [name for name, ex in EXERCISES.items() if ex]


def _solution(number):
    ex = next(e for exs in EXERCISES.values() for e in exs if e.number == number)
    src = BOOKS[ex.notebook].cells[ex.solution_cell].source
    return src.split(course.editions.BEGIN_SOLUTION, 1)[1].split(course.editions.END_SOLUTION, 1)[0]


# ------------------------------------------------------------------ the exercises as written

def test_at_least_16_exercises_in_every_numbered_notebook():
    found = [ex for exs in EXERCISES.values() for ex in exs]
    assert len(found) >= 16 and len(WITH_EXERCISES) >= 9, [ex.number for ex in found]
    for nn in ("05", "06", "07", "08"):
        assert any(name.startswith(nn) for name in WITH_EXERCISES), nn


def test_points_weight_the_exercises_and_written_answers_exist():
    points = {ex.number: ex.points for exs in EXERCISES.values() for ex in exs}
    assert len(set(points.values())) >= 3, points  # not one pass/fail point each
    assert points["02.3"] > points["02.1"] > points["01.1"]  # the Cramer-Rao bound is hardest
    written = [w for ws in WRITTEN.values() for w in ws]
    assert len(written) >= 4 and all(w.points >= 2 for w in written)
    for w in written:  # the teacher's model answer, not a placeholder
        body = BOOKS[w.notebook].cells[w.cell].source.split("\n", 1)[1]
        assert len(body.split()) >= 60, f"written answer {w.number}: model answer too short"


def test_the_capstone_has_hidden_accuracy_and_export_checks():
    names = [ex.number for ex in EXERCISES["08-calibrate-your-own-sensor.ipynb"]]
    assert names == ["08.1", "08.2"]
    check = BOOKS["08-calibrate-your-own-sensor.ipynb"].cells[
        EXERCISES["08-calibrate-your-own-sensor.ipynb"][1].check_cell].source
    assert 'hidden.check("08.2", globals())' in check
    assert hidden.CAPSTONE_MU_DEG <= 0.002 and hidden.CAPSTONE_M_DEG <= 0.003


@pytest.mark.parametrize("name", WITH_EXERCISES)
def test_each_answer_has_markers_hint_a_check_and_a_hidden_check(name):
    nb = BOOKS[name]
    code = [i for i, c in enumerate(nb.cells) if c.cell_type == "code"]
    for ex in EXERCISES[name]:
        src = nb.cells[ex.solution_cell].source
        assert course.editions.BEGIN_SOLUTION in src and course.editions.END_SOLUTION in src
        assert ex.hint, f"exercise {ex.number} has no '# Hint:' line"
        assert ex.number.startswith(name[:2]), f"exercise {ex.number} in {name}"
        gap = code.index(ex.check_cell) - code.index(ex.solution_cell)
        assert 1 <= gap <= 2, f"exercise {ex.number}: its check is {gap} code cells on"
        check = nb.cells[ex.check_cell].source
        assert "assert " in check and "Check" in check, f"check {ex.number} asserts nothing"
        assert f'hidden.check("{ex.number}", globals())' in check, ex.number
        assert ex.number in hidden.CHECKS, ex.number


def test_every_exercise_has_a_wrong_answer_to_test_its_check():
    numbers = {ex.number for exs in EXERCISES.values() for ex in exs}
    assert numbers == set(WRONG) == set(hidden.CHECKS)


def test_no_other_cell_carries_solution_markers():
    for name, nb in BOOKS.items():
        marked = [i for i, c in enumerate(nb.cells) if course.editions.BEGIN_SOLUTION in c.source]
        assert marked == [ex.solution_cell for ex in EXERCISES[name]], name


def test_one_sign_convention_everywhere():
    """nomenclature.md's s = R_y(-alpha) R_x(beta) e_z; no R_y(alpha) without the minus."""
    texts = {p.name: p.read_text(encoding="utf-8") for p in NOTEBOOK_DIR.glob("*.ipynb")}
    for doc in ("course.md", "teacher-notes.md", "nomenclature.md"):
        texts[doc] = (REPO / "docs" / doc).read_text(encoding="utf-8")
    assert "R_y(-alpha) R_x(beta) e_z" in texts["nomenclature.md"]
    for name, text in texts.items():
        assert not re.search(r"R_y\(alpha", text), f"{name} writes R_y(alpha ...)"


# ------------------------------------------------------------------ no answer in the hand-out

@pytest.fixture(scope="module")
def student_texts():
    return {name: nbformat.writes(course.editions.edition(nb, name, student=True))
            for name, nb in BOOKS.items()}


def test_student_edition_carries_no_solution_line_hidden_check_or_model_answer(student_texts):
    for name, nb in BOOKS.items():
        text = student_texts[name]
        assert "BEGIN SOLUTION" not in text and "HIDDEN TESTS" not in text, name
        # a call the notebook itself demonstrates outside its exercises is the material the
        # exercise builds on (08's capstone repeats, on new frames, calls that sections 3 and 5
        # show on the shipped example), not an answer the hand-out states
        taught = "\n".join(c.source for i, c in enumerate(nb.cells)
                           if i not in {e.solution_cell for e in EXERCISES[name]})
        assert "hidden.check" not in text, name
        for ex in EXERCISES[name]:
            answer = nb.cells[ex.solution_cell].source.split(course.editions.BEGIN_SOLUTION)[1]
            for line in answer.split(course.editions.END_SOLUTION)[0].splitlines():
                line = line.strip()
                if len(line) >= 12 and not line.startswith("#") and line not in taught:
                    assert json.dumps(line)[1:-1] not in text, (ex.number, line)
        for w in WRITTEN[name]:
            model = nb.cells[w.cell].source.split("\n", 1)[1].strip()
            for sentence in re.split(r"(?<=[.:;])\s", model):
                if len(sentence) >= 30:
                    assert json.dumps(sentence)[1:-1] not in text, (w.number, sentence)


@pytest.mark.parametrize("phrase", ANSWER_PHRASES)
def test_no_answer_phrase_in_the_student_edition_or_syllabus(student_texts, phrase):
    syllabus = (REPO / "docs" / "course.md").read_text(encoding="utf-8")
    assert not re.search(phrase, syllabus), f"docs/course.md states {phrase}"
    for name, text in student_texts.items():
        assert not re.search(phrase, text), f"{name} states {phrase}"


# ------------------------------------------------------------------ hidden checks, directly

def _namespace(source):
    from scipy.optimize import curve_fit

    from sunlab import calibration, centroid, export, geometry, io, stats
    from sunlab.calibration import Polynomial
    from sunlab.reproduce import fault as pf

    ns = {"np": np, "C": centroid, "centroid": centroid, "geometry": geometry, "stats": stats,
          "pf": pf, "Polynomial": Polynomial, "calibration": calibration, "io": io,
          "export": export, "curve_fit": curve_fit,
          "F": 5.0, "P": 0.007, "p": 0.007, "X_CF": 640.0, "Y_CF": 512.0}
    exec(compile(source, "<answer>", "exec"), ns)  # noqa: S102 - the answer under test
    return ns


@pytest.mark.parametrize("number", sorted(SHORTCUTS))
def test_a_library_shortcut_fails_the_hidden_check(number):
    source, called = SHORTCUTS[number]
    with pytest.raises(AssertionError, match=rf"hidden check {number} .*calls .*{called}"):
        hidden.check(number, _namespace(source), 5)


@pytest.mark.parametrize("number", sorted(CONSTANTS))
def test_an_answer_with_one_bench_written_in_fails_the_hidden_check(number):
    with pytest.raises(AssertionError, match=rf"hidden check {number} \(fresh inputs, seed 5\)"):
        hidden.check(number, _namespace(CONSTANTS[number]), 5)


@pytest.mark.parametrize("number", ["01.1", "01.2", "02.1", "02.2", "03.1", "03.2", "05.1",
                                    "06.1", "07.1", "09.1", "09.2"])
@pytest.mark.parametrize("seed", [5, 2026])
def test_the_answer_passes_its_hidden_check_on_any_seed(number, seed, capsys):
    hidden.check(number, _namespace(_solution(number)), seed)
    assert f"Hidden check {number} passed (fresh inputs, seed {seed})" in capsys.readouterr().out


def test_the_hidden_check_names_no_answer():
    """Its message says what failed on which inputs, not the expected value or formula."""
    with pytest.raises(AssertionError) as info:
        hidden.check("01.1", _namespace(WRONG["01.1"]), 5)
    msg = str(info.value)
    assert "poses you have not seen" in msg and "cos" not in msg and "radian" not in msg


# ------------------------------------------------------------------ the library and the CLI

def test_replace_solution_keeps_the_rest_of_the_cell():
    src = ("# Exercise 01.1: t\n# Hint: h\ndef f():\n    ### BEGIN SOLUTION\n    return 1\n"
           "    ### END SOLUTION\nprint(f())\n")
    out = course.editions.replace_solution(src, "raise NotImplementedError('h')")
    assert out == ("# Exercise 01.1: t\n# Hint: h\ndef f():\n    raise NotImplementedError('h')\n"
                   "print(f())\n")


def test_a_solution_without_its_check_is_refused():
    v4 = nbformat.v4
    answer = "# Exercise 07.1: t\n### BEGIN SOLUTION\nx = 1\n### END SOLUTION"
    cells = [v4.new_code_cell(answer), v4.new_code_cell("a = 1"), v4.new_code_cell("b = 1"),
             v4.new_code_cell("# Check 07.1\nassert x == 1")]
    with pytest.raises(ConfigurationError, match="no '# Check 07.1' cell within"):
        course.editions.find_exercises(v4.new_notebook(cells=cells), "07-x.ipynb")
    del cells[1]
    found = course.editions.find_exercises(v4.new_notebook(cells=cells))
    assert [e.number for e in found] == ["07.1"]


def test_unbalanced_markers_are_refused():
    v4 = nbformat.v4
    cells = [v4.new_code_cell("# Exercise 07.1: t\n### BEGIN SOLUTION\nx = 1\n")]
    with pytest.raises(ConfigurationError, match="cell 0: found 1 .* and 0"):
        course.editions.find_exercises(v4.new_notebook(cells=cells), "07-x.ipynb")


def _sunlab(*args, cwd=None, **kw):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "sunlab", *args], capture_output=True,
                          text=True, cwd=cwd, env=env, **kw)


def test_python_m_sunlab_course_writes_both_editions(tmp_path):
    res = _sunlab("course", "--out", str(tmp_path / "class"))
    assert res.returncode == 0, res.stderr
    n_ex = sum(map(len, EXERCISES.values()))
    n_w = sum(map(len, WRITTEN.values()))
    assert f"{n_ex} exercises in {len(WITH_EXERCISES)} notebooks, {n_w} written" in res.stdout
    for name in BOOKS:
        student = (tmp_path / "class" / "student" / name).read_text()
        student_nb = nbformat.reads(student, as_version=4)
        teacher = nbformat.read(tmp_path / "class" / "teacher" / name, as_version=4)
        assert "BEGIN SOLUTION" not in student and "END SOLUTION" not in student, name
        for ex in EXERCISES[name]:
            # the quick cell comes first: every index moves by one
            sol = teacher.cells[ex.solution_cell + 1]
            assert course.editions.BEGIN_SOLUTION in sol.source
            assert sol.metadata["nbgrader"]["solution"] is True
            chk = teacher.cells[ex.check_cell + 1]
            assert chk.metadata["nbgrader"]["grade"] is True
            assert chk.metadata["nbgrader"]["points"] == ex.points
            assert course.editions.BEGIN_HIDDEN in chk.source
            assert f"Exercise {ex.number}" in student and "raise NotImplementedError" in student
            locked = student_nb.cells[ex.check_cell + 1].metadata
            assert locked["editable"] is False and locked["nbgrader"]["locked"] is True
        for w in WRITTEN[name]:
            cell = student_nb.cells[w.cell + 1]
            assert cell.source.endswith(course.editions.WRITTEN_PROMPT)
            meta = teacher.cells[w.cell + 1].metadata["nbgrader"]
            assert meta["solution"] and meta["grade"] and meta["points"] == w.points
        first_code = next(c for c in teacher.cells if c.cell_type == "code")
        assert first_code.source == course.editions.QUICK_CELL, name
    again = _sunlab("course", "--out", str(tmp_path / "class"))
    assert again.returncode == 1 and "--overwrite" in again.stderr, again.stderr
    assert "nothing was written" in again.stderr
    assert _sunlab("course", "--out", str(tmp_path / "class"), "--overwrite").returncode == 0


def test_course_without_notebooks_names_the_folder_and_the_fix(tmp_path):
    res = _sunlab("course", "--out", str(tmp_path / "c"), "--notebooks", str(tmp_path))
    assert res.returncode == 1
    assert str(tmp_path) in res.stderr and "Fix:" in res.stderr and "Traceback" not in res.stderr


# ------------------------------------------------------------------ --out is all or nothing

def test_a_students_file_in_the_way_stops_the_run_before_anything_is_written(tmp_path):
    out = tmp_path / "class"
    (out / "student").mkdir(parents=True)
    mine = out / "student" / "03-geometric-models.ipynb"
    mine.write_text("Alice's answers")
    res = _sunlab("course", "--out", str(out))
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert str(mine) in res.stderr and "nothing was written" in res.stderr
    assert mine.read_text() == "Alice's answers"
    assert sorted(p.name for p in out.rglob("*")) == ["03-geometric-models.ipynb", "student"]
    assert [p.name for p in tmp_path.iterdir()] == ["class"]  # no temporary folder left


@pytest.fixture(scope="module")
def many_notebooks(tmp_path_factory):
    """A course of 40 notebooks (copies of notebook 03), slow enough to interrupt."""
    folder = tmp_path_factory.mktemp("many")
    text = (NOTEBOOK_DIR / "03-geometric-models.ipynb").read_text(encoding="utf-8")
    for k in range(40):
        (folder / f"03-copy{k:03d}.ipynb").write_text(text, encoding="utf-8")
    return folder


@pytest.mark.parametrize("sig", ["SIGTERM", "SIGINT", "SIGHUP"])
def test_a_signal_while_writing_leaves_nothing_and_a_rerun_works(tmp_path, many_notebooks, sig):
    out = tmp_path / "class"
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    proc = subprocess.Popen([sys.executable, "-m", "sunlab", "course", "--out", str(out),
                             "--notebooks", str(many_notebooks)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    staging = []
    for _ in range(6000):  # wait (up to 60 s) until the editions are being written
        staging = [p for p in tmp_path.iterdir() if p.name.startswith(".sl-")]
        if any(p.rglob("*.ipynb") for p in staging) or proc.poll() is not None:
            break
        time.sleep(0.01)
    assert staging and proc.poll() is None, "the run ended before the signal could be sent"
    proc.send_signal(getattr(signal, sig))
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0 and "Traceback" not in err, err
    assert list(tmp_path.iterdir()) == [], [p.name for p in tmp_path.iterdir()]
    res = _sunlab("course", "--out", str(out), "--notebooks", str(many_notebooks))
    assert res.returncode == 0, res.stderr
    assert len(list((out / "student").iterdir())) == 40
    assert len(list((out / "teacher").iterdir())) == 40


def test_a_killed_writers_leftovers_go_at_the_next_run(tmp_path):
    """SIGKILL cannot be caught: the next run removes what the dead writer left."""
    stale = tmp_path / ".sl-999999999-deadbeef.tmp"
    (stale / "student").mkdir(parents=True)
    (stale / "student" / "01-x.ipynb").write_text("{}")
    res = _sunlab("course", "--out", str(tmp_path / "class"))
    assert res.returncode == 0, res.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["class"]


# ------------------------------------------------------------------ grading

def _mini_course(folder):
    """A one-notebook course that runs in a second: two exercises, a written answer."""
    v4 = nbformat.v4
    folder.mkdir(parents=True, exist_ok=True)
    cells = [v4.new_markdown_cell("# 01 mini"),
             v4.new_code_cell("# Exercise 01.1: two\n# Hint: h\n### BEGIN SOLUTION\nx = 2\n"
                              "### END SOLUTION"),
             v4.new_code_cell("# Check 01.1\nassert x == 2, 'x is not two: count again'"),
             v4.new_code_cell("# Exercise 01.2: three\n# Hint: h\n### BEGIN SOLUTION\n"
                              "def three():\n    return 3\n### END SOLUTION"),
             v4.new_code_cell("# Check 01.2 (2 points)\nassert three() == 3, 'not three'\n"
                              "### BEGIN HIDDEN TESTS\nimport os\n"
                              "assert os.environ['SUNLAB_COURSE_SEED'] == '7', 'seed'\n"
                              "### END HIDDEN TESTS"),
             v4.new_markdown_cell("**Written answer 01.3** (2 points)\n\nBecause three.")]
    nbformat.write(v4.new_notebook(cells=cells), folder / "01-mini.ipynb")
    return folder


def _submit(folder, student, answers, edit=None):
    """The student edition of the mini course with ``answers`` {number: code}."""
    src = nbformat.read(folder / "course" / "01-mini.ipynb", as_version=4)
    nb = course.editions.edition(src, "01-mini.ipynb", student=True)
    for ex in course.editions.find_exercises(src):
        if ex.number in answers:
            nb.cells[ex.solution_cell + 1].source = course.editions.replace_solution(
                src.cells[ex.solution_cell].source, answers[ex.number])
    if edit:
        edit(nb)
    path = folder / student / "01-mini.ipynb"
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    return path


def test_grading_a_right_answer_exits_0_and_writes_the_gradebook(tmp_path):
    _mini_course(tmp_path / "course")
    ok = _submit(tmp_path, "ana", {"01.1": "x = 2", "01.2": "def three():\n    return 3"})
    res = _sunlab("course", "--grade", str(ok), "--notebooks", str(tmp_path / "course"),
                  "--seed", "7", "--gradebook", str(tmp_path / "book"))
    assert res.returncode == 0, res.stdout + res.stderr
    assert "ana/01-mini.ipynb: 3 of 3 points (2 of 2 checks pass; 2 points of written" in res.stdout
    rows = (tmp_path / "book" / "gradebook.csv").read_text().splitlines()
    assert rows[0] == "student,notebook,exercise,points,max_points,message"
    assert rows[1:3] == ["ana,01-mini.ipynb,01.1,1,1,", "ana,01-mini.ipynb,01.2,2,2,"]
    assert rows[3] == "ana,01-mini.ipynb,01.3 (written),,2,not answered"
    doc = json.loads((tmp_path / "book" / "gradebook.json").read_text())
    assert doc["seed"] == 7 and doc["totals"]["ana"] == {"points": 3, "max_points": 3,
                                                         "written_max_points": 2}
    again = _sunlab("course", "--grade", str(ok), "--notebooks", str(tmp_path / "course"),
                    "--gradebook", str(tmp_path / "book"))
    assert again.returncode == 1 and "--overwrite" in again.stderr  # refused before grading


def test_grading_reports_syntax_errors_unanswered_and_wrong_answers(tmp_path):
    _mini_course(tmp_path / "course")
    bad = _submit(tmp_path, "bo", {"01.1": "x = 3", "01.2": "def three(:\n    return 3"})
    lazy = _submit(tmp_path, "cy", {})
    res = _sunlab("course", "--grade", str(bad), str(lazy), "--notebooks",
                  str(tmp_path / "course"), "--seed", "7")
    assert res.returncode == 1, res.stdout + res.stderr
    out = res.stdout
    assert re.search(r"01\.1\s+0/1\s+wrong\s+x is not two: count again", out), out
    assert re.search(r"01\.2\s+0/2\s+syntax error\s+SyntaxError in your answer \(line 3 "
                     r"of the cell\): invalid syntax$", out, re.M), out
    assert re.search(r"cy/01-mini.ipynb: 0 of 3 points", out)
    assert re.search(r"01\.1\s+0/1\s+not answered\s+Exercise 01.1 \(two\) is yours", out), out


def test_grading_restores_replaced_and_deleted_checks_and_scores_them_0(tmp_path):
    _mini_course(tmp_path / "course")

    def tamper(nb):
        checks = [i for i, c in enumerate(nb.cells) if c.source.startswith("# Check")]
        nb.cells[checks[0]].source = 'print("Check 01.1 passed")'
        del nb.cells[checks[1]]

    path = _submit(tmp_path, "dan", {"01.1": "x = 5", "01.2": "def three():\n    return 3"},
                   tamper)
    rows = course.grading.grade_notebook(path, notebooks=tmp_path / "course", seed=7)
    by = {r["exercise"]: r for r in rows}
    assert by["01.1"]["points"] == 0 and by["01.1"]["result"] == "tampered"
    assert by["01.1"]["message"].startswith("check cell altered: scored 0")
    assert "wrong: x is not two" in by["01.1"]["message"]  # what the restored check said
    assert by["01.2"]["points"] == 0 and by["01.2"]["message"].startswith("check cell deleted")


def test_grading_a_file_that_is_not_a_notebook_says_so(tmp_path):
    _mini_course(tmp_path / "course")
    bad = tmp_path / "eve" / "01-mini.ipynb"
    bad.parent.mkdir()
    bad.write_text("my answers: 42")
    res = _sunlab("course", "--grade", str(bad), "--notebooks", str(tmp_path / "course"))
    assert res.returncode == 1 and "Traceback" not in res.stderr
    assert f"{bad}: not a Jupyter notebook" in res.stdout and "Fix:" in res.stdout
    other = tmp_path / "eve" / "42-unknown.ipynb"
    other.write_text(bad.read_text())
    res = _sunlab("course", "--grade", str(other), "--notebooks", str(tmp_path / "course"))
    assert res.returncode == 1 and "no course notebook of that name" in res.stdout  # a row
    assert "Traceback" not in res.stderr


@pytest.mark.slow
def test_three_simulated_students_on_notebook_03(tmp_path):
    """Right, wrong (one SyntaxError) and tampered (checks replaced by a print, deleted):
    the gradebook the closing note of issue 38 shows."""
    from _students import write_submissions

    name = "03-geometric-models.ipynb"
    made = write_submissions(tmp_path, [name])
    paths = [str(p) for ps in made.values() for p in ps]
    res = _sunlab("course", "--grade", *paths, "--seed", "2026", "--gradebook",
                  str(tmp_path / "book"))
    assert res.returncode == 1, res.stdout + res.stderr  # checks fail
    doc = json.loads((tmp_path / "book" / "gradebook.json").read_text())
    got = {(r["student"], r["exercise"]): r for r in doc["rows"]}
    assert doc["totals"]["right"]["points"] == doc["totals"]["right"]["max_points"] == 3
    assert got[("wrong", "03.1")]["result"] == "wrong"
    assert "hidden" not in got[("wrong", "03.1")]["message"]  # the visible check caught it
    assert got[("wrong", "03.2")]["result"] == "syntax error"
    assert got[("tampered", "03.1")]["result"] == "tampered"
    assert got[("tampered", "03.2")]["message"].startswith("check cell deleted: scored 0")
    assert doc["totals"]["wrong"]["points"] == doc["totals"]["tampered"]["points"] == 0
    csv_rows = (tmp_path / "book" / "gradebook.csv").read_text().splitlines()
    assert csv_rows[0] == ",".join(course.grading.COLUMNS) and len(csv_rows) == 1 + 3 * 3


# ------------------------------------------------------------------ executed editions

def _client(nb):
    nbclient = pytest.importorskip("nbclient")
    return nbclient.NotebookClient(nb, timeout=CELL_TIMEOUT_S, kernel_name="python3",
                                   resources={"metadata": {"path": str(NOTEBOOK_DIR)}})


def test_student_edition_stops_at_the_first_exercise():
    nbclient = pytest.importorskip("nbclient")
    name = "03-geometric-models.ipynb"  # the quickest to reach its first exercise
    nb = course.editions.edition(BOOKS[name], name, student=True)
    first = EXERCISES[name][0].solution_cell + 1  # after the quick cell
    with pytest.raises(nbclient.exceptions.CellExecutionError) as info:
        _client(nb).execute()
    assert info.value.ename == "NotImplementedError"
    assert f"Exercise {EXERCISES[name][0].number}" in info.value.evalue
    ran = [i for i, c in enumerate(nb.cells) if c.cell_type == "code" and c.execution_count]
    assert ran and ran[-1] == first, (ran, first)


@pytest.mark.slow
@pytest.mark.parametrize("name", WITH_EXERCISES)
def test_teacher_edition_passes_and_each_check_catches_a_wrong_answer(name, executed_notebook):
    # the teacher edition runs once, shared with tests/test_notebooks.py (conftest.py's
    # executed_notebook); a check that fails on its answer stops that run and fails here
    caught = executed_notebook.caught(NOTEBOOK_DIR / name)
    assert list(caught) == [ex.number for ex in EXERCISES[name]]
    for number, (ename, evalue) in caught.items():
        assert ename == "AssertionError", (number, ename, evalue)
        assert re.search(r"\w", evalue), f"check {number}: no message"


# ------------------------------------------------------------------ nbgrader

@pytest.mark.slow
def test_nbgrader_autograde_scores_the_teacher_edition_like_sunlab(tmp_path):
    """nbgrader (the ``course`` extra) releases the teacher edition and autogrades the three
    simulated students with the same grade ids and points; tampered checks are restored."""
    pytest.importorskip("nbgrader", reason="nbgrader is not installed (pip install "
                        "'sunlab[course]'); its autograde is tested where it installs")
    from _students import write_submissions
    from nbgrader.api import Gradebook

    name = "03-geometric-models.ipynb"
    root = tmp_path / "nbcourse"
    (root / "source" / "ps1").mkdir(parents=True)
    nbformat.write(course.editions.edition(BOOKS[name], name, student=False),
                   root / "source" / "ps1" / name)
    (root / "nbgrader_config.py").write_text(
        "c = get_config()\nc.CourseDirectory.course_id = 'sunlab'\n"
        "c.ExecutePreprocessor.timeout = 900\n")
    made = write_submissions(tmp_path / "subs", [name])
    for student, (path,) in made.items():
        dest = root / "submitted" / student / "ps1"
        dest.mkdir(parents=True)
        (dest / name).write_text(path.read_text())
    # nbgrader runs alembic and the kernel from this environment's bin folder
    env = {**os.environ, "PYTHONPATH": str(REPO),
           "PATH": os.pathsep.join([str(Path(sys.executable).parent), os.environ["PATH"]])}
    nbgrader = [sys.executable, "-m", "nbgrader"]
    for step in (["generate_assignment", "ps1", "--force"],
                 ["autograde", "ps1", "--force", "--create"]):
        res = subprocess.run(nbgrader + step, cwd=root, env=env, capture_output=True, text=True)
        assert res.returncode == 0, res.stdout[-2000:] + res.stderr[-4000:]
    released = (root / "release" / "ps1" / name).read_text()
    assert "HIDDEN TESTS" not in released and "hidden.check" not in released
    auto = sum(ex.points for ex in EXERCISES[name])
    with Gradebook(f"sqlite:///{root / 'gradebook.db'}") as gb:
        scores = {s: gb.find_submission("ps1", s).code_score for s in made}
        assert gb.find_submission("ps1", "right").max_code_score == auto
    assert scores == {"right": auto, "wrong": 0, "tampered": 0}, scores
