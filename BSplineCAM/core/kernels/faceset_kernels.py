# SPDX-License-Identifier: LGPL-2.1-or-later
"""Loop-style twins of the drop-cutter's per-level computations over (query, sub-patch) pairs
(:mod:`..toolpath.faceset_bounds`, :mod:`..toolpath.faceset_subdivide`,
:mod:`..toolpath.faceset_trims`), compiled by :class:`BSplineCAM.core.kernels.Kernel`.

Each function computes what its numpy twin computes, element by element in the same order of
operations, so both engines give the same bits: sums over a control net follow numpy's
pairwise summation (:func:`net_coords`), ``np.maximum``/``np.minimum`` keep their NaN rule
(a NaN operand gives NaN), and nothing is contracted into fused multiply-adds.  They take and
return contiguous float64, int64 and bool arrays only.
"""

from __future__ import annotations

import math

import numpy as np

#: Most control points of a net whose centroid :func:`net_coords` sums (numpy's pairwise sum
#: of up to 128 terms is one 8-way block; larger nets take the numpy engine).
MAX_NET = 128


def net_coords(flat, rational):
    """The control points' coordinate planes PX, PY, PZ (N, K) of homogeneous nets ``flat``
    (N, 4, K) (divided by the weights if ``rational``), their centroids (N, 3) (numpy's
    ``mean``: pairwise sum, then divided by K), the deviations G (3, N, K) of (z, x, y) from
    the centroid and the net boxes (N, 5): x min, x max, y min, y max, z max."""
    N = flat.shape[0]
    K = flat.shape[2]
    PX = np.empty((N, K))
    PY = np.empty((N, K))
    PZ = np.empty((N, K))
    cen = np.empty((N, 3))
    G = np.empty((3, N, K))
    box = np.empty((N, 5))
    for n in range(N):
        for k in range(K):
            if rational:
                w = flat[n, 3, k]
                PX[n, k] = flat[n, 0, k] / w
                PY[n, k] = flat[n, 1, k] / w
                PZ[n, k] = flat[n, 2, k] / w
            else:
                PX[n, k] = flat[n, 0, k]
                PY[n, k] = flat[n, 1, k]
                PZ[n, k] = flat[n, 2, k]
        for c in range(3):
            if c == 0:
                a = PX[n]
            elif c == 1:
                a = PY[n]
            else:
                a = PZ[n]
            # numpy's pairwise sum (reduction started at 0)
            if K < 8:
                s = -0.0
                for i in range(K):
                    s += a[i]
            else:
                r0 = a[0]
                r1 = a[1]
                r2 = a[2]
                r3 = a[3]
                r4 = a[4]
                r5 = a[5]
                r6 = a[6]
                r7 = a[7]
                i = 8
                top = K - K % 8
                while i < top:
                    r0 += a[i]
                    r1 += a[i + 1]
                    r2 += a[i + 2]
                    r3 += a[i + 3]
                    r4 += a[i + 4]
                    r5 += a[i + 5]
                    r6 += a[i + 6]
                    r7 += a[i + 7]
                    i += 8
                s = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
                while i < K:
                    s += a[i]
                    i += 1
            cen[n, c] = (0.0 + s) / K
        xlo = PX[n, 0]
        xhi = PX[n, 0]
        ylo = PY[n, 0]
        yhi = PY[n, 0]
        zhi = PZ[n, 0]
        for k in range(K):
            x = PX[n, k]
            y = PY[n, k]
            z = PZ[n, k]
            G[0, n, k] = z - cen[n, 2]
            G[1, n, k] = x - cen[n, 0]
            G[2, n, k] = y - cen[n, 1]
            if x < xlo or x != x:
                xlo = x
            if x > xhi or x != x:
                xhi = x
            if y < ylo or y != y:
                ylo = y
            if y > yhi or y != y:
                yhi = y
            if z > zhi or z != z:
                zhi = z
        box[n, 0] = xlo
        box[n, 1] = xhi
        box[n, 2] = ylo
        box[n, 3] = yhi
        box[n, 4] = zhi
    return PX, PY, PZ, cen, G, box


def pair_bounds(nd, qq, R2, box, cen, C, RS):
    """Per pair (query ``qq`` (n, 2), sub-patch ``nd`` (n,)): the box bound ``ub`` (-inf out
    of reach), the squared xy distance ``dd`` of the net's box and ``reach``; and the parts of
    the tangent-plane bound at the centroid: its z, s0 = sqrt(R^2 - d0^2), ``lin_ok``, the
    affine part's coefficients (n, 3), the largest residual and the affine part's largest
    value on the box (``faceset_bounds._box_bound`` and ``_tangent_plane``)."""
    n = nd.shape[0]
    K = RS.shape[2]
    ub = np.empty(n)
    dd = np.empty(n)
    reach = np.empty(n, np.bool_)
    cz = np.empty(n)
    s0 = np.empty(n)
    lin_ok = np.empty(n, np.bool_)
    coef = np.empty((n, 3))
    resid = np.empty(n)
    amax = np.empty(n)
    lim = 0.999 * R2
    for i in range(n):
        j = nd[i]
        qx = qq[i, 0]
        qy = qq[i, 1]
        dx = max(max(box[j, 0] - qx, qx - box[j, 1]), 0.0)
        dy = max(max(box[j, 2] - qy, qy - box[j, 3]), 0.0)
        d2 = dx * dx + dy * dy
        dd[i] = d2
        ok = d2 <= R2
        reach[i] = ok
        if ok:
            ub[i] = box[j, 4] + math.sqrt(max(R2 - d2, 0.0))
        else:
            ub[i] = -np.inf
        cz[i] = cen[j, 2]
        ox = cen[j, 0] - qx
        oy = cen[j, 1] - qy
        d0 = ox * ox + oy * oy
        lin_ok[i] = d0 < lim
        s = math.sqrt(max(R2 - d0, 1e-300))
        s0[i] = s
        a = ox / s
        b = oy / s
        for c in range(3):
            coef[i, c] = C[0, j, c] - a * C[1, j, c] - b * C[2, j, c]
        r = RS[0, j, 0] - a * RS[1, j, 0] - b * RS[2, j, 0]
        for k in range(1, K):
            x = RS[0, j, k] - a * RS[1, j, k] - b * RS[2, j, k]
            if x > r or x != x:
                r = x
        resid[i] = r
        amax[i] = coef[i, 0] + max(coef[i, 1], 0.0) + max(coef[i, 2], 0.0)
    return ub, dd, reach, cz, s0, lin_ok, coef, resid, amax


