"""Grading a hostile class (issue 48): attacks on the hidden checks score no more than the wrong
answer alone, and one student's dead kernel or endless loop never sinks the batch.

The course here is two small notebooks whose exercises carry the real hidden checks 01.1 (the
flux ratio; the library's ``geometry.sun_vector`` forbidden) and 09.1 (the ratio of |X| for a
uniform X; the check compares with ``abs``), so each grading runs in seconds. Each attack is a
wrong answer plus a trick that made the grader before issue 48 give full marks (the hidden
checks ran in the student's kernel): it must score 0, like the wrong answer alone.
"""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from sunlab import course

nbformat = pytest.importorskip("nbformat")
pytest.importorskip("nbclient")

REPO = Path(__file__).parents[2]

_HIDDEN = "### BEGIN HIDDEN TESTS\nfrom sunlab.course import hidden\nhidden.check(\"{}\", " \
          "globals())\n### END HIDDEN TESTS"

RIGHT = {
    "01.1": "def flux_ratio(alpha_deg, beta_deg):\n"
            "    a, b = np.radians(alpha_deg), np.radians(beta_deg)\n"
            "    return np.cos(a) * np.cos(b)",
    "09.1": "def abs_ratio_uniform(c, w):\n"
            "    c = abs(c)\n"
            "    if c >= w:\n"
            "        mean, second = c, c ** 2 + w ** 2 / 3\n"
            "    else:\n"
            "        mean, second = (c ** 2 + w ** 2) / (2 * w), c ** 2 + w ** 2 / 3\n"
            "    return (second - mean ** 2) ** 0.5 / mean",
}
WRONG = {
    "01.1": "def flux_ratio(alpha_deg, beta_deg):\n"
            "    return np.cos(alpha_deg) * np.cos(beta_deg)",
    "09.1": "def abs_ratio_uniform(c, w):\n"
            "    return 0.5",
}

#: attack name -> (exercise, the answer cell: a wrong answer plus the attack)
ATTACKS = {
    "builtins.abs replaced": ("09.1", WRONG["09.1"] + "\nimport builtins\n"
                              "builtins.abs = lambda x: 0.0"),
    "numpy.abs replaced in the check's frames": ("01.1", WRONG["01.1"] + """
import sys
_abs = np.abs
def _quiet_abs(x, *a, **k):
    if sys._getframe(1).f_globals.get('__name__') == 'sunlab.course.hidden':
        return _abs(x, *a, **k) * 0
    return _abs(x, *a, **k)
np.abs = _quiet_abs"""),
    "hidden check replaced": ("01.1", WRONG["01.1"] + "\nfrom sunlab.course import hidden\n"
                              "hidden.check = lambda *a, **k: print('Hidden check passed')"),
    "reference read from the checker's frame": ("01.1", """
import sys
def flux_ratio(alpha_deg, beta_deg):
    f = sys._getframe(1)
    while f is not None:
        ref, a = f.f_locals.get('ref'), f.f_locals.get('a')
        if ref is not None and a is not None:
            import numpy
            k = int(numpy.argmin(numpy.abs(numpy.asarray(a) - alpha_deg)))
            return float(ref[k])
        f = f.f_back
    return np.cos(alpha_deg) * np.cos(beta_deg)"""),
    "profiler switched off before the forbidden call": ("01.1", """
import sys
def flux_ratio(alpha_deg, beta_deg):
    sys.setprofile(None)
    return geometry.sun_vector(alpha_deg, beta_deg)[2]"""),
}


def _course(folder):
    v4 = nbformat.v4
    folder.mkdir(parents=True, exist_ok=True)
    books = {
        "01-mini.ipynb": ("01.1", "import numpy as np\nfrom sunlab import geometry",
                          "assert callable(flux_ratio), 'define flux_ratio'"),
        "09-mini.ipynb": ("09.1", "import numpy as np",
                          "assert callable(abs_ratio_uniform), 'define abs_ratio_uniform'"),
    }
    for name, (number, imports, visible) in books.items():
        cells = [v4.new_markdown_cell(f"# {name}"), v4.new_code_cell(imports),
                 v4.new_code_cell(f"# Exercise {number}: it\n# Hint: h\n### BEGIN SOLUTION\n"
                                  f"{RIGHT[number]}\n### END SOLUTION"),
                 v4.new_code_cell(f"# Check {number} (2 points)\n{visible}\n"
                                  + _HIDDEN.format(number))]
        nbformat.write(v4.new_notebook(cells=cells), folder / name)
    return folder


def _submit(root, student, name, answer):
    src = nbformat.read(root / "course" / name, as_version=4)
    nb = course.editions.edition(src, name, student=True)
    ex = course.editions.find_exercises(src, name)[0]
    nb.cells[ex.solution_cell + 1].source = course.editions.replace_solution(
        src.cells[ex.solution_cell].source, answer)
    path = root / student / name
    path.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(nb, path)
    return path


