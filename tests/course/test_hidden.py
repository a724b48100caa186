"""Hidden checks (sunlab.course.hidden): an answer passes on fresh inputs only when it is right,
fails with a message that says how without giving the answer, and may not call the library."""

import numpy as np
import pytest

from sunlab import geometry
from sunlab.course import hidden


def _flux_ratio(alpha, beta):
    # the student's answer: the sun vector's component along the sensor's normal
    a, b = np.radians(alpha), np.radians(beta)
    return np.cos(a) * np.cos(b)


def test_seed_comes_from_the_environment_or_the_default(monkeypatch):
    monkeypatch.delenv(hidden.SEED_VARIABLE, raising=False)
    assert hidden.seed() == hidden.DEFAULT_SEED
    monkeypatch.setenv(hidden.SEED_VARIABLE, " 1234 ")
    assert hidden.seed() == 1234


def test_a_right_answer_passes_on_fresh_inputs(capsys):
    for s in (1, 2, 3):
        hidden.check("01.1", {"flux_ratio": _flux_ratio}, seed_value=s)
    assert capsys.readouterr().out.count("Hidden check 01.1 passed") == 3


def test_a_wrong_answer_fails_saying_how():
    wrong = {"flux_ratio": lambda a, b: np.cos(np.radians(a))}  # forgets the inner axis
    with pytest.raises(AssertionError, match=r"hidden check 01.1 \(fresh inputs, seed 5\): "
                                             r"flux ratio at poses you have not seen"):
        hidden.check("01.1", wrong, seed_value=5)


def test_an_answer_that_calls_the_library_or_is_missing_fails():
    via_library = {"flux_ratio": lambda a, b: geometry.sun_vector(a, b)[2]}
    with pytest.raises(AssertionError, match="sun_vector.*write it yourself"):
        hidden.check("01.1", via_library, seed_value=0)
    with pytest.raises(AssertionError, match="`flux_ratio` is not defined"):
        hidden.check("01.1", {}, seed_value=0)


def test_an_answer_that_raises_fails_with_its_error():
    with pytest.raises(AssertionError, match="your `flux_ratio` raised ZeroDivisionError"):
        hidden.check("01.1", {"flux_ratio": lambda a, b: 1 / 0}, seed_value=0)


def test_another_bench_is_rebound_for_the_check_and_put_back():
    # eq. (1): x = x_cf + (F / p) tan(alpha), so dx/dalpha = F / p / cos^2(alpha) per radian
    ns = {"F": 5.0, "p": 0.007}
    ns["px_per_degree"] = lambda a: ns["F"] / ns["p"] / np.cos(np.radians(a))**2 * np.pi / 180
    hidden.check("01.2", ns, seed_value=3)
    assert (ns["F"], ns["p"]) == (5.0, 0.007)
    # an answer that ignores F (uses this bench's 5 mm whatever the grader's bench) fails
    ns["px_per_degree"] = lambda a: 5.0 / ns["p"] / np.cos(np.radians(a))**2 * np.pi / 180
    with pytest.raises(AssertionError, match="another bench"):
        hidden.check("01.2", ns, seed_value=3)


def test_every_exercise_number_has_the_notebook_form():
    assert hidden.CHECKS and all(len(k) >= 4 and k[2] == "." for k in hidden.CHECKS)


@pytest.mark.parametrize("number, answer", [
    ("09.1", "def abs_ratio_uniform(c, w):\n"
             "    e = np.abs(np.random.default_rng(0).uniform(c - w, c + w, 4 * 10**6))\n"
             "    return e.std() / e.mean()"),
    ("06.1", "def averaging_gain(common, specific, n):\n"
             "    g = np.random.default_rng(0)\n"
             "    e = g.normal(0, common, (200_000, 1)) + g.normal(0, specific, (200_000, n))\n"
             "    return e[:, 0].std() / e.mean(axis=1).std()"),
])
def test_a_monte_carlo_estimate_fails_a_check_that_asks_for_a_derivation(number, answer):
    ns = {"np": np}
    exec(answer, ns)  # noqa: S102 - the answer under test
    with pytest.raises(AssertionError, match="derivation, exact to 1e-9"):
        hidden.check(number, ns, seed_value=5)
