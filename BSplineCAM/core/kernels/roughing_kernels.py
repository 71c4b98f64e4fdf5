# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the Z-level roughing's grid loops
(:mod:`~BSplineCAM.core.toolpath.roughing`): distance transforms of the level's masks, the
distances of cells to a segment or a polyline, and the widths of cut of feeds against the
uncut cells.  Loop-style functions over plain contiguous arrays, one call where the numpy
engine makes dozens of whole-array operations and temporaries.

The arithmetic is the numpy engine's, operation by operation: the distance transforms work on
integers (squares of cell distances) or on floats holding integers, so their values are exact
in both engines; the distances to segments take the same products, sums, clips and
``hypot`` (the C library's in both engines) in the same order; the widths of cut compare the
same ``along`` and ``across`` values.  Where numpy computes a value whose last bit may depend
on its library (a dot product by BLAS), the caller computes it with numpy and passes it in.
So both engines take the same decisions and return the same bits.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper

#: Slack (mm) of the pruning of :func:`_polyline_distance_loops`: a segment's box farther than
#: the nearest distance so far by more than this cannot hold a nearer point.
PRUNE_MM = 1e-6


@helper
def _row_envelope(g, out, pos, val, v, z, far, reach, root):
    """One row of the separable squared distance transform (Felzenszwalb & Huttenlocher):
    ``g`` (nx) the distance of each cell down its column to the nearest set cell (an
    integer, ``far`` or more for none within reach), ``out`` (nx) holding each cell's own
    value (g, or g^2 with ``root`` False) and lowered where a parabola (q - p)^2 + g[p]^2 of
    the lower envelope of the row's cells gives less, to its square root with ``root``.
    Only cells nearer than ``far`` with a neighbour farther than themselves make the
    envelope (a cell no farther than both of its neighbours has its parabola on or above
    theirs but at itself, where its own value stands), and each parabola is evaluated over
    its stretch of the envelope within ``reach`` columns of its cell.  The values are
    integers held exactly in floats, and the breakpoints (ratios of integers with
    denominators below 2 nx, correctly rounded) never round across the integer columns they
    are compared with, so each value is the exact least square (the work arrays pos, val,
    v of nx and z of nx + 1 are scratch)."""
    nx = g.shape[0]
    m = 0
    for p in range(nx):
        gp = g[p]
        if gp >= far:
            continue
        if (p == 0 or g[p - 1] <= gp) and (p == nx - 1 or g[p + 1] <= gp):
            continue
        pos[m] = p
        val[m] = gp * gp + float(p * p)
        m += 1
    if m == 0:
        return
    e = 0
    v[0] = 0
    z[0] = -math.inf
    z[1] = math.inf
    for r in range(1, m):
        fr = val[r]
        pr = pos[r]
        while True:
            vk = v[e]
            s = (fr - val[vk]) / (2.0 * (pr - pos[vk]))
            if s <= z[e] and e > 0:
                e -= 1
            else:
                break
        e += 1
        v[e] = r
        z[e] = s
        z[e + 1] = math.inf
    for h in range(e + 1):
        # the parabola of stretch h is the lowest for the columns q in [z[h], z[h + 1]]
        pv = pos[v[h]]
        gv = g[int(pv)]
        lo = max(pv - reach, 0.0)
        if z[h] > lo:
            lo = float(math.ceil(z[h]))
        hi = min(pv + reach, nx - 1.0)
        if z[h + 1] < hi:
            hi = float(math.floor(z[h + 1]))
        for q in range(int(lo), int(hi) + 1):
            gq = g[q]
            d = (q - pv) * (q - pv) + gv * gv
            if d < gq * gq:
                out[q] = math.sqrt(d) if root else d


@helper
def _column_distances(mask, out, cap):
    """out[i, j] = the distance (cells) from (i, j) down or up its column to the nearest set
    cell of ``mask``, at most ``cap`` (inf: none), by two sweeps over the rows."""
    ny, nx = mask.shape
    for j in range(nx):
        out[0, j] = 0.0 if mask[0, j] else cap
    for i in range(1, ny):
        for j in range(nx):
            if mask[i, j]:
                out[i, j] = 0.0
            else:
                u = out[i - 1, j] + 1.0
                out[i, j] = u if u < cap else cap
    for i in range(ny - 2, -1, -1):
        for j in range(nx):
            u = out[i + 1, j] + 1.0
            if u < out[i, j]:
                out[i, j] = u


@helper
def _row_passes(out, far, reach, root):
    """Every row of ``out`` (ny, nx: each cell's distance down its column) through
    :func:`_row_envelope`, in place, with one set of scratch arrays; without ``root`` each
    cell's own value is first squared."""
    ny, nx = out.shape
    g = np.empty(nx)
    pos = np.empty(nx)
    val = np.empty(nx)
    v = np.zeros(nx, np.int64)
    z = np.empty(nx + 1)
    for i in range(ny):
        row = out[i]
        for p in range(nx):
            g[p] = row[p]
            if not root:
                row[p] = g[p] * g[p]
        _row_envelope(g, row, pos, val, v, z, far, reach, root)


def _squared_distance_loops(mask):
    """Squared Euclidean distance (cells^2) from each cell to the nearest set cell of the
    boolean grid ``mask`` (ny, nx; not empty), at most (ny + nx + 2)^2: the exact squared
    distance of :func:`~BSplineCAM.core.geometry.distance.squared_distance` (Felzenszwalb &
    Huttenlocher), here down the columns first and then along the rows, which are
    contiguous (:func:`_row_envelope`), in one grid."""
    ny, nx = mask.shape
    big = float((ny + nx + 2) ** 2)
    out = np.empty((ny, nx))
    _column_distances(mask, out, math.inf)
    _row_passes(out, math.inf, float(nx), False)
    for i in range(ny):
        for p in range(nx):
            if out[i, p] > big:
                out[i, p] = big
    return out


def _capped_distance_loops(mask, k, big):
    """sqrt of min(big^2, the squared distance from each cell to the nearest set cell of
    ``mask``), ``big`` = k + 1: what the integer passes of
    :func:`~BSplineCAM.core.toolpath.roughing.gridops.capped_distance` give over a whole
    grid, min(big^2, min over |dy| <= k of dy^2 + g(y + dy)^2) with g the distance along the
    row capped at ``big``: a term with |dy| > k or g = big is at least big^2, so both are
    min(big^2, the exact squared distance).  Here the passes run down the columns first,
    capped at ``big``, then along the rows, which are contiguous (:func:`_row_envelope`
    with the cells nearer than ``big`` within k columns: beyond, a parabola gives at least
    big^2), in one grid; the result is the numpy engine's to the bit."""
    ny, nx = mask.shape
    bigf = float(big)
    out = np.empty((ny, nx))
    _column_distances(mask, out, bigf)
    _row_passes(out, bigf, float(k), True)
    return out


def _polyline_distance_loops(pts, path):
    """Distance (mm) from each point (k, 2) to the polyline ``path`` (n >= 2, 2): the
    smallest over its segments of the distance to the clipped foot of the point.  A segment
    whose box lies farther along x or y than the smallest distance so far (by more than
    PRUNE_MM, far above the rounding of a distance) cannot be nearer: it is skipped, and the
    smallest distance is the same.  The segment nearest to the point before is taken first,
    so that its distance bounds the others from the start (the least of the same values)."""
    m = pts.shape[0]
    n = path.shape[0] - 1
    out = np.empty(m)
    abx = np.empty(n)
    aby = np.empty(n)
    L2 = np.empty(n)
    xlo = np.empty(n)
    xhi = np.empty(n)
    ylo = np.empty(n)
    yhi = np.empty(n)
    for s in range(n):
        abx[s] = path[s + 1, 0] - path[s, 0]
        aby[s] = path[s + 1, 1] - path[s, 1]
        L2[s] = max(abx[s] * abx[s] + aby[s] * aby[s], 1e-300)
        xlo[s] = min(path[s, 0], path[s + 1, 0])
        xhi[s] = max(path[s, 0], path[s + 1, 0])
        ylo[s] = min(path[s, 1], path[s + 1, 1])
        yhi[s] = max(path[s, 1], path[s + 1, 1])
    last = 0
    for p in range(m):
        qx = pts[p, 0]
        qy = pts[p, 1]
        # the segment nearest to the point before (points come in rows of cells) first:
        # the bound it gives skips most of the others
        rx = qx - path[last, 0]
        ry = qy - path[last, 1]
        t = (rx * abx[last] + ry * aby[last]) / L2[last]
        t = min(max(t, 0.0), 1.0)
        best = math.hypot(rx - t * abx[last], ry - t * aby[last])
        for s in range(n):
            gap = max(max(xlo[s] - qx, qx - xhi[s]), max(ylo[s] - qy, qy - yhi[s]))
            if gap > best + PRUNE_MM:
                continue
            rx = qx - path[s, 0]
            ry = qy - path[s, 1]
            t = (rx * abx[s] + ry * aby[s]) / L2[s]
            t = min(max(t, 0.0), 1.0)
            d = math.hypot(rx - t * abx[s], ry - t * aby[s])
            if d < best:
                best = d
                last = s
        out[p] = best
    return out


def _segment_distance_loops(xs, ys, x0, y0, abx, aby, ab2):
    """Distance (mm) from each cell centre (ys[i], xs[j]) to the segment from (x0, y0) along
    (abx, aby), ``ab2`` its squared length (at least 1e-300)."""
    ny = ys.shape[0]
    nx = xs.shape[0]
    out = np.empty((ny, nx))
    for i in range(ny):
        py = ys[i] - y0
        for j in range(nx):
            px = xs[j] - x0
            t = (px * abx + py * aby) / ab2
            t = min(max(t, 0.0), 1.0)
            out[i, j] = math.hypot(px - t * abx, py - t * aby)
    return out


squared_distance = Kernel(_squared_distance_loops)
capped_distance = Kernel(_capped_distance_loops)
polyline_distance = Kernel(_polyline_distance_loops)
segment_distance = Kernel(_segment_distance_loops)


def _engaged_flat_window_loops(A, length, d, uncut, work, i0, i1, j0, j1, x0, y0, cell, R):
    """Widths of cut (mm) and counts of ``work`` cells swept of the feeds from A[k] along the
    unit directions d[k] for length[k] (mm) of a flat end mill of radius R, over the cells of
    the window rows i0:i1, columns j0:j1 of the grids ``uncut`` and ``work`` that either
    holds, cell centres at x0 + (j + 0.5) cell, y0 + (i + 0.5) cell: a cell is swept when it
    lies ahead of the start within R of the feed's segment or of its end's disk; the width is
    the extent across the feed of the swept ``uncut`` cells plus a cell (0 if none).  Each
    feed visits the cells of its own box grown by R only (of a window round many feeds,
    the cells beyond it cannot be swept)."""
    n = A.shape[0]
    out = np.zeros(n)
    counts = np.zeros(n, np.int64)
    RR = R * R
    for k in range(n):
        ax = A[k, 0]
        ay = A[k, 1]
        d0 = d[k, 0]
        d1 = d[k, 1]
        L = length[k]
        hi = -math.inf
        lo = math.inf
        hit = False
        count = 0
        # a swept cell's centre lies within R of the feed: the feed's box grown by R and a
        # cell (far above the rounding of the tests below) within the window
        bx = ax + d0 * L
        by = ay + d1 * L
        ka = max(i0, int(math.floor((min(ay, by) - R - y0) / cell - 0.5)) - 1)
        kb = min(i1, int(math.ceil((max(ay, by) + R - y0) / cell - 0.5)) + 2)
        la = max(j0, int(math.floor((min(ax, bx) - R - x0) / cell - 0.5)) - 1)
        lb = min(j1, int(math.ceil((max(ax, bx) + R - x0) / cell - 0.5)) + 2)
        for i in range(ka, kb):
            ry = (y0 + (i + 0.5) * cell) - ay
            for j in range(la, lb):
                u = uncut[i, j]
                w = work[i, j]
                if not (u or w):
                    continue
                rx = (x0 + (j + 0.5) * cell) - ax
                along = rx * d0 + ry * d1
                across = ry * d0 - rx * d1
                e = along - L
                swept = ((along > 0) and (abs(across) <= R) and (along <= L)) or (
                    (along > L) and (e * e + across * across <= RR))
                if not swept:
                    continue
                if w:
                    count += 1
                if u:
                    hit = True
                    if across > hi:
                        hi = across
                    if across < lo:
                        lo = across
        counts[k] = count
        if hit:
            out[k] = hi - lo + cell
    return out, counts


engaged_flat_window = Kernel(_engaged_flat_window_loops)
