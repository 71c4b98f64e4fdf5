# SPDX-License-Identifier: LGPL-2.1-or-later
"""The numba engine of one level of the drop-cutter's branch and bound
(:mod:`~BSplineCAM.core.toolpath.faceset_branch`) for one face, in three calls where the numpy
engine makes a hundred array operations:

* :func:`bound_pairs` bounds every (query, sub-patch) pair: the box and tangent-plane bounds
  (``faceset_bounds._box_bound``, ``_tangent_plane``), the straddling pairs' material
  vertices (``_straddling``, a rational patch's drift ``faceset_bezier._rational_drift``
  included), the corners' lower bounds (``_lower_bounds``) and the trim vertex each
  straddling pair offers (``_lower_rest``); the rarer steps that evaluate the surface (a
  trim vertex's point, a shallow pair's seed) stay with the caller, the rim bound
  has a kernel of its own (:mod:`.faceset_rim_kernels`);
* :func:`record_contacts` raises a face's best contacts to its pairs' lower bounds
  (``faceset_branch._record_contacts``);
* :func:`open_split` keeps the pairs still open (``faceset_branch._open_pairs``), chooses
  the cuts along certified regions' sides (``faceset_subdivide.region_cuts``), halves or
  splits them (``faceset_subdivide.children``) and classifies the halves of straddling
  pairs against their parents' listed trim segments (``faceset_trims._FaceData._classify``);
  rows whose parent's segments were too many to list are left to the caller (marked -1).

The arithmetic is the numpy engine's, operation by operation, as in :mod:`.faceset_kernels`
and :mod:`.faceset_trim_kernels` (whose halving, splitting, clipping, vertex and trim-test
helpers these call): the same bits and the same decisions.  They take and return contiguous
float64, int64, int8 and bool arrays only.
"""

from __future__ import annotations

import math

import numpy as np

from . import Kernel, helper
from .faceset_kernels import halve, net_coords, split_at
from .faceset_trim_kernels import inside_one, kept_in_box, vertices_into
from .nurbs_eval import _check_loops, _rational_loops, _scattered_loops
from .scalars import nan_max


@helper
def net_planes(flat, rational, pinv, design):
    """The query-free part of the bounds of homogeneous nets ``flat`` (N, 4, K)
    (``faceset_bounds._NetPlanes``): the control points' coordinates PX, PY, PZ (N, K) and
    boxes (N, 5) and centroids (N, 3) (:func:`.faceset_kernels.net_coords`), the affine parts
    C (3, N, 3) of (z, x, y) about the centroid at the Greville abscissae (``pinv`` (3, K)
    times the deviations) and the residuals RS (3, N, K) (the deviations less C times
    ``design`` (K, 3)).  The products are summed term by term in order, where numpy's matrix
    product leaves the order to its BLAS: they agree with the numpy engine's to rounding."""
    PX, PY, PZ, cen, G, box = net_coords(flat, rational)
    N = flat.shape[0]
    K = flat.shape[2]
    C = np.empty((3, N, 3))
    RS = np.empty((3, N, K))
    for c in range(3):
        for n in range(N):
            for j in range(3):
                acc = 0.0
                for k in range(K):
                    acc += G[c, n, k] * pinv[j, k]
                C[c, n, j] = acc
            for k in range(K):
                RS[c, n, k] = G[c, n, k] - (C[c, n, 0] * design[k, 0] + C[c, n, 1] * design[k, 1]
                                            + C[c, n, 2] * design[k, 2])
    return PX, PY, PZ, cen, C, RS, box


