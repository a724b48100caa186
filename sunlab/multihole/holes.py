"""The holes of a multi-hole mask: grid indices, usable spots, cut-outs and layout centroiding.

Conventions: pixel coordinates (x = column, y = row, centre of the first pixel = 0); centroid
tables follow contract ``centroids/1`` on dims ``(pose, shot, hole)`` with the commanded angles
``alpha``, ``beta`` as coordinates on ``pose`` and, where known, the hole's grid row/column
``hole_i``, ``hole_j`` and design position ``hole_x_cf``, ``hole_y_cf`` (px) on ``hole``.

References
----------
.. [1] docs/paper.md, sec. 6 (the 2005 preprint on the Naples APS sun sensor).

Examples
--------
Two holes of a free (non-grid) layout, centroided by :func:`centroid_free_layout`:

>>> from sunlab import schema
>>> yy, xx = np.mgrid[0:200, 0:300]
>>> img = (400.0 * (np.hypot(xx - 80.3, yy - 100) < 15)
...        + 400.0 * (np.hypot(xx - 200, yy - 90.6) < 12))
>>> cube = schema.frames_dataset(img.astype(np.uint16)[None, None], alpha=[0.0], beta=[0.0])
>>> cube = cube.assign_coords(hole_x_cf=("hole", [80.0, 200.0]),
...                           hole_y_cf=("hole", [100.0, 90.0]))
>>> cen = centroid_free_layout(cube)
>>> bool(np.allclose(cen.x[0, 0], [80.3, 200.0], atol=0.15)
...      and np.allclose(cen.y[0, 0], [100.0, 90.6], atol=0.15))
True
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import xarray as xr

from .. import geometry, schema
from ..errors import SchemaError
from ..options import show_progress

__all__ = ["centroid_free_layout"]


def hole_grid(cen: xr.Dataset):
    """Grid row and column of every hole of a centroid table (or frame cube).

    Uses the ``hole_i`` / ``hole_j`` coordinates when present; otherwise assumes a square,
    row-major grid (a hole count that is no square: one row).

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table or frame cube with a ``hole`` dimension.

    Returns
    -------
    i, j : numpy.ndarray of int, shape (hole,)
        Grid row and column of every hole (0-based).
    n_rows, n_cols : int
        The grid's size.

    Raises
    ------
    SchemaError
        ``cen`` has no ``hole`` dimension.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> i, j, nr, nc = hole_grid(synthetic_centroids([0.0], [0.0], shots=1, layout="grid"))
    >>> (nr, nc), int(i[57]), int(j[57])
    ((10, 10), 5, 7)
    """
    n_h = cen.sizes.get("hole", 0)
    if n_h == 0:
        raise SchemaError("hole", "no 'hole' dimension", "a multi-hole table on (pose, shot, hole)",
                          "centroid the cube with a multi-spot method")
    if "hole_i" in cen.coords and "hole_j" in cen.coords:
        i = np.asarray(cen["hole_i"].values, dtype=int)
        j = np.asarray(cen["hole_j"].values, dtype=int)
        if np.all(i >= 0) and np.all(j >= 0):
            return i, j, int(i.max()) + 1, int(j.max()) + 1
    n = math.isqrt(n_h)
    if n * n == n_h:
        i, j = np.divmod(np.arange(n_h), n)
        return i, j, n, n
    # a free layout: one row
    return np.zeros(n_h, int), np.arange(n_h), 1, n_h


def centroid_free_layout(cube: xr.Dataset, *, half: int = 38, progress: bool = False,
                  **options) -> xr.Dataset:
    """Centroid every hole of a free (non-grid) layout, e.g. a random mask, frame by frame.

    Each spot is centroided by :func:`sunlab.centroid.tight_window` in a cut-out about the
    position eq. (1) predicts from the hole's design position and the commanded pose: holes
    must be ``half`` px plus a spot radius apart, the platform's mounting error small next to
    ``half``. (:func:`sunlab.centroid.locate` is the parallel path for grids.)

    Parameters
    ----------
    cube : xarray.Dataset
        Frame cube on (pose, shot) with ``hole_x_cf``, ``hole_y_cf`` (design positions, px).
    half : int
        Half-size of a hole's cut-out, px (``2 half + 1`` px square).
    progress : bool
        Draw a progress bar (where :func:`sunlab.options.show_progress` allows).
    **options
        Passed to ``tight_window`` (``saturation`` defaults to the cube's full scale, DN).

    Returns
    -------
    xarray.Dataset
        Contract ``centroids/1`` on (pose, shot, hole), px, with the cube's hole coordinates
        and the stamp moments ``radius``, ``ellipticity``, ``asymmetry``.

    Examples
    --------
    :mod:`sunlab.multihole.holes` centroids two holes of a free layout.
    """
    from .. import centroid

    for c in ("hole_x_cf", "hole_y_cf"):
        if c not in cube.coords:
            raise SchemaError(c, "missing", "design positions of the holes on 'hole', px",
                              "simulate a multi-hole mask or assign the coordinates")
    dx, dy = (np.asarray(cube[c].values, float) for c in ("hole_x_cf", "hole_y_cf"))
    n_p, n_s, n_h = cube.sizes["pose"], cube.sizes["shot"], dx.size
    sx, sy = geometry.ideal_centroid(cube["alpha"].values, cube["beta"].values,
                                     float(cube.attrs["mask_distance_mm"]),
                                     float(cube.attrs["pixel_pitch_mm"]), 0.0, 0.0)
    res = np.full((n_p, n_s, n_h, 8), np.nan)
    status = np.full((n_p, n_s, n_h), schema.STATUS["no_spot"], dtype=np.int8)
    options.setdefault("saturation", 2 ** int(cube.attrs.get("bit_depth", 10)) - 1)
    it = [(p, s) for p in range(n_p) for s in range(n_s)]
    if show_progress(progress):
        from tqdm.auto import tqdm

        it = tqdm(it, desc="centroid_free_layout")
    for p, s in it:
        frame = np.asarray(cube["frames"].isel(pose=p, shot=s).values, dtype=float)
        for h in range(n_h):
            st, (x0, y0) = cutout(frame, dx[h] + sx[p], dy[h] + sy[p], half)
            if st.shape != (2 * half + 1, 2 * half + 1):
                status[p, s, h] = schema.STATUS["clipped"]
                continue
            c = centroid.tight_window(st, **options)
            status[p, s, h] = c.status
            if np.isfinite(c.x):
                r, e, a = centroid.stamp_moments(st)
                res[p, s, h] = (c.x + x0, c.y + y0, c.flux, c.window[0] + x0, c.window[1] + x0,
                                r, e, a)
    ok, dims = status == schema.STATUS["ok"], ("pose", "shot", "hole")
    cen = schema.centroids_dataset(
        np.where(ok, res[..., 0], np.nan), np.where(ok, res[..., 1], np.nan), flux=res[..., 2],
        status=status, alpha=cube["alpha"].values, beta=cube["beta"].values,
        method="tight (layout)",
        attrs={k: cube.attrs[k] for k in ("pixel_pitch_mm", "mask_distance_mm", "bit_depth")
               if k in cube.attrs},
        extra={k: (dims, res[..., 5 + i]) for i, k in enumerate(("radius", "ellipticity",
                                                                  "asymmetry"))})
    coords = {c: ("hole", cube[c].values) for c in ("hole_i", "hole_j", "hole_x_cf", "hole_y_cf",
                                                    "hole_defect") if c in cube.coords}
    return cen.assign_coords(coords)


def usable(cen: xr.Dataset, accept: Sequence[str] = ("ok",)) -> xr.DataArray:
    """Boolean mask of centroids that may be used: finite x, y and an accepted status.

    Parameters
    ----------
    cen : xarray.Dataset
        Centroid table (contract ``centroids/1``) with ``x``, ``y``, ``status``.
    accept : sequence of str
        Status names (keys of :data:`sunlab.schema.STATUS`) counted as usable.

    Returns
    -------
    xarray.DataArray of bool
        True where the centroid may be used, on the table's dims.

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1, layout="grid",
    ...                           defects={3: {"missing": 1.0}})
    >>> int(usable(cen).sum())
    99
    """
    codes = [schema.STATUS[a] for a in accept]
    return np.isfinite(cen["x"]) & np.isfinite(cen["y"]) & cen["status"].isin(codes)


def cutout(frame, x, y, half: int):
    """The ``2 half + 1`` px square of a frame about the pixel nearest (x, y), cut at the edges.

    Parameters
    ----------
    frame : numpy.ndarray, shape (ny, nx)
    x, y : float
        Centre, px (column, row).
    half : int
        Half-size, px.

    Returns
    -------
    stamp : numpy.ndarray of float
        The cut-out (smaller than ``2 half + 1`` where it meets the frame's edge).
    (x0, y0) : (int, int)
        Frame pixel of the stamp's first pixel.

    Examples
    --------
    >>> st, (x0, y0) = cutout(np.arange(100.0).reshape(10, 10), 2.4, 7.6, 2)
    >>> st.shape, (x0, y0)
    ((4, 5), (0, 6))
    """
    ny, nx = frame.shape
    xi, yi = int(round(x)), int(round(y))
    x0, x1 = max(xi - half, 0), min(xi + half + 1, nx)
    y0, y1 = max(yi - half, 0), min(yi + half + 1, ny)
    return np.asarray(frame[y0:y1, x0:x1], dtype=float), (x0, y0)
