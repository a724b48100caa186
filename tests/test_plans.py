"""Tests of sunlab.plans: the paper's Table 3, grids, custom plans and their validation."""

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from sunlab import ConfigurationError, plans


@pytest.mark.parametrize(
    ("name", "n", "a0", "a1", "b0", "b1"),
    [
        ("I", 400, -17, 2, -2, 17),
        ("II", 169, -16.25, 1.75, -1.75, 16.25),
        ("III", 361, -16.5, 1.5, -1.5, 16.5),
    ],
)
def test_experiments_follow_table3(name, n, a0, a1, b0, b1):
    p = plans.experiment(name)
    assert len(p) == n and p.shots == 8 and p.name == name
    assert (p.alpha.min(), p.alpha.max(), p.beta.min(), p.beta.max()) == (a0, a1, b0, b1)
    side = int(round(np.sqrt(n)))
    assert p.unstack_shape() == (side, side)
    # alpha is the outer loop: beta varies fastest
    assert_array_equal(p.alpha[:side], np.full(side, a0))
    assert_allclose(np.diff(p.beta[:side]), np.diff(p.beta[:side])[0])


def test_experiment_steps_exact():
    p = plans.experiment("II")
    assert_array_equal(np.unique(p.alpha), -16.25 + 1.5 * np.arange(13))


def test_grid_and_custom_and_slicing():
    g = plans.grid(-1, 1, 0.5, 0, 1, 1, shots=2, name="g")
    assert len(g) == 10 and g.n_frames == 20
    assert g.alpha.tolist()[:3] == [-1.0, -1.0, -0.5]
    c = plans.custom([0.0, 1.0, 2.0], [3.0, 4.0, 5.0], shots=1)
    assert c[1:].alpha.tolist() == [1.0, 2.0]
    assert len(plans.experiment("I").subset(7)) == 58
    assert c == plans.custom([0.0, 1.0, 2.0], [3.0, 4.0, 5.0], shots=1)
    assert c != c.with_shots(3)
    with pytest.raises(ValueError):
        c.alpha[0] = 5.0  # plans are immutable


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: plans.experiment("IV"), "experiment"),
        (lambda: plans.experiment("I", shots=0), "shots"),
        (lambda: plans.custom([0.0], [95.0]), "beta"),
        (lambda: plans.custom([-90.0], [0.0]), "alpha"),
        (lambda: plans.custom([0.0, 1.0], [0.0]), "alpha, beta"),
        (lambda: plans.grid(0, 1, 0, 0, 1, 1), "alpha_step"),
        (lambda: plans.grid(2, 1, 1, 0, 1, 1), "alpha_min"),
        (lambda: plans.experiment("I").subset(0), "step"),
        (lambda: plans.custom([np.nan], [0.0]), "alpha"),
    ],
)
def test_bad_plans_raise(call, field):
    with pytest.raises(ConfigurationError, match=field):
        call()


def test_thin_keeps_a_grid_a_grid():
    exp3 = plans.experiment("III")  # 19 x 19
    quick = exp3.thin(3)
    assert quick.unstack_shape() == (7, 7)
    assert np.allclose(np.diff(np.unique(quick.alpha)), 3.0)
    assert np.allclose(np.diff(np.unique(quick.beta)), 3.0)
    assert exp3.thin(1) == exp3
    odd = plans.custom([0.0, 1.0, 2.0, 3.0], [0.0, 0.0, 5.0, 1.0])
    assert odd.thin(2) == odd.subset(2)
