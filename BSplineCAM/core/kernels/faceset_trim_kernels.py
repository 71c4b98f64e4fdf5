# SPDX-License-Identifier: LGPL-2.1-or-later
"""Loop-style twins of the drop-cutter's trim computations (:mod:`..toolpath.faceset_trims`):
Liang-Barsky clipping of trim segments by sub-patch boxes, the trim classification of boxes,
the material's vertices and the banded point-in-trim test, compiled by
:class:`BSplineCAM.core.kernels.Kernel`.

Each function computes what its numpy twin computes, element by element in the same order of
operations, so both engines give the same bits and the same decisions; ``np.maximum`` and
``np.minimum`` are written out with their NaN rule (a NaN operand gives NaN).  They take and
return contiguous float64, int64 and bool arrays only.

The clipping of one segment (:func:`clip_one`), the trim test of one point
(:func:`inside_one`) and one box's clipped segment ends (:func:`vertices_into`) are
:func:`~BSplineCAM.core.kernels.helper` functions, compiled once and called by every kernel
that needs them (here and in :mod:`.regions_kernels`, :mod:`.faceset_round_kernels`).
"""

from __future__ import annotations

import math

import numpy as np

from . import helper


@helper
def clip_one(a0, a1, d0, d1, lo0, hi0, lo1, hi1):
    """Liang-Barsky clipping of the segment from (a0, a1) along (d0, d1) by the box
    [lo0, hi0] x [lo1, hi1]: (hit, t0, t1), the clipped part running from t0 to t1
    (``faceset_trims._clip`` of one segment: an axis the segment runs across bounds t by
    NaN-propagating maxima and minima, one it runs along drops it where outside)."""
    t0 = 0.0
    t1 = 1.0
    h = math.isfinite(a0)
    if d0 == 0:
        if a0 < lo0 or a0 > hi0:
            h = False
    else:
        ta = (lo0 - a0) / d0
        tb = (hi0 - a0) / d0
        tlo = ta if (ta <= tb or ta != ta) else tb
        thi = ta if (ta >= tb or ta != ta) else tb
        t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
        t1 = t1 if (t1 <= thi or t1 != t1) else thi
    if d1 == 0:
        if a1 < lo1 or a1 > hi1:
            h = False
    else:
        ta = (lo1 - a1) / d1
        tb = (hi1 - a1) / d1
        tlo = ta if (ta <= tb or ta != ta) else tb
        thi = ta if (ta >= tb or ta != ta) else tb
        t0 = t0 if (t0 >= tlo or t0 != t0) else tlo
        t1 = t1 if (t1 <= thi or t1 != t1) else thi
    return h and t0 <= t1, t0, t1


@helper
def inside_one(table, v0, h, pu, pv, u_lo, u_hi, v_lo, v_hi):
    """Whether the point (pu, pv), clamped first into [u_lo, u_hi] x [v_lo, v_hi], lies
    inside the trim: the even-odd test against the segments of its band of v (``table``
    (nb, W, 4), NaN padding; band b covers v0 + [b, b + 1) h) with pnpoly's half-open
    crossing rule (``faceset_trims._Bands.__call__`` of one point; a NaN v is outside)."""
    pu = pu if (pu >= u_lo or pu != pu) else u_lo
    pu = pu if (pu <= u_hi or pu != pu) else u_hi
    pv = pv if (pv >= v_lo or pv != pv) else v_lo
    pv = pv if (pv <= v_hi or pv != pv) else v_hi
    f = np.floor((pv - v0) / h)
    if f != f:
        return False
    nb = table.shape[0]
    f = max(f, 0.0)
    f = min(f, nb - 1.0)
    b = int(f)
    odd = False
    for k in range(table.shape[1]):
        a0 = table[b, k, 0]
        a1 = table[b, k, 1]
        a2 = table[b, k, 2]
        a3 = table[b, k, 3]
        if (a1 > pv) != (a3 > pv):
            cross = a0 + (pv - a1) * ((a2 - a0) / (a3 - a1))
            if pu < cross:
                odd = not odd
    return odd


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
            a0 = seg[i, k, 0]
            a1 = seg[i, k, 1]
            d0 = seg[i, k, 2] - a0
            d1 = seg[i, k, 3] - a1
            h, t0, t1 = clip_one(a0, a1, d0, d1, box[i, 0], box[i, 1], box[i, 2], box[i, 3])
            hit[i, k] = h
            e0[i, k, 0] = a0 + t0 * d0
            e0[i, k, 1] = a1 + t0 * d1
            e1[i, k, 0] = a0 + t1 * d0
            e1[i, k, 1] = a1 + t1 * d1
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
        counts[i] = kept_in_box(edges, ps, i, box, i, kept)
    return counts, kept


