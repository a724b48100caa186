"""Simulated experiments: a plan on the virtual bench as a lazy, Dask-backed frame cube.

Frames are rendered on demand, deterministically from (seed, plan, pose, shot); the ground truth
(true platform angles, true centroids and rays) rides along, lazy too.

Examples
--------
>>> from sunlab import plans
>>> cube = simulate(plans.experiment("III").subset(90), seed=1)
>>> dict(cube.frames.sizes)
{'pose': 5, 'shot': 8, 'y': 1024, 'x': 1280}
"""

from __future__ import annotations

import numpy as np

from .bench import Bench
from .frame import render_frame, render_pose
from .platform import _entropy, _platform_table
from .render import mask_play, spot_geometry
from .source import _check
from .spots import _truth

__all__ = ["simulate"]


def _truth_task(bench, a_row, b_row, key, pose):
    """(4, 1, shots, holes): true x, true y, ray x, ray y of every shot of one pose."""
    out = np.full((4, 1, len(a_row), bench.n_holes), np.nan)
    play = mask_play(bench, key, pose)
    for s, (a, b) in enumerate(zip(a_row, b_row, strict=True)):
        geom = spot_geometry(bench, a, b, play)
        out[:2, 0, s], out[2:, 0, s] = _truth(bench, geom), geom.ray.T
    return out


def simulate(plan, bench: Bench | None = None, seed=0, chunks: str = "frame"):
    """A lazy, Dask-backed frame cube (contract frames/1) of a plan on the virtual bench.

    Frames are rendered on demand, one chunk per frame, deterministically from
    (seed, plan, pose, shot); the cube's ``sim_key`` attribute is the seed entropy actually used
    (``[seed, plan.crc32()]``): ``render_pose(bench, true_alpha[p], true_beta[p],
    seed=cube.attrs["sim_key"], pose=p)`` reproduces the frames of pose p.

    Parameters
    ----------
    plan : sunlab.plans.Plan
        Commanded poses and shots.
    bench : Bench, optional
        Default :meth:`Bench.paper_single_hole`.
    seed : int or sequence of int
        Seed of the experiment.
    chunks : {"frame", "pose"}
        One Dask chunk (and task) per frame, or per pose with all its shots: fewer, larger
        tasks for pipelines that reduce every frame at once (``sunlab reproduce``). The frames
        are identical either way.

    Returns
    -------
    xarray.Dataset
        ``frames`` (pose, shot, y, x) uint16, lazy; ground truth ``true_alpha``, ``true_beta`` on
        (pose, shot) (true axis angles, deg); ``true_x``, ``true_y`` (true centroids, px) and
        ``ray_x``, ``ray_y`` (geometric rays through the hole centres, px) on (pose, shot) for one
        hole or (pose, shot, hole), lazy; for multi-hole masks the coordinates ``hole_i``,
        ``hole_j``, ``hole_x_cf``, ``hole_y_cf`` (design zenith projections, px) and
        ``hole_defect`` (bit flags of :data:`sunlab.schema.DEFECT_FLAGS`) on ``hole``.

    Examples
    --------
    >>> from sunlab import plans
    >>> cube = simulate(plans.experiment("III").subset(60), seed=1)
    >>> dict(cube.frames.sizes), cube.frames.data.chunksize
    ({'pose': 7, 'shot': 8, 'y': 1024, 'x': 1280}, (1, 1, 1024, 1280))
    >>> frame = cube.frames[0, 0].values
    >>> bool(frame.max() > 300)
    True
    """
    from dask.base import tokenize

    from .. import schema
    from ..plans import Plan

    _check(isinstance(plan, Plan), "plan", type(plan).__name__, "a sunlab.plans.Plan",
           "use sunlab.plans.experiment('III') or sunlab.plans.custom(alpha, beta).")
    bench = Bench.paper_single_hole() if bench is None else bench
    _check(isinstance(bench, Bench), "bench", type(bench).__name__, "a sunlab.sim.Bench",
           "pass sunlab.sim.Bench.paper_single_hole() or omit bench.")
    _check(chunks in ("frame", "pose"), "chunks", chunks, "'frame' or 'pose'", "chunks='frame' "
           "(one frame per chunk) or chunks='pose' (all shots of a pose per chunk).")
    key = _entropy(seed) + [plan.crc32()]
    ta, tb = _platform_table(bench, plan, key)
    token = tokenize(bench.to_json(), key, ta, tb)
    frames = _frames_array(bench, key, ta, tb, token, chunks)
    xd, yd = bench.hole_design_px()
    ds = schema.frames_dataset(
        frames, plan.alpha, plan.beta, pixel_pitch_mm=bench.detector.pixel_pitch_mm,
        mask_distance_mm=bench.mask_distance_mm, x_cf_px=float(np.mean(xd)),
        y_cf_px=float(np.mean(yd)), bit_depth=bench.detector.bit_depth, mask=bench.mask.name,
        experiment=plan.name, coords=_hole_coords(bench, plan),
        attrs={"source": "sunlab virtual bench", "sim_seed": _entropy(seed), "sim_key": list(key),
               "sim_bench": bench.to_json(),
               # the motion history (sunlab.reproduce.fault reads it back)
               "scan_order": plan.scan, "approach": plan.approach,
               "visit_order": plan.visit_order().astype(np.int32)})
    ds = _add_truth(ds, bench, key, ta, tb, token)
    return schema.validate_frames(ds)


