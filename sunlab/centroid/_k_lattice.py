"""Kernels of the multi-hole lattice: lattice fit, per-hole assignment, ``locate_spots`` with the
tight window in one compiled call.

Private numba kernels of :mod:`sunlab.centroid` (see :mod:`sunlab.centroid._k_flags` for the
compilation flags every kernel shares).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .. import jit
from ._k_aperture import (
    BACKGROUND,
    FLUX,
    M03,
    M12,
    M21,
    M30,
    MEASURE_FIELDS,
    MXX,
    MXY,
    MYY,
    NSAT,
    PEAK,
    R_AP,
    X,
    Y,
    measure_spots,
)
from ._k_detect import coarse_blobs, sample_stats

__all__: list[str] = []


# --------------------------------------------------------------------------------------------
# Lattice of the multi-hole mask
# --------------------------------------------------------------------------------------------
@jit.kernel(cache=True, nogil=True)
def neighbour_vectors(q, pitch, k):
    """Vectors from each point of ``q`` (m, 2) to those of its ``k`` nearest points (itself
    included) that lie between 0.7 and 1.3 ``pitch`` away. Returns an (n_vectors, 2) array.

    Only points less than 1.3 pitch away can be kept, and all points nearer than a kept one
    are nearer than 1.3 pitch too, so the search runs over the 3 x 3 cells of 1.3 pitch
    around each point, ranking candidates by (distance, index) as a scan of all pairs in
    index order would: the same vectors in the same order, in O(m) instead of O(m^2).
    """
    m = q.shape[0]
    kk = min(k, m)
    out = np.empty((m * kk, 2))
    nv = 0
    if m == 0:
        return out
    lo = 0.7 * pitch
    hi = 1.3 * pitch
    x0 = q[0, 0]
    y0 = q[0, 1]
    x1 = x0
    y1 = y0
    for i in range(m):
        x0 = min(x0, q[i, 0])
        x1 = max(x1, q[i, 0])
        y0 = min(y0, q[i, 1])
        y1 = max(y1, q[i, 1])
    ncx = min(int((x1 - x0) / hi), m) + 1
    ncy = min(int((y1 - y0) / hi), m) + 1
    cell = np.empty(m, np.int64)
    start = np.zeros(ncx * ncy + 1, np.int64)
    for i in range(m):
        c = min(int((q[i, 1] - y0) / hi), ncy - 1) * ncx + min(int((q[i, 0] - x0) / hi), ncx - 1)
        cell[i] = c
        start[c + 1] += 1
    for c in range(ncx * ncy):
        start[c + 1] += start[c]
    fill = start[:-1].copy()
    order = np.empty(m, np.int64)
    for i in range(m):  # counting sort: each cell's points in index order
        order[fill[cell[i]]] = i
        fill[cell[i]] += 1
    bd = np.empty(kk)  # squared distances (ordering only)
    bi = np.empty(kk, np.int64)
    for i in range(m):
        cy, cx = divmod(cell[i], ncx)
        nb = 0
        for yy in range(max(cy - 1, 0), min(cy + 2, ncy)):
            for xx in range(max(cx - 1, 0), min(cx + 2, ncx)):
                c = yy * ncx + xx
                for t in range(start[c], start[c + 1]):
                    j = order[t]
                    dx = q[j, 0] - q[i, 0]
                    dy = q[j, 1] - q[i, 1]
                    d = dx * dx + dy * dy
                    # the k smallest in (distance, index) order, which is what a scan in
                    # index order keeps
                    if nb < kk:
                        pos = nb
                        nb += 1
                    elif d < bd[kk - 1] or (d == bd[kk - 1] and j < bi[kk - 1]):
                        pos = kk - 1
                    else:
                        continue
                    while pos > 0 and (bd[pos - 1] > d or (bd[pos - 1] == d and bi[pos - 1] > j)):
                        bd[pos] = bd[pos - 1]
                        bi[pos] = bi[pos - 1]
                        pos -= 1
                    bd[pos] = d
                    bi[pos] = j
        for t in range(nb):
            if lo < math.hypot(q[bi[t], 0] - q[i, 0], q[bi[t], 1] - q[i, 1]) < hi:
                out[nv, 0] = q[bi[t], 0] - q[i, 0]
                out[nv, 1] = q[bi[t], 1] - q[i, 1]
                nv += 1
    return out[:nv]


@njit(cache=True, nogil=True)
def _lattice_coords(p, origin, basis):
    """Lattice coordinates (u, v) of points p: solve basis @ (u, v) = p - origin."""
    a, b, c, d = basis[0, 0], basis[0, 1], basis[1, 0], basis[1, 1]
    det = a * d - b * c
    n = p.shape[0]
    uv = np.empty((n, 2))
    for k in range(n):
        x = p[k, 0] - origin[0]
        y = p[k, 1] - origin[1]
        uv[k, 0] = (d * x - b * y) / det
        uv[k, 1] = (a * y - c * x) / det
    return uv


@njit(cache=True, nogil=True)
def _affine_fit(uv, q, keep):
    """Least-squares affine map from the rounded lattice coordinates ``rint(uv)`` (j, i) to
    the points ``q`` (x, y) over the rows marked ``keep``: q = origin + basis @ (j, i).
    Normal equations about the means of (j, i), whose 2 x 2 matrix is that of integer grid
    indices (well conditioned for any two independent directions); returns (origin (2,),
    basis (2, 2), whether the kept nodes span the plane)."""
    n = 0
    mj = 0.0
    mi = 0.0
    mx = 0.0
    my = 0.0
    for k in range(q.shape[0]):
        if keep[k]:
            n += 1
            mj += np.rint(uv[k, 0])
            mi += np.rint(uv[k, 1])
            mx += q[k, 0]
            my += q[k, 1]
    mj /= n
    mi /= n
    mx /= n
    my /= n
    sjj = sji = sii = sjx = six = sjy = siy = 0.0
    for k in range(q.shape[0]):
        if keep[k]:
            dj = np.rint(uv[k, 0]) - mj
            di = np.rint(uv[k, 1]) - mi
            dx = q[k, 0] - mx
            dy = q[k, 1] - my
            sjj += dj * dj
            sji += dj * di
            sii += di * di
            sjx += dj * dx
            six += di * dx
            sjy += dj * dy
            siy += di * dy
    det = sjj * sii - sji * sji
    basis = np.full((2, 2), np.nan)
    origin = np.full(2, np.nan)
    if not det > 1e-9 * sjj * sii:  # all kept nodes on one line of the grid
        return origin, basis, False
    basis[0, 0] = (sii * sjx - sji * six) / det
    basis[0, 1] = (sjj * six - sji * sjx) / det
    basis[1, 0] = (sii * sjy - sji * siy) / det
    basis[1, 1] = (sjj * siy - sji * sjy) / det
    origin[0] = mx - basis[0, 0] * mj - basis[0, 1] * mi
    origin[1] = my - basis[1, 0] * mj - basis[1, 1] * mi
    return origin, basis, True


@jit.kernel(cache=True, nogil=True)
def fit_lattice(p, good, pitch, max_residual):
    """Affine lattice through the spots ``p`` (n, 2) marked ``good`` (see
    :func:`sunlab.centroid.locate_spots`, step 3). Returns (ij (n, 2) int, origin (2,),
    basis (2, 2): columns the steps along j and i, residual (n,) px); ``ok`` False when no
    spot is good."""
    n = p.shape[0]
    m = 0
    for k in range(n):
        if good[k]:
            m += 1
    q = np.empty((m, 2))
    t = 0
    for k in range(n):
        if good[k]:
            q[t, 0] = p[k, 0]
            q[t, 1] = p[k, 1]
            t += 1
    if m == 0:
        return np.zeros((n, 2), np.int64), np.full(2, np.nan), np.full((2, 2), np.nan), \
            np.full(n, np.nan), False
    ex0, ex1, ey0, ey1, step = 1.0, 0.0, 0.0, 1.0, pitch
    if m >= 2:
        v = neighbour_vectors(q, pitch, 5)
        nv = v.shape[0]
        if nv > 0:
            sc = 0.0
            ss = 0.0
            for k in range(nv):  # cos and sin of 4 theta: (x + i y)^4 / |x + i y|^4
                x2 = v[k, 0] * v[k, 0]
                y2 = v[k, 1] * v[k, 1]
                r4 = (x2 + y2) * (x2 + y2)
                sc += ((x2 - y2) * (x2 - y2) - 4.0 * x2 * y2) / r4
                ss += 4.0 * v[k, 0] * v[k, 1] * (x2 - y2) / r4
            phi = math.atan2(ss / nv, sc / nv) / 4.0
            ex0, ex1 = math.cos(phi), math.sin(phi)
            ey0, ey1 = -math.sin(phi), math.cos(phi)
            proj = np.empty(nv)
            for k in range(nv):
                proj[k] = max(abs(v[k, 0] * ex0 + v[k, 1] * ex1),
                              abs(v[k, 0] * ey0 + v[k, 1] * ey1))
            step = np.median(proj)
    mx = np.median(q[:, 0])
    my = np.median(q[:, 1])
    best = 0
    bd = np.inf
    for k in range(m):
        d = math.hypot(q[k, 0] - mx, q[k, 1] - my)
        if d < bd:
            bd = d
            best = k
    origin = q[best].copy()
    basis = np.empty((2, 2))
    basis[0, 0] = ex0 * step
    basis[1, 0] = ex1 * step
    basis[0, 1] = ey0 * step
    basis[1, 1] = ey1 * step
    for _ in range(2):
        uv = _lattice_coords(q, origin, basis)
        keep = np.zeros(m, np.bool_)
        nk = 0
        j_lo = i_lo = 1 << 60
        j_hi = i_hi = -(1 << 60)
        for k in range(m):
            fj = np.rint(uv[k, 0])
            fi = np.rint(uv[k, 1])
            du = uv[k, 0] - fj
            dv = uv[k, 1] - fi
            rx = basis[0, 0] * du + basis[0, 1] * dv
            ry = basis[1, 0] * du + basis[1, 1] * dv
            if math.hypot(rx, ry) < max_residual * step:
                keep[k] = True
                nk += 1
                j_lo = min(j_lo, int(fj))
                j_hi = max(j_hi, int(fj))
                i_lo = min(i_lo, int(fi))
                i_hi = max(i_hi, int(fi))
        if nk >= 3 and j_hi > j_lo and i_hi > i_lo:
            o, b, ok = _affine_fit(uv, q, keep)
            if not ok:
                break
            origin, basis = o, b
        else:
            break
    uv = _lattice_coords(p, origin, basis)
    ij = np.empty((n, 2), np.int64)
    resid = np.empty(n)
    for k in range(n):
        fj = np.rint(uv[k, 0])
        fi = np.rint(uv[k, 1])
        ij[k, 0] = int(fj)
        ij[k, 1] = int(fi)
        du = uv[k, 0] - fj
        dv = uv[k, 1] - fi
        resid[k] = math.hypot(basis[0, 0] * du + basis[0, 1] * dv,
                              basis[1, 0] * du + basis[1, 1] * dv)
    return ij, origin, basis, resid, True


@jit.kernel(cache=True, nogil=True)
def spot_table(m, nx, ny, ok, saturated, clipped):
    """Windows and status of measured spots (rows of :func:`measure_spots`, flux > 0).

    Returns (window (4, n) int32: x0, x1, y0, y1 of the circular aperture's bounding box,
    status (n,) int8: ``clipped`` when the aperture crosses the frame edge, else ``saturated``
    when a pixel reached full scale, else ``ok``)."""
    n = m.shape[0]
    win = np.empty((4, n), np.int32)
    st = np.empty(n, np.int8)
    for k in range(n):
        x = m[k, X]
        y = m[k, Y]
        r = m[k, R_AP]
        win[0, k] = max(math.ceil(x - r), 0)
        win[1, k] = min(math.floor(x + r) + 1, nx)
        win[2, k] = max(math.ceil(y - r), 0)
        win[3, k] = min(math.floor(y + r) + 1, ny)
        if x - r < 0 or y - r < 0 or x + r >= nx - 1 or y + r >= ny - 1:
            st[k] = clipped
        elif m[k, NSAT] > 0:
            st[k] = saturated
        else:
            st[k] = ok
    return win, st


#: Columns of the array returned by :func:`quality_metrics` (the order of SPOT_METRICS).
METRIC_FIELDS = ("peak", "background", "mxx", "myy", "mxy", "radius", "ellipticity",
                 "asymmetry", "lattice_residual")


@jit.kernel(cache=True, nogil=True, error_model="numpy")
def quality_metrics(m, resid):
    """Quality metrics of measured spots (rows of :func:`measure_spots`) and their lattice
    residuals: an (n, 9) array, columns METRIC_FIELDS (NaN where undefined)."""
    n = m.shape[0]
    out = np.empty((n, 9))
    for k in range(n):
        mxx = m[k, MXX]
        myy = m[k, MYY]
        mxy = m[k, MXY]
        tr = mxx + myy
        disc = math.sqrt(max((mxx - myy) ** 2 / 4 + mxy * mxy, 0.0))
        out[k, 0] = m[k, PEAK]
        out[k, 1] = m[k, BACKGROUND]
        out[k, 2] = mxx
        out[k, 3] = myy
        out[k, 4] = mxy
        out[k, 5] = math.sqrt(max(2 * tr, 0.0))
        out[k, 6] = 2 * disc / tr
        out[k, 7] = math.hypot(m[k, M30] + m[k, M12], m[k, M21] + m[k, M03]) / tr**1.5
        out[k, 8] = resid[k]
    return out


@jit.kernel(cache=True, nogil=True)
def nearest_spot_per_hole(hole, resid, n_holes):
    """Nearest spot of each hole: ``hole`` (n,) the hole of each spot (-1: none), ``resid``
    its distance from the node. Returns (spot of each hole or -1, duplicate flag per hole:
    more than one spot claims it)."""
    win = np.full(n_holes, -1, np.int64)
    dup = np.zeros(n_holes, np.bool_)
    order = np.argsort(resid)
    for t in range(order.size):
        k = order[t]
        h = hole[k]
        if h < 0:
            continue
        if win[h] < 0:
            win[h] = k
        else:
            dup[h] = True
    return win, dup


# --------------------------------------------------------------------------------------------
# locate_spots (method "tight") in two compiled calls
# --------------------------------------------------------------------------------------------
@jit.kernel(cache=True, nogil=True)
def tight_spots(frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat,
                pitch, max_residual, ok, saturated, clipped):
    """Steps 1-3 of :func:`sunlab.centroid.locate_spots` with the tight window: detection,
    measurement (:func:`measure_spots`, spots with flux > 0), windows and status
    (:func:`spot_table`), the spots good for the lattice and the lattice fit
    (:func:`fit_lattice`). Returns (n_groups detected, sample maximum, m (n, 16; columns
    MEASURE_FIELDS), window (4, n), status (n,), good (n,), ij (n, 2), origin (2,), basis
    (2, 2), residual (n,), on_node (n,))."""
    ny, nx = frame.shape
    med, sig, smax = sample_stats(frame, max(2 * stride, 1))
    thr = med + max(nsigma * sig, min_contrast)
    cnt, _flux, cx, cy, _bb, _pk = coarse_blobs(frame, stride, thr, med)
    nd = 0
    for k in range(cnt.size):
        if cnt[k] >= min_samples:
            nd += 1
    xs = np.empty(nd)
    ys = np.empty(nd)
    r0s = np.empty(nd)
    t = 0
    for k in range(cnt.size):
        if cnt[k] >= min_samples:
            xs[t] = cx[k]
            ys[t] = cy[k]
            r0s[t] = math.sqrt(cnt[k] * float(stride) ** 2 / np.pi) + stride / 3.0 + margin
            t += 1
    half = max(10.0 * sig, 20.0)
    mall = measure_spots(frame, xs, ys, r0s, margin, annulus, med - half, med + half, n_iter,
                         sat)
    n = 0
    for k in range(nd):
        if mall[k, FLUX] > 0:
            n += 1
    m = np.empty((n, len(MEASURE_FIELDS)))
    t = 0
    for k in range(nd):
        if mall[k, FLUX] > 0:
            m[t] = mall[k]
            t += 1
    win, st = spot_table(m, nx, ny, ok, saturated, clipped)
    p = np.empty((n, 2))
    good = np.zeros(n, np.bool_)
    ij = np.zeros((n, 2), np.int64)
    origin = np.full(2, np.nan)
    basis = np.full((2, 2), np.nan)
    resid = np.full(n, np.nan)
    on_node = np.zeros(n, np.bool_)
    if n == 0:
        return nd, smax, m, win, st, good, ij, origin, basis, resid, on_node
    for k in range(n):
        p[k, 0] = m[k, X]
        p[k, 1] = m[k, Y]
    med_flux = np.median(m[:, FLUX])
    ng = 0
    for k in range(n):
        good[k] = st[k] == ok and m[k, FLUX] > 0.3 * med_flux
        ng += good[k]
    if ng == 0:
        good[:] = True
    ij, origin, basis, resid, fitted = fit_lattice(p, good, pitch, max_residual)
    lim = max_residual * math.sqrt(abs(np.linalg.det(basis)))
    for k in range(n):
        on_node[k] = resid[k] < lim
    return nd, smax, m, win, st, good, ij, origin, basis, resid, on_node


@jit.kernel(cache=True, nogil=True)
def fill_holes(m, win, st, ij, dj, di, on_node, resid, lut, n_holes, x, y, flux, window, status,
               metrics, ambiguous):
    """Step 4 of :func:`sunlab.centroid.locate_spots` once the grid offset (dj, di) is known:
    hole of each spot (``lut[i, j]``, -1 none), the nearer spot of each hole
    (:func:`nearest_spot_per_hole`) written into the per-hole outputs (x, y, flux, window
    (4, n_holes), status, metrics (9, n_holes), columns METRIC_FIELDS). Returns whether each
    spot was assigned."""
    rows, cols = lut.shape
    n = m.shape[0]
    hole = np.full(n, -1, np.int64)
    for k in range(n):
        jj = ij[k, 0] + dj
        ii = ij[k, 1] + di
        if on_node[k] and 0 <= jj < cols and 0 <= ii < rows:
            hole[k] = lut[ii, jj]
    spot, dup = nearest_spot_per_hole(hole, resid, n_holes)
    assigned = np.zeros(n, np.bool_)
    one = np.empty((1, len(MEASURE_FIELDS)))
    rs = np.empty(1)
    for h in range(n_holes):
        k = spot[h]
        if k < 0:
            continue
        assigned[k] = True
        x[h] = m[k, X]
        y[h] = m[k, Y]
        flux[h] = m[k, FLUX]
        for q in range(4):
            window[q, h] = win[q, k]
        status[h] = st[k]
        one[0] = m[k]
        rs[0] = resid[k]
        met = quality_metrics(one, rs)
        for q in range(9):
            metrics[q, h] = met[0, q]
    for h in range(n_holes):
        if dup[h]:
            status[h] = ambiguous
    return assigned



@jit.kernel(cache=True, nogil=True)
def grid_offset(ij, pts, ref, lut, exp, has_exp):
    """Step 4a of :func:`sunlab.centroid.locate_spots`: the offset (dj, di) that puts the
    lattice indices ``ij`` (n, 2) of the reference spots (``ref``) on the mask's grid (``lut``,
    (rows, cols)). Of the offsets that keep them all inside the grid, the first (dj outer, di
    inner) that minimises, when ``has_exp``, the mean distance of the reference spots at
    ``pts`` (n, 2) from the ``exp``ected positions of their holes ((n_holes, 2), NaN unknown),
    else the distance of their mean index from the grid's centre."""
    rows, cols = lut.shape
    n = ij.shape[0]
    jmin = imin = 1 << 60
    jmax = imax = -(1 << 60)
    nref = 0
    sj = 0
    si = 0
    for k in range(n):
        if ref[k]:
            jmin = min(jmin, ij[k, 0])
            jmax = max(jmax, ij[k, 0])
            imin = min(imin, ij[k, 1])
            imax = max(imax, ij[k, 1])
            sj += ij[k, 0]
            si += ij[k, 1]
            nref += 1
    if jmax - jmin < cols:
        dj0, dj1 = -jmin, cols - jmax
    else:
        dj0, dj1 = -jmin, -jmin + 1
    if imax - imin < rows:
        di0, di1 = -imin, rows - imax
    else:
        di0, di1 = -imin, -imin + 1
    if (dj1 - dj0) * (di1 - di0) == 1:
        return dj0, di0
    mj = sj / nref
    mi = si / nref
    cj = (cols - 1) / 2
    ci = (rows - 1) / 2
    best = np.inf
    bj = dj0
    bi = di0
    for dj in range(dj0, dj1):
        for di in range(di0, di1):
            if has_exp:
                tot = 0.0
                cnt = 0
                for k in range(n):
                    if not ref[k]:
                        continue
                    h = lut[min(max(ij[k, 1] + di, 0), rows - 1),
                            min(max(ij[k, 0] + dj, 0), cols - 1)]
                    if h >= 0 and math.isfinite(exp[h, 0]) and math.isfinite(exp[h, 1]):
                        tot += math.hypot(pts[k, 0] - exp[h, 0], pts[k, 1] - exp[h, 1])
                        cnt += 1
                cost = tot / cnt if cnt > 0 else np.inf
            else:
                cost = abs(mj + dj - cj) + abs(mi + di - ci)
            if cost < best:
                best = cost
                bj = dj
                bi = di
    return bj, bi