@helper
def kept_in_box(edges, segs, i, box, r, out):
    """Write to the front of ``out[r]`` the segments of ``segs[i]`` (ids into ``edges``, -1
    none) that cross ``box[r]`` (u0, u1, v0, v1), in their order; return their count."""
    c = 0
    for k in range(segs.shape[1]):
        e = segs[i, k]
        if e < 0:
            continue
        u0 = edges[e, 0]
        v0 = edges[e, 1]
        h, _, _ = clip_one(u0, v0, edges[e, 2] - u0, edges[e, 3] - v0,
                           box[r, 0], box[r, 1], box[r, 2], box[r, 3])
        if h:
            out[r, c] = e
            c += 1
    return c


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
            h, _, _ = clip_one(u0, v0, edges[e, 2] - u0, edges[e, 3] - v0, b0, b1, b2, b3)
            if h:
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
    half-open crossing rule (``faceset_trims._Bands.__call__``; :func:`inside_one`)."""
    m = u.shape[0]
    out = np.zeros(m, np.bool_)
    for i in range(m):
        out[i] = inside_one(table, v0, h, u[i], v[i], dom[0], dom[1], dom[2], dom[3])
    return out


@helper
def vertices_into(edges, b0, b1, b2, b3, ps, st, ok, o):
    """The clipped trim segments' ends of :func:`vertices` for one box (b0, b1, b2, b3)
    crossed by segments ``ps`` (K,): their local (s, t) into ``st`` (4 + 2K, 2) rows 4...
    and their validity into ``ok`` (from index ``o``: 2K); the corners' rows of ``st`` are set, ``ok`` of the
    corners is left to the caller."""
    K = ps.shape[0]
    st[0, 0] = 0.0
    st[0, 1] = 0.0
    st[1, 0] = 1.0
    st[1, 1] = 0.0
    st[2, 0] = 0.0
    st[2, 1] = 1.0
    st[3, 0] = 1.0
    st[3, 1] = 1.0
    du = b1 - b0
    dv = b3 - b2
    for k in range(K):
        e = ps[k]
        if e < 0:
            # a NaN segment: no hit, its ends NaN, taken as 0
            ok[o + k] = False
            ok[o + K + k] = False
            st[4 + k, 0] = 0.0
            st[4 + k, 1] = 0.0
            st[4 + K + k, 0] = 0.0
            st[4 + K + k, 1] = 0.0
            continue
        a0 = edges[e, 0]
        a1 = edges[e, 1]
        d0 = edges[e, 2] - a0
        d1 = edges[e, 3] - a1
        h, t0, t1 = clip_one(a0, a1, d0, d1, b0, b1, b2, b3)
        ok[o + k] = h
        ok[o + K + k] = h
        for end in range(2):
            tc = t0 if end == 0 else t1
            x = ((a0 + tc * d0) - b0) / du
            if x != x:
                x = 0.0
            x = x if x >= 0.0 else 0.0
            st[4 + end * K + k, 0] = x if x <= 1.0 else 1.0
            x = ((a1 + tc * d1) - b2) / dv
            if x != x:
                x = 0.0
            x = x if x >= 0.0 else 0.0
            st[4 + end * K + k, 1] = x if x <= 1.0 else 1.0


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
        vertices_into(edges, box[i, 0], box[i, 1], box[i, 2], box[i, 3], ps[i], st[i], ok[i],
                      0)
    return st, ok
