"""Centroid a whole frame cube: every frame (and every hole) through Dask, into ``centroids/1``.

Examples
--------
>>> from sunlab.centroid import locate
>>> locate.__name__
'locate'
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .. import parallel
from ..errors import ConfigurationError, SchemaError
from ..io.calframes import corrected_frames, corrected_saturation, has_calibration_frames
from .estimators import METHODS, PER_SPOT
from .lattice import SPOT_METRICS, locate_spots

__all__ = ["locate", "locate_all", "default_method"]


_FIELDS = ("x", "y", "flux", "x0", "x1", "y0", "y1", "status")
_TRUTH = ("true_x", "true_y", "true_alpha", "true_beta", "alpha_read", "beta_read")
_CARRY_ATTRS = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "bit_depth", "mask",
                "experiment")


def _single_block(frames, estimator, kwargs):
    """Apply a single-spot estimator to a block (..., y, x) -> (..., 8) float64."""
    lead = frames.shape[:-2]
    flat = np.asarray(frames).reshape((-1,) + frames.shape[-2:])
    out = np.empty((flat.shape[0], len(_FIELDS)))
    for n, fr in enumerate(flat):
        c = estimator(fr, **kwargs)
        out[n] = (c.x, c.y, c.flux, *c.window, c.status)
    return out.reshape(lead + (len(_FIELDS),))


def _multi_block(frames, shift_x, shift_y, kwargs, design):
    """locate_spots on a block (pose, shot, y, x) -> (pose, shot, hole, 8 + metrics) float64;
    ``shift_x``, ``shift_y`` (pose,) of the block's poses."""
    lead = frames.shape[:-2]
    flat = np.asarray(frames).reshape((-1,) + frames.shape[-2:])
    sx = np.broadcast_to(np.asarray(shift_x)[:, None], lead).reshape(-1)
    sy = np.broadcast_to(np.asarray(shift_y)[:, None], lead).reshape(-1)
    n_holes = kwargs["holes"][0].size
    nf = len(_FIELDS) + len(SPOT_METRICS)
    out = np.empty((flat.shape[0], n_holes, nf))
    for n, fr in enumerate(flat):
        expected = None
        if design is not None and np.isfinite(sx[n]) and np.isfinite(sy[n]):
            expected = design + np.array([sx[n], sy[n]])
        s = locate_spots(fr, expected=expected, **kwargs)
        out[n, :, 0], out[n, :, 1], out[n, :, 2] = s.x, s.y, s.flux
        out[n, :, 3:7] = s.window.T
        out[n, :, 7] = s.status
        for k, name in enumerate(SPOT_METRICS):
            out[n, :, 8 + k] = s.metrics[name]
    return out.reshape(lead + (n_holes, nf))


def _map_frames(frames, block_func, sizes: dict, per_pose: dict | None = None, **kwargs):
    """The lazy (pose, shot, *sizes) table of ``block_func`` over the frame blocks of a
    (pose, shot, y, x) Dask-backed DataArray of whole frames (chunked by :func:`_prepare`), one
    task per block; ``per_pose`` arrays (pose,) reach ``block_func`` as keywords sliced to the
    block's poses, ``kwargs`` whole.

    :func:`dask.array.blockwise` without concatenation, rather than
    ``xarray.apply_ufunc(dask="parallelized")`` or :func:`dask.array.map_blocks` with
    ``drop_axis``: both contract the core dimensions (y, x) through
    :func:`dask.array.core.concatenate3`, which copies every block (a pose's 8 frames are
    21 MB) once more before the estimator sees it, even when (y, x) is a single chunk.
    """
    import dask.array as da
    import xarray as xr

    data = frames.transpose("pose", "shot", "y", "x").data
    new = tuple(f"n{k}" for k in range(len(sizes)))
    extra = ()
    if per_pose:
        # the block's place by a BlockwiseDep: Dask fuses the estimator with the task that
        # makes the frames (a Dask array argument, even a tiny one, would keep it from fusing)
        from dask.layers import ArrayBlockIdDep

        extra = (ArrayBlockIdDep(data.chunks[:2]), ("p", "s"))
        starts = np.concatenate([[0], np.cumsum(data.chunks[0])])
        kwargs["per_pose"] = ({k: np.asarray(v) for k, v in per_pose.items()}, starts)
    table = da.blockwise(
        _one_block, ("p", "s") + new, data, ("p", "s", "y", "x"), *extra,
        block_func=block_func, new_axes=dict(zip(new, sizes.values(), strict=True)),
        concatenate=False, align_arrays=False, dtype=np.float64,
        meta=np.empty((0,) * (2 + len(sizes))), **kwargs,
    )
    return xr.DataArray(table, dims=("pose", "shot", *sizes))