def _frames_block(index, bench, key, ta, tb):
    """The frames of one block: ``index`` holds pose numbers (pose, ) for a block of whole
    poses, or frame numbers pose * shots + shot (pose, shot) for a block of single frames;
    returns (poses, shots, ny, nx), each frame rendered in place."""
    n_s = ta.shape[1]
    shots = (n_s,) if index.ndim == 1 else ()  # a block of whole poses, or of single frames
    out = np.empty(index.shape + shots + bench.detector.shape, dtype=np.uint16)
    if index.ndim == 1:
        for i, p in enumerate(index):
            render_pose(bench, ta[p], tb[p], seed=key, pose=int(p), out=out[i])
        return out
    for (i, j), k in np.ndenumerate(index):
        p, s = divmod(int(k), n_s)
        render_frame(bench, ta[p, s], tb[p, s], seed=key, pose=p, shot=s, out=out[i, j],
                     shape_angles=(ta[p, 0], tb[p, 0]))
    return out


def _frames_array(bench: Bench, key, ta, tb, token: str, chunks: str):
    """The lazy frames (pose, shot, y, x): one task per frame or per pose (:func:`simulate`).

    A blockwise map over frame numbers, so that a blockwise reduction of the frames
    (:func:`sunlab.centroid.locate`) fuses with the rendering into one task per block: the
    frames never leave the worker (thread or process) that renders them."""
    import dask.array as da

    n_p, n_s = ta.shape
    ny, nx = bench.detector.shape
    if chunks == "frame":
        index = da.from_array(np.arange(n_p * n_s).reshape(n_p, n_s), chunks=1,
                              name="sunlab-sim-index-" + token)
        new_axis, shot_chunks = [2, 3], (1,) * n_s
    else:
        index = da.from_array(np.arange(n_p), chunks=1, name="sunlab-sim-poses-" + token)
        new_axis, shot_chunks = [1, 2, 3], (n_s,)
    return da.map_blocks(
        _frames_block, index, bench=bench, key=key, ta=ta, tb=tb, new_axis=new_axis,
        chunks=((1,) * n_p, shot_chunks, (ny,), (nx,)), dtype=np.uint16,
        meta=np.empty((0, 0, 0, 0), dtype=np.uint16),
        name=f"sunlab-sim-frames-{chunks}-" + token)


def _hole_coords(bench: Bench, plan) -> dict:
    """The cube's coordinates: each pose's approach direction and, for a multi-hole mask, the
    holes' grid places, design zenith projections and defect flags."""
    coords, holes = {}, bench.mask.holes
    if bench.n_holes > 1:
        xd, yd = bench.hole_design_px()
        coords = {
            "hole_i": ("hole", np.array([h.i for h in holes], dtype=np.int32)),
            "hole_j": ("hole", np.array([h.j for h in holes], dtype=np.int32)),
            "hole_x_cf": ("hole", xd, {"units": "px", "long_name": "design zenith projection x"}),
            "hole_y_cf": ("hole", yd, {"units": "px", "long_name": "design zenith projection y"}),
            "hole_defect": ("hole", np.array([h.defect_flags for h in holes], dtype=np.int8),
                            {"flag_masks": np.array([1, 2, 4, 8], dtype=np.int8),
                             "flag_meanings": "dust elliptical burred undersized"})}
    coords["beta_approach"] = ("pose", plan.beta_approach(), {
        "long_name": "direction in which the inner axis reached the pose (+1 up, -1 down)"})
    return coords


def _add_truth(ds, bench: Bench, key, ta, tb, token: str):
    """The ground truth: true platform angles, and the lazy true centroids and rays."""
    import dask.array as da

    n_p, n_s = ta.shape
    n_h = bench.n_holes
    tname = "sunlab-sim-truth-" + token
    tdsk = {(tname, 0, p, 0, 0): (_truth_task, bench, ta[p], tb[p], key, p) for p in range(n_p)}
    truth = da.Array(tdsk, tname, chunks=((4,), (1,) * n_p, (n_s,), (n_h,)), dtype=float)
    dims = ("pose", "shot", "hole") if n_h > 1 else ("pose", "shot")
    truth = truth if n_h > 1 else truth[..., 0]
    for var, angle, axis in (("true_alpha", ta, "outer"), ("true_beta", tb, "inner")):
        ds[var] = (("pose", "shot"), angle,
                   {"units": "deg", "long_name": f"true {axis}-axis angle"})
    signal = "(noiseless expected signal, fill factor included)"
    names = {"true_x": f"true centroid column {signal}", "true_y": f"true centroid row {signal}",
             "ray_x": "geometric ray through the hole centre, column",
             "ray_y": "geometric ray through the hole centre, row"}
    for i, (var, long) in enumerate(names.items()):
        ds[var] = (dims, truth[i], {"units": "px", "long_name": long})
    return ds
