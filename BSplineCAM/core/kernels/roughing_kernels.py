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
def _column_envelope(f, out, top):
    """out[q, c] = min(top, min over p of (q - p)^2 + f[p, c]) for every column c of ``f``
    (ny, nx): the lower envelope of parabolas down each column (Felzenszwalb &
    Huttenlocher), in time linear in the column's length."""
    ny, nx = f.shape
    v = np.zeros(ny, np.int64)
    z = np.empty(ny + 1)
    fq2 = np.empty(ny)
    for c in range(nx):
        for q in range(ny):
            fq2[q] = f[q, c] + float(q * q)
        k = 0
        v[0] = 0
        z[0] = -math.inf
        z[1] = math.inf
        for q in range(1, ny):
            fq = fq2[q]
            while True:
                vk = v[k]
                s = (fq - fq2[vk]) / (2.0 * (q - vk))
                if s <= z[k] and k > 0:
                    k -= 1
                else:
                    break
            k += 1
            v[k] = q
            z[k] = s
            z[k + 1] = math.inf
        k = 0
        for q in range(ny):
            while z[k + 1] < q:
                k += 1
            vk = v[k]
            d = float((q - vk) * (q - vk)) + f[vk, c]
            out[q, c] = min(d, top)


def _squared_distance_loops(mask):
    """Squared Euclidean distance (cells^2) from each cell to the nearest set cell of the
    boolean grid ``mask`` (ny, nx; not empty), at most (ny + nx + 2)^2: the row pass and the
    lower envelope of parabolas down each column of
    :func:`~BSplineCAM.core.geometry.distance.squared_distance` (Felzenszwalb &
    Huttenlocher), column by column."""
    ny, nx = mask.shape
    big = float((ny + nx + 2) ** 2)
    f = np.empty((ny, nx))
    for i in range(ny):
        last = -math.inf
        for j in range(nx):
            if mask[i, j]:
                last = float(j)
            f[i, j] = j - last
        nxt = math.inf
        for j in range(nx - 1, -1, -1):
            if mask[i, j]:
                nxt = float(j)
            g = min(f[i, j], nxt - j)
            f[i, j] = g * g if g != math.inf else big
    out = np.empty((ny, nx))
    _column_envelope(f, out, big)
    return out


def _capped_distance_loops(mask, k, big):
    """sqrt of min(big^2, min over |dy| <= k of dy^2 + g(y + dy)^2), g the distance along
    the row to the nearest set cell capped at ``big`` = k + 1 (the integer passes of
    :func:`~BSplineCAM.core.toolpath.roughing.gridops.capped_distance` over a whole grid).

    The column pass is the lower envelope of parabolas of :func:`_squared_distance_loops`
    over all dy, in time linear in the column's length whatever k: a term with |dy| > k is
    at least (k + 1)^2 = big^2, so the minimum capped at big^2 is the same.  Its values are
    integers held exactly in floats, and the envelope's breakpoints (ratios of integers
    with denominators below 2 ny) never round across the integer rows they are compared
    with, so the result is the numpy engine's to the bit."""
    ny, nx = mask.shape
    far = 10 * (nx + big)
    f = np.empty((ny, nx))
    for i in range(ny):
        left = -far
        for j in range(nx):
            if mask[i, j]:
                left = j
            f[i, j] = j - left
        right = far
        for j in range(nx - 1, -1, -1):
            if mask[i, j]:
                right = j
            g = min(min(f[i, j], right - j), big)
            f[i, j] = g * g
    out = np.empty((ny, nx))
    _column_envelope(f, out, float(big * big))
    for i in range(ny):
        for j in range(nx):
            out[i, j] = math.sqrt(out[i, j])
    return out


def _polyline_distance_loops(pts, path):
    """Distance (mm) from each point (k, 2) to the polyline ``path`` (n >= 2, 2): the
    smallest over its segments of the distance to the clipped foot of the point.  A segment
    whose box lies farther along x or y than the smallest distance so far (by more than
    PRUNE_MM, far above the rounding of a distance) cannot be nearer: it is skipped, and the
    smallest distance is the same."""
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
    for p in range(m):
        best = math.inf
        qx = pts[p, 0]
        qy = pts[p, 1]
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
    the extent across the feed of the swept ``uncut`` cells plus a cell (0 if none)."""
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
        for i in range(i0, i1):
            ry = (y0 + (i + 0.5) * cell) - ay
            for j in range(j0, j1):
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
