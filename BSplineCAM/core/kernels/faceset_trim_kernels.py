# SPDX-License-Identifier: LGPL-2.1-or-later
"""Loop-style twins of the drop-cutter's trim computations (:mod:`..toolpath.faceset_trims`):
Liang-Barsky clipping of trim segments by sub-patch boxes, the trim classification of boxes,
the material's vertices and the banded point-in-trim test, compiled by
:class:`BSplineCAM.core.kernels.Kernel`.

Each function computes what its numpy twin computes, element by element in the same order of
operations, so both engines give the same bits and the same decisions; ``np.maximum`` and
``np.minimum`` are written out with their NaN rule (a NaN operand gives NaN).  They take and
return contiguous float64, int64 and bool arrays only.
"""

from __future__ import annotations

import math

import numpy as np


def clip(seg, box):
    """Liang-Barsky clipping of segments (n, K, 4) (u0, v0, u1, v1) by boxes (n, 4)
    (u0, u1, v0, v1): hit mask (n, K) and the clipped end points (n, K, 2) each
    (``faceset_trims._clip``)."""
    n = seg.shape[0]
    K = seg.shape[1]
    hit = np.empty((n, K), np.bool_)
    e0 = np.empty((n, K, 2))
    e1 = np.empty((n, K, 2))
    for i in range(n):
        for k in range(K):
            t0 = 0.0
            t1 = 1.0
            h = math.isfinite(seg[i, k, 0])
            for c in range(2):
                lo = box[i, 2 * c]
                hi = box[i, 2 * c + 1]
                ac = seg[i, k, c]
                dc = seg[i, k, c + 2] - ac
                if dc == 0:
                    if ac < lo or ac > hi:
                        h = False
                    tlo = -np.inf
                    thi = np.inf
                else:
                    ta = (lo - ac) / dc
                    tb = (hi - ac) / dc
                    tlo = ta if (ta <= tb or ta != ta) else tb
                    thi = ta if (ta >= tb or ta != ta) else tb
                t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
                t1 = t1 if (t1 <= thi or t1 != t1) else thi
            hit[i, k] = h and t0 <= t1
            for c in range(2):
                ac = seg[i, k, c]
                dc = seg[i, k, c + 2] - ac
                e0[i, k, c] = ac + t0 * dc
                e1[i, k, c] = ac + t1 * dc
    return hit, e0, e1


def classify_listed(edges, ps, box):
    """Trim segments ``ps`` (n, K) (ids into ``edges`` (E, 4), -1 none) that cross each box
    (n, 4), compacted to the front of each row (-1 padding), and their count (the parents'
    segments part of ``faceset_trims._FaceData._classify``)."""
    n = ps.shape[0]
    K = ps.shape[1]
    kept = np.full((n, K), -1, np.int64)
    counts = np.zeros(n, np.int64)
    for i in range(n):
        b0 = box[i, 0]
        b1 = box[i, 1]
        b2 = box[i, 2]
        b3 = box[i, 3]
        c = 0
        for j in range(K):
            e = ps[i, j]
            if e < 0:
                continue
            u0 = edges[e, 0]
            v0 = edges[e, 1]
            du = edges[e, 2] - u0
            dv = edges[e, 3] - v0
            t0 = 0.0
            t1 = 1.0
            h = math.isfinite(u0)
            for a in range(2):
                if a == 0:
                    lo = b0
                    hi = b1
                    ac = u0
                    dc = du
                else:
                    lo = b2
                    hi = b3
                    ac = v0
                    dc = dv
                if dc == 0:
                    if ac < lo or ac > hi:
                        h = False
                else:
                    ta = (lo - ac) / dc
                    tb = (hi - ac) / dc
                    tlo = ta if (ta <= tb or ta != ta) else tb
                    thi = ta if (ta >= tb or ta != ta) else tb
                    t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
                    t1 = t1 if (t1 <= thi or t1 != t1) else thi
            if h and t0 <= t1:
                kept[i, c] = e
                c += 1
        counts[i] = c
    return counts, kept


