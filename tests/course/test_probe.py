"""The hidden checks run in the grader's process on outputs that come back as data
(sunlab.course.wire), and the forbidden library calls are caught in a fresh process
(sunlab.course.probe), for the real notebooks' exercises: the teacher's answer passes both,
the library shortcut fails the fresh process whatever it does to the profiler.

No kernel here: the notebook's namespace is built in this process and answers the grader's
requests through the same text a kernel would display (wire.answer and wire.reply).
"""

import ast
import sys
from pathlib import Path

import numpy as np
import pytest

from sunlab.course import editions, hidden, probe, wire

sys.path.insert(0, str(Path(__file__).parents[1]))
from test_course import BOOKS, EXERCISES, SHORTCUTS, _namespace, _solution  # noqa: E402


class LocalRun:
    """A notebook's namespace answering the grader's requests as a kernel does (the same JSON
    text, without the kernel: kernel.NotebookRun.call's part here)."""

    def __init__(self, ns):
        self.ns, self.calls = ns, []

    def call(self, name, args=(), kwargs=None, bind=None):
        return wire.reply(wire.answer(self.ns, name, args, kwargs, bind), name)


def _setup(number):
    ex = next(e for exs in EXERCISES.values() for e in exs if e.number == number)
    nb = BOOKS[ex.notebook]
    answers = {e.solution_cell for e in EXERCISES[ex.notebook]}
    checks = {e.check_cell for e in EXERCISES[ex.notebook]}
    return probe.setup_source([c.source for j, c in enumerate(nb.cells)
                               if c.cell_type == "code" and j < ex.solution_cell
                               and j not in answers and j not in checks])


def _notebook(source):
    """The namespace of the answer's statements that run without the notebook's variables."""
    ns = _namespace("")
    for node in ast.parse(source).body:
        try:
            exec(compile(ast.Module([node], []), "<answer>", "exec"), ns)  # noqa: S102
        except NameError:
            pass
    return ns


def _graded_here(number, source):
    ns = LocalRun(_notebook(source))
    try:
        hidden.check(number, ns, 5)
        verdict = None
    except AssertionError as err:
        verdict = str(err)
    return verdict, ns.calls


@pytest.mark.parametrize("number", sorted(SHORTCUTS))
def test_the_answer_passes_here_and_in_a_fresh_process(number):
    answer = _solution(number)
    verdict, calls = _graded_here(number, answer)
    assert verdict is None, verdict
    assert calls, "a check with forbidden functions records its call"
    assert probe.recheck(calls[0], _setup(number), [answer], timeout=120) is None


#: the library, imported in the answer cell (a notebook may not import all of it before)
_IMPORTS = ("from sunlab import calibration, geometry, stats\nfrom sunlab import centroid as C\n"
            "from sunlab.calibration import Polynomial\nfrom sunlab.reproduce import fault as pf")


@pytest.mark.parametrize("number", sorted(SHORTCUTS))
def test_a_shortcut_with_the_profiler_off_trips_in_a_fresh_process(number):
    source, called = SHORTCUTS[number]
    lines = source.splitlines()
    sneaky = "\n".join([_IMPORTS, lines[0], "    import sys", "    sys.setprofile(None)",
                        *lines[1:]])
    verdict, calls = _graded_here(number, sneaky)
    assert verdict is None, verdict  # with the profiler off, the kernel alone would pass it
    why = probe.recheck(calls[0], _setup(number), [sneaky], timeout=120)
    assert why is not None and called in why, why


def test_an_answer_that_behaves_otherwise_outside_its_notebook_fails():
    source = ("import sys\nfrom sunlab import geometry\n"
              "def flux_ratio(alpha_deg, beta_deg):\n"
              "    if 'ipykernel' not in sys.modules:\n"
              "        return 0.5\n"
              "    sys.setprofile(None)\n"
              "    return geometry.sun_vector(alpha_deg, beta_deg)[2]\n")
    ns = _namespace(source)
    import types
    ns["sys"] = types.SimpleNamespace(modules={"ipykernel": 1}, setprofile=lambda f: None)
    ns_remote = LocalRun(ns)
    hidden.check("01.1", ns_remote, 5)
    why = probe.recheck(ns_remote.calls[0], _setup("01.1"), [source], timeout=120)
    assert why is not None and "another answer" in why, why


def test_data_comes_back_as_data_and_a_calibration_as_its_document():
    from sunlab import sim
    from sunlab.calibration import Polynomial

    cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
    fitted = Polynomial(order=1).fit(cen)
    run = LocalRun({"make": lambda: fitted, "obj": lambda: {1, 2}})
    cal = run.call("make")
    assert cal is not fitted and isinstance(cal, Polynomial)  # rebuilt here from its document
    np.testing.assert_array_equal(cal.predict(cen)["alpha"], fitted.predict(cen)["alpha"])
    with pytest.raises(AssertionError, match="raised TypeError: a set is not data"):
        run.call("obj")  # any other object stays in the kernel, refused
    with pytest.raises(AssertionError, match="raised ZeroDivisionError"):
        LocalRun({"f": lambda: 1 / 0}).call("f")
    with pytest.raises(AssertionError, match="`nothing` is not defined"):
        LocalRun({}).call("nothing")
    assert editions.strip_hidden("a\n### BEGIN HIDDEN TESTS\nb\n### END HIDDEN TESTS") == "a"
