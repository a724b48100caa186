"""The spot windows of a frame cube: the pixels around each detected spot, what
:class:`sunlab.calibration.FrameNet` learns from.

:func:`detect_spots` finds every spot with the library's locator; :func:`spot_windows` cuts a
window about each one's nearest integer pixel (background subtracted, scaled by the spot's
plateau), with a margin for the training crops.

Examples
--------
>>> import numpy as np
>>> from sunlab import schema
>>> cube = schema.frames_dataset(np.zeros((1, 1, 64, 64), np.uint16), alpha=[0.0], beta=[0.0])
>>> spot_windows(cube, detect_spots(cube))["n_frames"]  # a dark frame: no spot
0
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import xarray as xr

from .base import _ok_mask

__all__: list[str] = []



def detect_spots(cube: xr.Dataset, hole_offset=(0.0, 0.0), *, progress: bool = False,
                 workers: int | None = None) -> xr.Dataset:
    """The spots of every frame, by the library's locator: algorithm B for one hole, the
    lattice locator (``"tight"``) for many, its spots numbered with the design places moved by
    ``hole_offset`` (px; the sensor's mounting,
    :func:`sunlab.reproduce.pipeline.mounting_offset_px`).

    Parameters
    ----------
    cube : xarray.Dataset
        A ``frames/1`` cube, as ``sunlab simulate`` or ``sunlab import`` writes it.
    hole_offset : (float, float)
        Many holes: offset of the spots from their design places, px (x, y).
    progress : bool
        Show a progress bar.
    workers : int, optional
        Threads of the locator.

    Returns
    -------
    xarray.Dataset
        The ``centroids/1`` table (design places kept).
    """
    from .. import centroid

    cube = cube.drop_vars(["true_x", "true_y"], errors="ignore")
    if not centroid.cube.is_multi_hole(cube):
        return centroid.locate(cube, "projection", progress=progress, num_workers=workers)
    moved = cube.assign_coords(hole_x_cf=cube["hole_x_cf"] + float(hole_offset[0]),
                               hole_y_cf=cube["hole_y_cf"] + float(hole_offset[1]))
    cen = centroid.locate(moved, "tight", progress=progress, num_workers=workers)
    return cen.assign_coords({k: cube[k].variable for k in ("hole_x_cf", "hole_y_cf")})


def _crop(frames: np.ndarray, x, y, ok, size: int, half: int):
    """Windows of ``size`` px about the integer place nearest (x, y) of every usable spot of
    one pose (``frames``: shot, y, x): background (median of the 2-px border) subtracted,
    scaled by the spot's plateau (median of the pixels above half the peak)."""
    ny, nx = frames.shape[-2:]
    out = []
    for s, h in zip(*np.nonzero(ok), strict=True):
        x0, y0 = int(round(x[s, h])) - half, int(round(y[s, h])) - half
        if x0 < 0 or y0 < 0 or x0 + size > nx or y0 + size > ny:
            continue  # a window across the frame's edge: the spot leaves the set
        w = frames[s, y0:y0 + size, x0:x0 + size].astype(np.float32)
        ring = np.concatenate([w[:2].ravel(), w[-2:].ravel(), w[2:-2, :2].ravel(),
                               w[2:-2, -2:].ravel()])
        w -= np.median(ring)
        peak = w.max()
        plateau = np.median(w[w > 0.5 * peak]) if peak > 0 else 0.0
        if not plateau > 0:
            continue
        out.append((s, h, x0, y0, w / plateau))
    return out


def spot_windows(cube: xr.Dataset, detections: xr.Dataset, *, window: int = 44, pad: int = 3,
                 threads: int = 2) -> dict:
    """The spot windows of every frame of ``cube`` at the places ``detections`` found.

    Parameters
    ----------
    cube : xarray.Dataset
        ``frames/1`` cube (lazy or in memory); frames are read one pose at a time.
    detections : xarray.Dataset
        Its ``centroids/1`` table (:func:`detect_spots`); spots of a usable status are kept.
    window, pad : int
        Window side and the margin stored around it for training crops, px.
    threads : int
        Poses read and cropped at once.

    Returns
    -------
    dict
        ``win`` (E, window + 2 pad, same) float32, ``corner`` (E, 2) px of the window's first
        pixel (x, y) at crop offset 0, ``hole`` (E, 2) design place px (0 for one hole),
        ``hole_index`` (E,), ``pose``, ``shot`` (F,) of the frames with a spot, ``start``
        (F + 1,) their first element, ``target`` (F, 2) commanded angles deg, and sizes.
    """
    multi = "hole" in detections["x"].dims
    x, y = (np.asarray(detections[v].values, dtype=float) for v in ("x", "y"))
    ok = _ok_mask(detections)
    if not multi:
        x, y, ok = x[..., None], y[..., None], ok[..., None]
    size, half = window + 2 * pad, window // 2 + pad
    frames = cube["frames"]

    def one(p):
        return _crop(np.asarray(frames.isel(pose=p).values), x[p], y[p], ok[p], size, half)

    with ThreadPoolExecutor(max(1, int(threads))) as ex:
        per_pose = list(ex.map(one, range(x.shape[0])))
    holes = (np.column_stack([cube["hole_x_cf"].values, cube["hole_y_cf"].values]) if multi
             else np.zeros((1, 2)))
    # in (pose, shot, hole) order: poses in turn, and each pose's spots in C order of (shot, hole)
    els = [(p, s, h, x0, y0, w) for p, items in enumerate(per_pose) for s, h, x0, y0, w in items]
    key = np.array([(e[0], e[1]) for e in els], dtype=int).reshape(-1, 2)
    first = np.flatnonzero(np.r_[True, np.any(key[1:] != key[:-1], axis=1)]) if len(els) else \
        np.zeros(0, int)
    alpha, beta = cube["alpha"].values, cube["beta"].values
    pose, shot = key[first, 0], key[first, 1]
    return {"win": np.stack([e[5] for e in els]) if els else np.zeros((0, size, size), "f4"),
            "corner": np.array([(e[3], e[4]) for e in els], dtype=float).reshape(-1, 2),
            "hole": holes[[e[2] for e in els]].reshape(-1, 2),
            "hole_index": np.array([e[2] for e in els], dtype=int),
            "pose": pose, "shot": shot, "start": np.r_[first, len(els)].astype(int),
            "target": np.column_stack([alpha[pose], beta[pose]]).astype(float),
            "n_frames": int(first.size), "window": int(window), "pad": int(pad),
            "multi": multi, "shape": (x.shape[0], x.shape[1])}


def _with_hole_uv(data: dict, scaling: dict) -> dict:
    hole_uv = (data["hole"] - scaling["hole_mean"]) / scaling["hole_std"]
    return {**data, "hole_uv": hole_uv if data["multi"] else np.zeros_like(hole_uv)}
