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
    assert len(g) == 10 and g.shots == 2
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


def test_scan_orders_visit_every_pose_once_and_keep_the_listing():
    raster = plans.experiment("I", scan="raster")
    serp = plans.experiment("I")  # the paper's experiments: serpentine (our inference)
    rnd = plans.experiment("I", scan="random")
    assert serp.scan == plans.PAPER_SCAN == "serpentine"
    for p in (raster, serp, rnd):
        assert sorted(p.visit_order().tolist()) == list(range(400))
        assert p.unstack_shape() == (20, 20)  # the listing stays a grid whatever the scan
    assert_array_equal(raster.visit_order(), np.arange(400))
    # serpentine: the second row (alpha = -16) is visited from beta = 17 down to -2
    row2 = serp.visit_order()[20:40]
    assert_array_equal(serp.beta[row2], np.arange(17.0, -3.0, -1.0))
    assert_array_equal(rnd.visit_order(), plans.experiment("I", scan="random").visit_order())
    assert not np.array_equal(rnd.visit_order(), np.arange(400))
    # thin, subset, slicing and with_shots keep the motion
    assert serp.thin(2).scan == "serpentine" and serp[3:].approach == "direct"
    assert serp.with_shots(2).scan == "serpentine" and serp != raster


def test_beta_approach_follows_the_scan():
    serp = plans.experiment("III")  # 19 x 19
    d = serp.beta_approach().reshape(19, 19)
    # a row scanned upward is reached upward, a downward row downward, except the first
    # visit of a row, where the inner axis does not move and keeps its flank; the run starts
    # from home (0 deg) with a move down to -1.5 deg
    assert d[0, 0] == -1 and (d[0, 1:] == 1).all() and (d[2, 1:] == 1).all() and d[2, 0] == -1
    assert (d[1, :-1] == -1).all() and d[1, -1] == 1
    raster = serp.with_motion(scan="raster").beta_approach().reshape(19, 19)
    assert (raster[:, 1:] == 1).all() and (raster[:, 0] == -1).all()  # row starts run back
    uni = serp.with_motion(approach="unidirectional")
    assert (uni.beta_approach() == 1).all()


def test_zero_check_and_bad_motion():
    z = plans.zero_check(plans.experiment("III"), 3, shots=2)
    assert (len(z), z.shots, z.name, z.approach) == (3, 2, "III", "unidirectional")
    assert not z.alpha.any() and not z.beta.any()
    with pytest.raises(ConfigurationError, match="checks"):
        plans.zero_check(plans.experiment("III"), 0)
    with pytest.raises(ConfigurationError, match="scan"):
        plans.experiment("I", scan="spiral")
    with pytest.raises(ConfigurationError, match="approach"):
        plans.grid(0, 1, 1, 0, 1, 1, approach="sideways")


def test_read_plan_names_an_experiment_or_reads_a_csv(tmp_path):
    assert plans.read_plan("ii", shots=3).name == "II"
    path = tmp_path / "poses.csv"
    path.write_text("alpha,beta\n-3,2\n1.5,0\n")
    p = plans.read_plan(path, shots=2)
    assert (p.name, p.alpha.tolist(), p.beta.tolist(), p.shots) == (
        "poses", [-3.0, 1.5], [2.0, 0.0], 2)
    path.write_text("a,b\n1,2\n")
    with pytest.raises(ConfigurationError, match=r"--plan .*missing \['alpha', 'beta'\]"):
        plans.read_plan(path, field="--plan")
    with pytest.raises(ConfigurationError, match=r"plan: found 'IV', expected I, II, III"):
        plans.read_plan("IV")
