"""The lattice of a multi-hole mask's spots: its fit and the assignment of spots to holes
(steps 3 and 4 of :func:`sunlab.centroid.locate_spots`; private to :mod:`sunlab.centroid`).

Examples
--------
>>> import numpy as np
>>> jj, ii = np.meshgrid(np.arange(4), np.arange(3))
>>> p = np.column_stack([100 + 70 * jj.ravel(), 50 + 70 * ii.ravel()]).astype(float)
>>> ij, origin, basis, resid = _fit_lattice(p, np.ones(12, bool), 71.0, 0.3)
>>> basis.round(6).tolist(), float(resid.max()) < 1e-9
([[70.0, 0.0], [0.0, 70.0]], True)
"""

from __future__ import annotations

import math

import numpy as np

from ._aperture import BKG, FLUX, M03, M12, M21, M30, MXX, MXY, MYY, NSAT, PEAK, R_AP, X, Y

__all__: list[str] = []

#: Rows of the metrics block of the per-hole values (the order of
#: :data:`sunlab.centroid.lattice.SPOT_METRICS`).
METRIC_FIELDS = ("peak", "background", "mxx", "myy", "mxy", "radius", "ellipticity",
                 "asymmetry", "lattice_residual")


def _neighbour_vectors(q, pitch, k=5):
    """Vectors from each point of ``q`` (m, 2) to those of its ``k`` nearest points (itself
    included; ties by index) that lie between 0.7 and 1.3 ``pitch`` away, (n_vectors, 2)."""
    dx, dy = q[None, :, 0] - q[:, None, 0], q[None, :, 1] - q[:, None, 1]
    near = np.argsort(dx * dx + dy * dy, axis=1, kind="stable")[:, :k]
    v = np.stack([np.take_along_axis(dx, near, 1), np.take_along_axis(dy, near, 1)], -1)
    dist = np.hypot(v[..., 0], v[..., 1])
    return v[(dist > 0.7 * pitch) & (dist < 1.3 * pitch)]


def _nodes(p, origin, basis):
    """Nearest lattice node (j, i) of each point and its distance from it, px."""
    uv = np.linalg.solve(basis, (p - origin).T).T
    ij = np.rint(uv)
    return ij.astype(np.int64), np.hypot(*(basis @ (uv - ij).T))


def _fit_lattice(p, good, pitch, max_residual):
    """Affine lattice through the spots ``p`` (n, 2) marked ``good``: the orientation (mod 90
    deg) and step of the vectors between neighbours, then ``origin + basis @ (j, i)`` fitted by
    least squares to the spots within ``max_residual`` pitch of a node, twice (kept when those
    nodes span the plane). Returns (ij (n, 2), origin (2,), basis (2, 2): columns the steps
    along j and i, residual (n,) px), or None when no spot is good."""
    q = p[good]
    if len(q) == 0:
        return None
    rot, step = np.eye(2), float(pitch)
    v = _neighbour_vectors(q, pitch) if len(q) >= 2 else q[:0]
    if len(v):
        x2, y2 = v[:, 0] ** 2, v[:, 1] ** 2  # cos and sin of 4 theta: (x + i y)^4 / |x + i y|^4
        r4 = (x2 + y2) ** 2
        phi = math.atan2(np.mean(4.0 * v[:, 0] * v[:, 1] * (x2 - y2) / r4),
                         np.mean(((x2 - y2) ** 2 - 4.0 * x2 * y2) / r4)) / 4.0
        rot = np.array([[math.cos(phi), -math.sin(phi)], [math.sin(phi), math.cos(phi)]])
        step = float(np.median(np.abs(v @ rot).max(1)))
    origin = q[np.argmin(np.hypot(*(q - np.median(q, axis=0)).T))]
    basis = rot * step
    for _ in range(2):
        ij, resid = _nodes(q, origin, basis)
        keep = resid < max_residual * step
        if keep.sum() < 3 or np.ptp(ij[keep, 0]) == 0 or np.ptp(ij[keep, 1]) == 0:
            break
        design = np.column_stack([np.ones(keep.sum()), ij[keep]])
        sol, _, rank, _ = np.linalg.lstsq(design, q[keep], rcond=None)
        if rank < 3:  # all kept nodes on one line of the grid
            break
        origin, basis = sol[0], sol[1:].T
    ij, resid = _nodes(p, origin, basis)
    return ij, origin, basis, resid


def _spot_table(m, nx, ny, ok, saturated, clipped):
    """Windows (4, n: x0, x1, y0, y1 of the circular aperture's bounding box) and status
    (``clipped`` when the aperture crosses the frame edge, else ``saturated`` when a pixel
    reached full scale, else ``ok``) of measured spots (rows of the measurement)."""
    x, y, r = m[:, X], m[:, Y], m[:, R_AP]
    win = np.stack([np.maximum(np.ceil(x - r), 0), np.minimum(np.floor(x + r) + 1, nx),
                    np.maximum(np.ceil(y - r), 0), np.minimum(np.floor(y + r) + 1, ny)])
    cut = (x - r < 0) | (y - r < 0) | (x + r >= nx - 1) | (y + r >= ny - 1)
    st = np.where(cut, clipped, np.where(m[:, NSAT] > 0, saturated, ok))
    return win.astype(np.int32), st.astype(np.int8)


