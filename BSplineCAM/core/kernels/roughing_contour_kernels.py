# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of the Z-level roughing's contours
(:func:`~BSplineCAM.core.toolpath.roughing.contours.marching_squares`): the level set F = 0
of a grid by marching squares, its segments chained into polylines, in one pass over the
grid and one over the segments, where the numpy engine makes a score of whole-grid
temporaries and chains in a Python loop over a dictionary.

The kernel follows the numpy engine step by step, so that the polylines are the same to the
bit and in the same order: the same cells (row-major), the same two crossed edges of a cell
(the first two in the order top, right, bottom, left) and the same two segments of a saddle
(by the cell's mean, summed in the same order), the segments listed in the same order (the
cells with one segment, then the saddles' first segments, then their second ones), the
crossing points by the same expressions (``j + f0 / (f0 - f1)`` on the cell's global
indices), each edge's crossing ending at most two segments, the chains walked from the
lowest unused segment forwards and then backwards, each taking the lowest unused segment at
a crossing, and a chain reversed when most of its segments' orientation tests disagree with
its direction.
"""

from __future__ import annotations

import numpy as np

from . import Kernel, helper


@helper
def _edge_point(F, edge, i, j):
    """(x, y) in fractional cell indices of the crossing on edge 0 (top), 1 (right), 2
    (bottom) or 3 (left) of the cell (i, j)."""
    if edge == 0:
        f0 = F[i, j]
        f1 = F[i, j + 1]
        return j + f0 / (f0 - f1), i + 0.0 * f0
    if edge == 1:
        f0 = F[i, j + 1]
        f1 = F[i + 1, j + 1]
        return (j + 1) + 0.0 * f0, i + f0 / (f0 - f1)
    if edge == 2:
        f0 = F[i + 1, j]
        f1 = F[i + 1, j + 1]
        return j + f0 / (f0 - f1), (i + 1) + 0.0 * f0
    f0 = F[i, j]
    f1 = F[i + 1, j]
    return j + 0.0 * f0, i + f0 / (f0 - f1)


@helper
def _edge_key(edge, i, j, nx, nh):
    """The crossing's key: horizontal edges i (nx - 1) + j, vertical ones nh + i nx + j."""
    if edge == 0:
        return i * (nx - 1) + j
    if edge == 1:
        return nh + i * nx + j + 1
    if edge == 2:
        return (i + 1) * (nx - 1) + j
    return nh + i * nx + j


def _marching_squares_loops(F):
    """(points (m, 2), starts (n + 1,)): the n polylines of F = 0, polyline k being
    points[starts[k]:starts[k + 1]], as the numpy engine returns them."""
    ny, nx = F.shape
    nh = ny * (nx - 1)
    # the cells the contour crosses, row-major; their saddles
    ncell = 0
    for i in range(ny - 1):
        for j in range(nx - 1):
            code = (F[i, j] <= 0.0) + 2 * (F[i, j + 1] <= 0.0) + 4 * (F[i + 1, j + 1] <= 0.0) \
                + 8 * (F[i + 1, j] <= 0.0)
            if code != 0 and code != 15:
                ncell += 1
    ci = np.empty(ncell, np.int64)
    cj = np.empty(ncell, np.int64)
    saddle = np.zeros(ncell, np.bool_)
    e0 = np.empty(ncell, np.int64)
    e1 = np.empty(ncell, np.int64)
    nsad = 0
    c = 0
    for i in range(ny - 1):
        for j in range(nx - 1):
            ia = F[i, j] <= 0.0
            ib = F[i, j + 1] <= 0.0
            ic = F[i + 1, j + 1] <= 0.0
            id_ = F[i + 1, j] <= 0.0
            code = ia + 2 * ib + 4 * ic + 8 * id_
            if code == 0 or code == 15:
                continue
            ci[c] = i
            cj[c] = j
            crossed = (ia != ib, ib != ic, id_ != ic, ia != id_)
            if crossed[0] and crossed[1] and crossed[2] and crossed[3]:
                saddle[c] = True
                nsad += 1
            else:
                first = -1
                second = -1
                for e in range(4):
                    if crossed[e]:
                        if first < 0:
                            first = e
                        elif second < 0:
                            second = e
                e0[c] = first
                e1[c] = second
            c += 1
    # segments: the cells with one, then the saddles' first, then their second segments
    nseg = ncell + nsad
    sc = np.empty(nseg, np.int64)
    s0 = np.empty(nseg, np.int64)
    s1 = np.empty(nseg, np.int64)
    n = 0
    for c in range(ncell):
        if not saddle[c]:
            sc[n] = c
            s0[n] = e0[c]
            s1[n] = e1[c]
            n += 1
    second_at = n + nsad
    m = 0
    for c in range(ncell):
        if saddle[c]:
            i = ci[c]
            j = cj[c]
            mean = (((F[i, j] + F[i, j + 1]) + F[i + 1, j + 1]) + F[i + 1, j]) / 4.0
            as_a = (mean <= 0.0) == (F[i, j] <= 0.0)
            sc[n + m] = c
            sc[second_at + m] = c
            if as_a:  # the centre joins a and c: cut off b (edges 0, 1) and d (2, 3)
                s0[n + m], s1[n + m] = 0, 1
                s0[second_at + m], s1[second_at + m] = 2, 3
            else:  # else a (3, 0) and c (1, 2)
                s0[n + m], s1[n + m] = 3, 0
                s0[second_at + m], s1[second_at + m] = 1, 2
            m += 1
    px = np.empty((nseg, 2))
    py = np.empty((nseg, 2))
    k0 = np.empty(nseg, np.int64)
    k1 = np.empty(nseg, np.int64)
    good = np.empty(nseg, np.bool_)
    ends = np.full((nh + ny * nx, 2), -1, np.int64)
    for s in range(nseg):
        i = ci[sc[s]]
        j = cj[sc[s]]
        x0, y0 = _edge_point(F, s0[s], i, j)
        x1, y1 = _edge_point(F, s1[s], i, j)
        px[s, 0] = x0
        px[s, 1] = x1
        py[s, 0] = y0
        py[s, 1] = y1
        a = _edge_key(s0[s], i, j, nx, nh)
        b = _edge_key(s1[s], i, j, nx, nh)
        k0[s] = a
        k1[s] = b
        for key in (a, b):
            if ends[key, 0] < 0:
                ends[key, 0] = s
            else:
                ends[key, 1] = s
        # orientation: inside (F decreasing) on the right of p0 -> p1
        u = 0.5 * (x0 + x1) - j
        v = 0.5 * (y0 + y1) - i
        fa = F[i, j]
        fb = F[i, j + 1]
        fc = F[i + 1, j + 1]
        fd = F[i + 1, j]
        gx = (1 - v) * (fb - fa) + v * (fc - fd)
        gy = (1 - u) * (fd - fa) + u * (fc - fb)
        good[s] = ((y1 - y0) * gx - (x1 - x0) * gy) < 0
    # chains
    used = np.zeros(nseg, np.bool_)
    fkeys = np.empty(nseg, np.int64)
    fsegs = np.empty(nseg, np.int64)
    bkeys = np.empty(nseg, np.int64)
    bsegs = np.empty(nseg, np.int64)
    keys = np.empty(nseg + 1, np.int64)
    segs = np.empty(nseg, np.int64)
    points = np.empty((2 * nseg, 2))
    starts = np.zeros(nseg + 1, np.int64)
    nline = 0
    npts = 0
    for s in range(nseg):
        if used[s]:
            continue
        used[s] = True
        nf = _walk(ends, used, k0, k1, k1[s], fkeys, fsegs)
        closed = nf > 0 and fkeys[nf - 1] == k0[s]
        nk = 0
        ns = 0
        if closed:
            keys[0] = k0[s]
            keys[1] = k1[s]
            nk = 2
            segs[0] = s
            ns = 1
        else:
            nb = _walk(ends, used, k0, k1, k0[s], bkeys, bsegs)
            for t in range(nb - 1, -1, -1):
                keys[nk] = bkeys[t]
                nk += 1
                segs[ns] = bsegs[t]
                ns += 1
            keys[nk] = k0[s]
            keys[nk + 1] = k1[s]
            nk += 2
            segs[ns] = s
            ns += 1
        for t in range(nf):
            keys[nk] = fkeys[t]
            nk += 1
            segs[ns] = fsegs[t]
            ns += 1
        agree = 0
        for t in range(ns):
            q = segs[t]
            if (k0[q] == keys[t]) == good[q]:
                agree += 1
        reverse = 2 * agree - ns < 0
        for t in range(nk):
            key = keys[nk - 1 - t] if reverse else keys[t]
            # the crossing's point: that of a segment ending there
            q = ends[key, 0]
            if k0[q] == key:
                points[npts, 0] = px[q, 0]
                points[npts, 1] = py[q, 0]
            else:
                points[npts, 0] = px[q, 1]
                points[npts, 1] = py[q, 1]
            npts += 1
        nline += 1
        starts[nline] = npts
    return points[:npts].copy(), starts[:nline + 1].copy()


@helper
def _walk(ends, used, k0, k1, key, keys, segs):
    """Follow the chain from the crossing ``key``, each step the lowest unused segment ending
    there, marking them used: their count, their far ends in ``keys`` and themselves in
    ``segs``."""
    n = 0
    while True:
        q = -1
        for slot in range(2):
            cand = ends[key, slot]
            if cand >= 0 and not used[cand]:
                q = cand
                break
        if q < 0:
            return n
        used[q] = True
        segs[n] = q
        key = k1[q] if k0[q] == key else k0[q]
        keys[n] = key
        n += 1


marching_squares = Kernel(_marching_squares_loops)