def classify_all(edges, elo, ehi, pad, box, width):
    """Trim segments crossing each box (n, 4) among all ``edges`` (E, 4) whose boxes
    (``elo``, ``ehi`` (E, 2)) padded by ``pad`` meet it: the first ``width`` ids in ascending
    order (-1 padding; a row of -2 when more cross) and their count (the all-segments part
    of ``faceset_trims._FaceData._classify``)."""
    n = box.shape[0]
    E = edges.shape[0]
    segs = np.full((n, width), -1, np.int64)
    counts = np.zeros(n, np.int64)
    for i in range(n):
        b0 = box[i, 0]
        b1 = box[i, 1]
        b2 = box[i, 2]
        b3 = box[i, 3]
        c = 0
        for e in range(E):
            if not (elo[e, 0] <= b1 + pad and ehi[e, 0] >= b0 - pad
                    and elo[e, 1] <= b3 + pad and ehi[e, 1] >= b2 - pad):
                continue
            u0 = edges[e, 0]
            v0 = edges[e, 1]
            du = edges[e, 2] - u0
            dv = edges[e, 3] - v0
            t0 = 0.0
            t1 = 1.0
            h = math.isfinite(u0)
            for a in range(2):
                if a == 0:
                    lo = b0
                    hi = b1
                    ac = u0
                    dc = du
                else:
                    lo = b2
                    hi = b3
                    ac = v0
                    dc = dv
                if dc == 0:
                    if ac < lo or ac > hi:
                        h = False
                else:
                    ta = (lo - ac) / dc
                    tb = (hi - ac) / dc
                    tlo = ta if (ta <= tb or ta != ta) else tb
                    thi = ta if (ta >= tb or ta != ta) else tb
                    t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
                    t1 = t1 if (t1 <= thi or t1 != t1) else thi
            if h and t0 <= t1:
                if c < width:
                    segs[i, c] = e
                c += 1
        counts[i] = c
        if c > width:
            for j in range(width):
                segs[i, j] = -2
    return counts, segs


def inside(table, v0, h, nb, u, v, dom):
    """Even-odd point-in-trim test of points (u, v) (m,) each, clamped first into ``dom``
    (u lo, u hi, v lo, v hi; infinite: no clamp), against the trim segments filed by bands of
    v (``table`` (nb, W, 4), NaN padding; band b covers v0 + [b, b + 1) h) with pnpoly's
    half-open crossing rule (``faceset_trims._Bands.__call__``)."""
    m = u.shape[0]
    W = table.shape[1]
    out = np.zeros(m, np.bool_)
    for i in range(m):
        pu = u[i]
        pu = pu if (pu >= dom[0] or pu != pu) else dom[0]
        pu = pu if (pu <= dom[1] or pu != pu) else dom[1]
        pv = v[i]
        pv = pv if (pv >= dom[2] or pv != pv) else dom[2]
        pv = pv if (pv <= dom[3] or pv != pv) else dom[3]
        f = np.floor((pv - v0) / h)
        if f != f:
            continue
        f = max(f, 0.0)
        f = min(f, nb - 1.0)
        b = int(f)
        odd = False
        for k in range(W):
            a0 = table[b, k, 0]
            a1 = table[b, k, 1]
            a2 = table[b, k, 2]
            a3 = table[b, k, 3]
            if (a1 > pv) != (a3 > pv):
                cross = a0 + (pv - a1) * ((a2 - a0) / (a3 - a1))
                if pu < cross:
                    odd = not odd
        out[i] = odd
    return out


def vertices(edges, box, ps):
    """Local (s, t) (n, 4 + 2K, 2) of the candidate vertices of the material in boxes (n, 4)
    crossed by segments ``ps`` (n, K) (ids into ``edges``, -1 none) and the validity
    (n, 2K) of the segments' ones: the corners, then the first and the second ends of the
    clipped segments (``faceset_trims._FaceData._vertices``, but for the corners' trim test,
    :func:`inside`)."""
    n = box.shape[0]
    K = ps.shape[1]
    st = np.zeros((n, 4 + 2 * K, 2))
    ok = np.zeros((n, 2 * K), np.bool_)
    for i in range(n):
        st[i, 1, 0] = 1.0
        st[i, 2, 1] = 1.0
        st[i, 3, 0] = 1.0
        st[i, 3, 1] = 1.0
        du = box[i, 1] - box[i, 0]
        dv = box[i, 3] - box[i, 2]
        for k in range(K):
            e = ps[i, k]
            if e < 0:
                # a NaN segment: no hit, its ends NaN, taken as 0
                continue
            t0 = 0.0
            t1 = 1.0
            h = math.isfinite(edges[e, 0])
            for c in range(2):
                lo = box[i, 2 * c]
                hi = box[i, 2 * c + 1]
                ac = edges[e, c]
                dc = edges[e, c + 2] - ac
                if dc == 0:
                    if ac < lo or ac > hi:
                        h = False
                    tlo = -np.inf
                    thi = np.inf
                else:
                    ta = (lo - ac) / dc
                    tb = (hi - ac) / dc
                    tlo = ta if (ta <= tb or ta != ta) else tb
                    thi = ta if (ta >= tb or ta != ta) else tb
                t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
                t1 = t1 if (t1 <= thi or t1 != t1) else thi
            h = h and t0 <= t1
            ok[i, k] = h
            ok[i, K + k] = h
            for c in range(2):
                ac = edges[e, c]
                dc = edges[e, c + 2] - ac
                for end in range(2):
                    x = ac + (t0 if end == 0 else t1) * dc
                    x = (x - box[i, 0]) / du if c == 0 else (x - box[i, 2]) / dv
                    if x != x:
                        x = 0.0
                    x = x if x >= 0.0 else 0.0
                    x = x if x <= 1.0 else 1.0
                    st[i, 4 + end * K + k, c] = x
    return st, ok