@jit.kernel(cache=True, nogil=True)
def new_holes(n_holes, no_spot):
    """Per-hole outputs of :func:`sunlab.centroid.locate_spots` before any spot is assigned:
    values (3 + 9, n_holes) (rows x, y, flux, then the metrics, columns METRIC_FIELDS) all
    NaN, windows (4, n_holes) all -1, status (n_holes,) all ``no_spot``."""
    return (np.full((3 + len(METRIC_FIELDS), n_holes), np.nan),
            np.full((4, n_holes), -1, np.int32), np.full(n_holes, no_spot, np.int8))


@jit.kernel(cache=True, nogil=True)
def assign_grid(m, win, st, good, ij, origin, basis, resid, on_node, pts, lut, exp, has_exp,
                vals, window, status, ambiguous):
    """Step 4 of :func:`sunlab.centroid.locate_spots` for measured spots (rows of
    :func:`measure_spots` with their windows, status, lattice indices, residuals and
    positions ``pts``): reference spots (on a node and good, or on a node if none is good),
    grid offset (:func:`grid_offset`) and the per-hole outputs (:func:`fill_holes`) written
    into ``vals``, ``window`` and ``status`` (see :func:`new_holes`). Returns (positions of
    the spots assigned to no hole (k, 2), lattice (3, 2): origin of hole (0, 0) and the steps
    along j and i; NaN when no spot is a reference)."""
    n = m.shape[0]
    ref = np.empty(n, np.bool_)
    nr = 0
    for k in range(n):
        ref[k] = on_node[k] and good[k]
        nr += ref[k]
    if nr == 0:
        for k in range(n):
            ref[k] = on_node[k]
            nr += ref[k]
    lattice = np.full((3, 2), np.nan)
    if nr == 0:
        return pts.copy(), lattice
    dj, di = grid_offset(ij, pts, ref, lut, exp, has_exp)
    for q in range(2):
        lattice[0, q] = origin[q] - dj * basis[q, 0] - di * basis[q, 1]
        lattice[1, q] = basis[q, 0]
        lattice[2, q] = basis[q, 1]
    assigned = fill_holes(m, win, st, ij, dj, di, on_node, resid, lut, vals.shape[1], vals[0],
                          vals[1], vals[2], window, status, vals[3:], ambiguous)
    nu = 0
    for k in range(n):
        nu += not assigned[k]
    unassigned = np.empty((nu, 2))
    t = 0
    for k in range(n):
        if not assigned[k]:
            unassigned[t, 0] = pts[k, 0]
            unassigned[t, 1] = pts[k, 1]
            t += 1
    return unassigned, lattice