def _one_block(blocks, block_id=None, *, block_func, per_pose=None, **kwargs):
    """``block_func`` of the single frame block that :func:`dask.array.blockwise` hands over
    without concatenation, as a list nested once per contracted axis (y, x); ``per_pose``
    (arrays by keyword, pose starts of the blocks) sliced to the block's poses by its
    ``block_id``."""
    while isinstance(blocks, list):
        (blocks,) = blocks
    if per_pose is not None:
        arrays, starts = per_pose
        p0, p1 = starts[block_id[0]], starts[block_id[0] + 1]
        kwargs.update({k: v[p0:p1] for k, v in arrays.items()})
    return block_func(blocks, **kwargs)


def is_multi_hole(cube) -> bool:
    """Whether a frame cube holds many spots per frame (a multi-hole mask): it has a ``hole``
    dimension, or the grid coordinates ``hole_i`` and ``hole_j`` of its holes.

    :func:`locate` centroids such a cube spot by spot on the mask's lattice.

    Parameters
    ----------
    cube : xarray.Dataset
        A ``frames/1`` cube.

    Returns
    -------
    bool
        True for a multi-hole cube.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> cube = schema.frames_dataset(np.zeros((1, 1, 8, 8), np.uint16), alpha=[0.0], beta=[0.0])
    >>> is_multi_hole(cube)
    False
    >>> is_multi_hole(cube.assign_coords(hole_i=("hole", [0, 0]), hole_j=("hole", [0, 1])))
    True
    """
    return "hole" in cube.dims or ("hole_i" in cube.variables and "hole_j" in cube.variables)


def default_method(cube, background: str | None = None) -> str:
    """The estimator a cube is centroided with when none is named (``sunlab centroid``):
    algorithm B, ``"projection"``, for one spot per frame; ``"tight"`` for a multi-hole cube
    (its spots take ``"tight"`` or ``"fit"`` only) or when a ``background`` model is asked for
    (an option of the tight window).

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``).
    background : {"ring", "plane"}, optional
        The tight window's background, if one is asked for.

    Returns
    -------
    str
        A key of :data:`METHODS`.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> default_method(schema.frames_dataset(np.zeros((1, 1, 8, 8), np.uint16), alpha=[0.0],
    ...                                      beta=[0.0]))
    'projection'
    """
    return "tight" if background is not None or is_multi_hole(cube) else "projection"