def corner_lower(nd, qq, touch_R2, R2, PX, PY, PZ, cidx, cok):
    """The best f at each pair's corner control points inside the trim (``cok`` (n, 4)) and
    within the ball's reach, -inf if none, and which corner (the first of equals)
    (the corners part of ``faceset_bounds._lower_bounds``)."""
    n = nd.shape[0]
    lb = np.empty(n)
    kk = np.zeros(n, np.int64)
    for i in range(n):
        j = nd[i]
        best = -np.inf
        arg = 0
        for c in range(4):
            k = cidx[c]
            dx = PX[j, k] - qq[i, 0]
            dy = PY[j, k] - qq[i, 1]
            d2 = dx * dx + dy * dy
            f = -np.inf
            if d2 <= touch_R2 and cok[i, c]:
                f = PZ[j, k] + math.sqrt(max(R2 - d2, 0.0))
            if c == 0:
                best = f
            elif f > best:
                best = f
                arg = c
        lb[i] = best
        kk[i] = arg
    return lb, kk


def halve(nets, rational):
    """de Casteljau halving of nets (U, 4, p+1, q+1) along the longer side (the sum of the
    corners' xy distances, u on ties): (along u (U,), left halves, right halves)
    (``faceset_subdivide._longer_u`` and ``faceset_bezier._split_into``)."""
    U = nets.shape[0]
    D = nets.shape[1]
    P1 = nets.shape[2]
    Q1 = nets.shape[3]
    along = np.empty(U, np.bool_)
    left = np.empty_like(nets)
    right = np.empty_like(nets)
    cx = np.empty((2, 2, 2))
    wk = np.empty(max(P1, Q1))
    for m in range(U):
        for i in range(2):
            for j in range(2):
                ii = i * (P1 - 1)
                jj = j * (Q1 - 1)
                for c in range(2):
                    if rational:
                        cx[c, i, j] = nets[m, c, ii, jj] / nets[m, 3, ii, jj]
                    else:
                        cx[c, i, j] = nets[m, c, ii, jj]
        len_u = -0.0
        len_v = -0.0
        for c in range(2):
            for j in range(2):
                len_u += abs(cx[c, 1, j] - cx[c, 0, j])
        for c in range(2):
            for i in range(2):
                len_v += abs(cx[c, i, 1] - cx[c, i, 0])
        au = len_u >= len_v
        along[m] = au
        if au:
            k = P1
            other = Q1
        else:
            k = Q1
            other = P1
        for d in range(D):
            for o in range(other):
                for r in range(k):
                    wk[r] = nets[m, d, r, o] if au else nets[m, d, o, r]
                if au:
                    left[m, d, 0, o] = wk[0]
                    right[m, d, k - 1, o] = wk[k - 1]
                else:
                    left[m, d, o, 0] = wk[0]
                    right[m, d, o, k - 1] = wk[k - 1]
                for r in range(1, k):
                    for i in range(k - r):
                        wk[i] = (wk[i] + wk[i + 1]) * 0.5
                    if au:
                        left[m, d, r, o] = wk[0]
                        right[m, d, k - 1 - r, o] = wk[k - 1 - r]
                    else:
                        left[m, d, o, r] = wk[0]
                        right[m, d, o, k - 1 - r] = wk[k - 1 - r]
    return along, left, right


def split_at(nets, along_u, t):
    """Both sides of de Casteljau's split of nets (n, 4, p+1, q+1) at local parameters t (n,)
    along u (``along_u``) or v (``faceset_bezier._split_at``, kept left and right)."""
    n = nets.shape[0]
    D = nets.shape[1]
    P1 = nets.shape[2]
    Q1 = nets.shape[3]
    left = np.empty_like(nets)
    right = np.empty_like(nets)
    wk = np.empty(max(P1, Q1))
    for m in range(n):
        au = along_u[m]
        tt = t[m]
        if au:
            k = P1
            other = Q1
        else:
            k = Q1
            other = P1
        for d in range(D):
            for o in range(other):
                for r in range(k):
                    wk[r] = nets[m, d, r, o] if au else nets[m, d, o, r]
                if au:
                    left[m, d, 0, o] = wk[0]
                    right[m, d, k - 1, o] = wk[k - 1]
                else:
                    left[m, d, o, 0] = wk[0]
                    right[m, d, o, k - 1] = wk[k - 1]
                for r in range(1, k):
                    for i in range(k - r):
                        wk[i] = wk[i] + tt * (wk[i + 1] - wk[i])
                    if au:
                        left[m, d, r, o] = wk[0]
                        right[m, d, k - 1 - r, o] = wk[k - 1 - r]
                    else:
                        left[m, d, o, r] = wk[0]
                        right[m, d, o, k - 1 - r] = wk[k - 1 - r]
    return left, right