def _bound_pairs_loops(nd, qq, R2, flat, rational, pinv, design, touch_R2, cidx, corners,
                       ibox, segs, status, edges, table, v0, h, inner, floor, depth, rim_r2,
                       rim_depth, seed_depth, knots_u, p, first_u, last_u, knots_v, q,
                       first_v, last_v, spans_v, orders, offsets, tables, dim, index, dom):
    """Bounds of the pairs (query ``qq`` (n, 2), sub-patch ``nd`` (n,) of the nets ``flat``)
    of one level of one face: (ub, dd, reach, lb, lu, lv, strad, st, ok, aval, listed, kv,
    rim, fine, and the nets' planes of :func:`net_planes`).

    ``ub`` is the upper bound before the rim bound (-inf out of reach), ``dd`` the squared
    xy distance of the net's box, ``reach`` whether it is within reach (no material: out),
    ``lb`` the lower bound of the corners, on straddling pairs of the surface point at the
    best trim vertex, and on pairs at most ``seed_depth`` deep of the point below the control
    point nearest the query, at (``lu``, ``lv``); ``strad`` (s,) the straddling pairs, ``st``,
    ``ok``, ``aval``, ``listed`` their material's vertices as ``faceset_bounds._Straddling``,
    ``kv`` (s,) the vertex whose surface point was tried (-1 none), and ``rim`` the number of
    pairs the rim bound is for.  The surface's points come from :mod:`.nurbs_eval`'s loops
    (its pack of the points' order, ``index`` of the quotient rule, the domain ``dom`` (lo u,
    hi u, tol u, lo v, hi v, tol v)); ``fine``: whether every point lay in the domain."""
    PX, PY, PZ, cen, C, RS, box = net_planes(flat, rational, pinv, design)
    n = nd.shape[0]
    K = RS.shape[2]
    MS = segs.shape[1]
    V = 4 + 2 * MS
    s = 0
    for i in range(n):
        if status[i] == 2:
            s += 1
    strad = np.empty(s, np.int64)
    st = np.zeros((s, V, 2))
    ok = np.zeros((s, V), np.bool_)
    aval = np.empty((s, V))
    listed = np.empty(s, np.bool_)
    kv = np.full(s, -1, np.int64)
    ub = np.empty(n)
    dd = np.empty(n)
    reach = np.empty(n, np.bool_)
    lb = np.empty(n)
    lu = np.empty(n)
    lv = np.empty(n)
    cok = np.ones(4, np.bool_)
    first = np.full(flat.shape[0], -1, np.int64)  # each node's first straddling pair
    lim = 0.999 * R2
    rim = 0
    r = 0
    for i in range(n):
        j = nd[i]
        qx = qq[i, 0]
        qy = qq[i, 1]
        # the box bound (pair_bounds)
        dx = max(max(box[j, 0] - qx, qx - box[j, 1]), 0.0)
        dy = max(max(box[j, 2] - qy, qy - box[j, 3]), 0.0)
        d2 = dx * dx + dy * dy
        dd[i] = d2
        rch = d2 <= R2
        u_b = box[j, 4] + math.sqrt(max(R2 - d2, 0.0)) if rch else -np.inf
        # the tangent plane at the centroid
        cz = cen[j, 2]
        ox = cen[j, 0] - qx
        oy = cen[j, 1] - qy
        d0 = ox * ox + oy * oy
        lin_ok = d0 < lim
        s0 = math.sqrt(max(R2 - d0, 1e-300))
        a = ox / s0
        b = oy / s0
        c0 = C[0, j, 0] - a * C[1, j, 0] - b * C[2, j, 0]
        c1 = C[0, j, 1] - a * C[1, j, 1] - b * C[2, j, 1]
        c2 = C[0, j, 2] - a * C[1, j, 2] - b * C[2, j, 2]
        res = RS[0, j, 0] - a * RS[1, j, 0] - b * RS[2, j, 0]
        for k in range(1, K):
            x = RS[0, j, k] - a * RS[1, j, k] - b * RS[2, j, k]
            if x > res or x != x:
                res = x
        amax = c0 + max(c1, 0.0) + max(c2, 0.0)
        for c in range(4):
            cok[c] = True
        if status[i] == 2:
            # the straddling pair's material (straddling)
            strad[r] = i
            b0 = ibox[i, 0]
            b1 = ibox[i, 1]
            b2 = ibox[i, 2]
            b3 = ibox[i, 3]
            # the material's vertices depend on the box and its segments alone: the queries
            # sharing a sub-patch take its first pair's
            f = first[j]
            if f >= 0 and same_box(ibox, segs, strad[f], i):
                for v in range(V):
                    st[r, v, 0] = st[f, v, 0]
                    st[r, v, 1] = st[f, v, 1]
                    ok[r, v] = ok[f, v]
            else:
                first[j] = r
                vertices_into(edges, b0, b1, b2, b3, segs[i], st[r], ok[r], 4)
                ok[r, 0] = inside_one(table, v0, h, b0, b2, inner[0], inner[1], inner[2],
                                      inner[3])
                ok[r, 1] = inside_one(table, v0, h, b1, b2, inner[0], inner[1], inner[2],
                                      inner[3])
                ok[r, 2] = inside_one(table, v0, h, b0, b3, inner[0], inner[1], inner[2],
                                      inner[3])
                ok[r, 3] = inside_one(table, v0, h, b1, b3, inner[0], inner[1], inner[2],
                                      inner[3])
            top = -np.inf
            some = False
            for v in range(V):
                x = c0 + c1 * st[r, v, 0] + c2 * st[r, v, 1]
                aval[r, v] = x
                y = x if ok[r, v] else -np.inf
                top = top if (top >= y or top != top) else y
                some = some or ok[r, v]
            for c in range(4):
                cok[c] = ok[r, c]
            lst = segs[i, 0] != -2
            listed[r] = lst
            if lst:
                if rational:
                    # the drift (faceset_bezier._rational_drift)
                    wmin = flat[j, 3, 0]
                    wmax = flat[j, 3, 0]
                    for k in range(1, K):
                        w = flat[j, 3, k]
                        if w < wmin or w != w:
                            wmin = w
                        if w > wmax or w != w:
                            wmax = w
                    eps = (wmax - wmin) / wmin
                    top = top + math.sqrt(2.0) * eps * math.hypot(c1, c2)
                    amax = amax if (amax <= top or amax != amax) else top
                else:
                    amax = top
                if not some:
                    rch = False
            # the best trim vertex (argmax, the first of equals, NaN first)
            best = -np.inf
            arg = 0
            for v in range(4, V):
                x = aval[r, v] if ok[r, v] else -np.inf
                if v == 4:
                    best = x
                elif best == best and (x > best or x != x):
                    best = x
                    arg = v - 4
            if math.isfinite(best) and rch:
                kv[r] = 4 + arg
            r += 1
        # the bound (sub_patch_bounds)
        lin = cz + s0 + amax + res
        if lin_ok and lin < u_b:
            u_b = lin
        if not rch:
            u_b = -np.inf
        ub[i] = u_b
        reach[i] = rch
        if u_b > floor[i] and d2 >= rim_r2 and depth[i] >= rim_depth:
            rim += 1
        # the corners' lower bound (corner_lower)
        f_best = -np.inf
        arg = 0
        for c in range(4):
            k = cidx[c]
            ex = PX[j, k] - qx
            ey = PY[j, k] - qy
            e2 = ex * ex + ey * ey
            f = -np.inf
            if e2 <= touch_R2 and cok[c]:
                f = PZ[j, k] + math.sqrt(max(R2 - e2, 0.0))
            if c == 0:
                f_best = f
            elif f > f_best:
                f_best = f
                arg = c
        lb[i] = f_best
        lu[i] = ibox[i, 0] + corners[arg, 0] * (ibox[i, 1] - ibox[i, 0])
        lv[i] = ibox[i, 2] + corners[arg, 1] * (ibox[i, 3] - ibox[i, 2])
    # the best trim vertices' surface points (faceset_bounds._ball_at and _raise_bound)
    c = 0
    for r in range(s):
        if kv[r] >= 0:
            c += 1
    pair = np.empty(c, np.int64)
    uu = np.empty(c)
    vv = np.empty(c)
    c = 0
    for r in range(s):
        if kv[r] >= 0:
            i = strad[r]
            pair[c] = i
            uu[c] = ibox[i, 0] + st[r, kv[r], 0] * (ibox[i, 1] - ibox[i, 0])
            vv[c] = ibox[i, 2] + st[r, kv[r], 1] * (ibox[i, 3] - ibox[i, 2])
            c += 1
    fine = raise_at(pair, uu, vv, False, qq, R2, touch_R2, lb, lu, lv, status, table, v0, h,
                    inner, rational, knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                    spans_v, orders, offsets, tables, dim, index, dom)
    # shallow pairs: the point at the Greville abscissae of the control point nearest the
    # query (faceset_bounds._seed_points), inside the trim
    c = 0
    for i in range(n):
        if depth[i] <= seed_depth and reach[i]:
            c += 1
    pair = np.empty(c, np.int64)
    uu = np.empty(c)
    vv = np.empty(c)
    c = 0
    for i in range(n):
        if not (depth[i] <= seed_depth and reach[i]):
            continue
        j = nd[i]
        best = 0.0
        kn = 0
        for k in range(K):
            x = (PX[j, k] - qq[i, 0]) ** 2 + (PY[j, k] - qq[i, 1]) ** 2
            if k == 0:
                best = x
            elif best == best and (x < best or x != x):
                best = x
                kn = k
        pair[c] = i
        uu[c] = ibox[i, 0] + design[kn, 1] * (ibox[i, 1] - ibox[i, 0])
        vv[c] = ibox[i, 2] + design[kn, 2] * (ibox[i, 3] - ibox[i, 2])
        c += 1
    fine = raise_at(pair, uu, vv, True, qq, R2, touch_R2, lb, lu, lv, status, table, v0, h,
                    inner, rational, knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                    spans_v, orders, offsets, tables, dim, index, dom) and fine
    return (ub, dd, reach, lb, lu, lv, strad, st, ok, aval, listed, kv, rim, fine, PX, PY, PZ,
            cen, C, RS)