def locate(
    cube, method: str = "projection", *, multi: bool | None = None, scheduler: str = "threads",
    address: str | None = None, num_workers: int | None = None, progress: bool = True,
    compute: bool = True, **options,
):
    """Centroid every frame of a cube: a ``centroids/1`` dataset over (pose, shot[, hole]).

    A cube that holds master dark, bias or flat frames
    (:func:`sunlab.io.with_calibration_frames`) is corrected frame by frame, lazily, before the
    estimator sees it (:func:`sunlab.io.corrected_frames`).

    The frames go through :func:`dask.array.blockwise`, one task per frame chunk and no copy
    of the frames, on Dask's threaded scheduler by default (numpy releases the GIL in its array
    passes), or on a ``dask.distributed`` cluster at ``address``.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``), NumPy- or Dask-backed.
    method : {"threshold", "projection", "tight", "fit"}
        Single-spot estimator (:data:`METHODS`); for a multi-hole cube the per-spot estimator of
        :func:`locate_spots`, ``"tight"`` or ``"fit"`` (``"projection"`` and ``"threshold"`` are
        single-spot algorithms: they raise :class:`~sunlab.errors.ConfigurationError` there).
    multi : bool, optional
        Multi-hole cube (default: the cube has a ``hole`` dimension with ``hole_i``, ``hole_j``).
    scheduler : str
        Dask scheduler when no address is given: ``"threads"``, ``"processes"``,
        ``"synchronous"`` or ``"cluster"`` (a local cluster of processes; see
        :func:`sunlab.parallel.compute`).
    address : str, optional
        Address of a ``dask.distributed`` scheduler, e.g. ``"tcp://10.0.0.5:8786"``.
    num_workers : int, optional
        Threads or processes of a local scheduler.
    progress : bool
        Show a progress bar.
    compute : bool
        Compute now (default); ``False`` returns the dataset with lazy Dask variables.
    **options
        Options of the estimator (``saturation`` defaults to ``2**bit_depth - 1`` of the cube,
        the level of :func:`sunlab.io.corrected_saturation` for a corrected cube).

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1``: ``x``, ``y`` (px), ``flux`` (DN), ``status``, window
        ``x0, x1, y0, y1``, with the cube's ``alpha``, ``beta`` coordinates, its sensor
        attributes, ground truth variables when present, and for multi-hole cubes the hole
        coordinates and the per-spot metrics of :data:`SPOT_METRICS`.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> yy, xx = np.mgrid[0:200, 0:240]
    >>> spot = lambda x, y: (30 + 400 * (np.hypot(xx - x, yy - y) < 15)).astype(np.uint16)
    >>> frames = np.stack([[spot(100.5, 80.0), spot(101.5, 80.0)]])
    >>> cube = schema.frames_dataset(frames, alpha=[0.0], beta=[0.0])
    >>> cen = locate(cube, "projection", progress=False)
    >>> cen.x.values.round(2).tolist(), cen.status.values.tolist()
    ([[100.5, 101.5]], [[0, 0]])
    """
    if not compute:
        lazy = _prepare(cube, method, multi, options)
        cen = _centroid_table(cube, lazy.table, lazy.dims, method, lazy.options, lazy.multi,
                              False)
        return _carry_cube_variables(cube, cen, lazy.dims, lazy.multi, False)
    return locate_all({0: cube}, method, multi=multi, scheduler=scheduler, address=address,
                      num_workers=num_workers, progress=progress, **options)[0]


def locate_all(
    cubes: dict, method: str = "projection", *, multi: bool | None = None,
    scheduler: str = "threads", address: str | None = None, num_workers: int | None = None,
    progress: bool = True, pool=None, **options,
) -> dict:
    """Centroid several cubes in one pass of Dask (:func:`locate` on each), e.g. the
    experiments of a table: the workers stay busy to the end, where one cube after the other
    would leave them idle at each tail.

    Each cube costs one task per frame chunk, which returns the chunk's whole table (every
    field, every spot); the ``centroids/1`` datasets are built from the computed tables, so a
    cube made lazily (e.g. rendered by :func:`sunlab.sim.simulate`) is made and centroided in
    the same task, frame by frame, and its frames never leave the worker. Lazy ground-truth
    variables of the cubes are computed in the same pass.

    Parameters
    ----------
    cubes : dict
        Frame cubes (contract ``frames/1``) by name.
    method, multi, scheduler, address, num_workers, progress, **options
        As for :func:`locate`, the same for every cube.
    pool : concurrent.futures.Executor, optional
        Worker processes kept between calls (:func:`sunlab.parallel.worker_pool`).

    Returns
    -------
    dict
        ``centroids/1`` datasets keyed as ``cubes``.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> yy, xx = np.mgrid[0:120, 0:160]
    >>> spot = lambda x: (30 + 400 * (np.hypot(xx - x, yy - 60.0) < 12)).astype(np.uint16)
    >>> cubes = {k: schema.frames_dataset(np.stack([[spot(x)]]), alpha=[0.0], beta=[0.0])
    ...          for k, x in (("a", 70.5), ("b", 90.0))}
    >>> cens = locate_all(cubes, progress=False)
    >>> {k: float(c.x[0, 0].round(2)) for k, c in cens.items()}
    {'a': 70.5, 'b': 90.0}
    """
    import dask.array as da

    work = {k: _prepare(cube, method, multi, options) for k, cube in cubes.items()}
    # the ground truth still lazy (e.g. a simulated cube's true centroids), by cube
    pending = {k: [n for n in w.truth if isinstance(cubes[k][n].data, da.Array)]
               for k, w in work.items()}
    lazy = []
    for k, w in work.items():
        lazy.append(w.table.data)
        lazy.extend(cubes[k][n].data for n in pending[k])
    done = iter(parallel.compute(*lazy, scheduler=scheduler, address=address,
                                 num_workers=num_workers, progress=progress, pool=pool))
    out = {}
    for k, w in work.items():
        cube = cubes[k]
        table = w.table.copy(data=next(done))
        for n in pending[k]:
            var = {n: cube[n].variable.copy(data=next(done))}
            cube = cube.assign_coords(var) if n in cube.coords else cube.assign(var)
        cen = _centroid_table(cube, table, w.dims, method, w.options, w.multi, True)
        out[k] = _carry_cube_variables(cube, cen, w.dims, w.multi, True)
    return out