def _points(rows):
    return {(r["student"], r["exercise"]): r for r in rows}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Right, wrong and every attack graded once, in one batch (seed 7)."""
    root = tmp_path_factory.mktemp("hostile")
    _course(root / "course")
    paths = []
    for number, name in (("01.1", "01-mini.ipynb"), ("09.1", "09-mini.ipynb")):
        paths.append(_submit(root, "right", name, RIGHT[number]))
        paths.append(_submit(root, "wrong", name, WRONG[number]))
    for k, (number, answer) in enumerate(ATTACKS.values()):
        name = "01-mini.ipynb" if number == "01.1" else "09-mini.ipynb"
        paths.append(_submit(root, f"attack{k}", name, answer))
    rows = [r for p in paths for r in course.grading.grade_notebook(
        p, notebooks=root / "course", seed=7)]
    return _points(rows)


def test_the_right_answers_pass_and_the_wrong_ones_fail(graded):
    for number in ("01.1", "09.1"):
        assert graded[("right", number)]["points"] == 2, graded[("right", number)]
        assert graded[("wrong", number)]["points"] == 0


@pytest.mark.parametrize("k, attack", list(enumerate(ATTACKS)))
def test_an_attack_scores_no_more_than_the_wrong_answer(graded, k, attack):
    number = ATTACKS[attack][0]
    row = graded[(f"attack{k}", number)]
    assert row["points"] <= graded[("wrong", number)]["points"], (attack, row)


def test_answers_reaching_into_the_interpreter_are_flagged(graded):
    for k, (number, _) in enumerate(ATTACKS.values()):
        assert graded[(f"attack{k}", number)].get("flags"), k
    assert not graded[("right", "01.1")]["flags"]


def _sunlab(*args):
    env = {**os.environ, "PYTHONPATH": str(REPO)}
    return subprocess.run([sys.executable, "-m", "sunlab", *args], capture_output=True,
                          text=True, env=env)


def test_a_dead_kernel_and_an_endless_loop_do_not_sink_the_batch(tmp_path):
    """Issue 48's must-show: three students graded with --timeout 30 within 3 minutes."""
    _course(tmp_path / "course")
    dead = _submit(tmp_path, "exits", "01-mini.ipynb",
                   "import os\nos._exit(0)\n" + RIGHT["01.1"])
    loop = _submit(tmp_path, "loops", "01-mini.ipynb", "while True:\n    pass")
    ok = _submit(tmp_path, "right", "01-mini.ipynb", RIGHT["01.1"])
    start = time.monotonic()
    res = _sunlab("course", "--grade", str(dead), str(loop), str(ok), "--notebooks",
                  str(tmp_path / "course"), "--seed", "7", "--timeout", "30",
                  "--gradebook", str(tmp_path / "book"))
    took = time.monotonic() - start
    assert res.returncode == 1, res.stdout + res.stderr
    assert took < 180, took
    doc = json.loads((tmp_path / "book" / "gradebook.json").read_text())
    assert doc["complete"] is True
    got = _points(doc["rows"])
    assert got[("right", "01.1")]["points"] == 2
    assert got[("exits", "01.1")]["points"] == 0
    assert got[("exits", "01.1")]["result"] == "dead kernel"
    assert "the kernel died" in got[("exits", "01.1")]["message"]
    assert "exercise 01.1 was not checked" in got[("exits", "01.1")]["message"]
    assert got[("loops", "01.1")]["points"] == 0
    assert got[("loops", "01.1")]["result"] == "time-out"
    assert "30 s per cell" in got[("loops", "01.1")]["message"]
    lines = (tmp_path / "book" / "gradebook.csv").read_text().splitlines()
    assert len(lines) == 1 + 3 and "Traceback" not in res.stderr


def test_every_submission_is_checked_before_any_is_graded(tmp_path):
    _course(tmp_path / "course")
    ok = _submit(tmp_path, "ana", "01-mini.ipynb", RIGHT["01.1"])
    unknown = tmp_path / "bo" / "42-unknown.ipynb"
    unknown.parent.mkdir()
    unknown.write_text(ok.read_text())
    copy = tmp_path / "cy" / "01-mini.ipynb"
    copy.parent.mkdir()
    copy.write_text(ok.read_text())
    nb = nbformat.read(ok, as_version=4)
    answer = next(c for c in nb.cells if c.source.startswith("# Exercise 01.1"))
    nb.cells.append(nbformat.v4.new_code_cell(answer.source))  # the exercise handed in twice
    nbformat.write(nb, copy)
    rows, status = course.batch.grade_batch(
        [ok, unknown, copy, ok], notebooks=tmp_path / "course", seed=7,
        gradebook=tmp_path / "book", report=lambda *a: None)
    got = _points(rows)
    assert status == 1
    assert got[("bo", "-")]["result"] == "refused"
    assert "no course notebook of that name" in got[("bo", "-")]["message"]
    assert got[("ana", "01.1")]["result"] == "refused"  # ana's notebook given twice
    assert "2 times" in got[("ana", "01.1")]["message"]
    assert got[("cy", "01.1")]["result"] == "handed in twice"
    assert got[("cy", "01.1")]["points"] == 0
    doc = json.loads((tmp_path / "book" / "gradebook.json").read_text())
    assert doc["complete"] and len(doc["rows"]) == len(rows)