def _record_contacts_loops(j, query, lb, lu, lv, fb, fu, fv, touched):
    """Raise face row ``j``'s best lower bounds ``fb`` (and contacts ``fu``, ``fv``) of each
    query to its pairs' finite lower bounds ``lb`` at (``lu``, ``lv``), in place: the largest,
    the last of equals (``faceset_branch._record_contacts``).  ``touched`` (m,) all False
    on entry, is scratch."""
    n = query.shape[0]
    for i in range(n):
        x = lb[i]
        if not math.isfinite(x):
            continue
        q = query[i]
        cur = fb[j, q]
        if x > cur or (touched[q] and x == cur):
            fb[j, q] = x
            fu[j, q] = lu[i]
            fv[j, q] = lv[i]
            touched[q] = True
    for i in range(n):
        touched[query[i]] = False


@helper
def raise_at(pair, uu, vv, trimmed, qq, R2, touch_R2, lb, lu, lv, status, table, v0, h, inner,
             rational, knots_u, p, first_u, last_u, knots_v, q, first_v, last_v, spans_v,
             orders, offsets, tables, dim, index, dom):
    """Raise the lower bounds ``lb`` of pairs ``pair`` to the centre height of the ball
    resting on the surface at (``uu``, ``vv``) where larger (-inf out of reach and, if
    ``trimmed``, on a straddling pair outside the trim), and their contacts (``lu``, ``lv``)
    there, in place (``faceset_bounds._ball_at`` and ``_raise_bound``): whether every point
    lay in the surface's domain (:mod:`.nurbs_eval`'s loops over the pack of order (0, 0))."""
    c = pair.shape[0]
    if c == 0:
        return True
    cu, cv, fine = _check_loops(uu, vv, dom[0], dom[1], dom[2], dom[3], dom[4], dom[5])
    pts, _, _ = _scattered_loops(knots_u, p, first_u, last_u, knots_v, q, first_v, last_v,
                                 spans_v, orders, offsets, tables, dim, cu, cv)
    if rational:
        pts = _rational_loops(pts, orders, index)
    for k in range(c):
        i = pair[k]
        ex = pts[0, k, 0] - qq[i, 0]
        ey = pts[0, k, 1] - qq[i, 1]
        e2 = ex ** 2 + ey ** 2
        f = pts[0, k, 2] + math.sqrt(max(R2 - e2, 0.0)) if e2 <= touch_R2 else -np.inf
        if trimmed and status[i] == 2 and not inside_one(table, v0, h, uu[k], vv[k], inner[0],
                                                         inner[1], inner[2], inner[3]):
            f = -np.inf
        if f > lb[i]:
            lb[i] = f
            lu[i] = uu[k]
            lv[i] = vv[k]
    return fine