class _Prepared(NamedTuple):
    table: object  # xarray.DataArray, lazy (dims, field)
    dims: tuple
    options: dict
    multi: bool
    truth: tuple  # names of the ground-truth variables carried


def _prepare(cube, method, multi, options) -> _Prepared:
    """Validate a cube and make its lazy table of every field of every frame (and hole)."""
    import dask.array as da

    from .. import schema

    schema.validate_frames(cube)
    if method not in METHODS:
        raise ConfigurationError(f"method: found {method!r}, expected one of {sorted(METHODS)}")
    options = dict(options)
    corrected = has_calibration_frames(cube)
    options.setdefault("saturation", corrected_saturation(cube) if corrected
                       else float(2 ** int(cube.attrs["bit_depth"]) - 1))
    if multi is None:
        multi = is_multi_hole(cube)
    # the frames as a Dask array, one chunk per frame (or the cube's own pose/shot chunks) and
    # whole frames in each; a cube already chunked so is left as it is: a rechunk layer, even
    # a no-op one, keeps Dask from fusing the estimator with the task that makes the frames
    # (e.g. renders them), and the frames would then travel between workers
    frames = cube["frames"]
    if not isinstance(frames.data, da.Array):
        frames = frames.chunk({"pose": 1, "shot": 1})
    if any(len(frames.chunks[frames.dims.index(d)]) > 1 for d in ("y", "x")):
        frames = frames.chunk({"y": -1, "x": -1})
    if corrected:  # dark, bias and flat applied in the task that centroids each frame
        frames = corrected_frames(cube.assign(frames=frames))
    if multi:  # the lazy (pose, shot, hole, field) table of locate_spots
        if method not in PER_SPOT.values():
            raise ConfigurationError(
                f"method: found {method!r} for a multi-hole cube (dimension 'hole'); {method!r} "
                f"is a single-spot algorithm. Fix: pass method={PER_SPOT.get(method, 'tight')!r} "
                f"(one of {sorted(set(PER_SPOT.values()))}: 'tight', the tight window of every "
                "spot; 'fit', a disk fit of every spot), or multi=False for one spot per frame"
            )
        if "hole_i" not in cube.variables or "hole_j" not in cube.variables:
            raise SchemaError("hole_i, hole_j", "missing", "grid row/column of each hole on dim "
                              "'hole'", "simulate with a multi-hole bench or add the coordinates")
        hi = np.asarray(cube["hole_i"].values, dtype=int)
        hj = np.asarray(cube["hole_j"].values, dtype=int)
        spot_opts = {**options, "method": method, "holes": (hi, hj)}
        spot_opts.setdefault("shape", (int(hi.max()) + 1, int(hj.max()) + 1))
        # the design positions of the holes' spots (n_holes, 2) and the shift of each pose (the
        # ideal centroid at its angles); None and NaN shifts when the cube has no design
        design, shift = None, np.full((2, cube.sizes["pose"]), np.nan)
        if "hole_x_cf" in cube.variables and "hole_y_cf" in cube.variables:
            from ..geometry import ideal_centroid

            design = np.column_stack([cube["hole_x_cf"].values, cube["hole_y_cf"].values])
            shift = np.array(ideal_centroid(cube["alpha"].values, cube["beta"].values,
                                            float(cube.attrs["mask_distance_mm"]),
                                            float(cube.attrs["pixel_pitch_mm"]), 0.0, 0.0),
                             dtype=float)
        dims = ("pose", "shot", "hole")
        res = _map_frames(frames, _multi_block, {"hole": spot_opts["holes"][0].size,
                                                 "field": len(_FIELDS) + len(SPOT_METRICS)},
                          per_pose={"shift_x": shift[0], "shift_y": shift[1]}, kwargs=spot_opts,
                          design=design)
    else:  # the lazy (pose, shot, field) table of a single-spot estimator
        dims = ("pose", "shot")
        res = _map_frames(frames, _single_block, {"field": len(_FIELDS)},
                          estimator=METHODS[method], kwargs=options)
    truth = tuple(n for n in _TRUTH if n in cube.variables and set(cube[n].dims) <= set(dims))
    return _Prepared(res.transpose(*dims, "field"), dims, options, multi, truth)