@jit.kernel(cache=True, nogil=True)
def locate_tight(frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat,
                 pitch, max_residual, ok, saturated, clipped, lut, exp, has_exp, n_holes,
                 no_spot, ambiguous):
    """:func:`sunlab.centroid.locate_spots` with the tight window in one compiled call:
    :func:`tight_spots` then :func:`assign_grid`. Returns (values, windows, status (see
    :func:`new_holes`), n_groups detected, sample maximum, unassigned spots (k, 2),
    lattice (3, 2))."""
    vals, window, status = new_holes(n_holes, no_spot)
    nd, smax, m, win, st, good, ij, origin, basis, resid, on_node = tight_spots(
        frame, stride, nsigma, min_contrast, min_samples, margin, annulus, n_iter, sat, pitch,
        max_residual, ok, saturated, clipped)
    n = m.shape[0]
    pts = np.empty((n, 2))
    for k in range(n):
        pts[k, 0] = m[k, X]
        pts[k, 1] = m[k, Y]
    if n == 0:
        return vals, window, status, nd, smax, pts, np.full((3, 2), np.nan)
    unassigned, lattice = assign_grid(m, win, st, good, ij, origin, basis, resid, on_node, pts,
                                      lut, exp, has_exp, vals, window, status, ambiguous)
    return vals, window, status, nd, smax, unassigned, lattice
