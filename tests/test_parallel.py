"""Scale-out: the same reproduction on a local cluster of processes as on threads."""

import numpy as np
import pytest

from sunlab import parallel
from sunlab.errors import ConfigurationError
from sunlab.reproduce.pipeline import simulate_and_locate


def _xy(cens):
    return {k: np.stack([v.x.values, v.y.values, v.status.values]) for k, v in cens.items()}


@pytest.fixture(scope="module")
def local():
    return _xy(simulate_and_locate(seed=3, step=7, shots=1, progress=False))


def test_two_process_cluster_gives_the_local_results(local):
    # A scheduler with two single-threaded worker processes, reached by its address as one
    # started by `dask scheduler` + `dask worker` would be (the cluster `scheduler="cluster"`
    # makes). Frames are a function of (seed, plan, pose, shot) only, so where they are
    # rendered cannot change them: centroids bit for bit equal to the threaded run.
    with parallel.local_cluster(2) as cluster:
        assert len(cluster.workers) == 2
        got = _xy(simulate_and_locate(seed=3, step=7, shots=1, progress=False,
                                      address=cluster.scheduler_address))
    assert got.keys() == local.keys()
    for k in local:
        np.testing.assert_array_equal(got[k], local[k])


def test_bad_scheduler_and_workers_are_refused():
    import dask.array as da

    with pytest.raises(ConfigurationError, match="scheduler"):
        parallel.compute(da.ones(2), scheduler="gpu", progress=False)
    with pytest.raises(ConfigurationError, match="num_workers"):
        parallel.compute(da.ones(2), num_workers=0, progress=False)


@pytest.mark.parametrize("chunks", ["pose", "frame"])
@pytest.mark.parametrize("holes", [1, 100])
def test_rendering_fuses_with_centroiding(chunks, holes):
    # every task that runs returns a table, never a block of frames: the frames are rendered
    # and reduced in one task, so on processes or a cluster only tables cross between workers
    # (a multi-hole cube's per-pose design shifts must not break the fusion)
    from dask.callbacks import Callback

    from sunlab import centroid, plans, sim

    bench = sim.Bench.paper_single_hole() if holes == 1 else sim.Bench.paper_multi_hole()
    plan = plans.experiment("III").thin(9 if holes == 1 else 20).with_shots(2)
    cube = sim.simulate(plan, bench, seed=2, chunks=chunks)
    sizes = []
    with Callback(posttask=lambda key, result, *_: sizes.append(getattr(result, "nbytes", 0))):
        cen = centroid.locate_all({"III": cube}, "projection" if holes == 1 else "tight",
                                  scheduler="synchronous", progress=False)["III"]
    n_frames = cube.sizes["pose"] * cube.sizes["shot"]
    assert int(cen.x.notnull().any(cen.x.dims[2:]).sum()) == n_frames
    assert sizes and max(sizes) < 1024 * 1280 * 2  # below one uint16 frame


def test_worker_pool_workers_are_forked_with_the_task_modules():
    # the workers of sunlab's own pool come from a fork server that imported the task modules
    # (imports only: nothing runs at import), so their first task imports nothing more. The
    # probe is a builtin (eval), so unpickling it in the worker imports nothing of sunlab.
    probe = f"all(m in __import__('sys').modules for m in {list(parallel.PRELOAD)!r})"
    with parallel.worker_pool("processes", 1) as pool:
        assert pool.submit(eval, probe).result(timeout=120) is True