@helper
def same_box(box, segs, a, b):
    """Whether pairs a and b have the same parameter box and trim segments."""
    for k in range(4):
        if box[a, k] != box[b, k]:
            return False
    for k in range(segs.shape[1]):  # noqa: SIM110  (a generator does not compile)
        if segs[a, k] != segs[b, k]:
            return False
    return True


@helper
def copy_row(src, a, dst, b):
    """dst[b] = src[a] of two 2-d arrays."""
    for k in range(src.shape[1]):
        dst[b, k] = src[a, k]


@helper
def open_pairs(j, query, box, depth, ub, best, gap, reg_box, reg_val, given_up, certify,
               max_depth, max_open, crowded):
    """Which pairs of face row ``j`` stay open and which lie in their query's region
    (``faceset_branch._open_pairs``; ``gap`` and ``crowded`` in place): (open (n,),
    in region (n,), pairs left uncertified)."""
    n = query.shape[0]
    m = gap.shape[0]
    opened = np.zeros(n, np.bool_)
    inreg = np.zeros(n, np.bool_)
    unc = 0
    count = np.zeros(m, np.int64)
    for i in range(n):
        q = query[i]
        lim = best[q] + certify
        o = ub[i] > lim
        ir = reg_val[j, q] <= lim
        inreg[i] = ir
        if (o and ir and box[i, 0] >= reg_box[j, q, 0] and box[i, 1] <= reg_box[j, q, 1]
                and box[i, 2] >= reg_box[j, q, 2] and box[i, 3] <= reg_box[j, q, 3]):
            o = False
        if o and (depth[i] >= max_depth or given_up[q]):
            # too deep, or crowded for the most levels: the bound goes to the gap
            gap[q] = nan_max(gap[q], ub[i] - best[q])
            unc += 1
            o = False
        opened[i] = o
        if o:
            count[q] += 1
    for q in range(m):
        if count[q] <= max_open:
            continue
        crowded[q] = True
        # a query whose maximum is (nearly) tied along a curve: its max_open best
        # sub-patches stay open (the first of equals), the rest's bounds go to its gap
        idx = np.empty(count[q], np.int64)
        c = 0
        for i in range(n):
            if opened[i] and query[i] == q:
                idx[c] = i
                c += 1
        # the open pairs by falling bound, the first of equals first (a stable
        # insertion sort: numpy's lexsort)
        for k in range(1, c):
            i = idx[k]
            x = ub[i]
            a = k
            while a > 0 and ub[idx[a - 1]] < x:
                idx[a] = idx[a - 1]
                a -= 1
            idx[a] = i
        for k in range(max_open, c):
            i = idx[k]
            gap[q] = nan_max(gap[q], ub[i] - best[q])
            unc += 1
            opened[i] = False
    return opened, inreg, unc


