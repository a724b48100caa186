"""The package sunlab.sim (the virtual bench): its public names are the modules' objects, and
the paper's bench renders a frame whose spot lies where its truth says."""

import importlib

import numpy as np

import sunlab.sim as sim
from sunlab.centroid import tight_window


def test_every_public_name_is_its_modules_object():
    for name in sim.__all__:
        obj = getattr(sim, name)
        home = getattr(obj, "__module__", None)
        if home and home.startswith("sunlab.sim."):
            assert getattr(importlib.import_module(home), name) is obj, name


def test_the_paper_bench_spot_is_where_its_truth_says():
    # the paper's single-hole bench at a pose; tight_window's centroid noise on this spot is a
    # few 0.01 px (the CRLB is ~0.01 px), and its bias from PRNU and dark non-uniformity a few
    # 0.01 px: 0.15 px leaves room for both
    bench = sim.Bench.paper_single_hole()
    a, b = sim.platform.platform_pose(bench, -8.0, 4.0, seed=0, pose=0, shot=0)
    frame = sim.render_frame(bench, a, b, seed=0, play_mm=(0.0, 0.0))
    x, y = sim.spots.spot_truth(bench, a, b)
    c = tight_window(frame)
    assert c.ok
    assert abs(c.x - x[0]) < 0.15 and abs(c.y - y[0]) < 0.15
    # the commanded and the true pose differ by the platform's errors, a few 0.01 deg at most
    assert abs(a + 8.0) < 0.1 and abs(b - 4.0) < 0.1


def test_synthetic_centroids_follow_the_pinhole_model_exactly():
    from sunlab.geometry.model import pinhole_centroid

    cen = sim.synthetic_centroids([0.0, -5.0], [0.0, 3.0], shots=2)
    x, y = pinhole_centroid(np.array([0.0, -5.0]), np.array([0.0, 3.0]), 5.0, 0.007, 639.5,
                            511.5)
    np.testing.assert_allclose(cen.x.values, np.repeat(np.asarray(x)[:, None], 2, 1), atol=1e-9)
    np.testing.assert_allclose(cen.y.values, np.repeat(np.asarray(y)[:, None], 2, 1), atol=1e-9)