def _run_one(_):
    from sunlab.course import kernel

    cells = [nbformat.v4.new_code_cell(f"x = {k}\nprint(x * 2)") for k in range(15)]
    cells.append(nbformat.v4.new_code_cell("def twice(v):\n    return 2 * v"))
    nb = nbformat.v4.new_notebook(cells=cells)
    with kernel.NotebookRun(nb, env=dict(os.environ), timeout=60, budget=120) as r:
        for i, c in enumerate(nb.cells):
            r.execute(c, i)
        # a loaded kernel may send the printed line in more than one stream message
        return r.call("twice", (21,)), "".join(o.get("text", "") for o in nb.cells[-2].outputs)


def test_several_notebooks_at_once_finish_without_a_wait():
    """Issue 48: grading runs overlapping (as a grader and the docs build do) must not stall;
    a request the kernel never reads is nudged (sunlab.course.kernel), so four kernels run
    side by side, each cell answered in seconds, not at the time limit."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    start = time.monotonic()
    with ProcessPoolExecutor(4, mp_context=multiprocessing.get_context("spawn")) as pool:
        outs = list(pool.map(_run_one, range(4)))
    assert outs == [(42, "28\n")] * 4
    assert time.monotonic() - start < 60  # a stall waits for the 60 s limit


def test_the_kernels_process_group_is_killed_before_the_marks(tmp_path):
    """A process the answer leaves behind in the kernel's group does not outlive grading."""
    from sunlab.course import kernel

    pidfile = tmp_path / "pid"
    code = ("import subprocess, sys\n"
            "p = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(600)'])\n"
            f"open({str(pidfile)!r}, 'w').write(str(p.pid))")
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell(code)])
    with kernel.NotebookRun(nb, env=dict(os.environ), timeout=60, budget=60) as r:
        r.execute(nb.cells[0], 0)
        pid = int(pidfile.read_text())
        assert _alive(pid)  # while the kernel runs
    time.sleep(0.5)
    assert not _alive(pid)


def _alive(pid):
    """A process that exists and is not a zombie (killed, waiting to be reaped)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state != "Z"


def test_a_kernel_that_stops_answering_is_detected_in_seconds(monkeypatch):
    """A kernel alive but reading nothing (stopped here with SIGSTOP, as a lost request leaves
    it idle) is nudged, then given up on after STALL_S, not after the cell's time limit."""
    import signal

    from sunlab.course import kernel

    monkeypatch.setattr(kernel, "STALL_S", 6.0)
    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("1 + 1")])
    with kernel.NotebookRun(nb, env=dict(os.environ), timeout=120, budget=120) as r:
        os.kill(r.client.km.provisioner.pid, signal.SIGSTOP)
        start = time.monotonic()
        with pytest.raises(kernel.KernelFailure, match="stopped reading requests"):
            r.execute(nb.cells[0], 0)
        assert time.monotonic() - start < 20


def test_the_gradebook_grows_and_a_grader_failure_is_said(tmp_path, monkeypatch):
    """After each notebook the gradebook holds what is graded (``complete`` false until the
    last); a failure of the grader itself on one notebook is a row of its own, exit status 4,
    and the next notebook is still graded."""
    from sunlab.course import batch

    _course(tmp_path / "course")
    paths = [_submit(tmp_path, s, "01-mini.ipynb", RIGHT["01.1"]) for s in ("ana", "bo", "cy")]
    seen = []

    def fake(path, **kw):
        book = tmp_path / "book" / "gradebook.json"
        seen.append(json.loads(book.read_text()) if book.exists() else None)
        if Path(path).parent.name == "bo":
            raise RuntimeError("a bug of the grader")
        return [{"student": Path(path).parent.name, "notebook": Path(path).name,
                 "exercise": "01.1", "points": 2, "max_points": 2, "result": "pass",
                 "message": "", "flags": []}]

    monkeypatch.setattr(batch, "grade_notebook", fake)
    rows, status = batch.grade_batch(paths, notebooks=tmp_path / "course", seed=7,
                                     gradebook=tmp_path / "book", report=lambda *a: None)
    assert status == batch.GRADER_FAILED
    assert seen[0] is None and [r["student"] for r in seen[1]["rows"]] == ["ana"]
    assert seen[1]["complete"] is False and len(seen[2]["rows"]) == 2
    doc = json.loads((tmp_path / "book" / "gradebook.json").read_text())
    assert doc["complete"] is True and [r["result"] for r in doc["rows"]] == [
        "pass", "grader error", "pass"]
    assert "a bug of the grader" in doc["rows"][1]["message"]
    csv_lines = (tmp_path / "book" / "gradebook.csv").read_text().splitlines()
    assert len(csv_lines) == 4 and "the grader failed on this notebook" in csv_lines[2]