def _metrics(m, resid):
    """Quality metrics (9, n), rows :data:`METRIC_FIELDS`, of measured spots."""
    mxx, myy, mxy = m[:, MXX], m[:, MYY], m[:, MXY]
    tr = mxx + myy
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.stack([
            m[:, PEAK], m[:, BKG], mxx, myy, mxy, np.sqrt(np.maximum(2 * tr, 0.0)),
            2 * np.sqrt(np.maximum((mxx - myy) ** 2 / 4 + mxy * mxy, 0.0)) / tr,
            np.hypot(m[:, M30] + m[:, M12], m[:, M21] + m[:, M03]) / tr**1.5, resid])


def _new_holes(n_holes, no_spot):
    """Per-hole outputs before any spot is assigned: values (3 + 9, n_holes) (rows x, y, flux,
    then the metrics) NaN, windows (4, n_holes) -1, status ``no_spot``."""
    return (np.full((3 + len(METRIC_FIELDS), n_holes), np.nan),
            np.full((4, n_holes), -1, np.int32), np.full(n_holes, no_spot, np.int8))


def _grid_offset(ij, pts, lut, exp):
    """The offset (dj, di) that puts the lattice indices ``ij`` (n, 2) of the reference spots
    on the mask's grid (``lut``, (rows, cols)). Forced when they span the grid; else, of the
    offsets that keep them inside it, the first (dj outer, di inner) that minimises the mean
    distance of the spots at ``pts`` from the ``exp``ected positions of their holes
    ((n_holes, 2), NaN unknown) when given, else the distance of their mean index from the
    grid's centre."""
    rows, cols = lut.shape
    lo, hi = ij.min(0), ij.max(0)
    dj = np.arange(-lo[0], cols - hi[0]) if hi[0] - lo[0] < cols else -lo[:1]
    di = np.arange(-lo[1], rows - hi[1]) if hi[1] - lo[1] < rows else -lo[1:]
    a, b = (g.ravel() for g in np.meshgrid(dj, di, indexing="ij"))  # dj outer, di inner
    if exp is None:
        mj, mi = ij.mean(0)
        cost = np.abs(mj + a - (cols - 1) / 2) + np.abs(mi + b - (rows - 1) / 2)
    else:  # (offset, spot)
        h = lut[np.clip(ij[:, 1] + b[:, None], 0, rows - 1),
                np.clip(ij[:, 0] + a[:, None], 0, cols - 1)]
        e = np.where((h >= 0)[..., None], exp[np.maximum(h, 0)], np.nan)
        d = np.hypot(pts[:, 0] - e[..., 0], pts[:, 1] - e[..., 1])
        n = np.isfinite(d).sum(1)
        cost = np.where(n > 0, np.where(np.isfinite(d), d, 0.0).sum(1) / np.maximum(n, 1), np.inf)
    k = int(np.argmin(cost))  # the first of equal costs
    return int(a[k]), int(b[k])


def _assign(m, win, st, good, fit, max_residual, lut, exp, vals, window, status, ambiguous):
    """Step 4 of :func:`sunlab.centroid.locate_spots`: reference spots (within ``max_residual``
    pitch of a node and good, or on a node if none is good), the grid offset, then each hole's
    nearest spot written into
    ``vals``, ``window`` and ``status`` (:func:`_new_holes`; ``ambiguous`` where several spots
    claim a hole). Returns (positions of the spots assigned to no hole (k, 2), lattice (3, 2):
    origin of hole (0, 0) and the steps along j and i; NaN when no spot is a reference)."""
    ij, origin, basis, resid = fit
    pts = m[:, [X, Y]]
    on_node = resid < max_residual * math.sqrt(abs(np.linalg.det(basis)))
    ref = on_node & good
    if not ref.any():
        ref = on_node
    if not ref.any():
        return pts.copy(), np.full((3, 2), np.nan)
    dj, di = _grid_offset(ij[ref], pts[ref], lut, exp)
    lattice = np.stack([origin - dj * basis[:, 0] - di * basis[:, 1], basis[:, 0], basis[:, 1]])
    rows, cols = lut.shape
    jj, ii = ij[:, 0] + dj, ij[:, 1] + di
    inside = on_node & (jj >= 0) & (jj < cols) & (ii >= 0) & (ii < rows)
    hole = np.where(inside, lut[np.clip(ii, 0, rows - 1), np.clip(jj, 0, cols - 1)], -1)
    order = np.argsort(resid, kind="stable")
    order = order[hole[order] >= 0]
    holes, first = np.unique(hole[order], return_index=True)
    spot = order[first]  # the nearest spot of each claimed hole
    vals[:3, holes] = m[spot][:, [X, Y, FLUX]].T
    vals[3:, holes] = _metrics(m[spot], resid[spot])
    window[:, holes], status[holes] = win[:, spot], st[spot]
    status[np.bincount(hole[order], minlength=status.size) > 1] = ambiguous
    assigned = np.zeros(len(m), bool)
    assigned[spot] = True
    return pts[~assigned], lattice