def _centroid_table(cube, res, dims, method, options, multi, computed):
    """The ``centroids/1`` dataset of the (computed or lazy) field table ``res``."""
    from .. import schema

    data = res.data
    extra = {}
    if multi:
        for k, name in enumerate(SPOT_METRICS):
            extra[name] = (dims, data[..., 8 + k], {"long_name": SPOT_METRICS[name]})
    attrs = {k: cube.attrs[k] for k in _CARRY_ATTRS if k in cube.attrs}
    attrs.update({"source_schema": cube.attrs.get("sunlab_schema", ""),
                  "options": repr({k: v for k, v in options.items() if k != "holes"})})
    if computed:
        return schema.centroids_dataset(
            data[..., 0], data[..., 1], flux=data[..., 2], status=data[..., 7].astype(np.int8),
            window=[data[..., 3 + k].astype(np.int32) for k in range(4)],
            alpha=cube["alpha"].values, beta=cube["beta"].values, method=method, attrs=attrs,
            extra=extra,
        )
    shape = tuple(res.sizes[d] for d in dims)
    template = schema.centroids_dataset(
        np.zeros(shape), np.zeros(shape), alpha=cube["alpha"].values,
        beta=cube["beta"].values, method=method, attrs=attrs,
    )
    cen = template.copy()
    for k, name in enumerate(_FIELDS):
        arr = data[..., k]
        if name == "status":
            arr = arr.astype(np.int8)
        elif name in ("x0", "x1", "y0", "y1"):
            arr = arr.astype(np.int32)
        cen[name] = (dims, arr, template[name].attrs)
    for name, val in extra.items():
        cen[name] = val
    return cen


def _carry_cube_variables(cube, cen, dims, multi, computed):
    """Hole coordinates (multi-hole) and ground-truth variables of the cube onto ``cen``."""
    for name in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf", "hole_defect"):
        if multi and name in cube.variables:
            cen = cen.assign_coords({name: ("hole", np.asarray(cube[name].values))})
    for name in _TRUTH:
        if name in cube.variables and set(cube[name].dims) <= set(dims):
            # the bare variable: a cube's own coordinates (e.g. alpha_read, time on an
            # acquisition store) must not collide with the table's
            cen[name] = cube[name].variable.transpose(*[d for d in dims if d in cube[name].dims])
            if computed:
                cen[name] = cen[name].compute()
    n_pose, n_shot = cube.sizes["pose"], cube.sizes["shot"]
    if n_pose != cen.sizes["pose"] or n_shot != cen.sizes["shot"]:  # pragma: no cover
        raise SchemaError("centroids", dict(cen.sizes), f"pose={n_pose}, shot={n_shot}")
    return cen