@helper
def region_cuts(j, query, box, opened, inreg, reg_box, margin):
    """Where an open pair overlaps its query's region, the local parameter of the region's
    side that cuts it (NaN: halve it) and whether along u (``faceset_subdivide.
    region_cuts``)."""
    n = query.shape[0]
    t = np.full(n, np.nan)
    along = np.zeros(n, np.bool_)
    hi = 1.0 - margin
    cand = np.empty(4)
    for i in range(n):
        q = query[i]
        if not (opened[i] and inreg[i] and box[i, 0] < reg_box[j, q, 1]
                and box[i, 1] > reg_box[j, q, 0] and box[i, 2] < reg_box[j, q, 3]
                and box[i, 3] > reg_box[j, q, 2]):
            continue
        wu = box[i, 1] - box[i, 0]
        wv = box[i, 3] - box[i, 2]
        cand[0] = (reg_box[j, q, 0] - box[i, 0]) / wu
        cand[1] = (reg_box[j, q, 1] - box[i, 0]) / wu
        cand[2] = (reg_box[j, q, 2] - box[i, 2]) / wv
        cand[3] = (reg_box[j, q, 3] - box[i, 2]) / wv
        score = np.inf
        k = 0
        for c in range(4):
            sc = abs(cand[c] - 0.5) if (cand[c] > margin and cand[c] < hi) else np.inf
            if c == 0 or sc < score:
                score = sc
                k = c
        if math.isfinite(score):
            t[i] = cand[k]
            along[i] = k < 2
    return t, along


@helper
def halves(node, nets, box, opened, t, along, rational):
    """The open pairs' pieces (``faceset_subdivide.children``): the halved nodes once each,
    ascending, then the pairs cut along u, then along v, each side's pieces together:
    (parent pair (n2,), node (n2,), nets (N2, 4, p+1, q+1), box (n2, 4))."""
    n = node.shape[0]
    N = nets.shape[0]
    mark = np.full(N, -1, np.int64)
    nfree = 0
    nu_ = 0
    nv_ = 0
    for i in range(n):
        if not opened[i]:
            continue
        if t[i] == t[i]:
            if along[i]:
                nu_ += 1
            else:
                nv_ += 1
        else:
            nfree += 1
            mark[node[i]] = 0
    U = 0
    for k in range(N):
        if mark[k] >= 0:
            mark[k] = U
            U += 1
    # (the nets copied as rows of D numbers: numba's copies of 4-d slices compile slowly)
    P1 = nets.shape[2]
    Q1 = nets.shape[3]
    D = nets.size // N if N else 0
    flat = nets.reshape(N, D)
    half = np.empty((U, D))
    for k in range(N):
        if mark[k] >= 0:
            copy_row(flat, k, half, mark[k])
    au, left, right = halve(half.reshape((U, 4, P1, Q1)), rational)
    nc = nu_ + nv_
    n2 = 2 * nfree + 2 * nc
    out = np.empty((2 * U + 2 * nc, D))
    lf = left.reshape(U, D)
    rf = right.reshape(U, D)
    for k in range(U):
        copy_row(lf, k, out, k)
        copy_row(rf, k, out, U + k)
    parent = np.empty(n2, np.int64)
    onode = np.empty(n2, np.int64)
    obox = np.empty((n2, 4))
    p = 0
    for i in range(n):
        if opened[i] and t[i] != t[i]:
            parent[p] = i
            parent[p + nfree] = i
            k = mark[node[i]]
            onode[p] = k
            onode[p + nfree] = U + k
            b0 = box[i, 0]
            b1 = box[i, 1]
            b2 = box[i, 2]
            b3 = box[i, 3]
            mu = 0.5 * (b0 + b1)
            mv = 0.5 * (b2 + b3)
            u_ = au[k]
            obox[p, 0] = b0
            obox[p, 1] = mu if u_ else b1
            obox[p, 2] = b2
            obox[p, 3] = b3 if u_ else mv
            obox[p + nfree, 0] = mu if u_ else b0
            obox[p + nfree, 1] = b1
            obox[p + nfree, 2] = b2 if u_ else mv
            obox[p + nfree, 3] = b3
            p += 1
    base = 2 * nfree
    nbase = 2 * U
    for side in range(2):
        axis_u = side == 0
        mk = nu_ if axis_u else nv_
        if mk == 0:
            continue
        src = np.empty((mk, D))
        tt = np.empty(mk)
        flags = np.zeros(mk, np.bool_)
        lo = 0 if axis_u else 2
        c = 0
        for i in range(n):
            if opened[i] and t[i] == t[i] and along[i] == axis_u:
                copy_row(flat, node[i], src, c)
                tt[c] = t[i]
                flags[c] = axis_u
                parent[base + c] = i
                parent[base + mk + c] = i
                onode[base + c] = nbase + c
                onode[base + mk + c] = nbase + mk + c
                mid = box[i, lo] + t[i] * (box[i, lo + 1] - box[i, lo])
                for e in range(4):
                    obox[base + c, e] = box[i, e]
                    obox[base + mk + c, e] = box[i, e]
                obox[base + c, lo + 1] = mid
                obox[base + mk + c, lo] = mid
                c += 1
        sl, sr = split_at(src.reshape((mk, 4, P1, Q1)), flags, tt)
        sl = sl.reshape(mk, D)
        sr = sr.reshape(mk, D)
        for k in range(mk):
            copy_row(sl, k, out, nbase + k)
            copy_row(sr, k, out, nbase + mk + k)
        base += 2 * mk
        nbase += 2 * mk
    return parent, onode, out.reshape((2 * U + 2 * nc, 4, P1, Q1)), obox


@helper
def classify_halves(parent, obox, status, segs, edges, table, v0, h, inner):
    """The pieces' trim status and segments: a straddling parent's listed segments that
    cross the piece, else the trim test at its middle (``faceset_trims._FaceData.
    _classify``); status -1 where the parent's segments were too many to list."""
    n2 = parent.shape[0]
    MS = segs.shape[1]
    ostatus = np.ones(n2, np.int8)
    osegs = np.full((n2, MS), -1, np.int64)
    for r in range(n2):
        i = parent[r]
        if status[i] != 2:
            continue
        if segs[i, 0] == -2:
            ostatus[r] = -1
            continue
        c = kept_in_box(edges, segs, i, obox, r, osegs)
        if c > 0:
            ostatus[r] = 2
        elif inside_one(table, v0, h, 0.5 * (obox[r, 0] + obox[r, 1]),
                        0.5 * (obox[r, 2] + obox[r, 3]), inner[0], inner[1], inner[2],
                        inner[3]):
            ostatus[r] = 1
        else:
            ostatus[r] = 0
    return ostatus, osegs


def _open_split_loops(j, query, node, nets, box, depth, status, segs, ub, best, gap, reg_box,
                      reg_val, given_up, certify, max_depth, max_open, margin, rational, edges,
                      table, v0, h, inner, crowded):
    """The pairs of face row ``j`` still open (:func:`open_pairs`: the gaps of the pairs
    left open otherwise go to ``gap``, and the crowded queries are marked in ``crowded``
    (m,), in place), cut along a region's side or halved (:func:`region_cuts`,
    :func:`halves`), their pieces' trim status and segments classified by their parents'
    listed segments (:func:`classify_halves`; status -1: a parent with too many to list,
    for the caller): (uncertified count, parent pair (n2,), query (n2,), node (n2,), nets
    (N2, 4, p+1, q+1), box (n2, 4), depth (n2,), status (n2,), segs (n2, K), whether the
    pieces outside the trim are dropped already: none waits for the caller)."""
    opened, inreg, unc = open_pairs(j, query, box, depth, ub, best, gap, reg_box, reg_val,
                                    given_up, certify, max_depth, max_open, crowded)
    t, along = region_cuts(j, query, box, opened, inreg, reg_box, margin)
    parent, onode, out, obox = halves(node, nets, box, opened, t, along, rational)
    n2 = parent.shape[0]
    oq = np.empty(n2, np.int64)
    odepth = np.empty(n2, np.int64)
    for r in range(n2):
        oq[r] = query[parent[r]]
        odepth[r] = depth[parent[r]] + 1
    ostatus, osegs = classify_halves(parent, obox, status, segs, edges, table, v0, h, inner)
    # the pieces outside the trim dropped here unless some wait for the caller's classification
    keep = 0
    for r in range(n2):
        if ostatus[r] < 0:
            return unc, parent, oq, onode, out, obox, odepth, ostatus, osegs, False
        if ostatus[r] > 0:
            keep += 1
    if keep < n2:
        rows = np.empty(keep, np.int64)
        c = 0
        for r in range(n2):
            if ostatus[r] > 0:
                rows[c] = r
                c += 1
        parent = parent[rows]
        oq = oq[rows]
        onode = onode[rows]
        obox = obox[rows]
        odepth = odepth[rows]
        ostatus = ostatus[rows]
        osegs = osegs[rows]
    return unc, parent, oq, onode, out, obox, odepth, ostatus, osegs, True


bound_pairs = Kernel(_bound_pairs_loops)
record_contacts = Kernel(_record_contacts_loops)
open_split = Kernel(_open_split_loops)
